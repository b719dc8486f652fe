"""Input checks shared by every entry point, eagerly and under ``jit``.

Eager (concrete) inputs are checked in Python with the offending values in the message;
traced inputs by ``equinox.error_if``, which survives ``jit``, ``vmap`` and ``scan`` and
costs nothing when its output is unused. Every error raised here is a ``LagraxError``.
"""

from collections.abc import Callable, Mapping
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._errors import ConfigurationError, NonFiniteError, ParameterError, ShapeError
from ._linalg import PIVOT_RTOL
from ._typing import Params


def is_traced(*xs: Any) -> bool:
    """Whether any leaf of ``xs`` is a JAX tracer (we are inside ``jit``/``vmap``/``grad``)."""
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(xs))


def pivot_threshold(dtype: Any) -> float:
    """Relative size below which a mass-matrix pivot/eigenvalue counts as singular."""
    return PIVOT_RTOL * float(jnp.finfo(dtype).eps)


# --------------------------------------------------------------------------- user calls


def describe_params(params: Params) -> str:
    if isinstance(params, dict):
        return f"params has keys {sorted(map(str, params))}"
    if hasattr(params, "_fields"):
        return f"params has fields {list(params._fields)}"
    return f"params is a {type(params).__name__}"


def _is_params_lookup(err: Exception, params: Params) -> bool:
    """Did ``err`` come from looking up a missing entry of ``params`` itself?"""
    if isinstance(err, KeyError):
        key = err.args[0] if err.args else None
        try:
            return isinstance(params, Mapping) and key not in params
        except TypeError:  # unhashable key
            return False
    return getattr(err, "obj", None) is params  # AttributeError on a NamedTuple/Module


def call_user(fn: Callable, role: str, params: Params, *args: Any) -> Any:
    """Call a user function ``fn(*args, params)``; a missing-parameter lookup becomes a
    ``ParameterError`` naming the entry and what ``params`` has."""
    try:
        return fn(*args, params)
    except (KeyError, AttributeError) as err:
        if not _is_params_lookup(err, params):
            raise
        missing = err.args[0] if isinstance(err, KeyError) else getattr(err, "name", "?")
        raise ParameterError(
            f"the {role} function looked up {missing!r} in params, which is not there; "
            f"{describe_params(params)}. Add the missing entry to params."
        ) from err


# --------------------------------------------------------------------------- arrays


def coords(q: Any, name: str, n_dof: int | None, system_name: str, host: bool = False) -> Any:
    """``q`` as a 1-D floating array of length ``n_dof`` (when given), or a ``ShapeError``.

    ``host=True`` converts with NumPy (no device transfer), for ``simulate``'s set-up.
    """
    q = np.asarray(q) if host else jnp.asarray(q)
    if not jnp.issubdtype(q.dtype, jnp.floating):
        q = q.astype(jnp.result_type(float))
    if q.ndim != 1:
        raise ShapeError(
            f"{name} must be a 1-D array of generalized coordinates, got shape {q.shape}"
            " (use jax.vmap for batches)"
        )
    if n_dof is not None and q.shape[0] != n_dof:
        raise ShapeError(
            f"{name} has length {q.shape[0]} but {system_name} has {n_dof} degrees of freedom"
        )
    return q


def same_shape(name: str, v: Any, q: Any) -> None:
    if v.shape != q.shape:
        raise ShapeError(f"{name} has shape {v.shape} but q has shape {q.shape}; they must match")


def finite(x: jax.Array, name: str) -> jax.Array:
    """Refuse NaN/inf: eagerly with the value when concrete, by ``error_if`` under jit."""
    if not is_traced(x):
        if not bool(np.all(np.isfinite(np.asarray(x)))):
            raise NonFiniteError(f"{name} contains non-finite values: {np.asarray(x)}")
        return x
    return eqx.error_if(
        x, ~jnp.all(jnp.isfinite(x)), f"{name} contains non-finite values (NaN or inf)"
    )


def finite_params(params: Params) -> None:
    """Eagerly refuse a non-finite numeric leaf of ``params``, naming its path."""
    for path, leaf in jax.tree_util.tree_leaves_with_path(params):
        if isinstance(leaf, (int, float, complex, np.ndarray, jax.Array)):
            if not bool(np.all(np.isfinite(np.asarray(leaf)))):
                raise NonFiniteError(f"params{jax.tree_util.keystr(path)} is not finite: {leaf}")


# --------------------------------------------------------------------------- options


def interval(t0: Any, t1: Any) -> None:
    """Eagerly require ``t0 < t1``."""
    if not float(t1) > float(t0):
        raise ConfigurationError(f"t1 must be greater than t0, got t0={t0}, t1={t1}")


def save_times(ts: Any, t0: Any, t1: Any, name: str = "ts") -> None:
    """Eagerly require sorted save times inside ``[t0, t1]``."""
    ts = np.asarray(ts)
    if ts.size and (np.any(np.diff(ts) < 0) or ts[0] < float(t0) or ts[-1] > float(t1)):
        raise ConfigurationError(
            f"{name} must be non-decreasing and inside [t0, t1] = [{t0}, {t1}]; got {ts}"
        )


def traced_save_times(ts: jax.Array, t0: jax.Array, t1: jax.Array) -> jax.Array:
    """Under ``jit``: ``ts`` with a run-time check that it is sorted inside ``[t0, t1]``."""
    if not ts.shape[0]:
        return ts
    return eqx.error_if(
        ts,
        jnp.any(ts[1:] < ts[:-1]) | (ts[0] < t0) | (ts[-1] > t1),
        "ts must be non-decreasing and inside [t0, t1]",
    )
