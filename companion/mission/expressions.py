"""Safe arithmetic expressions for mission files, compiled to numpy-vectorised callables.

A mission writes curves as text, e.g. ``y_of_x: "10*sin(0.078*x) + 20*cos(0.082*x)"``. The text is
parsed with :mod:`ast` and checked node by node against a whitelist; nothing the user writes is ever
passed to ``eval`` or ``exec``. The checked tree is turned into a tree of small Python closures that
apply numpy functions, so the result evaluates a whole array of parameter values at once.

Allowed: numbers, the one variable the path kind names (``x`` or ``s``), the constants ``pi`` and
``e``, ``+ - * / **``, unary ``-`` and ``+``, parentheses, and the functions in :data:`FUNCTIONS`.
Everything else (attributes, subscripts, comparisons, keyword arguments, strings, other names) is
rejected with a message naming what was found and what is allowed.

Examples
--------
>>> f = compile_expression("2*x + sin(pi*x)", "x")
>>> float(f(0.5))
2.0
"""

from __future__ import annotations

import ast
import math
from typing import Callable

import numpy as np

#: Function name -> (numpy implementation, number of arguments).
FUNCTIONS: dict[str, tuple[Callable, int]] = {
    "sin": (np.sin, 1),
    "cos": (np.cos, 1),
    "tan": (np.tan, 1),
    "asin": (np.arcsin, 1),
    "acos": (np.arccos, 1),
    "atan": (np.arctan, 1),
    "atan2": (np.arctan2, 2),
    "sinh": (np.sinh, 1),
    "cosh": (np.cosh, 1),
    "tanh": (np.tanh, 1),
    "exp": (np.exp, 1),
    "log": (np.log, 1),
    "sqrt": (np.sqrt, 1),
    "abs": (np.abs, 1),
}
CONSTANTS: dict[str, float] = {"pi": math.pi, "e": math.e}
BINARY_OPS = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply, ast.Div: np.divide,
              ast.Pow: np.power}
UNARY_OPS = {ast.USub: np.negative, ast.UAdd: np.positive}
OP_SYMBOLS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}

MAX_EXPRESSION_CHARS = 2000
MAX_DEPTH = 60


class ExpressionError(ValueError):
    """An expression is not in the whitelist. ``problems`` lists every reason, one per entry."""

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        super().__init__("; ".join(self.problems))


def _describe(node: ast.AST) -> str:
    try:
        return repr(ast.unparse(node))
    except Exception:  # pragma: no cover - unparse handles every node ast.parse produces
        return type(node).__name__


def compile_expression(text: str, variable: str) -> Callable[[np.ndarray], np.ndarray]:
    """Check ``text`` against the whitelist and compile it to a vectorised function of ``variable``.

    Parameters
    ----------
    text : the expression, e.g. ``"10*sin(0.078*x)"``.
    variable : the one free name allowed (``"x"`` for function paths, ``"s"`` for parametric ones;
        ``""`` for a constant expression such as ``"2*pi"``).

    Returns
    -------
    callable
        ``f(values) -> ndarray`` of the same shape as ``np.asarray(values, float)``; constant
        expressions are broadcast to that shape. Floating-point warnings are silenced: callers
        check the result for NaN and infinity.

    Raises
    ------
    ExpressionError
        listing every problem found (syntax, unknown names, forbidden constructs, wrong arity).
    """
    if not isinstance(text, str):
        raise ExpressionError([f"expected an expression string, got {type(text).__name__}"])
    if len(text) > MAX_EXPRESSION_CHARS:
        raise ExpressionError([f"expected at most {MAX_EXPRESSION_CHARS} characters, got {len(text)}"])
    if not text.strip():
        raise ExpressionError(["expected an expression, got an empty string"])
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as err:
        raise ExpressionError([f"expected an arithmetic expression, got a syntax error at column "
                               f"{err.offset or 0}: {text.strip()!r}"]) from None
    except (ValueError, RecursionError, MemoryError):
        raise ExpressionError(["expected an arithmetic expression, got unparseable text"]) from None

    problems: list[str] = []
    try:
        compiled = _compile(tree.body, variable, problems, depth=0)
    except RecursionError:
        raise ExpressionError([f"expected nesting deeper than {MAX_DEPTH} levels to be absent"]) from None
    if problems:
        raise ExpressionError(problems)

    def evaluate(values):
        arr = np.asarray(values, dtype=float)
        with np.errstate(all="ignore"):
            out = compiled(arr)
        return np.broadcast_to(np.asarray(out, dtype=float), arr.shape).copy()

    evaluate.__doc__ = f"{text.strip()} as a function of {variable}"
    evaluate.expression = text.strip()
    return evaluate


def _compile(node: ast.AST, variable: str, problems: list[str], depth: int):
    """Return a closure ``f(var_array)`` for ``node``, appending to ``problems`` what is not allowed."""
    if depth > MAX_DEPTH:
        problems.append(f"expected nesting of at most {MAX_DEPTH} levels")
        return lambda v: v
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            problems.append(f"expected a number, got {_describe(node)}")
            return lambda v: 0.0
        value = float(node.value)
        return lambda v: value
    if isinstance(node, ast.Name):
        if node.id == variable:
            return lambda v: v
        if node.id in CONSTANTS:
            value = CONSTANTS[node.id]
            return lambda v: value
        allowed = ", ".join([variable, *CONSTANTS] if variable else CONSTANTS)
        hint = " (a function name needs parentheses)" if node.id in FUNCTIONS else ""
        problems.append(f"expected a name among {allowed}, got {node.id!r}{hint}")
        return lambda v: v
    if isinstance(node, ast.BinOp):
        op = BINARY_OPS.get(type(node.op))
        left = _compile(node.left, variable, problems, depth + 1)
        right = _compile(node.right, variable, problems, depth + 1)
        if op is None:
            problems.append(f"expected an operator among + - * / **, got {_describe(node)}")
            return lambda v: v
        return lambda v: op(left(v), right(v))
    if isinstance(node, ast.UnaryOp):
        op = UNARY_OPS.get(type(node.op))
        operand = _compile(node.operand, variable, problems, depth + 1)
        if op is None:
            problems.append(f"expected unary - or +, got {_describe(node)}")
            return lambda v: v
        return lambda v: op(operand(v))
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            name = node.func.id if isinstance(node.func, ast.Name) else _describe(node.func)
            problems.append(f"expected a function among {', '.join(FUNCTIONS)}, got {name!r}")
            return lambda v: v
        func, arity = FUNCTIONS[node.func.id]
        if node.keywords:
            problems.append(f"expected positional arguments only in {node.func.id}()")
        if len(node.args) != arity or any(isinstance(a, ast.Starred) for a in node.args):
            problems.append(f"expected {arity} argument{'s' if arity > 1 else ''} to "
                            f"{node.func.id}(), got {len(node.args)}")
            return lambda v: v
        args = [_compile(a, variable, problems, depth + 1) for a in node.args]
        if arity == 1:
            (arg,) = args
            return lambda v: func(arg(v))
        a0, a1 = args
        return lambda v: func(a0(v), a1(v))
    problems.append(f"expected arithmetic only, got {type(node).__name__} {_describe(node)}")
    return lambda v: v
