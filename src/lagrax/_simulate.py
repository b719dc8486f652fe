"""One trajectory: ``simulate`` and its ``Solution``, on diffrax."""


import functools

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Float, Int

from . import _integrate
from ._constraints import ConstrainedSystem
from ._errors import ConstraintError, ShapeError, SimulationError
from ._methods import fixed_step_budget, resolve_solver
from ._results import RESULTS
from ._system import LagrangianSystem, _is_traced, _pivot_threshold
from ._typing import Coordinates, Params, Velocities
from ._vector_field import LagrangianVectorField, TauFn
from .integrators import Variational


class Solution(eqx.Module):
    """A simulated trajectory at the saved times.

    **Fields:**

    - ``ts``: saved times, shape ``(T,)``.
    - ``q``, ``qd``: coordinates and velocities at ``ts``, shape ``(T, n)``.
    - ``energy``: ``T + V`` at ``ts``, shape ``(T,)``.
    - ``result``: result code (``lagrax.RESULTS``: diffrax's codes plus
      ``non_finite_state``); ``ok`` tells success, ``RESULTS[sol.result]`` the message.
    - ``stats``: solver counters (``num_steps``, ``num_accepted_steps``,
      ``num_rejected_steps``, ``max_steps``).
    - ``t_end``, ``q_end``, ``qd_end``: the last state the solver reached: ``t1`` on
      success, the time it stopped at on failure (with a custom ``saveat``, the last save).
    - ``constraint_violation``: for a ``ConstrainedSystem``, ``φ(q)`` at ``ts``, shape
      ``(T, m)``; ``None`` otherwise.
    - ``multipliers``: for a ``ConstrainedSystem``, the Lagrange multipliers ``λ`` at
      ``ts``, shape ``(T, m)`` (``J(q)ᵀλ`` is the generalized constraint force); ``None``
      otherwise.

    After a failed solve with ``throw=False``, entries past the failure time are ``inf``
    (diffrax's fill value), never silently wrong numbers; a fixed-step solve that blew up
    is flagged ``RESULTS.non_finite_state`` (its values past the blow-up are NaN/inf).
    Check ``ok`` first.
    """

    ts: Float[Array, " T"]
    q: Float[Array, "T n"]
    qd: Float[Array, "T n"]
    energy: Float[Array, " T"]
    result: RESULTS
    stats: dict[str, Int[Array, ""]]
    t_end: Float[Array, ""]
    q_end: Float[Array, " n"]
    qd_end: Float[Array, " n"]
    constraint_violation: Float[Array, "T m"] | None = None
    multipliers: Float[Array, "T m"] | None = None

    @property
    def ok(self) -> Array:
        """``True`` where the solve succeeded (an array under ``vmap``)."""
        return self.result == RESULTS.successful

    @property
    def energy_error(self) -> Float[Array, " T"]:
        """Relative energy change ``(E(t) − E(t0)) / max(|E(t0)|, tiny)`` along the path."""
        e0 = self.energy[..., :1]
        return (self.energy - e0) / jnp.maximum(jnp.abs(e0), jnp.finfo(e0.dtype).tiny)


def _solve_core(
    system: LagrangianSystem,
    solver: dfx.AbstractSolver,
    tau_fn: TauFn | None,
    y0,
    params,
    tau_const,
    t0,
    t1,
    ts,
    n_save: int,
    rtol,
    atol,
    dt0,
    max_steps: int,
    saveat: dfx.SaveAt | None,
    stepsize_controller: dfx.AbstractStepSizeController | None,
    adjoint: dfx.AbstractAdjoint | None = None,
):
    own_saveat = saveat is None
    if own_saveat:
        if ts is None:
            ts = t0 + (t1 - t0) * jnp.linspace(0.0, 1.0, n_save, dtype=t0.dtype)
        elif ts.shape[0]:  # traced ts (eager calls are checked in simulate)
            ts = eqx.error_if(
                ts,
                jnp.any(ts[1:] < ts[:-1]) | (ts[0] < t0) | (ts[-1] > t1),
                "ts must be non-decreasing and inside [t0, t1]",
            )
        saveat = dfx.SaveAt(ts=ts, t1=True)  # the extra last entry: where the solve ended
    requested_ts = ts
    if stepsize_controller is None:
        stepsize_controller = dfx.PIDController(rtol=rtol, atol=atol)
    constrained = isinstance(system, ConstrainedSystem)
    if constrained and isinstance(solver, Variational):
        raise ValueError(
            "the variational integrators work on the Lagrangian of an unconstrained system "
            f"and would ignore the constraints of {system.name}: use an ODE method such "
            "as 'tsit5' (or 'rk4' at a fixed step)"
        )
    projected = True
    if constrained and system.project_initial:
        q0, qd0, projected = system._project(*y0, params)
        y0 = (q0, qd0)
    field = LagrangianVectorField(system, tau_fn)
    term = dfx.ODETerm(field)
    args = (params, tau_const)
    if adjoint is None and own_saveat and _integrate.is_lean(stepsize_controller):
        # the lean loop: the same steps as diffeqsolve, without its per-step machinery
        out = _integrate.integrate(
            term, solver, stepsize_controller, y0, args, t0, t1, dt0, ts, max_steps
        )
        (q, qd), t_end, (q_end, qd_end), result, steps, accepted, n_saved = out
        ts = jnp.where(jnp.arange(ts.shape[0]) < n_saved, ts, jnp.inf)
        stats = dict(num_steps=steps, num_accepted_steps=accepted,
                     num_rejected_steps=steps - accepted, max_steps=max_steps)  # fmt: skip
    else:
        sol = dfx.diffeqsolve(
            term,
            solver,
            t0,
            t1,
            dt0,
            y0,
            args=args,
            saveat=saveat,
            stepsize_controller=stepsize_controller,
            max_steps=max_steps,
            throw=False,
            **({} if adjoint is None else {"adjoint": adjoint}),
        )
        q, qd = sol.ys
        ts = sol.ts
        # The final state is the last finite save. With our own SaveAt(ts, t1=True), on a
        # failure diffrax writes it into the first unreached slot, so unreached slots
        # (whose time differs from the requested one) are reset to inf.
        last = jnp.max(jnp.where(jnp.isfinite(ts), jnp.arange(ts.shape[0]), 0))
        t_end, q_end, qd_end = ts[last], q[last], qd[last]
        if own_saveat:
            ts, q, qd = ts[:-1], q[:-1], qd[:-1]
            reached = ts == requested_ts
            inf = jnp.asarray(jnp.inf, q.dtype)
            ts = jnp.where(reached, ts, inf)
            q = jnp.where(reached[:, None], q, inf)
            qd = jnp.where(reached[:, None], qd, inf)
        result = RESULTS.promote(sol.result)
        stats = dict(sol.stats)
    energy = jax.vmap(lambda a, b: system.energy(a, b, params))(q, qd)
    energy = jnp.where(jnp.isfinite(ts), energy, jnp.inf)  # unreached: inf, like q and qd
    # A fixed-step solve that blows up "succeeds" in diffrax's eyes: flag it.
    finite = jnp.all(jnp.isfinite(q_end)) & jnp.all(jnp.isfinite(qd_end))
    result = RESULTS.where(finite | (result != RESULTS.successful), result,
                           RESULTS.non_finite_state)  # fmt: skip
    violation = multipliers = None
    if constrained:
        result = RESULTS.where(projected, result, RESULTS.constraint_projection_failed)
        reached = jnp.isfinite(ts)[:, None]
        violation = jax.vmap(lambda a: system._phi(a, params))(q)
        multipliers = jax.vmap(
            lambda t, a, b: system._kkt(t, a, b, params, field.tau(t, a, b, tau_const))[1]
        )(ts, q, qd)
        violation = jnp.where(reached, violation, jnp.inf)
        multipliers = jnp.where(reached, multipliers, jnp.inf)
    return Solution(ts, q, qd, energy, result, stats, t_end, q_end, qd_end,
                    violation, multipliers)  # fmt: skip


_solve = eqx.filter_jit(_solve_core)


def _inputs_ok(system, q0, qd0, params, tau_fn, tau_const, t0):
    """In-graph validity of a solve's inputs: finite parameters and state, finite energy,
    and finite accelerations at the start (which also requires a positive-definite mass
    matrix). A ``False`` here sends ``simulate`` to the eager, precise ``check_state``."""
    leaves = [jnp.all(jnp.isfinite(x)) for x in jax.tree_util.tree_leaves(params)
              if eqx.is_inexact_array(x)]  # fmt: skip
    field = LagrangianVectorField(system, tau_fn)
    _, qdd = field(t0, (q0, qd0), (params, tau_const))
    energy = system.energy(q0, qd0, params)
    checks = [*leaves, jnp.all(jnp.isfinite(q0)), jnp.all(jnp.isfinite(qd0)),
              jnp.isfinite(energy), jnp.all(jnp.isfinite(qdd))]  # fmt: skip
    return jnp.all(jnp.stack(checks))


@eqx.filter_jit
def _checked_once(system, solver, tau_fn, y0, params, tau_const, t0, *rest):
    sol = _solve_core(system, solver, tau_fn, y0, params, tau_const, t0, *rest)
    inputs_ok = _inputs_ok(system, *y0, params, tau_fn, tau_const, t0)
    solved_ok = sol.ok & jnp.all(jnp.isfinite(sol.q)) & jnp.all(jnp.isfinite(sol.qd))
    return sol, jnp.stack([inputs_ok, solved_ok])


@eqx.filter_jit
def _simulate_checked(system, solver, tau_fn, y0, params, tau_const, t0, *rest):
    """``_solve`` plus the two flags ``simulate`` needs on the host, fetched at once:
    whether the inputs were valid, and whether the solve succeeded with finite saves.

    Only called on concrete inputs (never differentiated), so the whole program can sit
    in a ``lax.while_loop`` that runs once: XLA:CPU then compiles it into one kernel (see
    ``_xla_flags``) instead of running dozens of small ones around the solver loop, which
    cost ~0.1 ms a call.
    """

    args = (system, solver, tau_fn, y0, params, tau_const, t0, *rest)
    shapes = eqx.filter_eval_shape(_checked_once, *args)  # traced once; the loop reuses it
    init = (jnp.asarray(False), jax.tree_util.tree_map(
        lambda x: jnp.zeros(x.shape, x.dtype) if isinstance(x, jax.ShapeDtypeStruct) else x,
        shapes))  # fmt: skip

    def once(_):
        return _checked_once(*args)

    _, out = jax.lax.while_loop(lambda c: ~c[0], lambda c: (jnp.asarray(True), once(None)), init)
    return out


def simulate(
    system: LagrangianSystem | ConstrainedSystem,
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
    throw: bool = True,
) -> Solution:
    """Integrate ``M(q) q̈ + C q̇ + G = τ + F − ∂D/∂q̇`` from ``(q0, q̇0)`` over ``[t0, t1]``.

    The state ``(q, q̇)`` is integrated as a first-order system with diffrax; the
    accelerations come from :meth:`LagrangianSystem.forward_dynamics` (unchecked inside the
    solver loop; failures are diagnosed after it, see *Raises*).

    A :class:`ConstrainedSystem` is integrated the same way with its constrained
    accelerations (KKT system with Baumgarte stabilization); its initial state is first
    projected onto ``φ(q) = 0``, ``J q̇ = 0`` (unless ``project_initial=False``), so
    ``Solution.q[0]`` may differ from ``q0``; ``Solution.constraint_violation`` and
    ``Solution.multipliers`` report ``φ`` and ``λ`` along the path. The variational
    integrators do not apply to constrained systems.

    **Arguments:**

    - ``system``, ``q0``, ``qd0``, ``params``: the model, its initial state and parameters.
    - ``t1``, ``t0``: time interval.
    - ``ts``: times at which to save; default ``n_save`` evenly spaced points in
      ``[t0, t1]``. ``saveat`` (a ``diffrax.SaveAt``) overrides both.
    - ``tau``: input generalized forces, a constant ``(n,)`` array or a function
      ``tau(t, q, qd) -> (n,)`` (a controller). Added to the system's own ``force``.
    - ``solver``: a method name or a diffrax solver. Names (see ``lagrax.METHODS``):
      ``"tsit5"`` (default; explicit 5(4), adaptive), ``"dopri5"``, ``"dopri8"`` (tight
      tolerances), ``"kvaerno5"`` (implicit; stiff springs and dampers), ``"rk4"`` (fixed
      step), ``"variational"`` / ``"variational4"`` (symplectic, fixed step; bounded
      energy error over long horizons).
    - ``rtol``, ``atol``: error-control tolerances of the adaptive step (default 1e-8);
      for implicit methods at a fixed step, the tolerances of their Newton iterations.
      Changing them, ``params``, the initial state, ``t1`` or ``dt`` does not recompile.
    - ``dt``: run at this fixed step instead (``diffrax.ConstantStepSize``). Required by
      the fixed-step methods; allowed with every method.
    - ``dt0``: initial step of an adaptive solve (default: chosen by diffrax).
    - ``max_steps``: step budget (accepted + rejected). Default: 100,000 for an adaptive
      solve; at a fixed step, enough steps for ``[t0, t1]``.
    - ``stepsize_controller``: override the default ``diffrax.PIDController(rtol, atol)``.
    - ``adjoint``: how to differentiate the solve. Default ``None``: lagrax's own lean
      stepping loop (diffrax's steps without ``diffeqsolve``'s per-step machinery; about
      2–3× faster for small mechanisms), differentiable by reverse mode (``jax.grad``,
      recursive checkpointing, as diffrax's default). Pass a diffrax adjoint to run
      ``diffrax.diffeqsolve`` with it instead, e.g. ``diffrax.ForwardMode()`` for
      ``jax.jacfwd`` / ``jax.jvp`` (few parameters, many outputs) or
      ``diffrax.RecursiveCheckpointAdjoint()`` for diffrax's default. A custom ``saveat``
      or a step-size controller other than ``PIDController`` / ``ConstantStepSize``
      also runs ``diffeqsolve``.
    - ``throw``: raise on failure (default). With ``throw=False`` the failure is reported
      in ``Solution.result`` / ``Solution.ok`` instead, which is what ``vmap`` and sweeps
      need: one bad member does not kill the batch.

    **Returns:** a :class:`Solution`.

    **Raises:** ``ShapeError``, ``NonFiniteError``, ``ParameterError``, ``MassMatrixError``
    for bad input (checked at the initial state), ``ConstraintError`` for a constrained
    system whose initial state cannot be projected onto its constraints or whose
    constraint Jacobian is rank-deficient there, and ``SimulationError`` when the solve
    fails: the message names the cause (step budget, non-finite state, singular mass
    matrix), the time reached and what to try.

    **Example:**

    ```python
    system, params = lagrax.models.planar_2r()
    sol = lagrax.simulate(system, [0.5, 0.8], [0.0, 0.0], params, t1=10.0)
    sol.q[-1], sol.energy_error.max()
    ```
    """
    eager = not _is_traced(q0, qd0, params, t0, t1, ts, rtol, atol, tau, dt, dt0)
    if eager:
        # NumPy conversions here: each jnp.asarray of a Python value is a device transfer
        # of its own, and a simulate call should cost one dispatch, not a dozen.
        q0, qd0 = system._host_state(q0, qd0)
        dtype = np.result_type(q0, qd0)
    else:
        q0, qd0 = system._state(q0, qd0)
        dtype = jnp.result_type(q0, qd0)
    q0, qd0 = q0.astype(dtype), qd0.astype(dtype)
    tdt = np.dtype(dtype)
    # Python scalars in params would be static under filter_jit (a recompile per value);
    # as arrays of the state's dtype they behave as JAX's weakly typed scalars would.
    params = jax.tree_util.tree_map(
        lambda x: np.asarray(x, tdt if isinstance(x, float) else None)
        if isinstance(x, (bool, int, float, complex)) else x, params
    )  # fmt: skip
    tau_fn = tau if callable(tau) else None
    tau_const = None
    if tau is not None and not callable(tau):
        (tau_const,) = system._state(q0, tau=tau)[1:]
        tau_const = system._finite(tau_const.astype(dtype), "tau")
    constrained = isinstance(system, ConstrainedSystem)
    if eager:
        if constrained:  # projection and constraint-rank checks: before the solve
            system.check_state(q0, qd0, params)
        if not float(t1) > float(t0):
            raise ValueError(f"t1 must be greater than t0, got t0={t0}, t1={t1}")
    if saveat is None and ts is not None:
        ts = (np.asarray if eager else jnp.asarray)(ts, dtype)
        if ts.ndim != 1:
            raise ShapeError(f"ts must be 1-D, got shape {ts.shape}")
        if eager and ts.size and (
            np.any(np.diff(ts) < 0) or ts[0] < float(t0) or ts[-1] > float(t1)
        ):
            raise ValueError(
                f"ts must be non-decreasing and inside [t0, t1] = [{t0}, {t1}]; got {ts}"
            )
    solver, stepsize_controller, dt0, max_steps = _configure(
        solver, rtol, atol, dt, dt0, max_steps, stepsize_controller, t0, t1, tdt, eager
    )
    asarray = np.asarray if eager else jnp.asarray
    call = (
        system,
        solver,
        tau_fn,
        (q0, qd0),
        params,
        tau_const,
        asarray(t0, tdt),
        asarray(t1, tdt),
        ts,
        int(n_save),
        asarray(rtol, tdt),
        asarray(atol, tdt),
        None if dt0 is None else asarray(dt0, tdt),
        int(max_steps),
        saveat,
        stepsize_controller,
        adjoint,
    )
    if not eager:
        sol = _solve(*call)
        if not throw:
            return sol
        # inside a user's jit: fail at run time
        return eqx.error_if(
            sol,
            ~sol.ok,
            "lagrax.simulate failed (max steps, non-finite state or singular mass "
            "matrix); call it outside jit, or with throw=False, for a diagnosis",
        )
    sol, flags = _call_checked(call)
    inputs_ok, solved_ok = np.asarray(flags)  # the one device-to-host transfer
    if not inputs_ok:
        system.check_state(q0, qd0, params)  # raises with the values in the message
    if not throw or solved_ok:
        return sol
    if sol.result == RESULTS.constraint_projection_failed:  # checked already; in case
        raise ConstraintError(system._projection_message(q0, params))
    raise SimulationError(_diagnose(system, sol, params, max_steps, rtol, atol))


# positions in a ``_simulate_checked`` call of the arguments that are arrays (or None) on
# every call: they are traced; the rest (model, solver, settings) are static
_DYNAMIC = (3, 4, 5, 6, 7, 8, 10, 11, 12)


@functools.lru_cache(maxsize=64)
def _compiled_checked(static):
    """A ``jax.jit`` of ``_simulate_checked`` for one static configuration.

    ``equinox.filter_jit`` sorts arrays from static values on every call, which for
    ``simulate``'s arguments costs about as much as a short solve; with the static part
    fixed here, a call is ``jax.jit``'s C++ fast path.
    """
    out_static = []

    def run(dynamic):
        args = list(static)
        for i, x in zip(_DYNAMIC, dynamic, strict=True):
            args[i] = x
        leaves, treedef = jax.tree_util.tree_flatten(_simulate_checked.__wrapped__(*args))
        arrays = [i for i, x in enumerate(leaves) if eqx.is_array(x)]
        out_static[:] = [treedef, leaves, arrays]
        return [leaves[i] for i in arrays]

    return jax.jit(run), out_static


def _call_checked(call):
    """``_simulate_checked(*call)``, through a cached ``jax.jit`` when it can be."""
    dynamic = tuple(call[i] for i in _DYNAMIC)
    static = tuple(None if i in _DYNAMIC else x for i, x in enumerate(call))
    try:
        if not all(eqx.is_array(x) for x in jax.tree_util.tree_leaves(dynamic)):
            raise TypeError  # e.g. strings in params: equinox sorts them out
        fn, out_static = _compiled_checked(static)
    except TypeError:  # an unhashable setting (a controller or saveat with arrays)
        return _simulate_checked(*call)
    values = fn(dynamic)
    treedef, leaves, arrays = out_static
    leaves = list(leaves)  # the static leaves, with the arrays put back in their places
    for i, value in zip(arrays, values, strict=True):
        leaves[i] = value
    return jax.tree_util.tree_unflatten(treedef, leaves)


def _configure(solver, rtol, atol, dt, dt0, max_steps, stepsize_controller, t0, t1, tdt, eager):
    """``(solver, stepsize_controller, dt0, max_steps)`` for a solve, with lagrax's defaults.

    Shared by ``simulate`` and ``sweep``. ``stepsize_controller`` stays ``None`` for the
    default ``PIDController(rtol, atol)``; the step budget is sized for a fixed ``dt``
    when ``t0``, ``t1`` are concrete (``eager``).
    """
    named_implicit = isinstance(solver, str)  # configure only the solvers we built
    solver, may_adapt = resolve_solver(solver)
    if dt is not None:
        if stepsize_controller is not None:
            raise ValueError("pass either dt= (a fixed step) or stepsize_controller=, not both")
        stepsize_controller = dfx.ConstantStepSize()
        dt0 = dt
        if max_steps is None and eager:
            max_steps = fixed_step_budget(t0, t1, dt)
    elif not may_adapt and not isinstance(stepsize_controller, dfx.ConstantStepSize):
        raise ValueError(
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


def _diagnose(system, sol: Solution, params, max_steps, rtol, atol) -> str:
    """A readable account of why a solve failed, from the state where it stopped."""
    t_end = float(sol.t_end)
    q_end, qd_end = np.asarray(sol.q_end), np.asarray(sol.qd_end)
    steps = int(sol.stats["num_steps"])
    reason = RESULTS[sol.result] if not bool(sol.ok) else "non-finite values"
    lines = [
        f"simulate failed for {system.name}: {reason}",
        f"  the solver stopped at t={t_end:.6g} with q={q_end}, qd={qd_end}",
    ]
    finite_state = np.all(np.isfinite(q_end)) and np.all(np.isfinite(qd_end))
    if not finite_state:
        saved = np.all(np.isfinite(np.asarray(sol.q)), axis=1)
        ts = np.asarray(sol.ts)
        bad = np.nonzero(~saved & ~np.isinf(ts))[0]
        if bad.size and bad[0] > 0:
            lines.append(
                f"  the state blew up (became non-finite) between the saves at "
                f"t={ts[bad[0] - 1]:.6g} and t={ts[bad[0]]:.6g}; if the step is fixed, it is "
                "likely past the method's stability limit: use a smaller dt, an adaptive "
                "step, or an implicit method for stiff scenes"
            )
        else:
            lines.append("  the state itself is non-finite there (it blew up)")
    else:
        qdd = np.asarray(system._forward(sol.t_end, sol.q_end, sol.qd_end, params, None))
        eigs = np.linalg.eigvalsh(np.asarray(system.mass_matrix(q_end, params, qd_end)))
        q0, qd0 = np.asarray(sol.q[0]), np.asarray(sol.qd[0])
        eigs0 = np.linalg.eigvalsh(np.asarray(system.mass_matrix(q0, params, qd0)))
        tiny = 1e3 * _pivot_threshold(eigs.dtype)
        # singular relative to its own largest eigenvalue, or collapsed since the start
        if not (eigs[0] > tiny * max(abs(eigs[-1]), 1e-300) and eigs[0] > 1e-6 * eigs0[0]):
            lines.append(
                f"  the mass matrix is (nearly) singular there (eigenvalues {eigs}): the "
                "coordinates are singular at this configuration, or a mass/inertia is zero. "
                "Use coordinates without this singularity."
            )
        elif not np.all(np.isfinite(qdd)):
            rank = (
                system._rank_message(sol.q_end, params)
                if isinstance(system, ConstrainedSystem)
                else None
            )
            lines.append(
                f"  {rank}"
                if rank is not None
                else "  the accelerations are non-finite there: check the force/tau "
                "functions and the energies for divisions by zero or overflow"
            )
    if sol.result == RESULTS.max_steps_reached:
        lines.append(
            f"  all {steps} steps of max_steps={max_steps} were used (rtol={rtol}, "
            f"atol={atol}). Try: a larger max_steps; looser tolerances; or, if the scene "
            "is stiff (stiff springs or dampers), an implicit solver such as "
            "solver=diffrax.Kvaerno5()."
        )
    lines.append(
        "  Pass throw=False to get the partial Solution (entries never reached are inf)."
    )
    return "\n".join(lines)
