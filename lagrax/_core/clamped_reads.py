"""Reads past the end of an array in a user's function, found while tracing.

JAX clamps a static index past the end of an array (`q[1]` of a
length-1 `q` reads `q[0]`) instead of raising, so an energy written for more
coordinates than it is given runs on silently. JAX lowers an in-range static index to a
`slice`, but an out-of-range one to a `dynamic_slice` whose start is computed from
literals; `clamped_reads` folds those constants in the jaxpr of the user function and
reports every such read. Traced once per function and argument shapes (cached), at
trace time: nothing is added to the compiled program.
"""

import weakref
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.extend.core as jax_core
import jax.numpy as jnp
import numpy as np

from .custom_types import Params
from .errors import ShapeError

_FOLD = {
    "add": lambda a, b: a + b,
    "sub": lambda a, b: a - b,
    "mul": lambda a, b: a * b,
    "neg": lambda a: -a,
    "max": max,
    "min": min,
    "lt": lambda a, b: a < b,
    "le": lambda a, b: a <= b,
    "gt": lambda a, b: a > b,
    "ge": lambda a, b: a >= b,
    "eq": lambda a, b: a == b,
    "ne": lambda a, b: a != b,
    "select_n": lambda p, *cases: cases[int(p)],
    "convert_element_type": lambda a: a,
}


def _jaxprs_of(params: dict) -> list[tuple[Any, bool]]:
    """Sub-jaxprs of an equation, and whether their inputs are the equation's own."""
    out = []
    for key, value in params.items():
        for v in value if isinstance(value, (tuple, list)) else (value,):
            jaxpr = getattr(v, "jaxpr", v)
            if isinstance(jaxpr, jax_core.Jaxpr):
                out.append((jaxpr, key in ("jaxpr", "call_jaxpr", "fun_jaxpr")))
    return out


def _clamped(jaxpr: Any, known: dict) -> list[tuple[int, int]]:
    """`(length, index)` of each out-of-range static read in `jaxpr`."""
    env = dict(known)
    found = []

    def value(v):
        return v.val if type(v).__name__ == "Literal" else env.get(v)

    for eqn in jaxpr.eqns:
        ins = [value(v) for v in eqn.invars]
        name = eqn.primitive.name
        if name == "dynamic_slice":
            shape = eqn.invars[0].aval.shape
            for axis, (start, size) in enumerate(
                zip(ins[1:], eqn.params["slice_sizes"], strict=False)
            ):
                if start is not None and (int(start) < 0 or int(start) + size > shape[axis]):
                    idx = int(start)
                    found.append((shape[axis], idx if idx >= 0 else idx - shape[axis]))
        elif name in _FOLD and all(x is not None for x in ins):
            if all(not getattr(v.aval, "shape", ()) for v in eqn.outvars):
                try:
                    env[eqn.outvars[0]] = _FOLD[name](*(np.asarray(x).item() for x in ins))
                except Exception:  # noqa: BLE001 - folding is best effort
                    pass
        for sub, positional in _jaxprs_of(eqn.params):
            inner = {}
            if positional and len(sub.invars) == len(ins):
                inner = {
                    var: x
                    for var, x in zip(sub.invars, ins, strict=True)
                    if x is not None and not getattr(var.aval, "shape", ())
                }
            found += _clamped(sub, inner)
    return found


# (id(fn), label, signature) -> (a reference to fn, the reads found): weak where fn
# allows, so that the cache does not keep a dropped model's energies (and what they close
# over) alive; the entry goes with fn, so its id cannot be reused while the entry lives.
_READS_CHECKED: dict = {}


def _weak(fn: Callable, key: Any) -> Callable[[], Any]:
    """A weak reference to `fn` that removes the entry `key` when `fn` is collected, or
    a strong one (a function returning `fn`) where `fn` takes no weak reference."""
    try:
        return weakref.ref(fn, lambda _, key=key: _READS_CHECKED.pop(key, None))
    except TypeError:
        return lambda: fn


def _signature(x: Any) -> Any:
    """What tracing depends on: an array's shape and dtype, any other leaf itself."""
    if isinstance(x, (jax.Array, np.ndarray, np.generic)):
        return (x.shape, x.dtype)
    return x


def _abstract(x: Any) -> Any:
    return jax.ShapeDtypeStruct(jnp.shape(x), jnp.result_type(x))


def clamped_reads(fn: Callable, label: str, params: Params, *args: Any) -> None:
    """Raise a `ShapeError` if `fn(*args, params)` reads past the end of an array.

    `args` are the arrays the function receives before `params` (their values are not
    used, only shapes and dtypes). A function that cannot be traced abstractly (one that
    converts a parameter to a Python float, say) is skipped: the real call reports its own
    errors.
    """
    leaves, treedef = jax.tree_util.tree_flatten(params)
    try:
        key = (
            id(fn),
            label,
            treedef,
            *((np.shape(a), getattr(a, "dtype", type(a))) for a in args),
            *(_signature(x) for x in leaves),
        )
        hash(key)
    except TypeError:  # an unhashable static leaf: check without caching
        key = None
    cached = _READS_CHECKED.get(key) if key is not None else None
    if cached is not None and cached[0]() is fn:
        found = cached[1]
    else:
        dyn, static = eqx.partition(params, eqx.is_array)
        try:
            closed = jax.make_jaxpr(lambda d, *a: fn(*a, eqx.combine(d, static)))(
                jax.tree_util.tree_map(_abstract, dyn), *(_abstract(a) for a in args)
            )
            found = _clamped(closed.jaxpr, {})
        except Exception:  # noqa: BLE001 - the real call reports its own errors
            found = []
        if key is not None:
            if len(_READS_CHECKED) > 1024:
                _READS_CHECKED.clear()
            _READS_CHECKED[key] = (_weak(fn, key), found)
    if found:
        length, index = found[0]
        sizes = sorted({jnp.shape(a)[0] for a in args if jnp.ndim(a) == 1})
        raise ShapeError(
            f"the {label} reads entry {index} of an array of length {length} "
            f"(it was given coordinates of length {', '.join(map(str, sizes))}). JAX "
            "clamps an out-of-range index instead of raising, so it would silently read "
            "another entry: pass q and qd of the length the energies use, and give the "
            "system n_dof= so that a wrong length is refused up front"
        )
