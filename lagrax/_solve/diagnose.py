"""The account of a failed solve that `simulate` raises.

The diagnosis names a cause only from states the solver actually reached: the state where
it stopped (`t_end`) or, when that blew up, the last finite saved state. There it
evaluates the pieces the accelerations are made of (the input `tau`, the system's
force, the energies' derivatives, the mass matrix:
[`AbstractSystem.components`][lagrax.AbstractSystem.components]) at that time and a little after it,
where the failed step was trying to go, and says which of them is non-finite. Only when all of them
are finite does it blame the mass matrix (singular relative to itself, or collapsed since the
initial state), the step size or the step budget.
"""

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.checks import pivot_threshold
from .._core.results import RESULTS
from .._systems.abstract import AbstractSystem
from .._systems.vector_field import LagrangianVectorField
from .events import Event
from .solution import Solution

TAU = "the input tau"
FORCE = "the force function F(t, q, qd, params)"  # as LagrangianSystem.components names it


@eqx.filter_jit
def _probe(system: AbstractSystem, field: LagrangianVectorField, ts, q, qd, params, tau_const):
    """Each component at `(t, q, q̇)` for every `t` in `ts`: one compiled call."""

    def at(t):
        out = {}
        tau = field.tau(t, q, qd, tau_const)
        if tau is not None:
            out[TAU] = tau
        return {**out, **system.components(t, q, qd, params)}

    return jax.vmap(at)(ts)


def _non_finite_component(system, field, ts, q, qd, params, tau_const):
    """`(name, t)` of the first non-finite component at `(q, q̇)` over the times
    `ts` (in order), or `None`. Best effort: never raises."""
    try:
        parts = _probe(system, field, jnp.asarray(ts, q.dtype), q, qd, params, tau_const)
        for name, value in parts.items():
            value = np.asarray(value).reshape(len(ts), -1)
            bad = ~np.all(np.isfinite(value), axis=1)
            if np.any(bad):
                return name, float(ts[int(np.argmax(bad))])
    except Exception:  # noqa: BLE001 - a diagnosis must not hide the failure itself
        return None
    return None


def _component_message(name: str, t: float, q, qd) -> str:
    what = (
        "tau(t, q, qd) (or the constant tau) returns NaN or inf there"
        if name == TAU
        else f"{name} is NaN or inf there"
    )
    return (
        f"  {what} (first seen at t={t:.9g}, q={np.asarray(q)}, qd={np.asarray(qd)}): the "
        "accelerations cannot be computed, so no step can get past this point. Check that "
        "function for a division by zero, a log/sqrt of a negative number, an overflow or "
        "a NaN it returns on purpose; more steps or other tolerances will not help"
    )


def failure_message(
    system: AbstractSystem,
    sol: Solution,
    events: tuple[Event, ...] | None,
    params: Any,
    max_steps: Any,
    rtol: Any,
    atol: Any,
    tau_fn: Any,
    tau_const: Any,
    y0: Any,
    t1: Any,
) -> str:
    """The message of the `SimulationError` that `simulate` raises for a failed solve:
    an event cascade (`events.cascade_message`: which event, when, how often), or the
    account of `diagnose` (see there for the arguments)."""
    if events is not None and sol.result == RESULTS.event_cascade:
        return f"simulate failed for {system.name}: " + cascade_message(
            events, sol.events, sol.t_end
        )
    if sol.result == RESULTS.step_past_stability_limit:
        return stability_message(system, sol, params)
    return diagnose(
        system,
        sol,
        params,
        max_steps,
        rtol,
        atol,
        tau_fn=tau_fn,
        tau_const=tau_const,
        y0=y0,
        t1=t1,
    )


def stability_message(system: AbstractSystem, sol: Solution, params: Any) -> str:
    """The account of a fixed step stopped past the stiff forces' stability limit: the
    time, the state, the fastest rate `λ` there and the largest stable step `2/λ`."""
    t_end = float(sol.t_end)
    q_end, qd_end = np.asarray(sol.q_end), np.asarray(sol.qd_end)
    rate = eqx.filter_jit(lambda s, q, v, p: s.stiff_rate(q, v, p))  # one program, not op by op
    lam = float(rate(system, jnp.asarray(q_end), jnp.asarray(qd_end), params))
    return (
        f"simulate failed for {system.name}: the fixed step is past the stability limit "
        f"of its stiff forces at t={t_end:.6g} (q={q_end}, qd={qd_end}): their fastest "
        f"rate there is lambda={lam:.4g} 1/s (a contact's omega = sqrt(k_eff/m), or its "
        f"stiction's 2 mu_s f_n/(v_s m)), so an explicit method needs dt <= 2/lambda = "
        f"{2.0 / lam:.3g} s there. The solve stopped before the state could blow up. Try: "
        "a smaller dt, an adaptive step (no dt), solver='rodas4', or a softer contact "
        "(a smaller stiffness=, a larger stiction_velocity=)."
        "\n  Pass throw=False to get the partial Solution (entries never reached are inf)."
    )


def diagnose(
    system: AbstractSystem,
    sol: Solution,
    params: Any,
    max_steps: Any,
    rtol: Any,
    atol: Any,
    *,
    tau_fn: Any = None,
    tau_const: Any = None,
    y0: Any = None,
    t1: Any = None,
) -> str:
    """A readable account of why a solve failed, from the states it reached.

    `tau_fn` / `tau_const` are the solve's inputs, `y0` its initial state (the
    reference for a mass matrix that collapses during the solve) and `t1` its end. A
    solve out of steps names the system's stiffest force where it has one
    (`AbstractSystem.stiff_account`).
    """
    t_end = float(sol.t_end)
    q_end, qd_end = np.asarray(sol.q_end), np.asarray(sol.qd_end)
    steps = int(sol.stats["num_steps"])
    reason = RESULTS[sol.result] if not bool(sol.ok) else "non-finite values"
    lines = [f"  the solver stopped at t={t_end:.6g} with q={q_end}, qd={qd_end}"]
    field = LagrangianVectorField(system, tau_fn)
    finite_state = np.isfinite(t_end) and np.all(np.isfinite(q_end)) & np.all(np.isfinite(qd_end))
    if not finite_state:
        more, input_cause = _blew_up(system, field, sol, params, tau_const)
    else:
        more, input_cause = _stopped(system, field, sol, params, tau_const, y0, t1)
    lines += more
    if input_cause:  # not the step budget or the step size, whatever diffrax says
        reason = (
            f"the accelerations became non-finite ({steps} steps were spent trying to "
            "step past the point)"
            if finite_state
            else "the state became non-finite (NaN or inf) because the equations did"
        )
    lines.insert(0, f"simulate failed for {system.name}: {reason}")
    if sol.result == RESULTS.max_steps_reached and not input_cause:
        stiff = _stiff_lines(system, sol, params) if finite_state else None
        if stiff is not None:
            lines += stiff
        lines.append(
            f"  all {steps} steps of max_steps={max_steps} were used (rtol={rtol}, "
            f"atol={atol}). Try: "
            + (
                "a larger max_steps; looser tolerances; or what is said above."
                if stiff is not None
                else "a larger max_steps; looser tolerances; or, if the scene is stiff "
                "(stiff springs or dampers), an implicit method: solver='rodas4' or 'kvaerno5'."
            )
        )
    lines.append("  Pass throw=False to get the partial Solution (entries never reached are inf).")
    return "\n".join(lines)


def _stiff_lines(system, sol: Solution, params) -> list[str] | None:
    """What is stiff where a solve ran out of steps (`AbstractSystem.stiff_account`):
    the force, its rate `λ` against the mean step the solve reached, and what to do;
    `None` where the system names nothing stiff."""
    found = system.stiff_account(np.asarray(sol.q_end), np.asarray(sol.qd_end), params)
    if found is None:
        return None
    what, lam = found
    accepted = max(int(sol.stats["num_accepted_steps"]), 1)
    h = (float(sol.t_end) - float(sol.ts[0])) / accepted
    text = [
        f"  the stiffest force there is {what}: its rate is lambda={lam:.4g} 1/s, against "
        f"a mean step of {h:.3g} s (h lambda = {h * lam:.3g})."
    ]
    text.append(
        "  An explicit method's step (tsit5, dopri5, ...) is held to h lambda <~ 2-3 "
        "there, so it crawls: use an implicit method, solver='rodas4' (the default "
        "where a contact can stick), whose step is not bound by lambda."
    )
    text.append(
        "  Or soften it: a smaller stiffness= (the spring's lambda grows as sqrt(k)), a "
        "larger stiction_velocity= (friction's lambda falls as 1/v_s, the creep of a held "
        "contact grows with it), or more dissipation= for a bouncing contact; or give it a "
        "larger max_steps."
    )
    return text


def _blew_up(system, field, sol: Solution, params, tau_const) -> tuple[list[str], bool]:
    """`(lines, input_cause)` for a solve whose final state is not finite: between
    which saves it blew up, and whether an input (`tau`, the force) is to blame there."""
    ts = np.asarray(sol.ts)
    saved = np.all(np.isfinite(np.asarray(sol.q)), axis=1) & np.all(
        np.isfinite(np.asarray(sol.qd)), axis=1
    )
    bad = np.nonzero(~saved & ~np.isinf(ts))[0]
    if not (bad.size and bad[0] > 0):
        return ["  the state itself is non-finite there (it blew up)"], False
    k = int(bad[0])
    ta, tb = float(ts[k - 1]), float(ts[k])
    found = _non_finite_component(
        system,
        field,
        np.linspace(ta, tb, 9),
        jnp.asarray(np.asarray(sol.q)[k - 1]),
        jnp.asarray(np.asarray(sol.qd)[k - 1]),
        params,
        tau_const,
    )
    # after a blow-up only an input (tau, the force) can be blamed: the energies'
    # derivatives overflow at any state that has grown far enough
    if found is not None and found[0] in (TAU, FORCE):
        return [
            f"  the state became non-finite between the saves at t={ta:.6g} and "
            f"t={tb:.6g}; from the last finite one,",
            _component_message(found[0], found[1], sol.q[k - 1], sol.qd[k - 1]),
        ], True
    return [
        f"  the state blew up (became non-finite) between the saves at "
        f"t={ta:.6g} and t={tb:.6g}; if the step is fixed, it is likely past "
        "the method's stability limit: use a smaller dt, an adaptive step, or "
        "an implicit method for stiff scenes"
    ], False


def _stopped(system, field, sol: Solution, params, tau_const, y0, t1) -> tuple[list[str], bool]:
    """`(lines, input_cause)` for a solve that stopped at a finite state: a component
    that is non-finite there or a little after it (where the failed step was trying to
    go), else a singular mass matrix or non-finite accelerations."""
    t_end = float(sol.t_end)
    q_end, qd_end = np.asarray(sol.q_end), np.asarray(sol.qd_end)
    t_last = float(t1) if t1 is not None and np.isfinite(float(t1)) else None
    span = abs((t_last if t_last is not None else t_end) - t_end) or max(abs(t_end), 1.0)
    probe_ts = [t_end] + [t_end + h * span for h in (1e-12, 1e-9, 1e-6, 1e-3, 1e-1)]
    if t_last is not None:
        probe_ts = [t for t in probe_ts if t <= t_last] or [t_end]
    found = _non_finite_component(
        system,
        field,
        np.asarray(probe_ts),
        jnp.asarray(q_end),
        jnp.asarray(qd_end),
        params,
        tau_const,
    )
    if found is not None:
        return [_component_message(found[0], found[1], q_end, qd_end)], True
    return _mass_or_accelerations(system, sol, params, y0), False


def _mass_or_accelerations(system: AbstractSystem, sol: Solution, params, y0) -> list[str]:
    """At the (finite, reached) final state: a singular mass matrix, or non-finite
    accelerations with every component finite."""
    q_end, qd_end = np.asarray(sol.q_end), np.asarray(sol.qd_end)
    t_end = np.asarray(sol.t_end)
    eigs = np.linalg.eigvalsh(np.asarray(system.mass_matrix(q_end, params, qd_end, t=t_end)))
    if not np.all(np.isfinite(eigs)):
        return []
    tiny = 1e3 * pivot_threshold(eigs.dtype)
    singular = not eigs[0] > tiny * max(abs(eigs[-1]), 1e-300)
    if y0 is not None:  # collapsed since the start (the initial state was checked)
        q0, qd0 = (np.asarray(v) for v in y0)
        t0 = np.asarray(sol.ts[0])  # the start (a time-dependent M(t, q) is read there)
        eigs0 = np.linalg.eigvalsh(np.asarray(system.mass_matrix(q0, params, qd0, t=t0)))
        if np.all(np.isfinite(eigs0)) and eigs0[0] > 0:
            singular = singular or not eigs[0] > 1e-6 * eigs0[0]
    if singular:
        return [
            f"  the mass matrix is (nearly) singular there (eigenvalues {eigs}): the "
            "coordinates are singular at this configuration, or a mass/inertia is zero. "
            "Use coordinates without this singularity."
        ]
    qdd = np.asarray(system.accelerations(sol.t_end, sol.q_end, sol.qd_end, params, None))
    if not np.all(np.isfinite(qdd)):
        rank = system.failure_hint(sol.q_end, params)
        return [
            f"  {rank}"
            if rank is not None
            else "  the accelerations are non-finite there: check the force/tau "
            "functions and the energies for divisions by zero or overflow"
        ]
    return []


def cascade_message(events: tuple[Event, ...], records, t_end) -> str:
    """Why a solve ended with `RESULTS.event_cascade`: which event, when, how often."""
    parts = []
    for i, (ev, rec) in enumerate(zip(events, records, strict=True)):
        count = int(rec.count)
        times = np.asarray(rec.times)[:count]
        last = f", the last at t={times[-1]:.12g}" if count else ""
        parts.append(f"events[{i}]: {count} of max_events={ev.max_events} recorded{last}")
    return (
        f"an event cascade at t={float(t_end):.12g}: an event occurred more than its "
        "max_events times, or a reset event recurred at the time of the previous one "
        "(events accumulating at a point, e.g. a bouncing ball with restitution < 1 "
        "comes to rest after infinitely many impacts in finite time). "
        + "; ".join(parts)
        + ". The solve stopped there; model the resting contact (e.g. a terminal event "
        "when the rebound speed is small), or raise max_events if the events are real."
    )
