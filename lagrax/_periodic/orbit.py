r"""Periodic orbits by Newton's method on a return map: `periodic_orbit`.

The return map `P` takes a state `x = (q, q̇)` to the state one period later:

- with a Poincaré **section** (an [`Event`][lagrax.Event] `g(t, q, q̇) = 0`): the state
  at the first crossing of the section after `t0` (in the event's `direction`), then the
  event's `reset` if it has one (an impact), the time restarting at `t0`: an autonomous
  system's first-return map;
- with a **period** `T` (a forced, time-dependent system): the state at `t0 + T`, the
  stroboscopic map.

The orbit is a fixed point `P(x*) = x*`, found by Newton's method on `F(x) = P(x) − x`
in the full state space, with `DP` from forward-mode derivatives through `simulate`
(`jax.jacfwd`: the crossing time's derivative and the reset's Jacobian give the saltation
term). With a section, `P` lands on the reset's image of the section for every `x`, so
`DP` has rank `2n − 1`: the trivial eigenvalue 0 (along the flow) and `DP − I` regular
exactly when no other multiplier is 1, so no bordering (return time as an unknown, phase
condition) is needed. The fixed point lies on the section where the reset maps it into
itself, and just after the reset otherwise (`sections`).
"""

from collections.abc import Callable, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Complex, Float, Int

from .._core import checks
from .._core.custom_types import Coordinates, Params, Velocities
from .._core.errors import ArgumentTypeError, ConfigurationError, PeriodicOrbitError
from .._core.results import RESULTS
from .._solve import arguments
from .._solve import events as _events
from .._solve.events import Event
from .._solve.simulate import simulate
from .._systems.abstract import AbstractSystem
from . import sections


class PeriodicOrbit(eqx.Module):
    r"""A periodic orbit found by [`lagrax.periodic_orbit`][]: a fixed point of the
    return map `P`, and its stability.

    **Fields:** (under `vmap` every field gains the batch axes in front)

    - `q`, `qd`: the fixed point `x* = (q*, q̇*)`, shape `(n,)`. With a section, the
      state just after the reset (the post-impact state: on the section where the reset
      maps it into itself, as the legs' swap does to `θ_ns + θ_s = 2γ`); with a period,
      the state at `t0` (mod `T`).
    - `period`: the return time `τ(x*)` (with a section), or the given period.
    - `residual`: `‖P(x) − x‖_∞` at the returned `x`.
    - `jacobian`: `DP(x*)`, the Jacobian of the return map in the full state space,
      shape `(2n, 2n)` (the monodromy matrix for a period; with a section, it includes the
      saltation of the crossing time and the reset's Jacobian, and has the trivial
      eigenvalue 0).
    - `multipliers`: the Floquet multipliers, the eigenvalues of `DP(x*)` sorted by
      decreasing modulus (complex): all `2n` of them for a period; with a section the
      `2n − 1` on the section (the trivial 0 of the direction across it dropped: the
      eigenvalue of smallest modulus).
    - `stable`: `True` when every multiplier has `|μ| < 1` (asymptotically stable,
      to first order) and the orbit was found (`ok`).
    - `iterations`: the Newton steps taken.
    - `result`: a [`lagrax.RESULTS`][] code: `successful`, or why not:
      `orbit_not_converged` (no convergence within `max_iter`: typically no orbit near
      the guess), `orbit_no_return` (an iterate's motion did not reach the section within
      `t_max`), `orbit_singular` (a multiplier at 1: a fold or a family of orbits),
      `orbit_bad_section` (the section cannot serve from the guess: see
      [`lagrax.periodic_orbit`][]), `event_cascade` (a Zeno cascade of impacts), or a
      solve's own failure
      (`max_steps_reached`, `non_finite_state`, …). `RESULTS[orbit.result]` is the message.
      A failed search never reports `ok`: its other fields are the last iterate's.
    """

    q: Float[Array, " n"]
    qd: Float[Array, " n"]
    period: Float[Array, ""]
    residual: Float[Array, ""]
    jacobian: Float[Array, "m m"]
    multipliers: Complex[Array, " k"]
    stable: Bool[Array, ""]
    iterations: Int[Array, ""]
    result: RESULTS

    @property
    def ok(self) -> Array:
        """`True` where the orbit was found (an array under `vmap`)."""
        return self.result == RESULTS.successful

    @property
    def state(self) -> Float[Array, " m"]:
        """The fixed point as one vector `(q, q̇)`, shape `(2n,)`."""
        return jnp.concatenate([self.q, self.qd], axis=-1)


class _Level(eqx.Module):
    """A section's condition shifted by a level: `g(t, q, q̇) − level` (an array leaf, so
    it is traced, not baked into the compiled solve)."""

    condition: Callable[..., Any]
    level: Array

    def __call__(self, t, q, qd, params):
        return self.condition(t, q, qd, params) - self.level


class SearchConfig(eqx.Module):
    """What fixes the compiled search (static) besides the arrays."""

    system: AbstractSystem
    section: Event | None
    events: tuple[Event, ...] | None
    solver: Any
    max_steps: int | None = eqx.field(static=True)
    max_iter: int = eqx.field(static=True)


class SearchInputs(eqx.Module):
    x0: Array
    params: Any
    t0: Array
    span: Array  # t_max with a section, the period without
    rtol: Array
    atol: Array
    tol: Array


def _return_map(cfg: SearchConfig, inp: SearchInputs, x, params, shifted):
    """`(P(x), (P(x), τ, code))`: the return map, the return time, and a result code
    (`successful`, or why the map could not be evaluated). `shifted`: where (a traced
    flag) a start on the near side of the section is not counted as a crossing."""
    system = cfg.system
    n = x.shape[0] // 2
    q, qd = x[:n], x[n:]
    common = dict(
        t0=inp.t0,
        n_save=2,
        rtol=inp.rtol,
        atol=inp.atol,
        solver=cfg.solver,
        max_steps=cfg.max_steps,
        throw=False,
    )
    if cfg.section is None:
        sol = simulate(system, q, qd, params, t1=inp.t0 + inp.span, events=cfg.events, **common)
        code = RESULTS.where(sol.result == RESULTS.successful, RESULTS.successful, sol.result)
        px = jnp.concatenate([sol.q_end, sol.qd_end])
        return px, (px, sol.t_end - inp.t0, code)
    section = cfg.section
    level = jnp.where(
        shifted, _start_level(system, section, inp.t0, q, qd, params), jnp.zeros((), x.dtype)
    )
    event = Event(
        _Level(section.condition, level), direction=section.direction, terminal=True, max_events=1
    )
    sol = simulate(system, q, qd, params, t1=inp.t0 + inp.span, events=event, **common)
    hit = sol.result == RESULTS.event_occurred
    code = RESULTS.where(
        hit,
        RESULTS.successful,
        RESULTS.where(sol.result == RESULTS.successful, RESULTS.orbit_no_return, sol.result),
    )
    q1, qd1 = sol.q_end, sol.qd_end
    if section.reset is not None:
        q1, qd1 = section.reset(sol.t_end, q1, qd1, params)
        q1, qd1 = jnp.asarray(q1, x.dtype), jnp.asarray(qd1, x.dtype)
    px = jnp.concatenate([q1.reshape(n), qd1.reshape(n)])
    return px, (px, sol.t_end - inp.t0, code)


def _start_level(system: AbstractSystem, section: Event, t0, q, qd, params):
    """The level through the start where the start sits, by round-off or a Newton step's
    curvature error, on the side *from which* the section is crossed (then the first
    solver step would find a spurious crossing at once; `0` otherwise). Not
    differentiated: `DP` stays the section's."""
    q, qd, params = jax.lax.stop_gradient((q, qd, params))
    qdd = system.accelerations(t0, q, qd, params, None)

    def g(t, a, b):
        return jnp.asarray(section.condition(t, a, b, params), q.dtype)

    g0, rate = jax.jvp(g, (t0, q, qd), (jnp.ones_like(t0), qd, qdd))
    side = jnp.sign(rate) if section.direction == 0 else section.direction
    return jnp.where(side * g0 < 0, g0, jnp.zeros_like(g0))


class _Newton(eqx.Module):
    x: Array
    residual: Array
    jacobian: Array
    tau: Array
    code: RESULTS
    k: Array
    done: Array


def newton_search(cfg: SearchConfig, inp: SearchInputs):
    """The search under `jit`: `(orbit, first_code)`, `first_code` the result of the
    return map at the (projected) guess."""
    params = inp.params
    project, unusable = _mode(cfg, inp)
    x0 = _onto_section(cfg, inp, inp.x0, project)

    def evaluate(x):
        jac, (px, tau, code) = jax.jacfwd(
            lambda y: _return_map(cfg, inp, y, params, shifted=project), has_aux=True
        )(x)
        return px - x, jac, tau, code

    def status(x, f, jac, tau, code, k):
        finite = jnp.all(jnp.isfinite(f)) & jnp.all(jnp.isfinite(jac))
        code = RESULTS.where((code == RESULTS.successful) & ~finite, RESULTS.orbit_singular, code)
        scale = jnp.maximum(1.0, jnp.max(jnp.abs(x)))
        converged = (code == RESULTS.successful) & (jnp.max(jnp.abs(f)) <= inp.tol * scale)
        return code, converged

    f, jac, tau, code = evaluate(x0)
    code = RESULTS.where(unusable, RESULTS.orbit_bad_section, code)
    first_code = code
    code, converged = status(x0, f, jac, tau, code, 0)
    zero = jnp.zeros((), jnp.int32)
    init = _Newton(x0, f, jac, tau, code, zero, converged | (code != RESULTS.successful))
    eye = jnp.eye(x0.shape[0], dtype=x0.dtype)

    def cond(s: _Newton):
        return ~s.done & (s.k < cfg.max_iter)

    def body(s: _Newton):
        step = jnp.linalg.solve(s.jacobian - eye, -s.residual)
        bad = ~jnp.all(jnp.isfinite(step))
        x = _onto_section(cfg, inp, s.x + jnp.where(bad, 0.0, step), project)
        f, jac, tau, code = evaluate(x)
        code = RESULTS.where(bad, RESULTS.orbit_singular, code)
        code, converged = status(x, f, jac, tau, code, s.k + 1)
        x = jnp.where(bad, s.x, x)
        return _Newton(x, f, jac, tau, code, s.k + 1, converged | (code != RESULTS.successful))

    out = jax.lax.while_loop(cond, body, init)
    code = RESULTS.where(
        (out.code == RESULTS.successful) & ~out.done, RESULTS.orbit_not_converged, out.code
    )
    found = code == RESULTS.successful
    mu = jnp.linalg.eigvals(out.jacobian)
    mu = mu[jnp.argsort(-jnp.abs(mu))]
    if cfg.section is not None:
        mu = mu[:-1]  # the trivial eigenvalue 0: across the section
    n = x0.shape[0] // 2
    period = inp.span if cfg.section is None else out.tau
    orbit = PeriodicOrbit(
        q=out.x[:n],
        qd=out.x[n:],
        period=jnp.asarray(period, x0.dtype),
        residual=jnp.max(jnp.abs(out.residual)),
        jacobian=out.jacobian,
        multipliers=mu,
        stable=found & jnp.all(jnp.abs(mu) < 1),
        iterations=out.k,
        result=code,
    )
    return orbit, first_code


def _mode(cfg: SearchConfig, inp: SearchInputs):
    """`(project, unusable)` at the guess (traced flags; see `sections`): whether the
    iterates are projected onto the section (the reset maps it into itself), and whether
    the section cannot serve from the guess at all."""
    if cfg.section is None:
        return jnp.asarray(False), jnp.asarray(False)
    at = sections.analyse(cfg.section, inp.t0, inp.x0, inp.params)
    return at.project, at.unusable


def _onto_section(cfg: SearchConfig, inp: SearchInputs, x, project):
    """`x` projected onto the section `g(t0, x) = 0` where `project` (a few Gauss–Newton
    steps along `∇g`; unchanged without a section): the guess, and each Newton iterate
    (whose step is tangent to the section only to first order)."""
    if cfg.section is None:
        return x
    return jnp.where(project, sections.project(cfg.section, inp.t0, x, inp.params), x)


_search_jit = eqx.filter_jit(newton_search)


def periodic_orbit(
    system: AbstractSystem,
    q0: Coordinates,
    qd0: Velocities,
    params: Params,
    *,
    section: Event | None = None,
    period: float | None = None,
    events: Event | Sequence[Event] | None = None,
    t0: float = 0.0,
    t_max: float = 100.0,
    tol: float | None = None,
    max_iter: int = 30,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    solver: Any = None,
    max_steps: int | None = None,
) -> PeriodicOrbit:
    r"""Find a periodic orbit near the guess `(q0, q̇0)`, and its Floquet multipliers.

    **The return map.** With a Poincaré `section` (an [`Event`][lagrax.Event]
    `g(t, q, q̇) = 0`), `P(x)` is the state at the first crossing of the section after
    `t0` (in the event's `direction`), followed by the event's `reset` if it has one (an
    impact: a walker's heel strike), the time restarting at `t0` (the system is taken as
    autonomous). With a `period` `T` (a forced system: `time_dependent=True`
    energies, or a `force(t, q, qd, params)`), `P(x)` is the state at `t0 + T`
    (impacts along the way given as `events`).

    **Newton's method.** The orbit is a fixed point, `F(x) = P(x) − x = 0`, solved by
    Newton's method in the full state space `x = (q, q̇) ∈ R²ⁿ`,
    `x ← x − (DP(x) − I)⁻¹ F(x)`, until `‖F‖_∞ ≤ tol · max(1, ‖x‖_∞)`. `DP` comes from
    `jax.jacfwd` through [`lagrax.simulate`][] (forward mode: `2n` tangents carried by
    one solve); differentiating the crossing time `τ(x)` and the reset gives the
    saltation term of an impact,

    $$
    DP = D_xR \Big(I − \frac{f^- \, ∇g^\top}{∇g \cdot f^-}\Big) Φ_x(τ),
    $$

    (`Φ_x` the flow's state transition matrix, `f⁻` the vector field at the crossing,
    `R` the reset) with no special code. With a section, `P(x)` lies on the reset's
    image of the section for every `x`, so `DP` has the trivial eigenvalue 0 (along the
    flow) and `DP − I` is singular only at another multiplier 1: no return-time unknown
    or phase condition is needed.

    **The section as written for `simulate`.** Where the reset maps the section into
    itself (none; a leg swap with the symmetric section `θ_ns + θ_s = 2γ`) the fixed
    point lies on the section: the guess and each Newton iterate are projected onto
    `g(t0, x) = 0` (along `∇g`), and a start that round-off puts on the near side is not
    counted as a crossing. Where the reset's image is off the section (a guarded heel
    strike, `jnp.where(swing leg ahead, foot height, 1.0)`, is `1` once the legs have
    swapped), the map `x⁺ ↦ R(flow to the next crossing)` is used unprojected, and the
    fixed point is the state just after the reset: give a post-reset guess. Which of
    the two is decided at the guess.

    **Stability.** The Floquet multipliers are the eigenvalues `μ` of `DP(x*)` (the
    monodromy matrix for a period); with a section, the `2n − 1` on the section (the
    trivial 0 dropped). The orbit is (linearly) asymptotically stable when every
    `|μ| < 1`. A conservative autonomous system has a multiplier 1 (a family of orbits,
    one per energy) and is out of reach of this formulation: Newton reports
    `orbit_singular` or no convergence.

    Works under `jax.jit` and `jax.vmap` (over guesses, `params`, `period`); failures
    are reported in `result`, never as an orbit with `ok` true.

    **Arguments:**

    - `system`, `q0`, `qd0`, `params`: the model, the guess and the parameters.
    - `section`: an [`Event`][lagrax.Event]: `condition(t, q, qd, params)`, its
      `direction`, and an optional `reset(t, q, qd, params) -> (q, qd)` applied at the
      crossing. (Its `terminal` and `max_events` are not used.)
    - `period`: the period `T` of a forced system (exactly one of `section` and `period`).
    - `events`: with `period`, events (impacts) along the period, passed to `simulate`.
    - `t0`: the start time of each return (the forcing phase of the fixed point).
    - `t_max`: with a section, the longest return time searched (default 100): a motion
      that has not crossed by then ends the search with `orbit_no_return`.
    - `tol`: Newton's tolerance on `‖P(x) − x‖_∞`, relative to `max(1, ‖x‖_∞)`
      (default `100 max(rtol, atol)`).
    - `max_iter`: the most Newton steps (default 30).
    - `rtol`, `atol`, `solver`, `max_steps`: of each solve (see [`lagrax.simulate`][]);
      tight tolerances (default `1e-10`) make the multipliers accurate.

    **Returns:** a [`PeriodicOrbit`][lagrax.PeriodicOrbit].

    **Raises:** `PeriodicOrbitError` when, called outside `jit`, the motion from the
    guess never reaches the section within `t_max` (saying where it crosses the other
    way; under `jit`: `result` is `orbit_no_return`), or the section cannot serve from
    the guess: its condition is constant there (`∇g = 0`) and it has no reset; the guess
    is on the section while the reset's image is not (pass the post-reset state; under
    `jit`: `result` is `orbit_bad_section`); or, from a post-reset guess, the search
    failed where the motion first crosses the section the other way (the wrong
    `direction`). Each message names the section, the condition's value, gradient or
    rate, and what to do. `ConfigurationError` for neither or both of `section` and
    `period`, `events` with a section, a period, `t_max`, `tol` or `max_iter` that is not
    positive; `ArgumentTypeError` for a section that is not an `Event`, or a condition
    or reset that does not take `(t, q, qd, params)`; `ShapeError` for a condition that is
    not a scalar or a reset that does not return `(q, qd)`; and `simulate`'s own errors
    for bad input.

    **Example:**

    ```python
    heel_strike = lagrax.Event(foot_height, direction=-1, reset=impact)
    orbit = lagrax.periodic_orbit(walker, q0, qd0, params, section=heel_strike)
    orbit.ok, orbit.period, abs(orbit.multipliers), orbit.stable
    ```
    """
    cfg, inp = prepare_search(
        system, q0, qd0, params, section, period, events, t0, t_max, tol, max_iter, rtol,
        atol, solver, max_steps,
    )  # fmt: skip
    eager = cfg.section is not None and not checks.is_traced(inp)
    if eager:
        sections.check_guess(cfg.section, inp.t0, inp.x0, inp.params)
    orbit, first_code = _search_jit(cfg, inp)
    if eager and first_code == RESULTS.orbit_no_return:
        raise PeriodicOrbitError(_no_crossing_message(cfg, inp))
    if eager and not bool(orbit.ok):
        message = _wrong_way_message(cfg, inp, orbit)
        if message is not None:
            raise PeriodicOrbitError(message)
    return orbit


def prepare_search(
    system, q0, qd0, params, section, period, events, t0, t_max, tol, max_iter, rtol, atol,
    solver, max_steps,
):  # fmt: skip
    """Check the arguments (eagerly, with the values in the messages) and build the
    compiled search's configuration and inputs."""
    eager = not checks.is_traced(q0, qd0, params, t0, t_max, period, rtol, atol, tol)
    q0, qd0, params, _, _ = arguments.arrays(system, q0, qd0, params, None, eager)
    if (section is None) == (period is None):
        raise ConfigurationError(
            "periodic_orbit needs exactly one of section= (a lagrax.Event: the Poincaré "
            "section of an autonomous system) and period= (the period of a forced "
            f"system), got section={section!r} and period={period!r}"
        )
    if section is not None and not isinstance(section, Event):
        raise ArgumentTypeError(
            f"section must be a lagrax.Event, got {type(section).__name__}: {section!r}. "
            "Wrap the condition: lagrax.Event(condition, direction=..., reset=...)"
        )
    if section is not None and events is not None:
        raise ConfigurationError(
            "events= is for impacts along a forced system's period (with period=); with a "
            "section, give the impact as the section's reset"
        )
    if not isinstance(max_iter, (int, np.integer)) or isinstance(max_iter, bool) or max_iter < 1:
        raise ConfigurationError(f"max_iter must be a positive integer, got {max_iter!r}")
    dtype = q0.dtype
    for name, value in (("t_max", t_max), ("period", period), ("tol", tol)):
        if value is not None and eager and not (np.isfinite(value) and value > 0):
            raise ConfigurationError(f"{name} must be positive and finite, got {name}={value!r}")
    if section is not None:
        if section.reset is not None and checks.binds(section.reset, 4) is False:
            raise ArgumentTypeError(
                "the section's reset must take the four arguments (t, q, qd, params) and "
                f"return (q, qd), got {section.reset!r}, which does not accept four: "
                "e.g. reset=lambda t, q, qd, p: (q, -p['e'] * qd)"
            )
        if checks.binds(section.condition, 4) is False:
            raise ArgumentTypeError(
                "the section's condition must take the four arguments (t, q, qd, params), "
                f"got {section.condition!r}, which does not accept four"
            )
        _events.check_events((section,), jnp.asarray(t0, dtype), q0, qd0, params)
    events = _events.as_events(events)
    if events is not None:
        _events.check_events(events, jnp.asarray(t0, dtype), q0, qd0, params)
    if tol is None:
        tol = 100 * max(rtol, atol) if eager else 100 * jnp.maximum(rtol, atol)
    x0 = jnp.concatenate([jnp.asarray(q0), jnp.asarray(qd0)])
    span = period if section is None else t_max
    cfg = SearchConfig(system, section, events, solver, max_steps, int(max_iter))
    arr = jnp.asarray
    inp = SearchInputs(
        x0, params, arr(t0, dtype), arr(span, dtype), arr(rtol, dtype), arr(atol, dtype),
        arr(tol, dtype),
    )  # fmt: skip
    return cfg, inp


def _start(cfg: SearchConfig, inp: SearchInputs):
    """The search's first state, eagerly: the guess, projected where the section allows."""
    project, _ = _mode(cfg, inp)
    return _onto_section(cfg, inp, inp.x0, project), bool(project)


def _first_crossing(cfg: SearchConfig, inp: SearchInputs, x):
    assert cfg.section is not None
    return sections.first_crossing(
        cfg.system, cfg.section, inp.t0, inp.t0 + inp.span, x, inp.params, rtol=inp.rtol,
        atol=inp.atol, solver=cfg.solver, max_steps=cfg.max_steps,
    )  # fmt: skip


def _wrong_way_message(cfg: SearchConfig, inp: SearchInputs, orbit: PeriodicOrbit) -> str | None:
    """Why a search from a post-reset guess failed, where the motion first crosses the
    section the other way (`None` otherwise, and for a projected guess: the motion from
    a state on the section may rightly cross it the other way first, as a walker's
    swing foot at mid-stance)."""
    assert cfg.section is not None
    x, projected = _start(cfg, inp)
    if projected or cfg.section.direction == 0:
        return None
    # the search's own result, without its advice ("Try increasing `max_steps`."): a
    # return map run on past an uncounted crossing fails whatever the budget
    why = f"the search ended with: {str(RESULTS[orbit.result]).split('. ')[0].rstrip('.')}"
    return sections.crossing_message(_first_crossing(cfg, inp, x), cfg.section, why)


def _no_crossing_message(cfg: SearchConfig, inp: SearchInputs) -> str:
    """Why the guess never reached the section: the condition's range along the motion,
    and a crossing the other way."""
    assert cfg.section is not None
    n = inp.x0.shape[0] // 2
    x, projected = _start(cfg, inp)
    q, qd = x[:n], x[n:]
    sol = simulate(
        cfg.system, q, qd, inp.params, t0=inp.t0, t1=inp.t0 + inp.span, n_save=401,
        rtol=inp.rtol, atol=inp.atol, solver=cfg.solver, max_steps=cfg.max_steps,
        throw=False,
    )  # fmt: skip
    ts, qs, qds = np.asarray(sol.ts), np.asarray(sol.q), np.asarray(sol.qd)
    reached = np.isfinite(ts)
    cond = cfg.section.condition
    values = np.asarray(
        [
            float(cond(t, a, b, inp.params))
            for t, a, b in zip(ts[reached], qs[reached], qds[reached], strict=True)
        ]
    )
    span = (
        f"the condition ranges over [{values.min():.6g}, {values.max():.6g}] along it"
        if values.size
        else "the solve failed at once"
    )
    direction = {0: "", 1: " upwards", -1: " downwards"}[cfg.section.direction]
    where = " (projected onto the section)" if projected else ""
    message = (
        f"the motion from the guess{where} q={np.asarray(q).tolist()}, "
        f"qd={np.asarray(qd).tolist()} never crosses the section{direction} within "
        f"t_max={float(inp.span):.6g} (from t0={float(inp.t0):.6g}; "
        f"{sections.describe(cfg.section)}): {span}. "
    )
    if cfg.section.direction != 0:
        crossing = _first_crossing(cfg, inp, x)
        if crossing is not None and crossing[0] != cfg.section.direction:
            s, t, _, _, rate = crossing
            return message + (
                f"It crosses the section {sections.WORDS[s]} instead, at t = {t:.6g} (the "
                f"condition's rate ġ = {rate:.6g} there), which direction="
                f"{cfg.section.direction:+d} does not count: if that crossing is the event, "
                f"give direction={s:+d}"
            )
    return message + (
        "Check the section's condition and direction, start nearer the orbit, or raise t_max"
    )
