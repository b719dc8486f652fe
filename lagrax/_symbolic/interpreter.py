"""An interpreter of JAX programs over SymPy expressions.

A JAX function is traced once to a jaxpr (`jax.make_jaxpr`, with zeros of the right
shapes standing for the symbolic arguments); then each equation of the jaxpr is
evaluated on SymPy expressions instead of numbers, by the rules of `primitives.py`.
What does not depend on a symbol (an identity matrix built with `iota` and `eq`, the
index arithmetic of `q[i]`) is evaluated by JAX itself, so only the operations on the
symbols need a SymPy meaning. Calls (`jit`, `closed_call`, `custom_jvp_call`,
`custom_vjp_call`, `checkpoint`) are followed into their bodies (a custom derivative rule
is the derivative of its body everywhere the body is smooth: SymPy differentiates the
body); `scan` is unrolled, and `while` and `cond` run where their condition does not
depend on a symbol.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.extend import core as jcore

from .conversions import is_symbolic, load_sympy, numeric_or_none, symbolic_array, to_sympy, wrap
from .errors import UnsupportedPrimitiveError
from .primitives import MOVED, bind_equation, decided, rules

# call-like primitives: the parameter holding the body
_CALLS = {
    "jit": "jaxpr",
    "pjit": "jaxpr",
    "closed_call": "call_jaxpr",
    "core_call": "call_jaxpr",
    "custom_jvp_call": "call_jaxpr",
    "custom_vjp_call": "call_jaxpr",
    "custom_vjp_call_jaxpr": "fun_jaxpr",
    "checkpoint": "jaxpr",
    "remat": "jaxpr",
    "remat2": "jaxpr",
}
# primitives that change derivatives without changing values: SymPy's derivative of the
# value would not be JAX's
_REFUSED = {
    "stop_gradient": "it hides its argument from differentiation, and SymPy differentiates "
    "through it, so the symbolic equations would differ from lagrax's numbers",
}
_MAX_WHILE = 100_000


class _Context:
    """Where an error happened, for its message: the function interpreted."""

    def __init__(self, where: str):
        self.where = where


def _body(eqn) -> tuple[Any, list[Any]]:
    """A call's body as `(open jaxpr, consts)`."""
    sub = eqn.params[_CALLS[eqn.primitive.name]]
    if isinstance(sub, jcore.ClosedJaxpr):
        return sub.jaxpr, list(sub.consts)
    return sub, []


def _scan(eqn, values, ctx):
    p = eqn.params
    body, consts = p["jaxpr"].jaxpr, list(p["jaxpr"].consts)
    n_consts, n_carry = p["num_consts"], p["num_carry"]
    fixed, carry = values[:n_consts], values[n_consts : n_consts + n_carry]
    xs = values[n_consts + n_carry :]
    steps = range(p["length"] - 1, -1, -1) if p["reverse"] else range(p["length"])
    ys: list[list[np.ndarray]] = []
    for i in steps:
        outs = evaluate(body, consts, [*fixed, *carry, *(x[i] for x in xs)], ctx)
        carry, y = outs[:n_carry], outs[n_carry:]
        ys.append(y)
    if p["reverse"]:
        ys.reverse()
    n_ys = len(eqn.outvars) - n_carry
    stacked = []
    for k in range(n_ys):
        column = [y[k] for y in ys]
        if any(is_symbolic(c) for c in column):
            stacked.append(np.stack([symbolic_array(c) for c in column]))
        else:
            stacked.append(np.stack(column))
    return [*carry, *stacked]


def _while(eqn, values, ctx):
    p = eqn.params
    nc, nb = p["cond_nconsts"], p["body_nconsts"]
    cond_consts, body_consts, carry = values[:nc], values[nc : nc + nb], values[nc + nb :]
    cond, body = p["cond_jaxpr"], p["body_jaxpr"]
    for _ in range(_MAX_WHILE):
        (go,) = evaluate(cond.jaxpr, list(cond.consts), [*cond_consts, *carry], ctx)
        if not bool(decided(go, "the condition of a while loop")):
            return carry
        carry = evaluate(body.jaxpr, list(body.consts), [*body_consts, *carry], ctx)
    raise UnsupportedPrimitiveError(
        f"a while loop in {ctx.where} ran {_MAX_WHILE} iterations without stopping"
    )


def _cond(eqn, values, ctx):
    index = int(decided(values[0], "the branch index of lax.cond/lax.switch"))
    branches = eqn.params["branches"]
    branch = branches[int(np.clip(index, 0, len(branches) - 1))]
    return evaluate(branch.jaxpr, list(branch.consts), values[1:], ctx)


_CONTROL = {"scan": _scan, "while": _while, "cond": _cond}


def _apply(eqn, values: list[np.ndarray], ctx: _Context) -> list[np.ndarray]:
    name = eqn.primitive.name
    if name in _REFUSED:
        raise UnsupportedPrimitiveError(
            f"lagrax.symbolic refuses the JAX primitive {name!r} in {ctx.where}: "
            f"{_REFUSED[name]}. Remove it from the function"
        )
    if name not in _CALLS and not any(is_symbolic(v) for v in values):
        return bind_equation(eqn, values)
    if name in _CALLS:
        body, consts = _body(eqn)
        return evaluate(body, consts, values, ctx)
    if name in _CONTROL:
        return _CONTROL[name](eqn, values, ctx)
    if name in MOVED:
        return MOVED[name](eqn.params, *values, eqn=eqn)
    table = rules()
    if name not in table:
        numeric = [numeric_or_none(v) for v in values]
        if all(v is not None for v in numeric):  # SymPy numbers only: JAX evaluates it
            dtypes = [var.aval.dtype for var in eqn.invars]
            typed = [np.asarray(v, dt) for v, dt in zip(numeric, dtypes, strict=True)]
            return bind_equation(eqn, typed)
        shown = " ".join(str(eqn).split())[:160]
        raise UnsupportedPrimitiveError(
            f"lagrax.symbolic cannot interpret the JAX primitive {name!r} (in {ctx.where}: "
            f"`{shown}`): it has no SymPy rule. Rewrite the function with the operations of "
            "lagrax.symbolic.supported_primitives(), or use the numeric equations"
        )
    return table[name](eqn.params, *values)


def evaluate(
    jaxpr: Any, consts: Sequence[Any], args: Sequence[np.ndarray], ctx: _Context
) -> list[np.ndarray]:
    """Evaluate an open jaxpr on interpreter values (see the module docstring)."""
    env: dict[Any, np.ndarray] = {}

    def read(v):
        if isinstance(v, jcore.Literal):
            return np.asarray(v.val)
        return env[v]

    for var, val in zip(jaxpr.constvars, consts, strict=True):
        env[var] = np.asarray(val)
    for var, val in zip(jaxpr.invars, args, strict=True):
        env[var] = wrap(val)
    for eqn in jaxpr.eqns:
        outs = _apply(eqn, [read(v) for v in eqn.invars], ctx)
        for var, val in zip(eqn.outvars, outs, strict=True):
            if not isinstance(var, jcore.DropVar):
                env[var] = wrap(val)
    return [read(v) for v in jaxpr.outvars]


def _leaf(x: Any) -> tuple[bool, Any]:
    """`(symbolic?, value)` of an argument leaf: SymPy objects and object arrays are
    symbolic (as object arrays); anything else is a number or an array of numbers."""
    sp = load_sympy()
    if isinstance(x, (sp.Basic, sp.MatrixBase, sp.NDimArray)):
        return True, symbolic_array(x)
    if isinstance(x, np.ndarray) and is_symbolic(x):
        return True, symbolic_array(x)
    return False, x


def interpret_arrays(fn: Callable[..., Any], *args: Any) -> Any:
    """[`interpret`][lagrax.symbolic.interpret], returning the output pytree with NumPy
    object arrays as leaves (every leaf an array, 0-d for a scalar)."""
    sp_leaves, treedef = jax.tree_util.tree_flatten(args)
    kinds = [_leaf(x) for x in sp_leaves]
    symbolic = [v for is_sym, v in kinds if is_sym]

    def numeric(*xs):
        it = iter(xs)
        leaves = [next(it) if is_sym else v for is_sym, v in kinds]
        return fn(*jax.tree_util.tree_unflatten(treedef, leaves))

    examples = [jnp.zeros(v.shape, jnp.float64) for v in symbolic]
    closed, shapes = jax.make_jaxpr(numeric, return_shape=True)(*examples)
    where = getattr(fn, "__qualname__", None) or repr(fn)
    outs = evaluate(closed.jaxpr, list(closed.consts), symbolic, _Context(where))
    out_tree = jax.tree_util.tree_structure(shapes)
    return jax.tree_util.tree_unflatten(out_tree, [symbolic_array(o) for o in outs])


def interpret(fn: Callable[..., Any], *args: Any) -> Any:
    """Evaluate a JAX function on SymPy expressions.

    `fn` is traced once with `jax.make_jaxpr` (zeros standing for the symbolic
    arguments) and its jaxpr is evaluated on SymPy objects, one primitive at a time. The
    result is exact: a primitive without an exact SymPy meaning raises
    `UnsupportedPrimitiveError` naming it, never an approximate expression. `fn` must be
    traceable by JAX (the functions lagrax differentiates are).

    **Arguments:**

    - `fn`: a function of JAX arrays (an energy, a pose map, a Newton–Euler oracle).
    - `*args`: its arguments, any pytrees (dicts, tuples, ...) whose leaves are SymPy
      expressions (a scalar), SymPy matrices (a column matrix is a 1-D array) or arrays,
      NumPy arrays of SymPy objects, or numbers (kept as numbers: they are constants of
      the jaxpr).

    **Returns:** `fn`'s output pytree with SymPy leaves: an expression for a scalar, a
    column `Matrix` for a vector, a `Matrix` for a matrix, an `ImmutableDenseNDimArray`
    beyond.

    **Raises:** `UnsupportedPrimitiveError` for a primitive without a SymPy rule, a
    branch or loop on a condition that depends on a symbol, or `stop_gradient`;
    `SympyMissingError` without SymPy.

    **Example:**

    ```python
    import jax.numpy as jnp
    import sympy as sp
    import lagrax as lx

    th, l = sp.symbols("theta l", real=True)
    lx.symbolic.interpret(lambda q, p: p["l"] * jnp.stack([jnp.sin(q), -jnp.cos(q)]), th, {"l": l})
    # Matrix([[l*sin(theta)], [-l*cos(theta)]])
    ```
    """
    return jax.tree_util.tree_map(to_sympy, interpret_arrays(fn, *args))


def supported_primitives() -> tuple[str, ...]:
    """The names of the JAX primitives the interpreter maps to SymPy (sorted).

    Besides these, any primitive is evaluated by JAX itself where none of its inputs
    depends on a symbol, `stop_gradient` is refused (it would make SymPy's derivatives
    differ from lagrax's), and `cond`, `while` run where their condition does not depend
    on a symbol.
    """
    return tuple(sorted({*rules(), *MOVED, *_CALLS, *_CONTROL}))
