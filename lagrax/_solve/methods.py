"""Named integration methods for `simulate`: what each is, and how it must be run."""

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import diffrax as dfx
import equinox as eqx
import jax.numpy as jnp
import optimistix as optx

from .._core import checks
from .._core.errors import ArgumentTypeError, ConfigurationError
from ..integrators import RK4, Rodas4, Variational


@dataclass(frozen=True)
class MethodInfo:
    """A named method: a factory for its diffrax solver and how it may be stepped."""

    make: Callable[[], dfx.AbstractSolver]
    adaptive: bool  # has an error estimate, may use an adaptive step
    implicit: bool
    summary: str

    def solver(self) -> dfx.AbstractSolver:
        return _instance(self.make)


METHODS: dict[str, MethodInfo] = {
    "tsit5": MethodInfo(
        dfx.Tsit5,
        True,
        False,
        "Tsitouras 5(4), explicit, adaptive: the default for smooth, non-stiff scenes",
    ),
    "dopri5": MethodInfo(dfx.Dopri5, True, False, "Dormand–Prince 5(4), explicit, adaptive"),
    "dopri8": MethodInfo(
        dfx.Dopri8,
        True,
        False,
        "Dormand–Prince 8(7), explicit, adaptive: tight tolerances (≤ 1e-10)",
    ),
    "kvaerno5": MethodInfo(
        dfx.Kvaerno5,
        True,
        True,
        "Kværnø 5(4) ESDIRK, implicit, adaptive: stiff springs and dampers",
    ),
    "rodas4": MethodInfo(
        Rodas4,
        True,
        True,
        "Rodas4, linearly implicit (Rosenbrock), L-stable, adaptive: stiff contact and "
        "limits at one Jacobian a step",
    ),
    "rk4": MethodInfo(RK4, False, False, "classic Runge–Kutta 4, explicit, fixed step only"),
    "variational": MethodInfo(
        lambda: Variational(order_=2),
        False,
        True,
        "midpoint variational integrator, symplectic, order 2, fixed step only",
    ),
    "variational4": MethodInfo(
        lambda: Variational(order_=4),
        False,
        True,
        "triple-jump composition of the midpoint variational integrator, order 4, fixed step",
    ),
}


@functools.cache
def _instance(make: Callable[[], dfx.AbstractSolver]) -> dfx.AbstractSolver:
    # solvers are immutable: one instance per method (building an equinox Module on every
    # simulate call costs tens of µs)
    return make()


def resolve_solver(solver) -> tuple[dfx.AbstractSolver, bool]:
    """`(diffrax solver, may_be_adaptive)` from a method name or a solver instance."""
    if solver is None:
        solver = "tsit5"
    if isinstance(solver, str):
        key = solver.lower()
        if key not in METHODS:
            raise ConfigurationError(f"unknown method {solver!r}; choose one of {sorted(METHODS)}")
        info = METHODS[key]
        return info.solver(), info.adaptive
    if not isinstance(solver, dfx.AbstractSolver):
        raise ArgumentTypeError(f"solver must be a method name or a diffrax solver, got {solver!r}")
    adaptive = not isinstance(solver, (Variational, RK4, dfx.SemiImplicitEuler, dfx.Euler))
    return solver, adaptive


def fixed_step_budget(t0: float, t1: float, dt: float) -> int:
    """Steps needed at a fixed `dt`, rounded up to a power of two, at least 4096.

    `max_steps` is a compile-time constant for diffrax; rounding keeps the number of
    distinct budgets (and so of compilations) logarithmic in the step count.
    """
    needed = math.ceil((float(t1) - float(t0)) / float(dt) * (1 + 1e-12)) + 1
    return max(4096, 1 << max(needed - 1, 1).bit_length())


def configure(solver, rtol, atol, dt, dt0, max_steps, stepsize_controller, t0, t1, tdt, eager):
    """`(solver, stepsize_controller, dt0, max_steps)` for a solve, with lagrax's defaults:
    `t0`, `t1`, `rtol` and `atol` checked (`checks.time_interval`,
    `checks.tolerances`), then `stepping`. Used by `sweep`; `simulate` checks those
    four itself (it passes their checked values on) and calls `stepping`.
    """
    checks.time_interval(t0, t1)
    rtol, atol = checks.tolerances(rtol, atol)
    return stepping(solver, rtol, atol, dt, dt0, max_steps, stepsize_controller, t0, t1, tdt, eager)


def stepping(solver, rtol, atol, dt, dt0, max_steps, stepsize_controller, t0, t1, tdt, eager):
    """`(solver, stepsize_controller, dt0, max_steps)` for a solve whose interval and
    tolerances are checked (see `configure`), with lagrax's defaults.

    `stepsize_controller` stays `None` for the default `PIDController(rtol, atol)`;
    the step budget is sized for a fixed `dt` when `t0`, `t1` and `dt` are concrete.
    Every other option is validated here (see the options section of `checks`): a bad
    concrete value raises a `ConfigurationError`, a traced one fails at run time
    through `equinox.error_if`.
    """
    named_implicit = isinstance(solver, str)  # configure only the solvers we built
    solver, may_adapt = resolve_solver(solver)
    # every option checked where it enters: concrete values here (raising), traced ones
    # wrapped in error_if (the returned dt0 is the one the solve uses)
    dt0 = checks.first_step(dt0)
    if max_steps is not None:
        max_steps = checks.positive_int(
            "max_steps", max_steps, "It is the step budget (accepted + rejected steps)"
        )
    if dt is not None:
        if stepsize_controller is not None:
            raise ConfigurationError(
                "pass either dt= (a fixed step) or stepsize_controller=, not both"
            )
        if dt0 is not None:
            raise ConfigurationError(
                f"pass either dt= (a fixed step, here dt={dt}) or dt0= (the first step of "
                f"an adaptive solve, here dt0={dt0}), not both"
            )
        dt = checks.fixed_step(dt, t0, t1)
        stepsize_controller = _instance(dfx.ConstantStepSize)  # one instance (see _instance)
        dt0 = dt
        if max_steps is None and (eager or not checks.is_traced(t0, t1, dt)):
            max_steps = fixed_step_budget(t0, t1, dt)
    elif not may_adapt and not isinstance(stepsize_controller, dfx.ConstantStepSize):
        raise ConfigurationError(
            f"{type(solver).__name__} has no error estimate and runs at a fixed step only "
            "(for a variational integrator, an adaptive step would also destroy its "
            "symplecticity): pass dt=..."
        )
    if max_steps is None:
        max_steps = 100_000
    if isinstance(solver, dfx.AbstractImplicitSolver) and named_implicit:
        # Newton with a fresh Jacobian each iteration: for the small n of mechanisms it is
        # cheap, and far more robust than a chord iteration on strongly nonlinear steps.
        solver = eqx.tree_at(
            lambda s: s.root_finder,
            solver,
            optx.Newton(rtol=jnp.asarray(rtol, tdt), atol=jnp.asarray(atol, tdt)),
        )
        if stepsize_controller is None:  # diffrax's advice for implicit methods
            stepsize_controller = dfx.PIDController(
                rtol=jnp.asarray(rtol, tdt), atol=jnp.asarray(atol, tdt), pcoeff=0.3, icoeff=0.3
            )
    return solver, stepsize_controller, dt0, int(max_steps)
