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
import numpy as np

from .._core.errors import ConfigurationError
from .._systems.vector_field import LagrangianVectorField
from .grid import Members

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


def _top_name(path: tuple) -> str:
    """The top-level entry of `params` a leaf lies under (a dict key or a field)."""
    return jtu.keystr(path[:1], simple=True) if path else jtu.keystr(path)


def refuse_unused(system, tau_fn, tau_const, members: Members) -> None:
    """A `ConfigurationError` when a swept parameter is read by nothing the solve
    evaluates (see `unused`): for a `Grid`, its swept names; for batched `params`, the
    leaves whose values differ between members."""
    member = members.first()
    q, qd = jnp.asarray(members.q0s[0]), jnp.asarray(members.qd0s[0])
    read = read_params(system, tau_fn, q, qd, member, tau_const)
    if read is None:
        return
    paths = [path for path, _ in jtu.tree_flatten_with_path(member)[0]]
    grid = members.grid
    if grid is not None:
        # a swept name is read when any leaf under it is
        names = [_top_name(p) for p in paths]
        names_read = {k for k, r in zip(names, read, strict=True) if r}
        # an element `m[3]` is read when its parameter is
        leaf = {k: grid.elements.get(k, (k,))[0] for k in grid.axes}
        unused = [k for k in grid.axes if leaf[k] not in names_read and k not in grid.states]
        all_names = list(dict.fromkeys(names))
    else:
        leaves = jtu.tree_leaves(members.params)
        varies = [bool(np.any(np.asarray(x) != np.asarray(x)[:1])) for x in leaves]
        names = ["params" + jtu.keystr(p) for p in paths]
        unused = [k for k, r, v in zip(names, read, varies, strict=True) if v and not r]
        names_read = {k for k, r in zip(names, read, strict=True) if r}
        all_names = names
    if not unused:
        return
    read_list = [k for k in all_names if k in names_read]
    it = "it" if len(unused) == 1 else "them"
    raise ConfigurationError(
        f"the sweep varies {', '.join(unused)} but no energy, force, tau or constraint of "
        f"the system reads {it}, so every member would give the same result (the system "
        f"reads {', '.join(read_list) or 'no parameter'}). A misspelt name? Sweep a "
        f"parameter the model reads, or pass allow_unused=True to sweep {it} anyway (e.g. "
        "as a label)."
    )
