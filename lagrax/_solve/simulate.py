"""One trajectory: `simulate`, on diffrax's steps.

`SolveConfig` (what fixes the compiled program: the model and the method) and
`SolveInputs` (its arrays) describe a solve; `solve` / `solve_from` compute it, and
`sweep` runs them too: lagrax's lean loop (`integrate`, or `events` with events) or
`diffrax.diffeqsolve`, then the [`Solution`][lagrax.Solution] (`postprocess.finish`: the
post-processing that `sweep` shares).

`simulate` is the entry point, in named steps: its arguments checked and converted
(`arguments`), the stepping configured (`methods.stepping`), the compiled call
(`compiled`: `checked_solve` through a cached `jax.jit`; under a user's `jit`,
`solve` itself) and, for a failed solve, the report (`diagnose.failure_message`).
"""

from collections.abc import Callable, Sequence
from typing import Any

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from .._core import checks, closures
from .._core.custom_types import Coordinates, Params, Velocities
from .._core.errors import ConfigurationError, SimulationError
from .._core.one_shot import one_shot_on
from .._core.results import RESULTS, code_of, messages
from .._systems.abstract import AbstractSystem
from .._systems.vector_field import LagrangianVectorField, TauFn
from ..integrators import Rodas4, Variational
from . import arguments, cut_sensitivities, integrate, sensitivities, transposed
from . import events as _events  # (`events` is simulate's argument)
from .compiled import call, compiled_or_none, configured
from .diagnose import failure_message
from .events import Event
from .methods import stepping
from .postprocess import WithWork, finish, no_power, relative_work
from .solution import Solution


class SolveConfig(eqx.Module):
    """What fixes the compiled program of a solve: the model and the method.

    `simulate` compiles one program per configuration and caches it; `sweep` runs
    the same solve under `vmap` or on its lane queue.
    """

    system: AbstractSystem
    solver: dfx.AbstractSolver
    tau_fn: Callable | None = None
    stepsize_controller: dfx.AbstractStepSizeController | None = None
    saveat: dfx.SaveAt | None = None
    adjoint: dfx.AbstractAdjoint | None = None
    n_save: int = eqx.field(default=0, static=True)
    max_steps: int = eqx.field(default=100_000, static=True)
    events: tuple[_events.Event, ...] | None = None


class SolveInputs(eqx.Module):
    """The arrays of a solve: changing them does not recompile."""

    y0: tuple[Any, Any]
    params: Any
    tau_const: Any
    t0: Any
    t1: Any
    ts: Any
    rtol: Any
    atol: Any
    dt0: Any


def solve(config: SolveConfig, inputs: SolveInputs) -> Solution:
    """The solve of `simulate`, never raising: the start from
    [`AbstractSystem.initial_state`][lagrax.AbstractSystem.initial_state], then `solve_from`."""
    config = prepared(config, inputs)
    q0, qd0, started = config.system.initial_state(*inputs.y0, inputs.params)
    return solve_from(config, inputs, (q0, qd0), started)


def prepared(config: SolveConfig, inputs: SolveInputs) -> SolveConfig:
    """`config` with its system [`prepared`][lagrax.AbstractSystem.prepared] at the
    solve's parameters: what depends on them alone is traced once, before the loop."""
    system = config.system.prepared(inputs.params, jnp.result_type(inputs.y0[0], float))
    return eqx.tree_at(lambda c: c.system, config, system)


def solve_from(config: SolveConfig, inputs: SolveInputs, y0, started) -> Solution:
    """Integrate from `y0` (already the system's initial state; `started` says whether
    it could be formed) and collect the [`Solution`][lagrax.Solution].

    The lean loop (`integrate.integrate`, or `events.integrate_events` with events)
    runs unless an adjoint other than `diffrax.ForwardMode` (which runs it as a plain
    `lax.while_loop`), a custom `saveat` or a step-size controller it does not reproduce
    asks for `diffrax.diffeqsolve`."""
    system, params = config.system, inputs.params
    ts, saveat = _save_times(config, inputs)
    own_saveat = config.saveat is None
    controller = config.stepsize_controller
    if controller is None:
        controller = dfx.PIDController(rtol=inputs.rtol, atol=inputs.atol)
    field = LagrangianVectorField(system, config.tau_fn)
    term = dfx.ODETerm(field)
    args = (params, inputs.tau_const)
    records = work = None
    forward = isinstance(config.adjoint, dfx.ForwardMode)
    if (config.adjoint is None or forward) and own_saveat and integrate.is_lean(controller):
        # the lean loop: the same steps as diffeqsolve, without its per-step machinery
        ts, q, qd, t_end, q_end, qd_end, result, stats, (records, work) = _lean(
            config, inputs, term, controller, y0, args, ts, field
        )
    else:
        sol = dfx.diffeqsolve(
            term,
            config.solver,
            inputs.t0,
            inputs.t1,
            inputs.dt0,
            y0,
            args=args,
            saveat=saveat,
            stepsize_controller=controller,
            max_steps=config.max_steps,
            throw=False,
            **({} if config.adjoint is None else {"adjoint": config.adjoint}),
        )
        ts, q, qd, t_end, q_end, qd_end = _diffrax_saves(sol, ts if own_saveat else None)
        result = RESULTS.promote(sol.result)
        stats = dict(sol.stats)
    return finish(
        system,
        field,
        args,
        (ts, q, qd),
        (t_end, q_end, qd_end),
        result,
        stats,
        started,
        records,
        work,
    )


def _save_times(config: SolveConfig, inputs: SolveInputs):
    """`(ts, saveat)`: the save times (`n_save` evenly spaced ones when `ts` is
    `None`; traced `ts` checked at run time, eager ones were checked by `simulate`)
    and lagrax's own `SaveAt(ts, t1=True)` (the extra last entry: where the solve
    ended), or `(inputs.ts, config.saveat)` for a custom `saveat`."""
    t0, t1, ts = inputs.t0, inputs.t1, inputs.ts
    if config.saveat is not None:
        return ts, config.saveat
    if ts is None:
        ts = t0 + (t1 - t0) * jnp.linspace(0.0, 1.0, config.n_save, dtype=t0.dtype)
    else:
        ts = checks.traced_save_times(ts, t0, t1)
    return ts, dfx.SaveAt(ts=ts, t1=True)


def _lean(config: SolveConfig, inputs: SolveInputs, term, controller, y0, args, ts, field):
    """The solve on lagrax's own loop: `(ts, q, qd, t_end, q_end, qd_end, result,
    stats, (records, work))`, the saves past the end `inf` (`records`: `None` without
    events; `work`: the work at the saves where the loop carried it as state, else
    `None`)."""
    solver, max_steps, records, work = config.solver, config.max_steps, None, None
    t0, t1, dt0 = inputs.t0, inputs.t1, inputs.dt0
    kind = "checkpointed"
    if isinstance(config.adjoint, dfx.ForwardMode):
        kind = "lax"
        if isinstance(solver, dfx.AbstractRungeKutta) and solver.scan_kind is None:
            # its stages loop as diffrax's ForwardMode has them loop: no custom_vjp
            solver = eqx.tree_at(lambda s: s.scan_kind, solver, "lax", is_leaf=lambda x: x is None)
    if config.events is None and kind == "lax":  # forward mode: tangents as state
        (q, qd), end = sensitivities.integrate(
            term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, kind
        )
    elif config.events is None and work_as_state(solver, field, args, t0, y0):
        # the work integrated with the state: the field traced once, in the stages
        carried = dfx.ODETerm(WithWork(field))
        ((q, qd), work), end = integrate.integrate(
            carried,
            solver,
            integrate.primal_controller(controller),
            (y0, jnp.zeros((), y0[0].dtype)),
            args,
            t0,
            t1,
            dt0,
            ts,
            max_steps,
            kind,
        )
        end = eqx.tree_at(lambda e: e.y, end, end.y[0])
    elif config.events is None:
        (q, qd), end = integrate.integrate(
            term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, kind
        )
    elif kind == "lax" and cut_sensitivities.applies(config.events, config.system):
        # events that only cut the steps, on a rough Jacobian: the tangents of the solve
        # without them, under the error control
        (q, qd), end, records = cut_sensitivities.integrate(
            term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, config.events, field
        )
    else:
        (q, qd), end, records = _events.integrate_events(
            term,
            solver,
            controller,
            y0,
            args,
            t0,
            t1,
            dt0,
            ts,
            max_steps,
            config.events,
            field,
            kind,
        )
    t_end, (q_end, qd_end), result = end.t, end.y, end.result
    ts = jnp.where(jnp.arange(ts.shape[0]) < end.save_index, ts, jnp.inf)
    steps, accepted = end.num_steps, end.num_accepted_steps
    stats = dict(
        num_steps=steps,
        num_accepted_steps=accepted,
        num_rejected_steps=steps - accepted,
        max_steps=max_steps,
    )
    if work is not None:
        work = relative_work(ts, work)
    return ts, q, qd, t_end, q_end, qd_end, result, stats, (records, work)


def work_as_state(solver, field, args, t0, y0) -> bool:
    """Whether the plain loop carries the work as state (`postprocess.WithWork`): a
    Runge–Kutta method (lagrax's variational integrators step `(q, v)` as such) and a
    system with a power to integrate."""
    if not isinstance(solver, (dfx.AbstractRungeKutta, Rodas4)):
        return False
    return not no_power(field.system, field, args[0], args[1], t0, *y0)


def _diffrax_saves(sol: dfx.Solution, requested_ts):
    """`(ts, q, qd, t_end, q_end, qd_end)` of a `diffeqsolve` solution: the final
    state is the last finite save. With lagrax's own `SaveAt(ts, t1=True)` (the
    `requested_ts` given; `None` for a custom `saveat`), its extra last entry is dropped
    and unreached saves are `inf`: on a failure diffrax writes the final state into the
    first unreached slot, whose time then differs from the requested one."""
    q, qd = sol.ys
    ts = sol.ts
    last = jnp.max(jnp.where(jnp.isfinite(ts), jnp.arange(ts.shape[0]), 0))
    t_end, q_end, qd_end = ts[last], q[last], qd[last]
    if requested_ts is not None:
        ts, q, qd = ts[:-1], q[:-1], qd[:-1]
        reached = ts == requested_ts
        inf = jnp.asarray(jnp.inf, q.dtype)
        ts = jnp.where(reached, ts, inf)
        q = jnp.where(reached[:, None], q, inf)
        qd = jnp.where(reached[:, None], qd, inf)
    return ts, q, qd, t_end, q_end, qd_end


@eqx.filter_jit
def _solve_keyed(config: SolveConfig, inputs: SolveInputs, one_shot: bool) -> Solution:
    return solve(config, inputs)


def _solve(config: SolveConfig, inputs: SolveInputs) -> Solution:
    """`solve` under a user's jit (traced inputs), its trace cached per configuration
    and per form of the recursions (`one_shot_on()`, a static argument)."""
    return _solve_keyed(config, inputs, one_shot_on())


def _solve_pair(pair) -> Solution:
    return solve(*pair)


@eqx.filter_jit
def _transposed_keyed(config: SolveConfig, inputs: SolveInputs, one_shot: bool) -> Solution:
    return transposed.call(_solve_pair, (config, inputs))


def _solve_transposed(config: SolveConfig, inputs: SolveInputs) -> Solution:
    """`solve` for `jax.grad` with few differentiated scalars: the loop in forward
    mode, its Jacobian contracted in the backward pass (`transposed`)."""
    return _transposed_keyed(config, inputs, one_shot_on())


def _inputs_ok(config: SolveConfig, inputs: SolveInputs, y0, started):
    """In-graph validity of a solve's inputs: the initial state could be formed, finite
    parameters and state, finite energy, and finite accelerations at the start (which
    also requires a positive-definite mass matrix). A `False` here sends `simulate` to
    the eager, precise `check_state`."""
    params, system = inputs.params, config.system
    leaves = [
        jnp.all(jnp.isfinite(x))
        for x in jax.tree_util.tree_leaves(params)
        if eqx.is_inexact_array(x)
    ]
    field = LagrangianVectorField(system, config.tau_fn)
    q0, qd0 = y0
    _, qdd = field(inputs.t0, (q0, qd0), (params, inputs.tau_const))
    energy = system.jacobi_integral(inputs.t0, q0, qd0, params)
    valid = [
        *leaves,
        jnp.asarray(started),
        jnp.all(jnp.isfinite(q0)),
        jnp.all(jnp.isfinite(qd0)),
        jnp.isfinite(energy),
        jnp.all(jnp.isfinite(qdd)),
    ]
    return jnp.all(jnp.stack(valid))


@eqx.filter_jit
def _checked_once(config: SolveConfig, inputs: SolveInputs):
    config = prepared(config, inputs)
    q0, qd0, started = config.system.initial_state(*inputs.y0, inputs.params)
    sol = solve_from(config, inputs, (q0, qd0), started)
    inputs_ok = _inputs_ok(config, inputs, (q0, qd0), started)
    if config.events is None:
        solved_ok = sol.ok & jnp.all(jnp.isfinite(sol.q)) & jnp.all(jnp.isfinite(sol.qd))
    else:  # a terminal event leaves the saves after it unreached (inf)
        reached = jnp.isfinite(sol.ts)[:, None]
        solved_ok = sol.ok & jnp.all(jnp.isfinite(sol.q) | ~reached)
        solved_ok = solved_ok & jnp.all(jnp.isfinite(sol.qd) | ~reached)
    return sol, jnp.stack([inputs_ok, solved_ok])


def checked_solve(config: SolveConfig, fields: tuple):
    """The program `simulate` runs on concrete inputs (through `compiled.call`): the
    solve and the two flags `simulate` needs on the host, fetched at once: whether the
    inputs were valid, and whether the solve succeeded with finite saves. `fields` are
    those of `SolveInputs`, in order."""
    # (building the SolveInputs Module inside the trace skips equinox's per-instance checks)
    return _checked_once(config, SolveInputs(*fields))


def simulate(
    system: AbstractSystem,
    q0: Coordinates,
    qd0: Velocities,
    params: Params,
    *,
    t1: float,
    t0: float = 0.0,
    ts: Float[Array, " T"] | None = None,
    n_save: int = 501,
    tau: Velocities | TauFn | None = None,
    solver: str | dfx.AbstractSolver | None = None,
    rtol: float = 1e-8,
    atol: float = 1e-8,
    dt: float | None = None,
    dt0: float | None = None,
    max_steps: int | None = None,
    saveat: dfx.SaveAt | None = None,
    stepsize_controller: dfx.AbstractStepSizeController | None = None,
    adjoint: dfx.AbstractAdjoint | None = None,
    events: Event | Sequence[Event] | None = None,
    throw: bool = True,
) -> Solution:
    """Integrate `M(q) q̈ + C q̇ + G = τ + F − ∂D/∂q̇` from `(q0, q̇0)` over `[t0, t1]`.

    The state `(q, q̇)` is integrated as a first-order system with diffrax; the
    accelerations come from
    [`LagrangianSystem.forward_dynamics`][lagrax.LagrangianSystem.forward_dynamics] (unchecked
    inside the solver loop; failures are diagnosed after it, see *Raises*).

    A [`ConstrainedSystem`][lagrax.ConstrainedSystem] is integrated the same way with its
    constrained accelerations (KKT system with Baumgarte stabilization); its initial state is first
    projected onto `φ(q) = 0`, `J q̇ = 0` (unless `project_initial=False`), so
    `Solution.q[0]` may differ from `q0`; `Solution.constraint_violation` and
    `Solution.multipliers` report `φ` and `λ` along the path. The variational
    integrators do not apply to constrained systems.

    **Arguments:**

    - `system`, `q0`, `qd0`, `params`: the model, its initial state and parameters.
    - `t1`, `t0`: time interval.
    - `ts`: times at which to save; default `n_save` evenly spaced points in
      `[t0, t1]`. `saveat` (a `diffrax.SaveAt`) overrides both.
    - `tau`: input generalized forces, a constant `(n,)` array or a function
      `tau(t, q, qd) -> (n,)` (a controller). Added to the system's own `force`. A
      system whose `n_input` differs takes that many entries (a
      [`from_mujoco`][lagrax.chains.from_mujoco] scene: MuJoCo's `ctrl`).
    - `solver`: a method name or a diffrax solver. Names (see `lagrax.METHODS`):
      `"tsit5"` (explicit 5(4), adaptive), `"dopri5"`, `"dopri8"` (tight
      tolerances), `"kvaerno5"` (implicit; stiff springs and dampers), `"rodas4"`
      (linearly implicit, one Jacobian a step; stiff contact), `"rk4"` (fixed
      step), `"variational"` / `"variational4"` (symplectic, fixed step; bounded
      energy error over long horizons). Default (`None`): the system's
      [`default_method`][lagrax.AbstractSystem.default_method]: `"tsit5"`, and
      `"rodas4"` for a contact scene where a contact can stick (friction) or joint
      limits are enforced; with `dt=`, `"tsit5"` at that step.
    - `rtol`, `atol`: error-control tolerances of the adaptive step (default 1e-8);
      for implicit methods at a fixed step, the tolerances of their Newton iterations.
      Changing them, `params`, the initial state, `t1` or `dt` does not recompile.
    - `dt`: run at this fixed step instead (`diffrax.ConstantStepSize`). Required by
      the fixed-step methods; allowed with every method.
    - `dt0`: initial step of an adaptive solve (default: chosen by diffrax).
    - `max_steps`: step budget (accepted + rejected). Default: 100,000 for an adaptive
      solve; at a fixed step, enough steps for `[t0, t1]`.
    - `stepsize_controller`: override the default `diffrax.PIDController(rtol, atol)`.
    - `adjoint`: how to differentiate the solve. Default `None`: lagrax's own lean
      stepping loop (diffrax's steps without `diffeqsolve`'s per-step machinery; about
      2–3× faster for small mechanisms), differentiated the way it is asked to be:
      reverse mode for `jax.grad` / `jax.vjp` (by forward sensitivities where at most
      `max(16, 4n)` input scalars are differentiated: the loop carries their tangents and
      the backward pass contracts them; otherwise recursive checkpointing, as diffrax's
      default, which also takes a function closing over a differentiated value),
      forward mode for `jax.jvp` / `jax.jacfwd` (plain `lax.while_loop`s, as
      `diffrax.ForwardMode`; few inputs, many outputs), and `diffrax.DirectAdjoint` for
      forward over reverse (`jax.hessian`). lagrax sees the mode from the arguments it
      is given, so where the forward-mode transform is applied *outside* a `jax.jit`
      that contains `simulate` (`jax.jacfwd(jax.jit(loss))`), pass
      `adjoint=diffrax.ForwardMode()`. Any other diffrax adjoint runs
      `diffrax.diffeqsolve` with it, e.g. `diffrax.RecursiveCheckpointAdjoint()` or
      `diffrax.BacksolveAdjoint()`; one that cannot do forward mode, under `jax.jvp`,
      raises a `ConfigurationError`. A custom `saveat` or a step-size controller other
      than `PIDController` / `ConstantStepSize` also runs `diffeqsolve`.
    - `events`: a [`lagrax.Event`][] or a sequence of them: zero crossings of
      `condition(t, q, qd, params)`, located on the solver's dense output and recorded
      in `Solution.events`; a terminal event ends the solve at its root, an event with
      a `reset` continues from the reset state (an impact), a cascade of events (more
      than `max_events`, or resets accumulating at a point) ends it with
      `RESULTS.event_cascade`. Events run on lagrax's own stepping loop: not with
      `adjoint`, `saveat` or a controller other than `PIDController` /
      `ConstantStepSize`, nor with the variational integrators (their linear dense
      output would locate events to second order only, and a reset breaks their discrete
      variational structure); the fixed-step `"rk4"` is supported (cubic Hermite
      output).
    - `throw`: raise on failure (default). With `throw=False` the failure is reported
      in `Solution.result` / `Solution.ok` instead, which is what `vmap` and sweeps
      need: one bad member does not kill the batch.

    **Returns:** a [`Solution`][lagrax.Solution].

    **Raises:** `ConfigurationError` for a bad option (`t0`/`t1` not finite or
    `t1 <= t0`; `dt` or `dt0` not positive and finite, `dt` longer than
    `t1 - t0` or given with `dt0`; `rtol`/`atol` negative, non-finite or both zero;
    `max_steps`/`n_save` not a positive integer; under `jit` a traced option fails at
    run time), `ArgumentTypeError` for the wrong kind of object;
    `ShapeError`, `NonFiniteError`, `ParameterError`, `MassMatrixError`
    for bad input (checked at the initial state), `ConstraintError` for a constrained
    system whose initial state cannot be projected onto its constraints or whose
    constraint Jacobian is rank-deficient there, and `SimulationError` when the solve
    fails: the message names the cause (step budget, non-finite state, singular mass
    matrix, an event cascade with its time and counts), the time reached and what to try.
    An event whose condition is not a scalar or whose reset returns the wrong shapes
    raises a `ShapeError`; events with an option they cannot run with a
    `ConfigurationError`.

    **Example:**

    ```python
    system, params = lagrax.models.planar_2r()
    sol = lagrax.simulate(system, [0.5, 0.8], [0.0, 0.0], params, t1=10.0)
    sol.q[-1], sol.energy_error.max()
    ```
    """
    eager = not checks.is_traced(q0, qd0, params, t0, t1, ts, rtol, atol, tau, dt, dt0)
    eager = eager and not closures.closes_over_tracers(tau, system)
    q0, qd0, params, tau_fn, tau_const = arguments.arrays(system, q0, qd0, params, tau, eager)
    tdt = np.dtype(q0.dtype)
    t0, t1, rtol, atol, n_save, ts = arguments.options(
        t0, t1, rtol, atol, n_save, ts, saveat, tdt, eager
    )
    # (t0, t1, rtol and atol are checked: under jit the checks travel with these values)
    solver = system.default_method if solver is None and dt is None else solver
    solver, stepsize_controller, dt0, max_steps = stepping(
        solver, rtol, atol, dt, dt0, max_steps, stepsize_controller, t0, t1, tdt, eager
    )
    transposed_ok = False
    if not eager:  # jax.jvp / jax.jacfwd through simulate: forward mode
        if tau_fn is not None:  # a controller's differentiated gains, say: as its fields,
            # where the solve's derivative rules see them (not hidden in its closure)
            tau_fn = closures.hoisted(tau_fn, jnp.zeros((), tdt), q0, qd0)
        # (jax.grad by forward sensitivities: lagrax's adjoint, few differentiated scalars)
        values = (q0, qd0, params, tau_const, t0, t1, ts, system, tau_fn)
        k = arguments.differentiated_scalars(*values) if adjoint is None else None
        transposed_ok = k is not None and 0 < k <= transposed.max_tangents(2 * q0.shape[-1])
        if closures.differentiated_closure(system):
            # (the compiled solve holds the system's functions as constants: a derivative
            # with respect to a value they close over would silently be zero)
            raise ConfigurationError(
                "simulate is differentiated (jax.grad, jax.jvp, ...) with respect to a "
                "value that the system's energy, force or dissipation functions close "
                "over, which the solve cannot differentiate: pass that value through "
                "params (the functions' last argument) instead"
            )
        hidden = closures.hidden_tracers(tau_fn)  # a tau function's closure
        values = (q0, qd0, params, tau_const, t0, t1, ts, tau_fn, *hidden)
        adjoint = arguments.adjoint_for(adjoint, *values)
    events = _events.as_events(events)
    if events is not None:
        events_supported(solver, stepsize_controller, saveat, adjoint)
        _events.check_events(events, t0, q0, qd0, params)
    asarray = np.asarray if eager else jnp.asarray
    fields = (  # SolveInputs' fields, in order
        (q0, qd0),
        params,
        tau_const,
        asarray(t0, tdt),
        asarray(t1, tdt),
        ts,
        asarray(rtol, tdt),
        asarray(atol, tdt),
        None if dt0 is None else asarray(dt0, tdt),
    )
    parts = (system, solver, tau_fn, stepsize_controller, saveat, adjoint)
    if not eager:
        limits = (n_save, max_steps, events)
        return _traced_solve(parts, fields, limits, transposed_ok and saveat is None, throw)
    sol, (inputs_ok, solved_ok) = _eager_solve(parts, fields, n_save, max_steps, events)
    if not inputs_ok:
        system.check_state(q0, qd0, params, t=t0)  # raises with the values in the message
    if not throw or solved_ok:
        return sol
    why = failure_message(
        system, sol, events, params, max_steps, rtol, atol, tau_fn, tau_const, (q0, qd0), t1
    )
    raise SimulationError(why)


def _eager_solve(parts: tuple, fields: tuple, n_save, max_steps, events):
    """`simulate` called eagerly: `(solution, (inputs_ok, solved_ok))` from one compiled
    call (its program cached by the configuration), with one device-to-host transfer."""
    if events is None:
        config, fn = configured(checked_solve, SolveConfig, parts, n_save, max_steps)
    else:  # (events: a fresh tuple each call, no front cache)
        config = SolveConfig(*parts, n_save, max_steps, events)
        fn = compiled_or_none(checked_solve, config)
    sol, flags = call(checked_solve, config, fields, fn)
    return sol, tuple(np.asarray(flags))


def _traced_solve(parts: tuple, fields: tuple, limits: tuple, transposed: bool, throw: bool):
    """`simulate` inside a trace (a user's `jit`, `grad` or `vmap`): the solve as part of
    the caller's program, on the transposed loop where it serves (`transposed`: its loop
    runs in forward mode), failing at run time with the failure's own message."""
    if transposed:
        config = SolveConfig(*parts[:-1], dfx.ForwardMode(), *limits)
        sol = _solve_transposed(config, SolveInputs(*fields))
    else:
        sol = _solve(SolveConfig(*parts, *limits), SolveInputs(*fields))
    if not throw:
        return sol
    return eqx.branched_error_if(sol, ~sol.ok, code_of(sol.result), _JIT_MESSAGES)


def events_supported(solver, controller, saveat, adjoint) -> None:
    """A `ConfigurationError` where `events=` cannot run (see `simulate`)."""
    if isinstance(solver, Variational):
        raise ConfigurationError(
            "events are not supported with the variational integrators (their dense output "
            "is linear, so event times would be second order, and a reset breaks their "
            "discrete variational structure): use solver='rk4' at a fixed dt, or an "
            "adaptive method such as 'tsit5' or 'dopri8'"
        )
    if isinstance(adjoint, dfx.ForwardMode):
        adjoint = None  # (forward mode runs on the lean loop too)
    for name, value in (("adjoint", adjoint), ("saveat", saveat)):
        if value is not None:
            raise ConfigurationError(
                f"events run on lagrax's own stepping loop, which {name}= replaces with "
                f"diffrax.diffeqsolve: drop {name}={value!r}, or use diffrax.Event with "
                "diffeqsolve directly"
            )
    if not integrate.is_lean(controller):
        raise ConfigurationError(
            "events run on lagrax's own stepping loop, which supports the step-size "
            "controllers diffrax.PIDController and diffrax.ConstantStepSize only, got "
            f"stepsize_controller={controller!r}"
        )


_JIT_MESSAGES = [
    f"lagrax.simulate failed: {message} Call simulate outside jit, or with throw=False, "
    "for a diagnosis."
    for message in messages()
]
