"""SymPy rules for JAX's primitives: what each operation of a jaxpr means on expressions.

A rule takes the equation's parameters and its input values (NumPy arrays, of SymPy
objects where they depend on a symbol) and returns the list of its outputs. Element-wise
rules broadcast as NumPy does (a jaxpr may multiply an `f64[]` by an `f64[2]`); the
structural ones (`slice`, `reshape`, `dot_general`, ...) move the entries of object
arrays with NumPy's own indexing. Every rule is exact: where a primitive has no exact
SymPy meaning (a branch on a symbolic predicate, an integer conversion of an expression)
the rule raises `UnsupportedPrimitiveError` instead of guessing.

The control-flow and call primitives (`jit`, `scan`, `while`, `cond`, `custom_jvp_call`,
...) are in `interpreter.py`, which owns the evaluation loop they recurse into.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import numpy as np

from .conversions import load_sympy, numeric_or_none, symbolic_array, wrap
from .errors import UnsupportedPrimitiveError

Rule = Callable[..., list[np.ndarray]]


def _elementwise(fn: Callable[..., Any], *values: np.ndarray) -> np.ndarray:
    """`fn` applied entry by entry to SymPy versions of `values`, broadcast together."""
    arrays = np.broadcast_arrays(*(symbolic_array(v) for v in values))
    return wrap(np.frompyfunc(fn, len(arrays), 1)(*arrays)).astype(object)


def _unary(fn: Callable[[Any], Any]) -> Rule:
    return lambda params, x: [_elementwise(fn, x)]


def _binary(fn: Callable[[Any, Any], Any]) -> Rule:
    return lambda params, x, y: [_elementwise(fn, x, y)]


def bind_equation(eqn: Any, values: list[np.ndarray]) -> list[np.ndarray]:
    """Evaluate a jaxpr equation on arrays of numbers with JAX itself (eagerly)."""
    import jax

    bound = eqn.primitive.get_bind_params(eqn.params)
    # JAX >= 0.7 returns the parameters; older versions `(subfunctions, parameters)`
    subfuns, params = bound if isinstance(bound, tuple) else ((), bound)
    with jax.ensure_compile_time_eval():
        outs = eqn.primitive.bind(*subfuns, *values, **params)
    outs = outs if eqn.primitive.multiple_results else [outs]
    return [np.asarray(o) for o in outs]


def decided(x: np.ndarray, what: str) -> np.ndarray:
    """A predicate or an index as numbers, or the error that it depends on a symbol."""
    out = numeric_or_none(x)
    if out is None:
        raise UnsupportedPrimitiveError(
            f"{what} depends on q, qd or params (a `jnp.where`, `lax.cond` or loop on a "
            f"symbolic condition such as {_first_symbolic(x)}): its symbolic value would be "
            "a different expression on each side of the condition. Write the function "
            "without the branch (for a safe norm or division, the plain formula)"
        )
    return out


def _first_symbolic(x: np.ndarray) -> Any:
    sp = load_sympy()
    for v in x.ravel():
        if not isinstance(v, (sp.Number, sp.logic.boolalg.BooleanAtom)):
            return v
    return x.ravel()[0]  # pragma: no cover


def _select_n(params, which, *cases):
    index = decided(which, "the predicate of select_n")
    shape = np.broadcast_shapes(index.shape, *(c.shape for c in cases))
    options = [np.broadcast_to(symbolic_array(c), shape) for c in cases]
    return [wrap(np.choose(np.broadcast_to(index.astype(np.int64), shape), options))]


def _convert(params, x):
    sp = load_sympy()
    dtype = np.dtype(params["new_dtype"])
    truth = any(isinstance(v, sp.logic.boolalg.Boolean) for v in x.ravel())
    if np.issubdtype(dtype, np.inexact) and not truth:
        return [x]
    numbers = numeric_or_none(x)
    if numbers is not None:  # SymPy numbers or truth values only: convert as NumPy does
        return [numbers.astype(dtype)]
    raise UnsupportedPrimitiveError(
        f"convert_element_type to {dtype} of an expression that depends on q, qd or params "
        "(an `astype(int)`, a comparison turned into a number, a rounding): it has no exact "
        "symbolic meaning. Keep the function in floating point"
    )


def _integer_pow(params, x):
    return [_elementwise(lambda a: a ** params["y"], x)]


def _reduce(fn: Callable[[list[Any]], Any]) -> Rule:
    def rule(params, x):
        x = symbolic_array(x)
        axes = tuple(params["axes"])
        kept = [a for a in range(x.ndim) if a not in axes]
        moved = np.transpose(x, kept + list(axes)).reshape([x.shape[a] for a in kept] + [-1])
        out = np.empty(moved.shape[:-1], dtype=object)
        for index in np.ndindex(*out.shape):
            out[index] = fn(list(moved[index]))
        return [out]

    return rule


def _cumulative(fn: Callable[[Any, Any], Any]) -> Rule:
    def rule(params, x):
        x = symbolic_array(x)
        axis, reverse = params["axis"], params["reverse"]
        x = np.flip(x, axis) if reverse else x
        out = np.empty(x.shape, dtype=object)
        for index in np.ndindex(*x.shape):
            before = list(index)
            if index[axis] == 0:
                out[index] = x[index]
            else:
                before[axis] -= 1
                out[index] = fn(out[tuple(before)], x[index])
        return [np.flip(out, axis) if reverse else out]

    return rule


def _dot_general(params, lhs, rhs):
    (lc, rc), (lb, rb) = params["dimension_numbers"]
    lhs, rhs = symbolic_array(lhs), symbolic_array(rhs)
    lf = [d for d in range(lhs.ndim) if d not in lc and d not in lb]
    rf = [d for d in range(rhs.ndim) if d not in rc and d not in rb]
    batch = [lhs.shape[d] for d in lb]
    size = int(np.prod([lhs.shape[d] for d in lc], dtype=np.int64))
    a = np.transpose(lhs, list(lb) + lf + list(lc)).reshape(
        batch + [int(np.prod([lhs.shape[d] for d in lf], dtype=np.int64)), size]
    )
    b = np.transpose(rhs, list(rb) + list(rc) + rf).reshape(
        batch + [size, int(np.prod([rhs.shape[d] for d in rf], dtype=np.int64))]
    )
    out = np.empty(a.shape[:-1] + b.shape[-1:], dtype=object)
    for index in np.ndindex(*out.shape):
        row, col = a[index[:-1]], b[index[:-2] + (slice(None), index[-1])]
        out[index] = _sum([u * v for u, v in zip(row, col, strict=True)])
    shape = batch + [lhs.shape[d] for d in lf] + [rhs.shape[d] for d in rf]
    return [out.reshape(shape)]


def _sum(terms: list[Any]) -> Any:
    sp = load_sympy()
    return sp.Add(*terms) if terms else sp.Integer(0)


def _product(terms: list[Any]) -> Any:
    sp = load_sympy()
    return sp.Mul(*terms) if terms else sp.Integer(1)


def _broadcast_in_dim(params, x):
    shape = tuple(params["shape"])
    expanded = [1] * len(shape)
    for axis, dim in zip(params["broadcast_dimensions"], x.shape, strict=True):
        expanded[axis] = dim
    return [np.broadcast_to(x.reshape(expanded), shape).copy()]


def _reshape(params, x):
    if params.get("dimensions") is not None:
        x = np.transpose(x, params["dimensions"])
    return [x.reshape(tuple(params["new_sizes"]))]


def _slice(params, x):
    strides = params["strides"] or (1,) * x.ndim
    bounds = zip(params["start_indices"], params["limit_indices"], strides, strict=True)
    index = tuple(slice(lo, hi, st) for lo, hi, st in bounds)
    return [x[index]]


def _starts(x: np.ndarray, sizes, starts) -> tuple[int, ...]:
    """Start indices clamped as XLA clamps them (the slice stays inside the array)."""
    return tuple(
        int(np.clip(int(decided(s, "a dynamic index")), 0, dim - size))
        for s, dim, size in zip(starts, x.shape, sizes, strict=True)
    )


def _dynamic_slice(params, x, *starts):
    sizes = params["slice_sizes"]
    lo = _starts(x, sizes, starts)
    return [x[tuple(slice(a, a + s) for a, s in zip(lo, sizes, strict=True))]]


def _dynamic_update_slice(params, x, update, *starts):
    out = symbolic_array(x).copy()
    lo = _starts(out, update.shape, starts)
    out[tuple(slice(a, a + s) for a, s in zip(lo, update.shape, strict=True))] = symbolic_array(
        update
    )
    return [out]


def _concatenate(params, *xs):
    return [np.concatenate([symbolic_array(x) for x in xs], axis=params["dimension"])]


def _stack(params, *xs):
    return [np.stack([symbolic_array(x) for x in xs], axis=params["axis"])]


def _split(params, x):
    cuts = np.cumsum(params["sizes"])[:-1]
    return list(np.split(x, cuts, axis=params["axis"]))


def _clamp(params, lo, x, hi):
    sp = load_sympy()
    return [_elementwise(lambda a, b, c: sp.Min(sp.Max(b, a), c), lo, x, hi)]


def _moved(primitive: str) -> Rule:
    """A pure data-movement primitive (`gather`, `pad`, `scatter`, ...) with concrete
    indices: JAX moves the *positions* of the entries (an integer array), and the entries
    follow them. Position 0 stands for the zero JAX fills in (`pad`, out-of-bounds
    `gather`)."""

    def rule(params, *values, eqn):
        sp = load_sympy()
        data = _DATA_OPERANDS[primitive]
        pool: list[Any] = [sp.Integer(0)]
        args = []
        for i, v in enumerate(values):
            if i in data:
                entries = symbolic_array(v)
                positions = np.arange(len(pool), len(pool) + entries.size).reshape(entries.shape)
                pool.extend(entries.ravel())
                args.append(positions.astype(np.int64))
            else:
                args.append(decided(v, f"an index operand of {primitive}"))
        results = []
        outs = bind_equation(eqn, args)
        for out in outs:
            out = np.asarray(out)
            if out.size and (out.min() < 0 or out.max() >= len(pool)):
                raise UnsupportedPrimitiveError(
                    f"{primitive} produced values that are not entries of its operands "
                    "(a fill value other than zero): it cannot be followed symbolically"
                )
            table = np.empty(len(pool), dtype=object)
            table[:] = pool
            results.append(table[out])
        return results

    return rule


# which operands of a data-movement primitive are data (the rest are indices)
_DATA_OPERANDS = {"gather": {0}, "pad": {0, 1}, "scatter": {0, 2}}


def _arithmetic(sp: Any) -> dict[str, Rule]:
    """Element-wise rules: arithmetic, elementary functions, comparisons."""
    return {
        "neg": _unary(lambda a: -a),
        "sin": _unary(sp.sin),
        "cos": _unary(sp.cos),
        "tan": _unary(sp.tan),
        "asin": _unary(sp.asin),
        "acos": _unary(sp.acos),
        "atan": _unary(sp.atan),
        "sinh": _unary(sp.sinh),
        "cosh": _unary(sp.cosh),
        "tanh": _unary(sp.tanh),
        "asinh": _unary(sp.asinh),
        "acosh": _unary(sp.acosh),
        "atanh": _unary(sp.atanh),
        "exp": _unary(sp.exp),
        "exp2": _unary(lambda a: 2**a),
        "log": _unary(sp.log),
        "log1p": _unary(lambda a: sp.log(1 + a)),
        "expm1": _unary(lambda a: sp.exp(a) - 1),
        "sqrt": _unary(sp.sqrt),
        "rsqrt": _unary(lambda a: 1 / sp.sqrt(a)),
        "cbrt": _unary(sp.cbrt),
        "square": _unary(lambda a: a**2),
        "abs": _unary(sp.Abs),
        "sign": _unary(sp.sign),
        "logistic": _unary(lambda a: 1 / (1 + sp.exp(-a))),
        "erf": _unary(sp.erf),
        "integer_pow": _integer_pow,
        "add": _binary(lambda a, b: a + b),
        "add_any": _binary(lambda a, b: a + b),
        "sub": _binary(lambda a, b: a - b),
        "mul": _binary(lambda a, b: a * b),
        "div": _binary(lambda a, b: a / b),
        "pow": _binary(lambda a, b: a**b),
        "max": _binary(sp.Max),
        "min": _binary(sp.Min),
        "atan2": _binary(sp.atan2),
        "clamp": _clamp,
        "lt": _binary(sp.Lt),
        "le": _binary(sp.Le),
        "gt": _binary(sp.Gt),
        "ge": _binary(sp.Ge),
        "eq": _binary(sp.Eq),
        "ne": _binary(sp.Ne),
        "and": _binary(sp.And),
        "or": _binary(sp.Or),
        "not": _unary(sp.Not),
    }


def _structural(sp: Any) -> dict[str, Rule]:
    """Rules that move, select, reduce or contract entries."""
    return {
        "select_n": _select_n,
        "convert_element_type": _convert,
        "copy": lambda params, x: [x],
        "copy_p": lambda params, x: [x],
        "reduce_sum": _reduce(_sum),
        "reduce_prod": _reduce(_product),
        "reduce_max": _reduce(lambda v: sp.Max(*v)),
        "reduce_min": _reduce(lambda v: sp.Min(*v)),
        "cumsum": _cumulative(lambda a, b: a + b),
        "cumprod": _cumulative(lambda a, b: a * b),
        "cummax": _cumulative(sp.Max),
        "cummin": _cumulative(sp.Min),
        "dot_general": _dot_general,
        "transpose": lambda params, x: [np.transpose(x, params["permutation"])],
        "reshape": _reshape,
        "squeeze": lambda params, x: [np.squeeze(x, axis=tuple(params["dimensions"]))],
        "broadcast_in_dim": _broadcast_in_dim,
        "slice": _slice,
        "dynamic_slice": _dynamic_slice,
        "dynamic_update_slice": _dynamic_update_slice,
        "concatenate": _concatenate,
        "stack": _stack,
        "split": _split,
        "unstack": lambda params, x: [wrap(v) for v in np.moveaxis(x, params["axis"], 0)],
        "rev": lambda params, x: [np.flip(x, tuple(params["dimensions"]))],
    }


@functools.cache
def rules() -> dict[str, Rule]:
    """The rules by primitive name (built on first use, when SymPy is imported)."""
    sp = load_sympy()
    return {**_arithmetic(sp), **_structural(sp)}


# primitives whose rule needs the equation itself (to bind it on positions)
MOVED = {name: _moved(name) for name in ("gather", "pad", "scatter")}
