"""Swept parameters that nothing reads: a misspelt grid name would sweep nothing.

Which leaves of `params` a member's results can depend on is read off the jaxpr of
everything the solve evaluates with them: the vector field `(q̇, q̈)` (`T`, `V`,
`D`, the force, `tau`, constraints), the initial state (a constrained system's
projection), the energy and the observables. A leaf is *read* when some output depends
on it through the data flow of that jaxpr (a backward pass over its equations).

Calls into nested jaxprs (`jit`/`pjit`, custom derivatives, checkpointing) are
followed input by input; any other primitive with sub-jaxprs (`cond`, `while`,
`scan`, …) counts every operand as read. So a parameter read inside one branch of a
`lax.cond` or a `jnp.where` counts as read whichever branch the base member takes:
the test is structural, never a numerical derivative that a branch or a zero state could
hide. Its limit: a parameter read only in Python control flow on concrete values cannot
be traced at all; if tracing fails, nothing is reported (the solve then raises its own
error).
"""

from collections.abc import Callable, Sequence
from typing import Any

import jax
import jax.extend.core as jcore
import jax.numpy as jnp
import jax.tree_util as jtu

from .._systems.vector_field import LagrangianVectorField

_CALL_KEYS = ("jaxpr", "call_jaxpr", "fun_jaxpr")
_cache: dict[Any, tuple[bool, ...]] = {}


def _inner(eqn: Any) -> Any:
    """The nested jaxpr whose inputs and outputs are the equation's own, one to one."""
    for key in _CALL_KEYS:
        sub = eqn.params.get(key)
        sub = getattr(sub, "jaxpr", sub)
        if (
            isinstance(sub, jcore.Jaxpr)
            and len(sub.invars) == len(eqn.invars)
            and len(sub.outvars) == len(eqn.outvars)
        ):
            return sub
    return None


def _used_inputs(jaxpr: Any, used_outputs: Sequence[bool]) -> list[bool]:
    needed = {
        v
        for v, u in zip(jaxpr.outvars, used_outputs, strict=True)
        if u and not isinstance(v, jcore.Literal)
    }
    for eqn in reversed(jaxpr.eqns):
        outs = [v in needed for v in eqn.outvars]
        if not any(outs):
            continue
        sub = _inner(eqn)
        ins = _used_inputs(sub, outs) if sub is not None else [True] * len(eqn.invars)
        needed.update(
            v
            for v, u in zip(eqn.invars, ins, strict=True)
            if u and not isinstance(v, jcore.Literal)
        )
    return [v in needed for v in jaxpr.invars]


def read_leaves(fn: Callable[[Any], Any], tree: Any) -> tuple[bool, ...]:
    """Per leaf of `tree`: whether some output of `fn(tree)` depends on it."""
    leaves, treedef = jtu.tree_flatten(tree)
    closed = jax.make_jaxpr(lambda *xs: fn(jtu.tree_unflatten(treedef, xs)))(*leaves)
    return tuple(_used_inputs(closed.jaxpr, [True] * len(closed.jaxpr.outvars)))


def read_params(system: Any, tau_fn: Any, q: Any, qd: Any, params: Any, tau: Any) -> Any:
    """Per leaf of one member's `params`: whether the solve reads it (`None` when the
    functions cannot be traced). Cached per system, `tau` and parameter structure."""
    leaves, treedef = jtu.tree_flatten(params)
    avals = tuple((jnp.shape(x), jnp.result_type(x)) for x in leaves)
    key = (system, tau_fn, treedef, avals, jnp.shape(q), jnp.result_type(q), tau is None)
    try:
        hit = _cache.get(key)
    except TypeError:  # unhashable: no cache
        key, hit = None, None
    if hit is not None:
        return hit
    field = LagrangianVectorField(system, tau_fn)
    t = jnp.zeros((), jnp.result_type(q))

    def solve_inputs(p):
        q0, qd0, _ = system.initial_state(q, qd, p)
        return (
            field(t, (q0, qd0), (p, tau)),
            system.jacobi_integral(t, q, qd, p),
            system.observables(t, q, qd, p, field.tau(t, q, qd, tau)),
        )

    try:
        read = read_leaves(solve_inputs, params)
    except Exception:  # noqa: BLE001 - the solve itself reports what is wrong
        return None
    if key is not None:
        if len(_cache) > 64:
            _cache.clear()
        _cache[key] = read
    return read
