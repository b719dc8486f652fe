"""`sweep`'s own option checks: host-side, once per call, before anything is traced,
compiled or written.

Wrong kinds of object raise `ArgumentTypeError`, unusable values `ConfigurationError`
(and `ShapeError` for arrays of the wrong shape); each message names the option, the
value and the fix. The checks shared with `simulate` (times, tolerances, steps) are
`lagrax._core.checks`'.
"""

import dataclasses
import difflib
import os
from collections.abc import Callable, Sized
from typing import Any

import diffrax as dfx
import jax
import numpy as np

from .._core.checks import (
    first_step,
    fixed_step,
    non_negative_real,
    positive_int,
    save_times,
    time_interval,
    tolerances,
)
from .._core.errors import ArgumentTypeError, ConfigurationError, ShapeError


def _kind(value: Any) -> str:
    return f"{value!r} ({type(value).__name__})"


def sweep_times(t0: Any, t1: Any) -> tuple[float, float]:
    """Finite `t0 < t1` as Python floats (see `time_interval`)."""
    t0, t1 = time_interval(t0, t1)
    return float(t0), float(t1)


_KEEP_NAMES = ("final", "trajectory")


def keep_option(keep: Any, t0: float, t1: float) -> np.ndarray | None:
    """`keep=`: a known name, a callable, or sorted finite times inside `[t0, t1]`.

    **Returns:** the times as a float array, or `None` for a name or a callable.
    """
    if callable(keep):
        return None
    if isinstance(keep, str):
        if keep not in _KEEP_NAMES:
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


@dataclasses.dataclass(frozen=True)
class Kept:
    """What a sweep keeps per member (from `keep=`, see `what_to_keep`).

    **Attributes:**

    - `mode`: `"final"` (the state at the end), `"path"` (the states at `ts`: a
      trajectory or the given times) or `"reduce"` (the outputs of `reduce`).
    - `ts`: the times every member is saved at inside the solve, `(T,)`: the kept times
      (`"path"`), `n_save` times for the `Solution` of `reduce`, and for `"final"`
      none, or `n_save` times where the energy balance needs the work along the path
      (then dropped).
    - `reduce`: the function of `keep=reduce`, else `None`.
    - `observed`: the system's observables kept (`observables=`), each as
      `(name, dims)`, its dimension names at one state.
    """

    mode: str
    ts: np.ndarray
    reduce: Callable | None = None
    observed: tuple[tuple[str, tuple[str, ...]], ...] = ()

    @property
    def path(self) -> bool:
        """Whether the states at the saves are part of the result."""
        return self.mode == "path"


def what_to_keep(keep: Any, n_save: int, t0: float, t1: float, balance: bool) -> Kept:
    """`keep=` (already checked by `sweep_options`) as a `Kept`; `balance`: whether a
    member's energy balance needs the work along its path (inputs, dissipation or
    explicit time dependence), so that `keep="final"` saves at `n_save` times for it."""
    every = np.linspace(t0, t1, int(n_save))
    if callable(keep):
        return Kept("reduce", every, keep)
    if isinstance(keep, str):
        if keep == "final":
            return Kept("final", every if balance else np.zeros(0))
        return Kept("path", every)
    return Kept("path", np.asarray(keep, dtype=float))


def lanes_option(n_lanes: Any, chunk_size: int | None, n_devices: int) -> int | None:
    """`n_lanes`: `None` or a positive integer, at most the members of a chunk per
    device when `chunk_size` was given (more lanes than members would only idle)."""
    if n_lanes is None:
        return None
    lanes = positive_int(
        "n_lanes", n_lanes, "It is the number of members integrated at once per device."
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
    """`devices`: `None`, a count in `1..len(jax.devices())` or a non-empty list."""
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
    if isinstance(devices, (str, bytes, float)) or not isinstance(devices, Sized):
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
    """Check `sweep`'s scalar options on the host, once per call, before anything is
    traced. **Returns:** `(t0, t1, chunk_size)` as Python numbers."""
    t0, t1 = sweep_times(t0, t1)
    keep_option(keep, t0, t1)
    positive_int("n_save", n_save, "It is the number of saved times per member.")
    if dt is not None:
        fixed_step(dt, t0, t1)
    first_step(dt0)
    if stepsize_controller is not None and not isinstance(
        stepsize_controller, dfx.AbstractStepSizeController
    ):
        raise ArgumentTypeError(
            "stepsize_controller must be a diffrax.AbstractStepSizeController (e.g. "
            f"diffrax.PIDController(rtol=1e-8, atol=1e-8)); got {_kind(stepsize_controller)}"
        )
    if dt is None and stepsize_controller is None:
        tolerances(rtol, atol)
    else:
        non_negative_real("rtol", rtol)
        non_negative_real("atol", atol)
    if max_steps is not None:
        positive_int("max_steps", max_steps, "It is each member's step budget.")
    size = None
    if chunk_size is not None:
        size = positive_int("chunk_size", chunk_size, "It is the number of members per chunk.")
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
    """The member count of batched `params` (every leaf a numeric array with the same
    leading axis, at least one member), or a `LagraxError` naming the leaves."""
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
