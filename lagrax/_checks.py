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


# ----- sweep options
#
# Host-side checks of ``sweep``'s options, run once per call before anything is compiled.
# Wrong kinds of object raise ``ArgumentTypeError``, unusable values ``ConfigurationError``;
# each message names the option, the value and the fix. (This section keeps its own
# imports, so that it merges cleanly with edits to the rest of the module.)

import os  # noqa: E402

from ._errors import ArgumentTypeError  # noqa: E402


def _kind(value: Any) -> str:
    return f"{value!r} ({type(value).__name__})"


def positive_int(value: Any, name: str, fix: str = "") -> int:
    """``value`` as an ``int >= 1``; an integral float (``64.0``) is accepted."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.integer, np.floating)
    ):
        raise ArgumentTypeError(f"{name} must be a positive integer, got {_kind(value)}. {fix}")
    if not np.isfinite(value) or value != int(value) or value < 1:
        raise ConfigurationError(f"{name} must be a positive integer, got {value!r}. {fix}")
    return int(value)


def real_number(value: Any, name: str) -> float:
    """``value`` as a finite Python float, or a ``LagraxError`` naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or (
        not isinstance(value, (int, float, np.integer, np.floating))
        and not (isinstance(value, (np.ndarray, jax.Array)) and np.ndim(value) == 0)
    ):
        raise ArgumentTypeError(f"{name} must be a real number, got {_kind(value)}")
    if np.iscomplexobj(value):
        raise ArgumentTypeError(f"{name} must be a real number, got {_kind(value)}")
    x = float(value)
    if not np.isfinite(x):
        raise ConfigurationError(
            f"{name} must be finite, got {x!r}: integrate over a finite interval, with a "
            "finite step and tolerances"
        )
    return x


def sweep_times(t0: Any, t1: Any) -> tuple[float, float]:
    """Finite ``t0 < t1``."""
    t0, t1 = real_number(t0, "t0"), real_number(t1, "t1")
    interval(t0, t1)
    return t0, t1


def positive_step(value: Any, name: str, t0: float, t1: float) -> float | None:
    """A step (``dt``, ``dt0``): ``None``, or finite and ``> 0`` (the solve runs forward
    from ``t0`` to ``t1 > t0``; a negative step would integrate away from ``t1``)."""
    if value is None:
        return None
    x = real_number(value, name)
    if x <= 0:
        raise ConfigurationError(
            f"{name} must be positive, got {name}={x!r}: sweep integrates forward from "
            f"t0={t0} to t1={t1}; pass a step such as {name}={(t1 - t0) / 1000:.3g}"
        )
    return x


def tolerances(rtol: Any, atol: Any, adaptive: bool) -> None:
    """``rtol``, ``atol`` finite and ``>= 0``, and not both zero for an adaptive step."""
    r, a = real_number(rtol, "rtol"), real_number(atol, "atol")
    for name, x in (("rtol", r), ("atol", a)):
        if x < 0:
            raise ConfigurationError(
                f"{name} must be >= 0, got {name}={x!r}: a tolerance is a size, e.g. {name}=1e-8"
            )
    if adaptive and r == 0 and a == 0:
        raise ConfigurationError(
            f"rtol and atol are both 0 (rtol={rtol!r}, atol={atol!r}): no adaptive step "
            "can meet a zero error bound. Pass a positive rtol or atol, e.g. 1e-8."
        )


_KEEP_NAMES = ("final", "trajectory")


def keep_option(keep: Any, t0: float, t1: float) -> np.ndarray | None:
    """``keep=``: a known name, a callable, or sorted finite times inside ``[t0, t1]``.

    **Returns:** the times as a float array, or ``None`` for a name or a callable.
    """
    if callable(keep):
        return None
    if isinstance(keep, str):
        if keep not in _KEEP_NAMES:
            import difflib

            close = difflib.get_close_matches(keep, _KEEP_NAMES, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ConfigurationError(
                f"keep={keep!r} is not a name sweep knows{hint}: pass 'final', "
                "'trajectory', an array of times, or a function reduce(solution)"
            )
        return None
    try:
        ts = np.asarray(keep, dtype=float)
    except (TypeError, ValueError) as err:
        raise ArgumentTypeError(
            f"keep must be 'final', 'trajectory', an array of times or a function "
            f"reduce(solution); got {_kind(keep)}"
        ) from err
    if ts.ndim != 1 or ts.size == 0:
        raise ShapeError(f"keep= times must be a non-empty 1-D array, got shape {ts.shape}")
    if not np.all(np.isfinite(ts)):
        raise ConfigurationError(f"keep= times must be finite, got {ts}")
    save_times(ts, t0, t1, "keep= times")
    return ts


def lanes_option(n_lanes: Any, chunk_size: int | None, n_devices: int) -> int | None:
    """``n_lanes``: ``None`` or a positive integer, at most the members of a chunk per
    device when ``chunk_size`` was given (more lanes than members would only idle)."""
    if n_lanes is None:
        return None
    lanes = positive_int(
        n_lanes, "n_lanes", "It is the number of members integrated at once per device."
    )
    if chunk_size is not None:
        per_device = -(-chunk_size // n_devices)
        if lanes > per_device:
            raise ConfigurationError(
                f"n_lanes={lanes} is more than the {per_device} member(s) of a chunk per "
                f"device (chunk_size={chunk_size} over {n_devices} device(s)): the extra "
                f"lanes would stay idle. Pass n_lanes <= {per_device} or a larger chunk_size."
            )
    return lanes


def devices_option(devices: Any) -> None:
    """``devices``: ``None``, a count in ``1..len(jax.devices())`` or a non-empty list."""
    if devices is None:
        return
    available = len(jax.devices())
    if isinstance(devices, (int, np.integer)) and not isinstance(devices, (bool, np.bool_)):
        if not 1 <= devices <= available:
            raise ConfigurationError(
                f"devices={devices!r}: pass a count from 1 to {available} (the devices JAX "
                "sees), a list of devices, or None for all of them"
            )
        return
    if isinstance(devices, (str, bytes, float)) or not hasattr(devices, "__len__"):
        raise ArgumentTypeError(
            f"devices must be None, a count or a list of JAX devices; got {_kind(devices)}"
        )
    if len(devices) == 0:
        raise ConfigurationError("devices=[] names no device: pass None for all of them")


def sweep_options(
    *,
    t0: Any,
    t1: Any,
    keep: Any,
    n_save: Any,
    rtol: Any,
    atol: Any,
    dt: Any,
    dt0: Any,
    max_steps: Any,
    stepsize_controller: Any,
    chunk_size: Any,
    schedule: Any,
    devices: Any,
    checkpoint: Any,
    progress: Any,
) -> tuple[float, float, int | None]:
    """Check ``sweep``'s scalar options on the host, once per call, before anything is
    traced. **Returns:** ``(t0, t1, chunk_size)`` as Python numbers."""
    import diffrax as dfx

    t0, t1 = sweep_times(t0, t1)
    keep_option(keep, t0, t1)
    positive_int(n_save, "n_save", "It is the number of saved times per member.")
    positive_step(dt, "dt", t0, t1)
    positive_step(dt0, "dt0", t0, t1)
    if stepsize_controller is not None and not isinstance(
        stepsize_controller, dfx.AbstractStepSizeController
    ):
        raise ArgumentTypeError(
            "stepsize_controller must be a diffrax.AbstractStepSizeController (e.g. "
            f"diffrax.PIDController(rtol=1e-8, atol=1e-8)); got {_kind(stepsize_controller)}"
        )
    tolerances(rtol, atol, adaptive=dt is None and stepsize_controller is None)
    if max_steps is not None:
        positive_int(max_steps, "max_steps", "It is each member's step budget.")
    size = None
    if chunk_size is not None:
        size = positive_int(chunk_size, "chunk_size", "It is the number of members per chunk.")
    if not isinstance(schedule, str) or schedule not in ("queue", "lockstep"):
        raise ConfigurationError(f"schedule must be 'queue' or 'lockstep', got {schedule!r}")
    devices_option(devices)
    if checkpoint is not None and not isinstance(checkpoint, (str, os.PathLike)):
        raise ArgumentTypeError(
            f"checkpoint must be a directory path (str or os.PathLike) or None; got "
            f"{_kind(checkpoint)}"
        )
    if progress is not None and not isinstance(progress, (bool, np.bool_)):
        raise ArgumentTypeError(f"progress must be True, False or None; got {_kind(progress)}")
    return t0, t1, size


def batch_size(params: Any) -> int:
    """The member count of batched ``params`` (every leaf a numeric array with the same
    leading axis, at least one member), or a ``LagraxError`` naming the leaves."""
    leaves = jax.tree_util.tree_leaves_with_path(params)
    if not leaves:
        raise ShapeError(
            f"sweep() params has no array leaves to sweep over (got {_kind(params)}): pass "
            "lagrax.grid(params, name=values), lagrax.samples(...), or a pytree whose "
            "leaves carry a leading batch axis"
        )
    sizes = {}
    for path, x in leaves:
        key = "params" + jax.tree_util.keystr(path)
        kind = np.asarray(x).dtype.kind if not isinstance(x, jax.Array) else x.dtype.kind
        if kind not in "biuf":
            raise ArgumentTypeError(
                f"{key} must be a numeric array, got {_kind(x)}: parameters are numbers"
            )
        sizes[key] = np.shape(x)[0] if np.ndim(x) else None
    scalars = [k for k, v in sizes.items() if v is None]
    if scalars:
        raise ShapeError(
            f"sweep() params must carry a leading batch axis on every leaf; {scalars} are "
            "scalars. Use lagrax.grid(params, name=values) or lagrax.samples(...) for a mix "
            "of fixed and swept parameters."
        )
    if len(set(sizes.values())) != 1:
        raise ShapeError(
            f"params leaves have different batch sizes (leading axes): {sizes}; every leaf "
            "needs one entry per member"
        )
    n = next(iter(sizes.values()))
    if n == 0:
        raise ShapeError(
            f"sweep() params has 0 members (leading axes {sizes}): pass at least one parameter set"
        )
    return n
