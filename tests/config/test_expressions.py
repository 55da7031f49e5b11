"""The expression translator accepts its grammar and nothing else."""
import math
import re
import time

import numpy as np
import pytest

from signorini_cli.config import expressions

pytestmark = pytest.mark.fast

XY = ("x", "y")


@pytest.mark.parametrize("text, value", [
    ("sin(2*pi*x)*(1-y)**2", math.sin(2 * math.pi * 0.25) * 0.5**2),
    ("-x + +y - 3/4", -0.25 + 0.5 - 0.75),
    ("exp(x)*log(2) + sqrt(4) - abs(-1) + tanh(0) + cos(0)", math.exp(0.25) * math.log(2) + 2),
    ("e**x", math.e**0.25),
    ("1e-2", 1e-2),
    (3, 3.0),
])
def test_parse_accepts_grammar(text, value):
    expr = expressions.parse(text, XY)
    assert expr({"x": 0.25, "y": 0.5}, expressions.numpy_functions()) == pytest.approx(value)


@pytest.mark.parametrize("text, message", [
    pytest.param("x.__class__", "attribute access is not allowed", id="attribute"),
    pytest.param("__import__('os')", "unknown function '__import__'", id="dunder-call"),
    pytest.param("__builtins__", "unknown name '__builtins__'", id="dunder-name"),
    pytest.param("import os", "import statements are not allowed", id="import"),
    pytest.param("open('f')", "unknown function 'open'", id="unknown-call"),
    pytest.param("z + 1", "unknown name 'z'", id="z-in-2d"),
    pytest.param("lambda: 1", "lambdas are not allowed", id="lambda"),
    pytest.param("[x for x in y]", "comprehensions are not allowed", id="comprehension"),
    pytest.param("'text'", "only numbers", id="string"),
    pytest.param("x**1000", "exponent larger than 100", id="huge-exponent"),
    pytest.param("sin(x, y)", "exactly one argument", id="arity"),
    pytest.param("sin(x", "syntax error", id="syntax"),
    pytest.param("x if y else 1", "if/else is not allowed", id="ternary"),
    pytest.param("x < y", "comparisons are not allowed", id="compare"),
    pytest.param("True", "only numbers", id="bool"),
    pytest.param("(lambda: 0).__globals__", "not allowed", id="globals"),
])
def test_parse_rejects(text, message):
    with pytest.raises(expressions.ExpressionError, match=message.replace("(", r"\(").replace("*", r"\*")):
        expressions.parse(text, XY)


def test_parse_reports_names():
    assert expressions.parse("x*eps + pi", ("x", "y", "eps")).names == {"x", "eps", "pi"}


def test_evaluate_numpy_vectorised():
    expr = expressions.parse("x**2 + y", XY)
    x = np.linspace(0, 1, 5)
    assert np.allclose(expr({"x": x, "y": 1.0}, expressions.numpy_functions()), x**2 + 1)


SENTINEL = "signorini-pwned"
# Known Python-injection payloads; each would create SENTINEL in the working folder if it ran.
INJECTIONS = [
    f"__import__('os').system('touch {SENTINEL}')",
    f"__import__('pathlib').Path('{SENTINEL}').touch()",
    f"open('{SENTINEL}', 'w').write('x')",
    f"exec(\"open('{SENTINEL}', 'w')\")",
    f"eval(\"open('{SENTINEL}', 'w')\")",
    f"compile(\"open('{SENTINEL}', 'w')\", 'f', 'exec')",
    f"getattr(__builtins__, 'open')('{SENTINEL}', 'w')",
    f"().__class__.__base__.__subclasses__()[0]('{SENTINEL}')",
    f"[c for c in ().__class__.__base__.__subclasses__() if c.__name__ == 'FileIO'][0]('{SENTINEL}', 'w')",
    f"(lambda: open('{SENTINEL}', 'w'))()",
    f"f\"{{open('{SENTINEL}', 'w')}}\"",
    f"(o := open)('{SENTINEL}', 'w')",
    f"x if open('{SENTINEL}', 'w') else 1",
    f"sin(open('{SENTINEL}', 'w'))",
    f"x.__class__.__init__.__globals__['os'].system('touch {SENTINEL}')",
    f"globals()['__builtins__'].open('{SENTINEL}', 'w')",
    f"breakpoint() or open('{SENTINEL}', 'w')",
    f"import os; os.system('touch {SENTINEL}')",
    f"__import__('subprocess').run(['touch', '{SENTINEL}'])",
    f"1 + exit()",
    f"x; open('{SENTINEL}', 'w')",
    f"\\u005f\\u005fimport\\u005f\\u005f('os').system('touch {SENTINEL}')",
]


@pytest.mark.parametrize("payload", INJECTIONS)
def test_parse_injection_has_no_side_effect(payload, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(expressions.ExpressionError):
        expressions.parse(payload, XY)
    assert not (tmp_path / SENTINEL).exists()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("text, message", [
    pytest.param("1/0", "division by zero in '1/0'", id="division-by-zero"),
    pytest.param("x/(2-2)", "division by zero in 'x/(2-2)'", id="division-by-folded-zero"),
    pytest.param("9**9**9", "exponent larger than 100 in '9**9**9'", id="exponent-tower"),
    pytest.param("x**(10*11)", "exponent larger than 100 in 'x**(10*11)'", id="folded-exponent"),
    pytest.param("exp(1000)", "'exp(1000)' cannot be evaluated: math range error", id="overflow"),
    pytest.param("log(0)", "'log(0)' cannot be evaluated: math domain error", id="log-zero"),
    pytest.param("(-8)**(1/3)", "'(-8)**(1/3)' is not a finite real number", id="complex"),
    pytest.param("1e999*x", "'1e999' is not a finite real number", id="inf-literal"),
    pytest.param("x\x00", "cannot parse", id="nul"),
    pytest.param("x = 1", "assignment statements are not allowed", id="statement"),
    pytest.param("x % 2", "operator '%' is not allowed", id="modulo"),
])
def test_parse_rejects_constant_faults(text, message):
    with pytest.raises(expressions.ExpressionError, match="^" + re.escape(message)):
        expressions.parse(text, XY)


def test_parse_accepts_large_but_finite_constants():
    expr = expressions.parse("2**100*x + exp(700) - 1e300", XY)
    assert np.isfinite(expr({"x": 1.0, "y": 0.0}, expressions.numpy_functions()))


def test_math_functions_raise_where_numpy_returns_nan():
    """config checks δ(h, eps) on floats: a domain error must raise, not pass as nan."""
    assert expressions.parse("sqrt(h)", ("h",))({"h": 4.0}, expressions.math_functions()) == 2.0
    with pytest.raises(ValueError):
        expressions.parse("log(h)", ("h",))({"h": 0.0}, expressions.math_functions())


# --- the functions of research problems and named definitions ----------------------------------------

@pytest.mark.parametrize("text, reference", [
    pytest.param("atan2(y, x)", np.arctan2, id="atan2"),
    pytest.param("min(x, y)", np.minimum, id="min"),
    pytest.param("max(x, y)", np.maximum, id="max"),
])
def test_two_argument_functions_agree_with_numpy(text, reference):
    x, y = np.array([-1.0, 0.5, 0.0]), np.array([1.0, -0.5, 0.0])
    assert np.array_equal(expressions.parse(text, XY)({"x": x, "y": y}, expressions.numpy_functions()),
                          reference(y, x) if text.startswith("atan2") else reference(x, y))


@pytest.mark.parametrize("name", ["asin", "acos", "atan", "sinh", "cosh", "tan"])
def test_one_argument_functions_fold_and_evaluate(name):
    folded = getattr(math, name)(0.3)
    assert expressions.parse(f"{name}(0.3) + 0*x", XY)({"x": 0.0, "y": 0.0}, expressions.math_functions()) == folded


def test_arity_is_checked():
    with pytest.raises(expressions.ExpressionError, match=r"^atan2\(\) takes exactly 2 arguments"):
        expressions.parse("atan2(y)", XY)
    with pytest.raises(expressions.ExpressionError, match=r"^sin\(\) takes exactly one argument"):
        expressions.parse("sin(x, y)", XY)


def test_definitions_inline_in_order():
    defined = expressions.definitions({"r": "sqrt(x**2 + y**2)", "t": "atan2(y, x)", "s": "r*t"}, XY)
    corner = expressions.parse("r**(2/3)*sin(2*t/3) + s", XY, defined)
    x, y = -0.5, 0.5
    r, t = math.hypot(x, y), math.atan2(y, x)
    assert corner({"x": x, "y": y}, expressions.math_functions()) == pytest.approx(r**(2/3) * math.sin(2*t/3) + r*t,
                                                                                 rel=1e-15)
    assert corner.names == {"x", "y"}  # what the definitions use, not their names


@pytest.mark.parametrize("texts, message", [
    pytest.param({"t": "r*2", "r": "x"}, "t: unknown name 'r'", id="later-name-first"),
    pytest.param({"x": "y"}, "'x': a definition cannot redefine the variable x", id="redefine-variable"),
    pytest.param({"sin": "x"}, "'sin': a definition's name must be a new identifier", id="function-name"),
])
def test_definitions_rejected(texts, message):
    with pytest.raises(expressions.ExpressionError, match="^" + re.escape(message)):
        expressions.definitions(texts, XY)


def chain(count, text):
    """count definitions a1 .. a<count>, each `text` with K the previous one's name (a0 = x)."""
    return {f"a{k}": text.replace("K", f"a{k - 1}" if k > 1 else "x") for k in range(1, count + 1)}


@pytest.mark.parametrize("texts, exact, message", [
    # each definition alone is small; inserted, they exceed the limits a literal expression has
    pytest.param(chain(1000, "sin(K)"), "a1000",
                 "a61: nested too deeply with its definitions inserted (depth 62, at most 61)", id="1000-nested"),
    pytest.param(chain(30, "K*K"), "a30", "a10: too large with its definitions inserted (2047 terms",
                 id="30-doublings"),
    pytest.param({"a": "1000"}, "x*exp(a)", "'exp(a)' cannot be evaluated: math range error", id="exp-overflow"),
    pytest.param({"p": "50+51"}, "x**p", "exponent larger than 100 in 'x**p'", id="exponent-sum"),
    pytest.param({"𝑥": "0.5"}, "x", "'𝑥': a definition's name must be ASCII", id="non-ascii-name"),
    pytest.param({}, "𝑥*(1-y)", "non-ASCII character '𝑥' (U+1D465)", id="non-ascii-expression"),
])
def test_definitions_hold_the_limits_of_literal_expressions(texts, exact, message):
    with pytest.raises(expressions.ExpressionError, match="^" + re.escape(message)):
        expressions.parse(exact, XY, expressions.definitions(texts, XY))


def test_definitions_are_shared_not_copied():
    """A definition used twice is one subtree, used twice: parsing stays linear in the definitions."""
    defined = expressions.definitions({"s": "sin(x)", "t": "s*s"}, XY)
    tree = expressions.parse("t + s", XY, defined).tree
    assert tree.left.left is tree.left.right is tree.right is defined["s"].tree


def test_thirty_doublings_are_refused_at_once():
    """Counting the inserted size visits each shared node once (it took minutes when definitions were copied)."""
    start = time.perf_counter()
    with pytest.raises(expressions.ExpressionError, match="too large"):
        expressions.definitions(chain(30, "K*K"), XY)
    assert time.perf_counter() - start < 1.0  # linear: a few ms; 1 s leaves the shared machine its slack
