"""Whitelisted arithmetic expressions from configs, translated to UFL or numpy without eval."""
import ast
import math
from dataclasses import dataclass

FUNCTIONS = ("sin", "cos", "tan", "exp", "log", "sqrt", "abs", "tanh", "sinh", "cosh", "asin", "acos", "atan",
             "atan2", "min", "max")
ARITY = {"atan2": 2, "min": 2, "max": 2}  # the others take one argument
CONSTANTS = {"pi": math.pi, "e": math.e}
MAX_EXPONENT = 100  # a constant power above this is a typo or an attack, not a solution
MAX_LENGTH = 2000
MAX_DEPTH = 60
# nodes of an expression with its definitions inserted: a literal expression of MAX_LENGTH characters has
# fewer, and definitions may not get around the limit by doubling (a: "x*x", b: "a*a", ...)
MAX_NODES = MAX_LENGTH

_BINARY = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_UNARY = {ast.UAdd: "+", ast.USub: "-"}
# what a rejected construct is called in the message (the AST class name otherwise)
_FORBIDDEN = {ast.Attribute: "attribute access is", ast.Subscript: "subscripts are", ast.Lambda: "lambdas are",
              ast.ListComp: "comprehensions are", ast.SetComp: "comprehensions are",
              ast.DictComp: "comprehensions are", ast.GeneratorExp: "comprehensions are",
              ast.Compare: "comparisons are", ast.BoolOp: "and/or are", ast.IfExp: "if/else is",
              ast.JoinedStr: "f-strings are", ast.NamedExpr: "assignments (:=) are", ast.List: "lists are",
              ast.Tuple: "tuples are", ast.Set: "sets are", ast.Dict: "dicts are", ast.Await: "await is"}
_OPERATORS = {ast.Mod: "%", ast.FloorDiv: "//", ast.MatMult: "@", ast.LShift: "<<", ast.RShift: ">>",
              ast.BitAnd: "&", ast.BitOr: "|", ast.BitXor: "^", ast.Invert: "~", ast.Not: "not"}
_MATH = {"sin": math.sin, "cos": math.cos, "tan": math.tan, "exp": math.exp, "log": math.log,
         "sqrt": math.sqrt, "abs": abs, "tanh": math.tanh, "sinh": math.sinh, "cosh": math.cosh,
         "asin": math.asin, "acos": math.acos, "atan": math.atan, "atan2": math.atan2, "min": min,
         "max": max}  # folds constant sub-expressions at parse time


class ExpressionError(ValueError):
    """An expression outside the grammar; the message says what is wrong."""


class DefinitionError(ExpressionError):
    """A definition's text outside the grammar: `name` says which definition."""

    def __init__(self, name, message):
        self.name, self.message = name, message
        super().__init__(f"{name}: {message}")


@dataclass(frozen=True)
class Expression:
    """A parsed, validated expression: its text, its AST (the trees of the definitions it uses are shared,
    not copied), the variables it uses, and its value when it is a constant."""
    text: str
    tree: ast.AST
    names: frozenset
    value: float = None

    def __call__(self, variables, functions):
        """Evaluate with `variables` (name -> value) and `functions` (name -> callable)."""
        return _evaluate(self.tree, variables, functions)


def parse(text, variables, defined=None):
    """Parse `text` and check it uses only numbers, + - * / **, `variables`, pi, e, FUNCTIONS and the
    names `defined` (name -> Expression), which are replaced by their definitions."""
    if isinstance(text, bool) or not isinstance(text, (str, int, float)):
        raise ExpressionError(f"must be an expression string, got {type(text).__name__}")
    if isinstance(text, float) and not math.isfinite(text):
        raise ExpressionError(f"must be finite, got {text}")
    text = str(text)
    if not text.isascii():  # Python would read a name such as 𝑥 (mathematical italic) as x
        character = next(c for c in text if not c.isascii())
        raise ExpressionError(f"non-ASCII character {character!r} (U+{ord(character):04X}): names, numbers and "
                              "operators are ASCII")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"longer than {MAX_LENGTH} characters")
    source = text.strip()
    try:
        tree = ast.parse(source, mode="eval").body
    except SyntaxError as err:
        raise ExpressionError(_statement(source) or
                              f"syntax error in {_clip(text)!r} at column {err.offset}: {err.msg}") from None
    except (ValueError, RecursionError) as err:  # NUL bytes; nesting beyond the parser's stack
        raise ExpressionError(f"cannot parse {_clip(text)!r}: {err}") from None
    defined = defined or {}
    grammar = _Grammar(set(variables), source, defined)
    value = grammar.check(tree, depth=0)
    tree = _Inline(defined).visit(tree)
    _check_extent(tree)
    used = set().union(*(defined[n].names if n in defined else {n} for n in grammar.names))
    return Expression(text, tree, frozenset(used), value)


def definitions(texts, variables):
    """{name: Expression} of named subexpressions, in order: each may use the variables and the names
    defined before it. `texts` is a mapping name -> expression text."""
    defined = {}
    for name, text in texts.items():
        if not isinstance(name, str) or not name.isidentifier() or name in FUNCTIONS or name in CONSTANTS:
            raise ExpressionError(f"{name!r}: a definition's name must be a new identifier")
        if not name.isascii():  # Python reads 𝑥 in an expression as x: the definition would never be used
            raise ExpressionError(f"{name!r}: a definition's name must be ASCII")
        if name in variables:
            raise ExpressionError(f"{name!r}: a definition cannot redefine the variable {name}")
        try:
            defined[name] = parse(text, variables, defined)
        except ExpressionError as err:
            raise DefinitionError(name, str(err)) from None
    return defined


class _Inline(ast.NodeTransformer):
    """Replaces each defined name by its definition's tree, shared (never copied, never changed)."""

    def __init__(self, defined):
        self.defined = defined

    def visit_Name(self, node):
        return self.defined[node.id].tree if node.id in self.defined else node


def _check_extent(tree):
    """Refuse a tree deeper than MAX_DEPTH or larger than MAX_NODES once its shared definitions are counted
    at every use; each node is visited once, so a million-fold expansion is counted, not built."""
    extent = {}  # id(node) -> (depth, nodes)
    stack = [(tree, False)]
    while stack:  # depth-first, children before their parent, without recursion
        node, expanded = stack.pop()
        if id(node) in extent:
            continue
        children = [child for child in ast.iter_child_nodes(node) if isinstance(child, ast.expr)]  # not ops
        if not expanded:
            stack.append((node, True))
            stack.extend((child, False) for child in children if id(child) not in extent)
            continue
        below = [extent[id(child)] for child in children]
        extent[id(node)] = (1 + max((d for d, _ in below), default=0), 1 + sum(n for _, n in below))
    depth, nodes = extent[id(tree)]
    if depth > MAX_DEPTH + 1:
        raise ExpressionError(f"nested too deeply with its definitions inserted (depth {depth}, at most "
                              f"{MAX_DEPTH + 1})")
    if nodes > MAX_NODES:
        raise ExpressionError(f"too large with its definitions inserted ({nodes} terms, at most {MAX_NODES})")


def _statement(source):
    """'import statements are not allowed ...' when `source` is a Python statement, not an expression."""
    try:
        body = ast.parse(source, mode="exec").body  # parsed only, never compiled or run
    except (SyntaxError, ValueError, RecursionError):
        return None
    if not body or isinstance(body[0], ast.Expr):
        return None
    kind = _STATEMENTS.get(type(body[0]), type(body[0]).__name__.lower())
    return f"{kind} statements are not allowed (an expression is expected)"


_STATEMENTS = {ast.Import: "import", ast.ImportFrom: "import", ast.Assign: "assignment",
               ast.AugAssign: "assignment", ast.AnnAssign: "assignment", ast.FunctionDef: "def",
               ast.AsyncFunctionDef: "def", ast.ClassDef: "class"}


def _clip(text, width=40):
    return text if len(text) <= width else text[:width - 3] + "..."


class _Grammar:
    """The checker: walks the AST, collects the names used, folds and checks constant parts."""

    def __init__(self, variables, source, defined):
        self.variables, self.source, self.defined, self.names = variables, source, defined, set()

    def check(self, node, depth):
        """Check `node` against the grammar; return its value when it is constant, else None."""
        if depth > MAX_DEPTH:
            raise ExpressionError("nested too deeply")
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise ExpressionError(f"only numbers are allowed as literals, got {_clip(repr(node.value))}")
            return self.finite(lambda: float(node.value), node)
        if isinstance(node, ast.Name):
            return self.name(node)
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            left, right = self.check(node.left, depth + 1), self.check(node.right, depth + 1)
            return self.fold_binary(node, left, right)
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            value = self.check(node.operand, depth + 1)
            return None if value is None else (-value if isinstance(node.op, ast.USub) else value)
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        raise ExpressionError(f"{_construct(node)} not allowed (only numbers, + - * / **, "
                              f"names and {', '.join(FUNCTIONS)})")

    def name(self, node):
        """A variable (None), a constant, or a definition: its value where it is constant, so that the
        limits on constant parts hold through definitions (a: "1000" in exp(a), p: "50+51" in x**p)."""
        if node.id not in self.variables and node.id not in CONSTANTS and node.id not in self.defined:
            allowed = ", ".join(sorted(self.variables) + sorted(self.defined) + sorted(CONSTANTS))
            raise ExpressionError(f"unknown name {_clip(node.id)!r} (allowed: {allowed})")
        self.names.add(node.id)
        if node.id in self.defined:
            return self.defined[node.id].value
        return CONSTANTS[node.id] if node.id not in self.variables else None

    def fold_binary(self, node, left, right):
        """Reject exponents above MAX_EXPONENT and division by zero; fold two constant sides."""
        if isinstance(node.op, ast.Pow) and right is not None and abs(right) > MAX_EXPONENT:
            raise ExpressionError(f"exponent larger than {MAX_EXPONENT} in {self.show(node)!r}")
        if isinstance(node.op, ast.Div) and right == 0:
            raise ExpressionError(f"division by zero in {self.show(node)!r}")
        if left is None or right is None:
            return None
        operation = {ast.Add: float.__add__, ast.Sub: float.__sub__, ast.Mult: float.__mul__,
                     ast.Div: float.__truediv__, ast.Pow: float.__pow__}[type(node.op)]
        return self.finite(lambda: operation(left, right), node)

    def call(self, node, depth):
        if not isinstance(node.func, ast.Name):
            self.check(node.func, depth + 1)  # names what is wrong in `x.f()`, `(lambda: 0)()` ...
            raise ExpressionError(f"only calls of plain function names are allowed, not {self.show(node.func)!r}")
        if node.func.id not in FUNCTIONS:
            raise ExpressionError(f"unknown function {_clip(node.func.id)!r} (allowed: {', '.join(FUNCTIONS)})")
        arity = ARITY.get(node.func.id, 1)
        if node.keywords or len(node.args) != arity:
            takes = "one argument" if arity == 1 else f"{arity} arguments"
            raise ExpressionError(f"{node.func.id}() takes exactly {takes}")
        values = [self.check(arg, depth + 1) for arg in node.args]
        if any(v is None for v in values):
            return None
        return self.finite(lambda: _MATH[node.func.id](*values), node)

    def finite(self, compute, node):
        """compute(), which must be a finite real number: a constant part that is not (1e999,
        10.0**400, exp(1000), log(0), (-1)**0.5) would make every level's data inf or nan."""
        try:
            value = compute()
        except (OverflowError, ValueError, ZeroDivisionError) as err:
            raise ExpressionError(f"{self.show(node)!r} cannot be evaluated: {err}") from None
        if not isinstance(value, float) or not math.isfinite(value):
            raise ExpressionError(f"{self.show(node)!r} is not a finite real number")
        return value

    def show(self, node):
        """The source text of `node`, shortened."""
        return _clip(ast.get_source_segment(self.source, node) or ast.unparse(node))


def _construct(node):
    """How a rejected node is named in the message: 'attribute access is', 'lambdas are' ..."""
    if isinstance(node, (ast.BinOp, ast.UnaryOp)) and type(node.op) in _OPERATORS:
        return f"operator {_OPERATORS[type(node.op)]!r} is"
    return _FORBIDDEN.get(type(node), f"{type(node).__name__} is")


def _evaluate(node, variables, functions):
    if isinstance(node, ast.Constant):
        return float(node.value)
    if isinstance(node, ast.Name):
        return variables[node.id] if node.id in variables else CONSTANTS[node.id]
    if isinstance(node, ast.UnaryOp):
        value = _evaluate(node.operand, variables, functions)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.Call):
        return functions[node.func.id](*(_evaluate(arg, variables, functions) for arg in node.args))
    left = _evaluate(node.left, variables, functions)
    right = _evaluate(node.right, variables, functions)
    return {"+": lambda: left + right, "-": lambda: left - right, "*": lambda: left * right,
            "/": lambda: left / right, "**": lambda: left ** right}[_BINARY[type(node.op)]]()


def math_functions():
    """The whitelisted functions on Python floats (math: errors raise instead of returning nan)."""
    return dict(_MATH)


def ufl_functions():
    """The whitelisted functions as UFL operators."""
    import ufl
    return {"sin": ufl.sin, "cos": ufl.cos, "tan": ufl.tan, "exp": ufl.exp, "log": ufl.ln, "sqrt": ufl.sqrt,
            "abs": abs, "tanh": ufl.tanh, "sinh": ufl.sinh, "cosh": ufl.cosh, "asin": ufl.asin,
            "acos": ufl.acos, "atan": ufl.atan, "atan2": ufl.atan_2, "min": ufl.min_value, "max": ufl.max_value}


def numpy_functions():
    """The whitelisted functions as numpy ufuncs."""
    import numpy as np
    return {"sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp, "log": np.log, "sqrt": np.sqrt,
            "abs": np.abs, "tanh": np.tanh, "sinh": np.sinh, "cosh": np.cosh, "asin": np.arcsin,
            "acos": np.arccos, "atan": np.arctan, "atan2": np.arctan2, "min": np.minimum, "max": np.maximum}
