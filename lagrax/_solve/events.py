"""Events: zero crossings of `condition(t, q, q̇, params)` located on the dense output,
recorded, and either ending the solve (`terminal`) or continuing it from a new state
(`reset`: an impact, a joint limit).

`integrate_events` is a third scheduler over the stepping engine of `integrate`
(`init_state` / `advance` / `interpolate` / `save_dense`), beside `integrate`
(no events: its compiled code is untouched by this module) and the sweep's lane queue.
After each accepted step `[t_a, t_b]` it compares the sign of every condition at
`t_b` with its sign at `t_a`; where it changed in the event's `direction`, the
root is located on the step's dense interpolant by a safeguarded Newton–bisection
iteration (bracketed, so it cannot leave the step; to a few ulps of `t`). Then the
earliest root of a terminal or resetting event cuts the step there:

- terminal: the solve ends at the root (`t_end`, `q_end`, `q̇_end`), the saves
  after it are `inf` (as after any stop), and `result` is `event_occurred`;
- reset: the state at the root is replaced by `reset(t, q, q̇, params)` and the
  solver restarts there (a fresh `solver.init`; the next step as long as the last one);
- a cascade (an event more than `max_events` times, or a reset at the time of the
  previous one: events accumulating at a point, as a ball with restitution `e < 1`
  bouncing infinitely often before it comes to rest) ends the solve at that time with
  `RESULTS.event_cascade`: it is reported, never looped.
"""

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import numpy as np

from .._core.errors import ArgumentTypeError, ConfigurationError, ShapeError
from .._core.results import RESULTS
from . import integrate
from .solution import EventRecord

_ROOT_ITERATIONS = 48  # worst case all bisections: 2**-48 of the step, ~1e-14 relative


class Event(eqx.Module):
    r"""An event: a zero crossing of `condition(t, q, q̇, params)` along a solve.

    Pass one or a list to [`lagrax.simulate`][] (`events=`) or [`lagrax.sweep`][].
    After each accepted step the solver compares the sign of the condition at the step's
    ends; where it changed (in `direction`), the crossing time `t*` is found on the
    step's dense output (the solver's interpolant) by a bracketed Newton–bisection
    iteration, to a few ulps of `t` (the interpolant's own error, about the solver's
    tolerance, is the limit on `t*`). Crossings are recorded in
    `Solution.events` (time and state). At most one crossing of an event per step
    is seen: a condition that crosses zero twice within one step is missed (as in SciPy's
    `solve_ivp`): tighten the tolerances or use `dt0`/`max_steps` accordingly.

    A zero of the condition at the start, or right after a reset of this event, is not a
    crossing: the sign there is taken from the condition's rate `ġ` along the motion.

    **Arguments:**

    - `condition`: `condition(t, q, qd, params) -> scalar`, the function whose zeros
      are the events (e.g. `lambda t, q, qd, p: q[0]` for a pendulum passing the
      vertical; the height of a ball above the floor).
    - `direction`: `0` (default) any crossing; `+1` only from negative to positive;
      `-1` only from positive to negative.
    - `terminal`: end the solve at the first crossing (`Solution.t_end` is the root;
      `Solution.result` is `RESULTS.event_occurred` and `ok` stays true).
    - `reset`: `reset(t, q, qd, params) -> (q, qd)`, the state after the event, from
      the state just before it; the solve continues from there. An impact with
      restitution `e`: `lambda t, q, qd, p: (q, -e * qd)`. Not with `terminal`.
    - `max_events`: the most crossings recorded (the size of the arrays in
      `Solution.events`, default 100). One more ends the solve with
      `RESULTS.event_cascade` (a `SimulationError` with `throw=True`): an event
      that happens without end (a Zeno cascade of impacts) is reported, not looped.

    **Raises:** `ArgumentTypeError` when `condition` or `reset` is not callable;
    `ConfigurationError` for a `direction` other than `-1, 0, 1`, a terminal event
    with a reset, or `max_events` not a positive integer. A condition that does not
    return a scalar, or a reset that does not return `(q, qd)` of the state's shapes,
    raise a `ShapeError` from `simulate`.

    **Example:**

    ```python
    floor = lagrax.Event(lambda t, q, qd, p: q[0], direction=-1,
                         reset=lambda t, q, qd, p: (q, -0.8 * qd))
    sol = lagrax.simulate(ball, [1.0], [0.0], params, t1=3.0, events=floor)
    sol.events[0].times[: sol.events[0].count]   # the bounce times
    ```
    """

    condition: Callable[..., Any]
    direction: int = eqx.field(default=0, static=True)
    terminal: bool = eqx.field(default=False, static=True)
    reset: Callable[..., Any] | None = None
    max_events: int = eqx.field(default=100, static=True)

    def __check_init__(self):
        if not callable(self.condition):
            raise ArgumentTypeError(
                "Event needs a function condition(t, q, qd, params) -> scalar, got "
                f"{type(self.condition).__name__}: {self.condition!r}"
            )
        if self.reset is not None and not callable(self.reset):
            raise ArgumentTypeError(
                "Event's reset must be a function reset(t, q, qd, params) -> (q, qd) or "
                f"None, got {type(self.reset).__name__}: {self.reset!r}"
            )
        if isinstance(self.direction, bool) or self.direction not in (-1, 0, 1):
            raise ConfigurationError(
                f"Event's direction must be -1 (crossing downwards), 0 (either way) or +1 "
                f"(upwards), got direction={self.direction!r}"
            )
        if not isinstance(self.terminal, (bool, np.bool_)):
            raise ArgumentTypeError(
                f"Event's terminal must be True or False, got {self.terminal!r}"
            )
        if self.terminal and self.reset is not None:
            raise ConfigurationError(
                "an Event is either terminal (the solve ends at it) or has a reset (the "
                "solve continues from the reset state), not both: drop one of terminal=True "
                "and reset="
            )
        if (
            isinstance(self.max_events, (bool, np.bool_))
            or not isinstance(self.max_events, (int, np.integer))
            or self.max_events < 1
        ):
            raise ConfigurationError(
                f"Event's max_events must be a positive integer (the most crossings "
                f"recorded), got max_events={self.max_events!r}"
            )


def keep(t, q, qd, params):
    """The identity reset, `(q, q̇)` unchanged: an event with it only cuts the step at
    its root (a contact's onset, [`ContactSystem.events`][lagrax.contact.ContactSystem.events])."""
    return q, qd


def as_events(events: Any) -> tuple[Event, ...] | None:
    """`events=` as a tuple of [`Event`][lagrax.Event] (`None` for none), or an error."""
    if events is None:
        return None
    if isinstance(events, Event):
        return (events,)
    if isinstance(events, Sequence) and not isinstance(events, str):
        events = tuple(events)
        for i, ev in enumerate(events):
            if not isinstance(ev, Event):
                raise ArgumentTypeError(
                    f"events must be a lagrax.Event or a sequence of them; events[{i}] is a "
                    f"{type(ev).__name__}: {ev!r}. Wrap a condition function as "
                    "lagrax.Event(condition)"
                )
        return events or None
    raise ArgumentTypeError(
        f"events must be a lagrax.Event or a sequence of them, got {type(events).__name__}: "
        f"{events!r}. Wrap a condition function as lagrax.Event(condition)"
    )


def check_events(events: tuple[Event, ...], t0, q0, qd0, params) -> None:
    """Shapes of every condition (a scalar) and reset (`(q, qd)` as the state), from
    their traces at the initial state: a `ShapeError` naming the event otherwise."""
    q0, qd0 = jnp.asarray(q0), jnp.asarray(qd0)

    def call(i, name, fn):
        try:
            return jax.eval_shape(fn, t0, q0, qd0, params)
        except TypeError as err:
            raise ArgumentTypeError(
                f"events[{i}]: {name}(t, q, qd, params) cannot be called with the time, "
                f"the state and params ({err}): it takes those four arguments"
            ) from err

    for i, ev in enumerate(events):
        g = call(i, "condition", ev.condition)
        shape = getattr(g, "shape", None)
        if shape is None or shape != () or not jnp.issubdtype(g.dtype, jnp.floating):
            what = f"shape {shape}" if shape is not None else type(g).__name__
            if shape == () and not jnp.issubdtype(g.dtype, jnp.floating):
                what = f"dtype {g.dtype}"
            raise ShapeError(
                f"events[{i}]: condition(t, q, qd, params) must return a real scalar, got "
                f"{what}: return one number whose sign change marks the event (e.g. "
                "q[0], not q)"
            )
        if ev.reset is None:
            continue
        out = call(i, "reset", ev.reset)
        ok = isinstance(out, (tuple, list)) and len(out) == 2
        if ok:
            ok = tuple(getattr(o, "shape", None) for o in out) == (q0.shape, qd0.shape)
        if not ok:
            got = (
                tuple(getattr(o, "shape", type(o).__name__) for o in out)
                if isinstance(out, (tuple, list))
                else getattr(out, "shape", type(out).__name__)
            )
            raise ShapeError(
                f"events[{i}]: reset(t, q, qd, params) must return the pair (q, qd), of "
                f"shapes {q0.shape} and {qd0.shape}, got {got}"
            )


def _crossed(direction: int, g_a, g_b):
    up = (g_a <= 0) & (g_b > 0)
    down = (g_a >= 0) & (g_b < 0)
    if direction > 0:
        return up
    if direction < 0:
        return down
    return up | down


def along(ev: Event, t, y, field, args):
    """`g` and its rate `ġ` along the motion at `(t, y)` (the field's `(q̇, q̈)`: `q̇ =
    N(q) v` on a floating base, whose `q` and `v` differ in size)."""
    params = args[0]
    q_rate, qdd = field(t, y, args)
    q, qd = y
    return jax.jvp(
        lambda s, a, b: jnp.asarray(ev.condition(s, a, b, params), q.dtype),
        (t, q, qd),
        (jnp.ones_like(t), q_rate, qdd),
    )


def _signed(g, rate):
    """`g`, with an exact zero replaced by a tiny number of the sign of its rate."""
    tiny = jnp.finfo(g.dtype).tiny
    return jnp.where(g == 0, jnp.sign(rate) * tiny, g)


def _locate(ev: Event, solver, dense, ta, tb, g_a, g_b, params):
    """The root of `g(t) = condition(t, y(t))` on the interpolant of `[ta, tb]`,
    bracketed by the signs `g_a`, `g_b`: Newton steps where they stay inside the
    shrinking bracket and halve it at least, bisection otherwise (a fixed number of
    iterations, so it runs inside a reverse-differentiable loop); a last Newton step
    makes the root's derivatives those of the implicit function `g(t*) = 0`."""

    def g(t):
        q, qd = integrate.interpolate(solver, dense, ta, tb, t)
        return jnp.asarray(ev.condition(t, q, qd, params), q.dtype)

    def g_and_rate(t):
        return jax.jvp(g, (t,), (jnp.ones_like(t),))

    neg_a = g_a < 0
    eps = jnp.finfo(g_a.dtype).eps

    def body(_, c):
        lo, hi, t = c
        val, rate = g_and_rate(t)
        same = (val < 0) == neg_a
        lo = jnp.where(same, t, lo)
        hi = jnp.where(same, hi, t)
        lo = jnp.where(val == 0, t, lo)
        hi = jnp.where(val == 0, t, hi)
        step = val / jnp.where(rate == 0, jnp.inf, rate)
        newton = t - step
        good = (newton > lo) & (newton < hi) & (jnp.abs(step) <= 0.5 * (hi - lo))
        # converged: the Newton step is below the resolution of t
        done = (val == 0) | (jnp.abs(step) <= 2 * eps * jnp.abs(t))
        t = jnp.where(done, t, jnp.where(good, newton, 0.5 * (lo + hi)))
        return lo, hi, t

    ta_, tb_ = jax.lax.stop_gradient((ta, tb))
    # the first guess: the secant of the bracket, away from its ends (after a reset the
    # condition is zero at ta, which is not the crossing sought)
    w = jnp.where(g_b != g_a, g_a / (g_a - g_b), 0.5)
    t_first = ta_ + jnp.clip(w, 1 / 16, 15 / 16) * (tb_ - ta_)
    lo, hi, t = jax.lax.fori_loop(
        0, _ROOT_ITERATIONS, body, (ta_, tb_, jax.lax.stop_gradient(t_first))
    )
    t = jax.lax.stop_gradient(jnp.clip(t, lo, hi))
    val, rate = g_and_rate(t)
    polish = t - val / jnp.where(rate == 0, jnp.inf, rate)
    return jnp.where((polish >= lo) & (polish <= hi), polish, t)


class _Carry(eqx.Module):
    state: integrate.StepState
    ys: Any  # the saves
    g: jax.Array  # (E,) each condition (signed, see _signed) at state.t
    times: tuple  # per event (K,)
    qs: tuple  # per event (K, n)
    qds: tuple
    counts: jax.Array  # (E,) int32
    t_reset: jax.Array  # the time of the last reset (-inf before any)


class _Step(NamedTuple):
    """One attempted step of the loop: what `integrate.advance` returned, from `state`."""

    state: integrate.StepState  # before the attempt
    new: integrate.StepState  # after it
    keep: jax.Array  # whether it was accepted
    dense: Any  # its dense-output information over [state.t, state.tnext]


class _Cut(NamedTuple):
    """Where the earliest terminal or resetting event (or a cascade) cuts a step."""

    t: jax.Array  # the time of the cut (inf: none)
    winner: jax.Array  # the event that cuts it
    cascade: jax.Array  # whether it is a cascade
    recorded: jax.Array  # (E,) which crossings are recorded


@dataclasses.dataclass(frozen=True, eq=False)
class _EventLoop:
    """The fixed parts of one `integrate_events` solve, and the named steps of its loop
    body: `crossings`, `cut_at`, `record`, the saves (`integrate.save_dense`), then
    `cut` where an event (or a cascade) cuts the step."""

    term: Any
    solver: Any
    controller: Any
    args: Any
    t1: jax.Array
    ts: jax.Array
    max_steps: int
    kind: str  # the loops' kind (integrate.LOOP_KINDS)
    events: tuple[Event, ...]
    field: Any
    q0: jax.Array  # the initial coordinates (their shape and dtype)
    inf: jax.Array
    stops: np.ndarray  # (E,) terminal or resetting
    resets: np.ndarray  # (E,) resetting
    capacity: jax.Array  # (E,) max_events
    no_progress: Any  # a reset within this (relative) time of the last one: a cascade

    @property
    def params(self):
        return self.args[0]

    def conditions_at(self, t, y, winner=None):
        """Every condition at `(t, y)`, signed by its rate where zero (and zero for the
        event `winner` that has just reset the state)."""
        out = []
        for i, ev in enumerate(self.events):
            g, rate = along(ev, t, y, self.field, self.args)
            if winner is not None:
                g = jnp.where(winner == i, jnp.zeros_like(g), g)
            out.append(_signed(g, rate))
        return jnp.stack(out)

    def cond(self, c: _Carry):
        s = c.state
        return (s.t < self.t1) & (s.result == RESULTS.successful)

    def body(self, c: _Carry) -> _Carry:
        s = c.state
        new, keep, dense = integrate.advance(
            self.term, self.solver, self.controller, s, self.args, self.t1, self.max_steps
        )
        step = _Step(s, new, keep, dense)
        g_b, crossed, roots = self.crossings(c, step)
        cut = self.cut_at(c, crossed, roots)
        # the state at the cut from a step that ends there, and the root refined on it
        cuts = jnp.isfinite(cut.t)
        t_cut, y_cut = jax.lax.cond(
            cuts, lambda: self.step_to(step, cut), lambda: (cut.t, step.new.y)
        )
        own = cuts & ~cut.cascade  # the winner's own root (a cascade cuts at its time)
        roots = roots.at[cut.winner].set(jnp.where(own, t_cut, roots[cut.winner]))
        cut = cut._replace(t=t_cut)
        times, qs, qds, counts = self.record(c, step, roots, cut.recorded)
        # saves inside the step, up to the cut
        save_end = jnp.minimum(s.tnext, cut.t)
        save_i, ys = integrate.save_dense(
            self.solver,
            dense,
            s.t,
            s.tnext,
            save_end,
            keep,
            self.ts,
            s.save_index,
            c.ys,
            kind=self.kind,
        )
        step = step._replace(new=eqx.tree_at(lambda x: x.save_index, new, save_i))
        new, g, t_reset = jax.lax.cond(
            jnp.isfinite(cut.t),
            lambda _: self.cut(c, step, cut, y_cut),
            lambda _: (step.new, jnp.where(keep, g_b, c.g), c.t_reset),
            None,
        )
        return _Carry(new, ys, g, tuple(times), tuple(qs), tuple(qds), counts, t_reset)

    def crossings(self, c: _Carry, step: _Step):
        """`(g_b, crossed, roots)`: every condition at the step's end, whether it
        crossed zero (in its direction) over an accepted step, and the crossing time
        located on the dense output (`inf` where it did not cross)."""
        ta, tb, new, dtype = step.state.t, step.state.tnext, step.new, self.q0.dtype
        live = step.keep & (new.result == RESULTS.successful)
        g_b = jnp.stack(
            [
                jnp.asarray(ev.condition(tb, new.y[0], new.y[1], self.params), dtype)
                for ev in self.events
            ]
        )
        crossed = jnp.stack(
            [_crossed(ev.direction, c.g[i], g_b[i]) for i, ev in enumerate(self.events)]
        )
        crossed = crossed & live
        roots = jnp.stack(
            [
                jax.lax.cond(
                    crossed[i],
                    lambda i=i, ev=ev: _locate(
                        ev, self.solver, step.dense, ta, tb, c.g[i], g_b[i], self.params
                    ).astype(dtype),
                    lambda: self.inf,
                )
                for i, ev in enumerate(self.events)
            ]
        )
        return g_b, crossed, roots

    def cut_at(self, c: _Carry, crossed, roots) -> _Cut:
        """The earliest crossing of a terminal or resetting event cuts the step there; an
        event past its `max_events`, or a reset at the time of the previous one, is a
        cascade and cuts it at its own time. Crossings up to the cut are recorded."""
        inf = self.inf
        stop_roots = jnp.where(crossed & self.stops, roots, inf)
        winner = jnp.argmin(stop_roots)
        t_stop = stop_roots[winner]
        recorded = crossed & (roots <= t_stop)
        overflow = recorded & (c.counts >= self.capacity)
        zeno = jnp.isfinite(t_stop) & jnp.asarray(self.resets)[winner]
        since = t_stop - c.t_reset
        zeno = zeno & (since <= self.no_progress * jnp.maximum(jnp.abs(t_stop), 1.0))
        t_cascade = jnp.minimum(
            jnp.min(jnp.where(overflow, roots, inf)), jnp.where(zeno, t_stop, inf)
        )
        cascade = jnp.isfinite(t_cascade)
        t_cut = jnp.minimum(t_stop, t_cascade)
        recorded = recorded & (roots <= t_cut) & ~overflow
        return _Cut(t_cut, winner, cascade, recorded)

    def record(self, c: _Carry, step: _Step, roots, recorded):
        """`(times, qs, qds, counts)`: the recorded crossings written into the next free
        slot of each event's record (the state there from the dense output)."""
        ta, tb = step.state.t, step.state.tnext
        times, qs, qds = [], [], []
        for i in range(len(self.events)):
            k = jnp.minimum(c.counts[i], self.capacity[i] - 1)
            yq, yqd = integrate.interpolate(self.solver, step.dense, ta, tb, roots[i])
            times.append(c.times[i].at[k].set(jnp.where(recorded[i], roots[i], c.times[i][k])))
            qs.append(c.qs[i].at[k].set(jnp.where(recorded[i], yq, c.qs[i][k])))
            qds.append(c.qds[i].at[k].set(jnp.where(recorded[i], yqd, c.qds[i][k])))
        counts = c.counts + recorded.astype(jnp.int32)
        return times, qs, qds, counts

    def step_to(self, step: _Step, cut: _Cut):
        """`(t*, y(t*))` at the cut: a step from the accepted step's start `t_a` that
        ends at the located root `t_c`, on which the motion is smooth (before an onset
        no stage feels the contact; the accepted step's interpolant did), the root then
        refined on it, `t* = t_c − g/ġ` (so `dt*/dθ = −(∂g/∂θ)/ġ`, the implicit
        function's, in either mode), and the state carried to it, `y(t_c) + f (t* − t_c)`
        (the flow's derivatives, `dy/dθ = ∂y/∂θ + f dt*/dθ`)."""
        ta, tb = step.state.t, step.state.tnext
        t_c = jax.lax.stop_gradient(cut.t)
        y_c = self.solver.step(
            self.term, ta, t_c, step.state.y, self.args, step.state.solver_state, False
        )[0]
        y_c = integrate.project(self.term, y_c)
        branches = [lambda y, ev=ev: along(ev, t_c, y, self.field, self.args) for ev in self.events]
        g, rate = jax.lax.switch(cut.winner, branches, y_c)
        # a cascade cuts at its own time; a touch without rate (grazing) has no implicit
        # derivative: both keep t_c
        polish = ~cut.cascade & (rate != 0)
        dt = jnp.clip(jnp.where(polish, -g / jnp.where(polish, rate, 1.0), 0.0), ta - t_c, tb - t_c)
        rate_y = self.field(t_c, y_c, self.args)
        return t_c + dt, jax.tree_util.tree_map(lambda y, f: y + f * dt, y_c, rate_y)

    def cut(self, c: _Carry, step: _Step, cut: _Cut, y_cut):
        """`(state, g, t_reset)` after a cut at `cut.t`, where the state is `y_cut`
        (`step_to`): that state reset by the winning event, or kept by a terminal event
        or a cascade (which also end the solve with their result), the solver restarted
        from it, and the conditions there."""
        ta, tb, dtype = step.state.t, step.state.tnext, self.q0.dtype
        t_cut, winner, params = cut.t, cut.winner, self.params
        is_reset = ~cut.cascade & jnp.asarray(self.resets)[winner]
        if self.resets.any():
            branches = [
                (lambda y, ev=ev: y)
                if ev.reset is None
                else (
                    lambda y, ev=ev: tuple(
                        jnp.asarray(v, dtype).reshape(part.shape)  # q and q̇ (sizes may differ)
                        for v, part in zip(ev.reset(t_cut, y[0], y[1], params), y, strict=True)
                    )
                )
                for ev in self.events
            ]
            y_after = jax.lax.switch(winner, branches, y_cut)
            y_next = integrate.tree_where(is_reset, y_after, y_cut)
        else:
            y_next = y_cut
        result = RESULTS.where(
            cut.cascade,
            RESULTS.event_cascade,
            RESULTS.where(is_reset, RESULTS.successful, RESULTS.event_occurred),
        )
        tnext = jnp.minimum(t_cut + (tb - ta), self.t1)
        sstate = self.solver.init(self.term, t_cut, tnext, y_next, self.args)
        g = self.conditions_at(t_cut, y_next, jnp.where(is_reset, winner, -1))
        t_reset = jnp.where(is_reset, t_cut, c.t_reset)
        new = eqx.tree_at(
            lambda x: (x.t, x.tnext, x.y, x.solver_state, x.result),
            step.new,
            (t_cut, tnext, y_next, sstate, result),
        )
        return new, g, t_reset


def integrate_events(
    term,
    solver,
    controller,
    y0,
    args,
    t0,
    t1,
    dt0,
    ts,
    max_steps: int,
    events,
    field,
    kind="checkpointed",
):
    """`integrate.integrate` with `events` (a tuple of [`Event`][lagrax.Event]), its
    loops of `kind` (`integrate.LOOP_KINDS`).

    **Returns:** `(ys, state, records)`: as `integrate`, plus one
    [`EventRecord`][lagrax.EventRecord] per event.
    """
    state = integrate.init_state(term, solver, controller, t0, t1, y0, dt0, args)
    ys = integrate.unreached_saves(y0, ts.shape[0])
    q0 = y0[0]
    dtype = q0.dtype
    loop = _EventLoop(
        term,
        solver,
        controller,
        args,
        t1,
        ts,
        max_steps,
        kind,
        events,
        field,
        q0,
        inf=jnp.asarray(jnp.inf, dtype),
        stops=np.asarray([ev.terminal or ev.reset is not None for ev in events]),
        resets=np.asarray([ev.reset is not None for ev in events]),
        capacity=jnp.asarray([ev.max_events for ev in events], jnp.int32),
        no_progress=64 * jnp.finfo(dtype).eps,
    )
    init = _Carry(
        state,
        ys,
        loop.conditions_at(t0, y0),
        tuple(jnp.full((ev.max_events,), loop.inf) for ev in events),
        tuple(jnp.full((ev.max_events,) + q0.shape, loop.inf) for ev in events),
        tuple(jnp.full((ev.max_events,) + y0[1].shape, loop.inf) for ev in events),
        jnp.zeros((len(events),), jnp.int32),
        jnp.asarray(-jnp.inf, dtype),
    )
    out = eqxi.while_loop(
        loop.cond,
        loop.body,
        init,
        max_steps=max_steps,
        buffers=lambda c: c.ys,
        **integrate.loop_kind(kind),
    )
    records = tuple(
        EventRecord(out.times[i], out.qs[i], out.qds[i], out.counts[i]) for i in range(len(events))
    )
    return out.ys, out.state, records
