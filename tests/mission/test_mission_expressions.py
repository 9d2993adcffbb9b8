"""The safe expression parser: whitelisted arithmetic compiled to vectorised numpy, nothing else."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from companion.mission.expressions import ExpressionError, compile_expression


def test_paper_sine_matches_math_pointwise_and_is_vectorised():
    f = compile_expression("10*sin(0.078*x) + 20*cos(0.082*x)", "x")
    xs = np.linspace(-15, 300, 7)
    expected = [10 * math.sin(0.078 * x) + 20 * math.cos(0.082 * x) for x in xs]
    assert f(xs) == pytest.approx(expected, abs=1e-12)
    assert f(xs).shape == xs.shape


def test_every_whitelisted_function_and_operator_evaluates_like_math():
    text = ("sqrt(abs(-x)) + exp(-x) + log(x + 1) + tan(x/3) + asin(x/4) + acos(x/4) + atan(x)"
            " + atan2(x, 2) + sinh(x) + cosh(x) + tanh(x) + 2**x - +x + pi*e")
    f = compile_expression(text, "x")
    x = 0.7
    expected = (math.sqrt(abs(-x)) + math.exp(-x) + math.log(x + 1) + math.tan(x / 3)
                + math.asin(x / 4) + math.acos(x / 4) + math.atan(x) + math.atan2(x, 2)
                + math.sinh(x) + math.cosh(x) + math.tanh(x) + 2 ** x - x + math.pi * math.e)
    assert float(f(x)) == pytest.approx(expected, rel=1e-14)


def test_power_binds_tighter_than_unary_minus_as_in_python():
    assert float(compile_expression("-2**2", "x")(0.0)) == -4.0
    assert float(compile_expression("(-2)**2", "x")(0.0)) == 4.0


def test_constant_expression_is_broadcast_to_the_input_shape():
    f = compile_expression("3*pi", "s")
    out = f(np.zeros(5))
    assert out.shape == (5,) and np.all(out == 3 * math.pi)


def test_domain_errors_give_nan_not_exceptions():
    f = compile_expression("sqrt(x)", "x")
    assert np.isnan(f(-1.0))


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("__import__('os').system('true')", "expected a function among"),
        ("x.real", "expected arithmetic only, got Attribute"),
        ("[x][0]", "expected arithmetic only, got Subscript"),
        ("x if x else 1", "expected arithmetic only, got IfExp"),
        ("lambda: 1", "expected arithmetic only, got Lambda"),
        ("x < 1", "expected arithmetic only, got Compare"),
        ("'abc'", "expected a number, got \"'abc'\""),
        ("True", "expected a number, got 'True'"),
        ("y", "expected a name among x, pi, e, got 'y'"),
        ("sin", "expected a name among x, pi, e, got 'sin' (a function name needs parentheses)"),
        ("floor(x)", "expected a function among sin, cos"),
        ("x % 2", "expected an operator among + - * / **"),
        ("x @ x", "expected an operator among + - * / **"),
        ("~x", "expected unary - or +"),
        ("sin(x, 1)", "expected 1 argument to sin(), got 2"),
        ("atan2(x=1, y=2)", "expected positional arguments only in atan2()"),
        ("sin(*x)", "expected 1 argument to sin(), got 1"),
        ("x +", "syntax error"),
        ("", "got an empty string"),
        ("sin(" * 100 + "x" + ")" * 100, "nesting"),
    ],
)
def test_forbidden_constructs_are_refused_with_a_reason(text, fragment):
    with pytest.raises(ExpressionError) as info:
        compile_expression(text, "x")
    assert fragment in str(info.value)


def test_every_problem_in_one_expression_is_listed():
    with pytest.raises(ExpressionError) as info:
        compile_expression("a*x + floor(x) + b", "x")
    assert len(info.value.problems) == 3


def test_long_text_is_refused_before_parsing():
    with pytest.raises(ExpressionError, match="at most 2000 characters"):
        compile_expression("x+" * 1500 + "x", "x")


@settings(max_examples=60, deadline=None)
@given(a=st.floats(-50, 50), b=st.floats(-2, 2), c=st.floats(-50, 50),
       x=st.lists(st.floats(-100, 100), min_size=1, max_size=8))
def test_random_affine_sines_match_math(a, b, c, x):
    f = compile_expression(f"({a!r})*sin(({b!r})*x) + ({c!r})", "x")
    expected = [a * math.sin(b * v) + c for v in x]
    assert f(np.array(x)) == pytest.approx(expected, rel=1e-12, abs=1e-12)
