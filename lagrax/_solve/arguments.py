"""`simulate`'s arguments: the user's values checked, and converted to the arrays and
options of a solve.

Eagerly (concrete arguments) the conversions use NumPy: each `jnp.asarray` of a Python
value is a device transfer of its own, and a `simulate` call should cost one dispatch,
not a dozen. Under `jit` they use `jax.numpy`, and the checks of traced options travel
with the values returned (`equinox.error_if`, see `checks`).
"""

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np

from .._core import checks, closures
from .._core.errors import ArgumentTypeError, ConfigurationError, ShapeError
from .._systems.abstract import AbstractSystem
from .._systems.vector_field import split_tau


def arrays(system: AbstractSystem, q0, qd0, params, tau, eager: bool):
    """`(q0, qd0, params, tau_fn, tau_const)` of a `simulate` call: the state as 1-D
    arrays of one floating dtype (NumPy arrays when `eager`), Python scalars in `params`
    as arrays, and `tau` split (`split_tau`).

    **Raises:** `ArgumentTypeError` (also for a `system` that is not one), `ShapeError`,
    `NonFiniteError` (a constant `tau`).
    """
    if not isinstance(system, AbstractSystem):
        raise ArgumentTypeError(
            "simulate needs a system (lagrax.LagrangianSystem or lagrax.ConstrainedSystem) "
            f"as its first argument, got {type(system).__name__}: {system!r}"
        )
    n, name = system.n_dof, system.name
    size = checks.configuration_size(system.n_configuration, n)
    q0 = checks.coords(q0, "q0", system.n_configuration, name, host=eager, size=size)
    qd0 = checks.coords(qd0, "qd0", n, name, host=eager)
    if system.n_configuration == n:  # (else each has its own size: q̇ = N(q) v)
        checks.same_shape("qd0", qd0, q0, "q0")
    dtype = np.result_type(q0, qd0) if eager else jnp.result_type(q0, qd0)
    q0, qd0 = q0.astype(dtype), qd0.astype(dtype)
    tdt = np.dtype(dtype)
    # Python scalars in params would be static under filter_jit (a recompile per value);
    # as arrays of the state's dtype they behave as JAX's weakly typed scalars would.
    params = jax.tree_util.tree_map(
        lambda x: (
            np.asarray(x, tdt if isinstance(x, float) else None)
            if isinstance(x, (bool, int, float, complex))
            else x
        ),
        params,
    )
    tau_fn, tau_const = split_tau(system, tau, qd0, host=eager)  # (one force per velocity)
    return q0, qd0, params, tau_fn, tau_const


def options(t0, t1, rtol, atol, n_save, ts, saveat, tdt, eager: bool):
    """`(t0, t1, rtol, atol, n_save, ts)` checked (see `checks`): a finite interval,
    tolerances, a positive `n_save`, and `ts` (unless `saveat` replaces it) a 1-D array
    of `tdt`, sorted inside `[t0, t1]` (traced `ts` are checked in the solve).

    **Raises:** `ConfigurationError`, `ArgumentTypeError`, `ShapeError`.
    """
    t0, t1 = checks.time_interval(t0, t1)
    rtol, atol = checks.tolerances(rtol, atol)
    n_save = checks.positive_int(
        "n_save", n_save, "It is the number of evenly spaced save times (or pass ts=)"
    )
    if saveat is None and ts is not None:
        ts = (np.asarray if eager else jnp.asarray)(ts, tdt)
        if ts.ndim != 1:
            raise ShapeError(f"ts must be 1-D, got shape {ts.shape}")
        if eager:
            checks.save_times(ts, t0, t1)
    return t0, t1, rtol, atol, n_save, ts


def adjoint_for(adjoint, *values):
    """The adjoint a traced `simulate` runs with: for `jax.jvp` / `jax.jacfwd` through it
    (a forward-mode tracer among `values`), `diffrax.ForwardMode()` (its lean loop as a
    plain `lax.while_loop`), or `diffrax.DirectAdjoint()` where reverse mode is applied
    as well (a Hessian); otherwise `adjoint` unchanged.

    **Raises:** `ConfigurationError` where `adjoint` was given and cannot differentiate
    in forward mode.
    """
    modes = set()
    for leaf in jax.tree_util.tree_leaves(values):
        modes |= closures.modes(leaf)
    if "forward" not in modes:
        return adjoint
    both = "reverse" in modes
    if adjoint is None:
        return dfx.DirectAdjoint() if both else dfx.ForwardMode()
    if isinstance(adjoint, dfx.DirectAdjoint) or (
        isinstance(adjoint, dfx.ForwardMode) and not both
    ):
        return adjoint
    wanted = "adjoint=diffrax.DirectAdjoint()" if both else "adjoint=diffrax.ForwardMode()"
    raise ConfigurationError(
        f"simulate is differentiated in forward mode (jax.jvp, jax.jacfwd"
        f"{', over reverse mode' if both else ''}), which adjoint={adjoint!r} cannot do: "
        f"leave adjoint=None (lagrax then picks the mode), or pass {wanted}"
    )


def differentiated_scalars(*values) -> int | None:
    """How many scalars among `values` reverse mode differentiates (`jax.grad`,
    `jax.vjp`), or `None` where forward mode traces any of them, or where a function
    among `values` closes over a differentiated value (only the checkpointed loop, which
    closure-converts its body, takes those)."""
    count = 0
    functions = []
    for leaf in jax.tree_util.tree_leaves(values):
        if isinstance(leaf, jax.core.Tracer):
            modes = closures.modes(leaf)
            if "forward" in modes:
                return None
            if "reverse" in modes:
                count += int(np.prod(leaf.shape))
        elif callable(leaf):
            functions.append(leaf)
    seen: set[int] = set()
    for fn in functions:
        for leaf in closures.closure_tracers(fn, 4, seen):
            if closures.modes(leaf):
                return None
    return count
