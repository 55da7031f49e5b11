"""Whitelisted arithmetic expressions from configs, translated to UFL or numpy without eval."""
import ast
import math
from dataclasses import dataclass

FUNCTIONS = ("sin", "cos", "exp", "log", "sqrt", "abs", "tanh")
CONSTANTS = {"pi": math.pi, "e": math.e}
MAX_EXPONENT = 100  # a literal power above this is a typo or an attack, not a solution
MAX_LENGTH = 2000
MAX_DEPTH = 60

_BINARY = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_UNARY = {ast.UAdd: "+", ast.USub: "-"}


class ExpressionError(ValueError):
    """An expression outside the grammar; the message says what is wrong."""


@dataclass(frozen=True)
class Expression:
    """A parsed, validated expression: its text, its AST, and the variables it uses."""
    text: str
    tree: ast.AST
    names: frozenset

    def __call__(self, variables, functions):
        """Evaluate with `variables` (name -> value) and `functions` (name -> callable)."""
        return _evaluate(self.tree, variables, functions)


def parse(text, variables):
    """Parse `text` and check it uses only numbers, + - * / **, `variables`, pi, e and FUNCTIONS."""
    if isinstance(text, bool) or not isinstance(text, (str, int, float)):
        raise ExpressionError(f"must be an expression string, got {type(text).__name__}")
    text = str(text)
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"longer than {MAX_LENGTH} characters")
    try:
        tree = ast.parse(text.strip(), mode="eval").body
    except SyntaxError as err:
        raise ExpressionError(f"syntax error in {text!r} at column {err.offset}") from None
    names = set()
    _check(tree, set(variables), names, depth=0)
    return Expression(text, tree, frozenset(names))


def _check(node, variables, names, depth):
    if depth > MAX_DEPTH:
        raise ExpressionError("nested too deeply")
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            raise ExpressionError(f"only numbers are allowed as literals, got {node.value!r}")
    elif isinstance(node, ast.Name):
        if node.id not in variables and node.id not in CONSTANTS:
            allowed = ", ".join(sorted(variables) + sorted(CONSTANTS))
            raise ExpressionError(f"unknown name {node.id!r} (allowed: {allowed})")
        names.add(node.id)
    elif isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        if isinstance(node.op, ast.Pow) and _literal_value(node.right) is not None:
            if abs(_literal_value(node.right)) > MAX_EXPONENT:
                raise ExpressionError(f"exponent larger than {MAX_EXPONENT}")
        _check(node.left, variables, names, depth + 1)
        _check(node.right, variables, names, depth + 1)
    elif isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        _check(node.operand, variables, names, depth + 1)
    elif isinstance(node, ast.Call):
        _check_call(node, variables, names, depth)
    else:
        raise ExpressionError(f"{type(node).__name__} is not allowed (only numbers, + - * / **, "
                              f"names and {', '.join(FUNCTIONS)})")


def _check_call(node, variables, names, depth):
    if not isinstance(node.func, ast.Name):
        raise ExpressionError("only calls of plain function names are allowed")
    if node.func.id not in FUNCTIONS:
        raise ExpressionError(f"unknown function {node.func.id!r} (allowed: {', '.join(FUNCTIONS)})")
    if node.keywords or len(node.args) != 1:
        raise ExpressionError(f"{node.func.id}() takes exactly one argument")
    _check(node.args[0], variables, names, depth + 1)


def _literal_value(node):
    """The number a literal (possibly negated) stands for, else None."""
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
        return node.value
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        inner = _literal_value(node.operand)
        return None if inner is None else -inner
    return None


def _evaluate(node, variables, functions):
    if isinstance(node, ast.Constant):
        return float(node.value)
    if isinstance(node, ast.Name):
        return variables[node.id] if node.id in variables else CONSTANTS[node.id]
    if isinstance(node, ast.UnaryOp):
        value = _evaluate(node.operand, variables, functions)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.Call):
        return functions[node.func.id](_evaluate(node.args[0], variables, functions))
    left = _evaluate(node.left, variables, functions)
    right = _evaluate(node.right, variables, functions)
    return {"+": lambda: left + right, "-": lambda: left - right, "*": lambda: left * right,
            "/": lambda: left / right, "**": lambda: left ** right}[_BINARY[type(node.op)]]()


def ufl_functions():
    """The whitelisted functions as UFL operators."""
    import ufl
    return {"sin": ufl.sin, "cos": ufl.cos, "exp": ufl.exp, "log": ufl.ln, "sqrt": ufl.sqrt,
            "abs": abs, "tanh": ufl.tanh}


def numpy_functions():
    """The whitelisted functions as numpy ufuncs."""
    import numpy as np
    return {"sin": np.sin, "cos": np.cos, "exp": np.exp, "log": np.log, "sqrt": np.sqrt,
            "abs": np.abs, "tanh": np.tanh}
