"""The expression translator accepts its grammar and nothing else."""
import math

import numpy as np
import pytest

from signorini_cli import expressions

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
    pytest.param("x.__class__", "Attribute is not allowed", id="attribute"),
    pytest.param("__import__('os')", "unknown function '__import__'", id="dunder-call"),
    pytest.param("__builtins__", "unknown name '__builtins__'", id="dunder-name"),
    pytest.param("import os", "syntax error", id="import"),
    pytest.param("open('f')", "unknown function 'open'", id="unknown-call"),
    pytest.param("z + 1", "unknown name 'z'", id="z-in-2d"),
    pytest.param("lambda: 1", "Lambda is not allowed", id="lambda"),
    pytest.param("[x for x in y]", "ListComp is not allowed", id="comprehension"),
    pytest.param("'text'", "only numbers", id="string"),
    pytest.param("x**1000", "exponent larger than 100", id="huge-exponent"),
    pytest.param("sin(x, y)", "exactly one argument", id="arity"),
    pytest.param("sin(x", "syntax error", id="syntax"),
    pytest.param("x if y else 1", "IfExp is not allowed", id="ternary"),
    pytest.param("x < y", "Compare is not allowed", id="compare"),
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
