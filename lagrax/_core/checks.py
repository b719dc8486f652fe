"""Input checks shared by every entry point, eagerly and under `jit`.

Eager (concrete) inputs are checked in Python with the offending values in the message;
traced inputs by `equinox.error_if`, which survives `jit`, `vmap` and `scan` and
costs nothing when its output is unused. Every error raised here is a `LagraxError`.
"""

import inspect
import math
import numbers
from collections.abc import Callable, Mapping
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .closures import closes_over_tracers
from .custom_types import Params
from .errors import (
    ArgumentTypeError,
    ConfigurationError,
    NonFiniteError,
    ParameterError,
    ShapeError,
)
from .linalg import PIVOT_RTOL


def is_traced(*xs: Any) -> bool:
    """Whether any leaf of `xs` is a JAX tracer (we are inside `jit`/`vmap`/`grad`)."""
    return any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(xs))


def traced(system: Any, *values: Any) -> bool:
    """Whether a call of `system` on `values` is traced: a leaf of `values` is a tracer,
    or the system's functions close over one (a system built inside a function that
    `jax.jit`, `jax.vmap` or `jax.grad` transforms)."""
    return is_traced(*values) or closes_over_tracers(system)


def eager_only(what: str, system: Any, *values: Any) -> None:
    """Raise a `ConfigurationError` where an eager validation (`check_state`) is given
    traced values, or a system whose functions close over traced values: it reads the
    values to name the problem, which only concrete values allow."""
    if traced(system, *values):
        raise ConfigurationError(
            f"{what} validates concrete values outside jax.jit, jax.vmap and jax.grad, "
            "and was given traced ones (or a system whose functions close over a traced "
            "value): call it outside the transformation; inside, forward_dynamics and "
            "simulate check their results at run time"
        )


def pivot_threshold(dtype: Any) -> float:
    """Relative size below which a mass-matrix pivot/eigenvalue counts as singular."""
    return PIVOT_RTOL * float(jnp.finfo(dtype).eps)


# --------------------------------------------------------------------------- user calls


def is_namedtuple(x: Any) -> bool:
    """Whether `x` is a `NamedTuple` (a tuple whose class lists its `_fields`): the one
    kind of params with no common base class to `isinstance` against."""
    return isinstance(x, tuple) and isinstance(getattr(type(x), "_fields", None), tuple)


def describe_params(params: Params) -> str:
    if isinstance(params, dict):
        return f"params has keys {sorted(map(str, params))}"
    if is_namedtuple(params):
        return f"params has fields {list(params._fields)}"  # type: ignore[attr-defined]
    return f"params is a {type(params).__name__}"


def _is_params_lookup(err: Exception, params: Params) -> bool:
    """Did `err` come from looking up a missing entry of `params` itself?"""
    if isinstance(err, KeyError):
        key = err.args[0] if err.args else None
        try:
            return isinstance(params, Mapping) and key not in params
        except TypeError:  # unhashable key
            return False
    return getattr(err, "obj", None) is params  # AttributeError on a NamedTuple/Module


def call_user(fn: Callable, role: str, params: Params, *args: Any) -> Any:
    """Call a user function `fn(*args, params)`; a missing-parameter lookup becomes a
    `ParameterError` naming the entry and what `params` has."""
    try:
        return fn(*args, params)
    except TypeError as err:
        if isinstance(params, (list, tuple)) and not is_namedtuple(params):
            if "indices must be integers" in str(err):
                raise ArgumentTypeError(
                    f"the {role} function looks params up by name, but params is a "
                    f"{type(params).__name__} ({err}); pass params as a dict (or a "
                    "NamedTuple / equinox Module) with the names the energies read"
                ) from err
        if params is None and "not subscriptable" in str(err):
            raise ArgumentTypeError(
                f"the {role} function reads params, but params is None; pass the "
                "parameters the energies read (a dict, NamedTuple or equinox Module)"
            ) from err
        raise
    except (KeyError, AttributeError) as err:
        if not _is_params_lookup(err, params):
            raise
        missing = err.args[0] if isinstance(err, KeyError) else getattr(err, "name", "?")
        raise ParameterError(
            f"the {role} function looked up {missing!r} in params, which is not there; "
            f"{describe_params(params)}. Add the missing entry to params."
        ) from err


def binds(fn: Callable, n: int) -> bool | None:
    """Whether `fn` accepts `n` positional arguments (`None`: cannot tell)."""
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return None
    try:
        sig.bind(*range(n))
    except TypeError:
        return False
    return True


def time_signature_message(label: str, n_args: int, fn: Callable, time_dependent: bool) -> str:
    """Why a user energy with `n_args` arguments (`params` included) does not fit."""
    if time_dependent:
        return (
            f"the system was built with time_dependent=True, so lagrax calls its {label}"
            f" with the time first, but {_name(fn)} does not accept {n_args} arguments: "
            "add t as the first argument (T(t, q, qd, params), V(t, q, params), "
            "D(t, q, qd, params)), or drop time_dependent=True if the energies do not "
            "depend on time"
        )
    return (
        f"lagrax calls the {label} with {n_args} arguments, but {_name(fn)} does not accept "
        f"them{' (it takes one more: the time?)' if binds(fn, n_args + 1) else ''}: an "
        "energy that depends on time explicitly needs LagrangianSystem(..., "
        "time_dependent=True), which calls T(t, q, qd, params), V(t, q, params) and "
        "D(t, q, qd, params)"
    )


def _name(fn: Callable) -> str:
    return f"{getattr(fn, '__name__', type(fn).__name__)}{_signature_text(fn)}"


def _signature_text(fn: Callable) -> str:
    try:
        return str(inspect.signature(fn))
    except (TypeError, ValueError):
        return ""


def call_energy(fn: Callable, role: str, label: str, params: Params, *args: Any) -> Any:
    """`call_user` for an energy (`T`, `V`, `D`): a call that fails because the
    function takes another number of arguments (a `T(q, qd, params)` given to a
    time-dependent system, or the reverse) becomes an `ArgumentTypeError` naming it, at
    trace time."""
    try:
        return call_user(fn, role, params, *args)
    except TypeError as err:
        if binds(fn, len(args) + 1) is False:
            # the label says "(t, q, ...)" exactly when the system is time-dependent
            raise ArgumentTypeError(
                time_signature_message(label, len(args) + 1, fn, label.count("(t,") > 0)
            ) from err
        raise


# --------------------------------------------------------------------------- arrays


def coords(
    q: Any,
    name: str,
    n_dof: int | None,
    system_name: str,
    host: bool = False,
    size: str = "degrees of freedom",
) -> Any:
    """`q` as a 1-D floating array of length `n_dof` (when given), or a `ShapeError`.

    `name` is the caller's argument (`q0` for `simulate`, `q_eq` for `linearize`), as
    the messages say it; `size` what `n_dof` counts. `host=True` converts with NumPy (no
    device transfer), for `simulate`'s set-up.
    """
    try:
        q = np.asarray(q) if host else jnp.asarray(q)
    except (TypeError, ValueError) as err:
        raise ArgumentTypeError(
            f"{name} must be an array of real numbers, got {type(q).__name__}: {err}"
        ) from None
    if q.dtype == object or not (
        jnp.issubdtype(q.dtype, jnp.floating)
        or jnp.issubdtype(q.dtype, jnp.integer)
        or jnp.issubdtype(q.dtype, jnp.bool_)
    ):
        raise ArgumentTypeError(f"{name} must be an array of real numbers, got dtype {q.dtype}")
    if not jnp.issubdtype(q.dtype, jnp.floating):
        q = q.astype(jnp.result_type(float))
    if q.ndim != 1:
        raise ShapeError(
            f"{name} must be a 1-D array of generalized coordinates, got shape {q.shape}"
            " (use jax.vmap for batches)"
        )
    if n_dof is not None and q.shape[0] != n_dof:
        raise ShapeError(f"{name} has length {q.shape[0]} but {system_name} has {n_dof} {size}")
    return q


def same_shape(name: str, v: Any, q: Any, q_name: str = "q") -> None:
    if v.shape != q.shape:
        raise ShapeError(
            f"{name} has shape {v.shape} but {q_name} has shape {q.shape}; they must match"
        )


def configuration_size(n_configuration: int | None, n_dof: int | None) -> str:
    """What the size of `q` counts, for `coords`'s message: the degrees of freedom, or
    (a floating base's position and quaternion) the configuration's coordinates."""
    if n_configuration == n_dof:
        return "degrees of freedom"
    return f"configuration coordinates (and {n_dof} velocities)"


def finite(x: jax.Array, name: str) -> jax.Array:
    """Refuse NaN/inf: eagerly with the value when concrete, by `error_if` under jit."""
    if not is_traced(x):
        if not bool(np.all(np.isfinite(np.asarray(x)))):
            raise NonFiniteError(f"{name} contains non-finite values: {np.asarray(x)}")
        return x
    return eqx.error_if(
        x, ~jnp.all(jnp.isfinite(x)), f"{name} contains non-finite values (NaN or inf)"
    )


def finite_params(params: Params) -> None:
    """Eagerly refuse a non-finite numeric leaf of `params`, naming its path."""
    for path, leaf in jax.tree_util.tree_leaves_with_path(params):
        if isinstance(leaf, (int, float, complex, np.ndarray, jax.Array)):
            if not bool(np.all(np.isfinite(np.asarray(leaf)))):
                raise NonFiniteError(f"params{jax.tree_util.keystr(path)} is not finite: {leaf}")


def param_shapes(
    params: Params,
    shapes: Mapping[str, tuple[int, ...]],
    who: str,
    broadcast: tuple[str, ...] = (),
) -> None:
    """Refuse an entry of `params` that a structure-aware system reads with the wrong
    shape (or that is missing): a `ShapeError` naming the entry, its shape and the one
    `who` needs. Shapes are static, so this runs while JAX traces and works inside `jit`
    and `vmap` (a sweep's member sees its own entries). Without it JAX clamps an
    out-of-range read of a short array and the answer is silently wrong.

    `broadcast`: entries that may also be given as any shape broadcasting to theirs (a
    scalar joint damping). `params` that is not a mapping is left to the lookups.
    """
    if not isinstance(params, Mapping):
        return
    for key, shape in shapes.items():
        if key not in params:
            raise ParameterError(
                f"{who} reads params[{key!r}] (shape {shape}), which is missing: "
                f"{describe_params(params)}"
            )
        got = tuple(jnp.shape(params[key]))
        if got == tuple(shape):
            continue
        if key in broadcast:
            try:
                if np.broadcast_shapes(got, shape) == tuple(shape):
                    continue
            except ValueError:
                pass
        allowed = " (or a shape that broadcasts to it)" if key in broadcast else ""
        raise ShapeError(
            f"params[{key!r}] has shape {got}, but {who} needs shape {tuple(shape)}"
            f"{allowed}: one entry per body or joint, as its params() returns them"
        )


# --------------------------------------------------------------------------- energies
#
# What a user's energy or force returns is checked where it is called, on its shape and
# dtype only: both are static, so the checks run once while JAX traces and cost nothing
# when the compiled program runs.


def energy_value(out: Any, label: str, q: Any) -> Any:
    """The result of a user energy (`T`, `V`, `D`) as a real scalar, or a
    `ShapeError` / `ArgumentTypeError` naming `label` and what it returned."""
    if out is None:
        raise ArgumentTypeError(f"the {label} returned None; did it forget `return`?")
    try:
        out = jnp.asarray(out)
    except TypeError as err:
        raise ArgumentTypeError(
            f"the {label} returned {type(out).__name__}, not a number: {err}"
        ) from None
    if jnp.issubdtype(out.dtype, jnp.complexfloating):
        raise ArgumentTypeError(
            f"the {label} returned a complex value (dtype {out.dtype}); energies "
            "must be real: find the expression that became complex (e.g. a sqrt or power "
            "of a negative number, or a complex literal) and keep it real"
        )
    if not (jnp.issubdtype(out.dtype, jnp.floating) or jnp.issubdtype(out.dtype, jnp.integer)):
        raise ArgumentTypeError(f"the {label} returned dtype {out.dtype}, not a number")
    if out.shape != ():
        hint = " (for one coordinate write qd[0], not qd)" if out.shape == (1,) else ""
        raise ShapeError(
            f"the {label} returned an array of shape {out.shape}; it must return "
            f"a real scalar: sum its terms, e.g. with jnp.sum(...){hint}"
        )
    if not jnp.issubdtype(out.dtype, jnp.floating):  # a constant, e.g. V = 0
        out = out.astype(jnp.result_type(q))
    return out


def force_value(out: Any, who: str, q: Any, shape: tuple[int, ...] | None = None) -> Any:
    """The result of a user force (`force`, `tau`): a real array shaped like `q` (or
    `shape`, for an input that is not a generalized force: an actuator's controls)."""
    if out is None:
        raise ArgumentTypeError(f"{who} returned None; did it forget `return`?")
    try:
        out = jnp.asarray(out)
    except TypeError as err:
        raise ArgumentTypeError(
            f"{who} returned {type(out).__name__}, not an array: {err}"
        ) from None
    if jnp.issubdtype(out.dtype, jnp.complexfloating):
        raise ArgumentTypeError(
            f"{who} returned a complex array (dtype {out.dtype}); generalized forces must be real"
        )
    if not (jnp.issubdtype(out.dtype, jnp.floating) or jnp.issubdtype(out.dtype, jnp.integer)):
        raise ArgumentTypeError(f"{who} returned dtype {out.dtype}, not numbers")
    expected = jnp.shape(q) if shape is None else shape
    if out.shape != expected:
        what = "one generalized force per coordinate" if shape is None else "one per input"
        raise ShapeError(f"{who} returned shape {out.shape}; expected {expected} ({what})")
    return out


# --------------------------------------------------------------------------- physics


def physical(
    value: Any, label: str, *, what: str = "mass", positive: bool = False, item: str = ""
) -> Any:
    """A mass (or another physical amount) that must be `>= 0` (`> 0` with
    `positive`) and finite, entry by entry; a `ParameterError` names `label`, the
    entry (`item` and its 1-based number, e.g. "link 2") and the value. A traced
    value comes back wrapped in `equinox.error_if`. A callable (a parameter looked up
    later) is returned unchecked."""
    if callable(value):
        return value
    if is_traced(value):
        x = jnp.asarray(value)
        bad = ~jnp.isfinite(x) | ((x <= 0) if positive else (x < 0))
        return eqx.error_if(x, jnp.any(bad), f"{label}: every {what} must be finite and >= 0")
    arr = np.asarray(value, dtype=float)
    bad = ~np.isfinite(arr) | ((arr <= 0) if positive else (arr < 0))
    if np.any(bad):
        flat = arr.reshape(-1)
        k = int(np.argmax(bad.reshape(-1)))
        where = f"[{k}]" if arr.ndim else ""
        whose = f" ({item} {k + 1})" if item and arr.ndim else ""
        sign = "positive" if positive else "non-negative"
        raise ParameterError(
            f"{label}{where} = {flat[k]:.6g}{whose} is not a {sign} finite {what}: "
            f"every {what} must be {'> 0' if positive else '>= 0'}; check its sign and units"
        )
    return value


# --------------------------------------------------------------------------- options
#
# Small validators for the options of every entry point (simulate, sweep, the system's
# methods). A concrete value (a Python number, a NumPy or concrete JAX scalar) is checked
# in Python and refused with a ``ConfigurationError`` that names the option, the value and
# the fix; a wrong kind of object (a string, a list, a complex number) is an
# ``ArgumentTypeError``. A traced value (inside ``jit``/``vmap``) comes back wrapped in
# ``equinox.error_if``, so the check runs once where the option enters the program, never
# per step. Each returns the value to use in place of its argument.


def _real_scalar(name: str, value: Any, fix: str) -> Any:
    """`value` as a Python float when concrete, else the tracer; refuses other kinds."""
    if isinstance(value, jax.core.Tracer):
        if jnp.ndim(value) != 0:
            raise ConfigurationError(
                f"{name} must be a scalar, got an array of shape {jnp.shape(value)}; {fix}"
            )
        if not jnp.issubdtype(value.dtype, jnp.floating) and not jnp.issubdtype(
            value.dtype, jnp.integer
        ):
            raise ArgumentTypeError(f"{name} must be a real number, got dtype {value.dtype}")
        return value
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (numbers.Real, np.ndarray, np.generic, jax.Array)
    ):
        raise ArgumentTypeError(
            f"{name} must be a real number, got {value!r} ({type(value).__name__}); {fix}"
        )
    arr = np.asarray(value)
    if arr.ndim != 0:
        raise ConfigurationError(f"{name} must be a scalar, got an array of shape {arr.shape}")
    if not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
        raise ArgumentTypeError(f"{name} must be a real number, got {value!r} ({arr.dtype})")
    return float(arr)


def finite_real(name: str, value: Any, fix: str = "") -> Any:
    """A finite real scalar option (e.g. `t0`)."""
    x = _real_scalar(name, value, fix)
    if isinstance(x, float):
        if not math.isfinite(x):
            raise ConfigurationError(f"{name} must be finite, got {name}={value!r}. {fix}")
        return value
    return eqx.error_if(x, ~jnp.isfinite(x), f"{name} must be finite (got NaN or inf). {fix}")


def positive_real(name: str, value: Any, fix: str = "") -> Any:
    """A finite real scalar `> 0` (a step, a time span)."""
    x = _real_scalar(name, value, fix)
    if isinstance(x, float):
        if not (math.isfinite(x) and x > 0):
            raise ConfigurationError(
                f"{name} must be a positive finite number, got {name}={value!r}. {fix}"
            )
        return value
    return eqx.error_if(
        x, ~(jnp.isfinite(x) & (x > 0)), f"{name} must be a positive finite number. {fix}"
    )


def non_negative_real(name: str, value: Any, fix: str = "") -> Any:
    """A finite real scalar `>= 0` (a tolerance, a gain)."""
    x = _real_scalar(name, value, fix)
    if isinstance(x, float):
        if not (math.isfinite(x) and x >= 0):
            raise ConfigurationError(
                f"{name} must be a non-negative finite number, got {name}={value!r}. {fix}"
            )
        return value
    return eqx.error_if(
        x, ~(jnp.isfinite(x) & (x >= 0)), f"{name} must be a non-negative finite number. {fix}"
    )


def positive_int(name: str, value: Any, fix: str = "") -> int:
    """A positive whole number (a count: `max_steps`, `n_save`, a chunk size).

    Whole-valued floats (`1e5`) are accepted; counts fix the shape of the compiled
    program, so a traced value is refused with an `ArgumentTypeError`.
    """
    if isinstance(value, jax.core.Tracer):
        raise ArgumentTypeError(
            f"{name} must be a Python int (it fixes the size of the compiled program), "
            f"got a traced value; pass it as a static argument. {fix}"
        )
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (numbers.Real, np.integer, np.floating)
    ):
        raise ArgumentTypeError(
            f"{name} must be a positive integer, got {value!r} ({type(value).__name__}). {fix}"
        )
    x = float(value)
    if not (math.isfinite(x) and x == math.floor(x) and x >= 1):
        raise ConfigurationError(f"{name} must be a positive integer, got {name}={value!r}. {fix}")
    return int(x)


def time_interval(t0: Any, t1: Any) -> tuple[Any, Any]:
    """`(t0, t1)`: finite, with `t1 > t0` (eagerly, or by `error_if` on `t1`)."""
    fix = "Integrate over a finite interval t0 < t1, e.g. t0=0.0, t1=10.0"
    t0 = finite_real("t0", t0, fix)
    t1 = finite_real("t1", t1, fix)
    if not is_traced(t0, t1):
        if not float(t1) > float(t0):
            raise ConfigurationError(
                f"t1 must be greater than t0, got t0={t0}, t1={t1} (lagrax integrates "
                "forward in time; to go backwards, negate the velocities)"
            )
        return t0, t1
    t1 = eqx.error_if(jnp.asarray(t1), ~(jnp.asarray(t1) > t0), "t1 must be greater than t0")
    return t0, t1


def tolerances(rtol: Any, atol: Any) -> tuple[Any, Any]:
    """`(rtol, atol)`: finite, `>= 0` and not both zero."""
    fix = "Use e.g. rtol=1e-8, atol=1e-8"
    rtol = non_negative_real("rtol", rtol, fix)
    atol = non_negative_real("atol", atol, fix)
    if not is_traced(rtol, atol):
        if float(rtol) == 0.0 and float(atol) == 0.0:
            raise ConfigurationError(
                f"rtol and atol are both 0 (rtol={rtol}, atol={atol}): no step can meet a "
                f"zero error tolerance. Give at least one a positive value. {fix}"
            )
        return rtol, atol
    atol = eqx.error_if(
        jnp.asarray(atol),
        (jnp.asarray(rtol) == 0) & (jnp.asarray(atol) == 0),
        f"rtol and atol are both 0: no step can meet a zero error tolerance. {fix}",
    )
    return rtol, atol


def fixed_step(dt: Any, t0: Any, t1: Any) -> Any:
    """A fixed step `0 < dt <= t1 - t0`.

    A step longer than the interval would silently be cut to `t1 - t0` (one step of
    another size than asked for), which is nearly always a slip (`dt` and `t1`
    swapped, or wrong units), so it is refused.
    """
    fix = "Pass the step of a fixed-step solve as dt > 0, e.g. dt=0.01"
    dt = positive_real("dt", dt, fix)
    if not is_traced(dt, t0, t1):
        span = float(t1) - float(t0)
        if float(dt) > span * (1 + 1e-9):
            raise ConfigurationError(
                f"the fixed step dt={dt} is longer than the whole interval t1 - t0 = "
                f"{span:.6g}: the solve would take one step of {span:.6g}, not of dt. Pass "
                "dt <= t1 - t0 (or t1 = t0 + dt for a single step)"
            )
        return dt
    span = jnp.asarray(t1) - jnp.asarray(t0)
    return eqx.error_if(
        jnp.asarray(dt),
        jnp.asarray(dt) > span * (1 + 1e-9),
        "the fixed step dt is longer than the whole interval t1 - t0",
    )


def first_step(dt0: Any) -> Any:
    """The first step `dt0` of an adaptive solve: `None` (automatic) or `> 0`."""
    if dt0 is None:
        return None
    return positive_real(
        "dt0",
        dt0,
        "dt0 is the first step of an adaptive solve (forward in time); leave it None to "
        "let the controller choose it",
    )


def interval(t0: Any, t1: Any) -> None:
    """Eagerly require finite `t0 < t1` (see `time_interval`)."""
    time_interval(t0, t1)


def save_times(ts: Any, t0: Any, t1: Any, name: str = "ts") -> None:
    """Eagerly require finite, sorted save times inside `[t0, t1]`."""
    ts = np.asarray(ts)
    if not np.issubdtype(ts.dtype, np.number) or np.iscomplexobj(ts):
        raise ArgumentTypeError(f"{name} must be an array of real times, got {ts!r}")
    if not np.all(np.isfinite(ts)):
        raise ConfigurationError(f"{name} must be finite times, got {ts}")
    if ts.size and (np.any(np.diff(ts) < 0) or ts[0] < float(t0) or ts[-1] > float(t1)):
        raise ConfigurationError(
            f"{name} must be non-decreasing and inside [t0, t1] = [{t0}, {t1}]; got {ts}"
        )


def traced_save_times(ts: jax.Array, t0: jax.Array, t1: jax.Array) -> jax.Array:
    """Under `jit`: `ts` with a run-time check that it is sorted inside `[t0, t1]`."""
    if not ts.shape[0]:
        return ts
    return eqx.error_if(
        ts,
        jnp.any(ts[1:] < ts[:-1]) | (ts[0] < t0) | (ts[-1] > t1) | ~jnp.all(jnp.isfinite(ts)),
        "ts must be non-decreasing and inside [t0, t1], and finite",
    )
