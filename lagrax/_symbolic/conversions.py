"""SymPy, imported on first use, and the conversions between SymPy objects and the arrays
the interpreter works on.

Inside the interpreter a value is a NumPy array: of numbers (`float64`, `int`, `bool`)
while it does not depend on a symbol, or of `dtype=object` holding SymPy expressions once
it does. Numbers meet symbols as exact SymPy numbers: a float within 4 units in the last place of
a fraction with a denominator up to 10⁶ (`0.5`, `1/12`, `9.81`, `0.1 + 0.2`) becomes that
`Rational` (the number the user wrote, before round-off), any other float a `Float` with
the same 53-bit value. Exact numbers cancel exactly, where floats would leave terms of
size 1e-19 behind.
"""

from __future__ import annotations

import fractions
import importlib
from typing import TYPE_CHECKING, Any

import numpy as np

from .errors import SympyMissingError

if TYPE_CHECKING:  # pragma: no cover
    import sympy

_MAX_DENOMINATOR = 10**6
_ULPS = 4  # a fraction this close is the number the user wrote (0.1 + 0.2 is 3/10)


def load_sympy() -> sympy:  # type: ignore[name-defined]
    """The `sympy` module, imported on first use (`import lagrax` does not need it).

    **Raises:** `SympyMissingError` (an `ImportError`) naming the install command when
    SymPy is not installed.
    """
    try:
        return importlib.import_module("sympy")
    except ImportError as err:  # pragma: no cover - sympy is a dev dependency
        raise SympyMissingError(
            'lagrax.symbolic needs SymPy, which is not installed: pip install "lagrax[symbolic]"'
        ) from err


def number(value: Any) -> Any:
    """A NumPy or Python number as an exact SymPy number (see the module docstring)."""
    sp = load_sympy()
    value = np.asarray(value).item()
    if isinstance(value, bool):
        return sp.true if value else sp.false
    if isinstance(value, int):
        return sp.Integer(value)
    if isinstance(value, complex):
        return sp.Float(value.real) + sp.I * sp.Float(value.imag)
    if not np.isfinite(value):
        return {np.inf: sp.oo, -np.inf: -sp.oo}.get(value, sp.nan)
    if value == int(value):
        return sp.Integer(int(value))
    frac = fractions.Fraction(value).limit_denominator(_MAX_DENOMINATOR)
    if abs(float(frac) - value) <= _ULPS * np.spacing(abs(value)):
        return sp.Rational(frac.numerator, frac.denominator)
    return sp.Float(value)


def is_symbolic(x: np.ndarray) -> bool:
    """Whether an interpreter value holds SymPy objects (`dtype=object`)."""
    return x.dtype == object


def symbolic_array(x: Any) -> np.ndarray:
    """`x` (a NumPy array of numbers or of SymPy objects, a SymPy matrix or array, a SymPy
    expression or a Python number) as an array of SymPy objects. A SymPy column matrix
    becomes a 1-D array."""
    sp = load_sympy()
    if isinstance(x, sp.MatrixBase):
        rows = np.empty(x.shape, dtype=object)
        for i, j in np.ndindex(*x.shape):
            rows[i, j] = x[i, j]
        return rows[:, 0] if x.shape[1] == 1 else rows
    if isinstance(x, sp.NDimArray):
        out = np.empty(x.shape, dtype=object)
        for index in np.ndindex(*x.shape):
            out[index] = x[index]
        return out
    if isinstance(x, sp.Basic):
        out = np.empty((), dtype=object)
        out[()] = x
        return out
    x = np.asarray(x)
    if is_symbolic(x):
        return x
    out = np.empty(x.shape, dtype=object)
    for index in np.ndindex(*x.shape):
        out[index] = number(x[index])
    return out


def wrap(value: Any) -> np.ndarray:
    """The result of a NumPy operation on object arrays (a bare SymPy object for a 0-d
    result) as an array again."""
    if isinstance(value, np.ndarray):
        return value
    out = np.empty((), dtype=object)
    out[()] = value
    return out


def numeric_or_none(x: np.ndarray) -> np.ndarray | None:
    """`x` as an array of numbers when every entry is a SymPy number or truth value (so
    an operation on it can be evaluated by JAX itself), else `None`."""
    if not is_symbolic(x):
        return x
    sp = load_sympy()
    flat = x.ravel()
    if all(isinstance(v, sp.logic.boolalg.BooleanAtom) for v in flat):
        return np.array([bool(v) for v in flat], dtype=bool).reshape(x.shape)
    if all(isinstance(v, sp.Integer) for v in flat):
        return np.array([int(v) for v in flat], dtype=np.int64).reshape(x.shape)
    if all(isinstance(v, sp.Number) and v.is_real for v in flat):
        return np.array([float(v) for v in flat], dtype=np.float64).reshape(x.shape)
    return None


def to_sympy(x: np.ndarray) -> Any:
    """An interpreter value as SymPy: an expression (0-d), a column `Matrix` (1-D), a
    `Matrix` (2-D) or an `ImmutableDenseNDimArray` (more axes)."""
    sp = load_sympy()
    x = symbolic_array(x)
    if x.ndim == 0:
        return x[()]
    if x.ndim == 1:
        return sp.Matrix(list(x))
    if x.ndim == 2:
        return sp.Matrix(x.tolist())
    return sp.ImmutableDenseNDimArray(x.tolist(), x.shape)


def tree_size(expr: Any) -> int:
    """The number of nodes of `expr`'s expression tree (symbols, numbers and operations,
    each shared subexpression counted every time it appears, as it is printed): linear
    time in the number of *distinct* subexpressions, so a call on an expression whose tree
    is exponentially large returns at once."""
    sizes: dict[Any, int] = {}
    stack = [(expr, False)]
    while stack:
        node, expanded = stack.pop()
        if node in sizes:
            continue
        args = node.args
        if expanded or not args:
            sizes[node] = 1 + sum(sizes[a] for a in args)
        else:
            stack.append((node, True))
            stack.extend((a, False) for a in args if a not in sizes)
    return sizes[expr]
