"""A lean stepping loop for one trajectory, on diffrax's own steps.

`diffrax.diffeqsolve` is general: events, jump times, several kinds of saving, progress
meters, SDEs. Each of those costs a little on every step, and for the small systems
mechanics produces (n = 1 … 10 coordinates) the step itself is cheap, so the machinery
dominates: about 4 µs a step for the 2R arm against well under 1 µs for the stepping alone.

`integrate` keeps only what `simulate` needs: `solver.step`, the step-size
controller's `adapt_step_size`, diffrax's clipping of the last step to `t1`, and
dense output at the save times (`solver.interpolation_cls`). Each step is therefore the
one `diffeqsolve` would take. The loops are `equinox.internal.while_loop` with
`kind="checkpointed"` (as diffrax's default adjoint), so reverse-mode `jax.grad`
works through them with recursive checkpointing, or `kind="lax"` (as diffrax's
`ForwardMode`) for `jax.jvp` / `jax.jacfwd`; the saved outputs are written in place
(`buffers`).

The engine is `StepState` with `init_state` / `advance` (one attempted step, its
counts and result) and `interpolate` / `save_due` / `save_dense` (dense saving: the
one save loop). Three schedulers run it: `integrate` here (one trajectory),
`events.integrate_events` (one trajectory with events) and the sweep's lane queue
(`lanes.run_lanes`, `advance` under `vmap`).
"""

import functools
from typing import Any

import diffrax as dfx
import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np

from .._core.results import RESULTS, code_of
from .._systems.abstract import AbstractSystem
from .._systems.vector_field import LagrangianVectorField, unwrapped_term
from ..integrators import Rodas4, Variational
from ..integrators._rosenbrock import TangentLinearField
from .postprocess import WithWork

_DEFAULT_STIFF_RATE = AbstractSystem.stiff_rate

DEFAULT_DT0 = 0.01

# How a trajectory's loops are differentiated: `"checkpointed"` (the default, as diffrax's
# `RecursiveCheckpointAdjoint`) differentiates in reverse mode, with recursive
# checkpointing; `"lax"` (a plain `jax.lax.while_loop`, as diffrax's `ForwardMode`) in
# forward mode. Neither supports the other's mode.
LOOP_KINDS = ("checkpointed", "lax")


def loop_kind(kind: str, checkpoints: int | None = None) -> dict:
    """The keyword arguments of `equinox.internal.while_loop` for a loop of `kind`."""
    if kind == "lax" or checkpoints is None:
        return {"kind": kind}
    return {"kind": kind, "checkpoints": checkpoints}


def tree_where(pred, a, b):
    """`where` over matching pytrees, broadcasting a (batched) scalar `pred`."""

    def pick(x, y):
        if not (eqx.is_array(x) or eqx.is_array(y)):
            return x  # static (Python) leaves, e.g. a solver's flags
        x, y = jnp.asarray(x), jnp.asarray(y)
        p = pred.reshape(pred.shape + (1,) * (x.ndim - pred.ndim))
        return jnp.where(p, x, y)

    return jtu.tree_map(pick, a, b)


def t1_floor(t1):
    """diffrax snaps a step end within ~100 ulps of `t1` to `t1`."""
    return t1 - 100 * jnp.finfo(t1.dtype).eps * jnp.maximum(jnp.abs(t1), 1.0)


def init(term, solver, controller, t0, t1, y0, dt0, args):
    """`(tnext, solver_state, controller_state)` at the start of a solve."""
    if dt0 is None:
        # What diffeqsolve ends up doing: it wraps the terms (diffrax.WrapTerm), and its
        # PID controller's initial-step heuristic then falls back to 0.01. Matching it
        # keeps the step sequence that of diffeqsolve.
        dt0 = jnp.asarray(DEFAULT_DT0, t0.dtype)
    error_order = solver.error_order(term)
    tnext, cstate = controller.init(term, t0, t1, y0, dt0, args, solver.func, error_order)
    tnext = jnp.minimum(tnext, t1)
    sstate = solver.init(term, t0, tnext, y0, args)
    return tnext, sstate, cstate


def step(term, solver, controller, t, tnext, y, args, sstate, cstate, t1):
    """One attempted step `[t, tnext]`, accepted or rejected by the controller.

    **Returns:** `(keep, tprev, tnew, y, solver_state, controller_state, result, dense)`:
    whether the step was accepted, the new current time (`tnext` if accepted, else
    `t`), the end of the next attempt (clipped to `t1`), the state at `tprev`, the
    new solver/controller states, a `RESULTS` code and the dense-output information of
    the attempt.
    """
    error_order = solver.error_order(term)
    y1, y_err, dense, sstate1, sres = solver.step(term, t, tnext, y, args, sstate, False)
    if y_err is not None:  # a NaN error would be accepted by nothing: reject, shrink
        y_err = jtu.tree_map(lambda e: jnp.where(jnp.isnan(e), jnp.inf, e), y_err)
    keep, tprev, tnew, _, cstate1, cres = controller.adapt_step_size(
        t, tnext, y, y1, args, y_err, error_order, cstate
    )
    keep = jnp.asarray(keep)
    tprev = jnp.minimum(tprev, t1)
    clip = jnp.where(keep, t1, tprev + 0.5 * (t1 - tprev))
    tnew = jnp.where(tnew > t1_floor(t1), clip, tnew)
    # explicit methods report a constant success: skip the eager ops on constants (each
    # would compile a tiny kernel during tracing, ~0.1 s in all on the first call)
    sres, cres = _promote(sres), _promote(cres)
    if _known_success(sres):
        res = cres
    else:
        sres = RESULTS.where(keep, sres, RESULTS.successful)
        res = RESULTS.where(sres == RESULTS.successful, cres, sres)
    y_next = tree_where(keep, y1, y)
    sstate_next = tree_where(keep, sstate1, sstate)
    return keep, tprev, tnew, y_next, sstate_next, cstate1, res, dense


def _known_success(result) -> bool:
    """Whether `result` is the constant `RESULTS.successful` (known at trace time)."""
    value = code_of(result)
    if isinstance(value, jax.core.Tracer):
        return False
    return bool(np.all(np.asarray(value) == np.asarray(code_of(RESULTS.successful))))


def _promote(result):
    """`RESULTS.promote`, without eager ops when `result` is a constant success."""
    return RESULTS.successful if _known_success(result) else RESULTS.promote(result)


def _primal_part(term, y):
    """`y`, or its primal part for an augmented system: the forward sensitivities
    (`sensitivities.Sensitivities`: the state `(y, s)`) or the work carried as state
    (`postprocess.WithWork`: `(y, W)`)."""
    return y[0] if getattr(getattr(term, "vector_field", None), "augmented", False) else y


class _PrimalNorm(eqx.Module):
    """A step-size controller's error norm of an augmented state `(y, extra)`: the
    norm of `y`, or (`ratio` given) the largest of it and `ratio` times each tangent's
    norm, so that the steps resolve the forward sensitivities as well (`tangents`: `k`
    tangents on a leading axis of `extra`)."""

    norm: Any
    ratio: float | None = eqx.field(default=None, static=True)
    tangents: bool = eqx.field(default=False, static=True)
    gate: Any = None  # a traced 0/1 factor on the tangents' part (None: 1)

    def __call__(self, error):
        primal = self.norm(error[0])
        if self.ratio is None:
            return primal
        if self.tangents:
            tangent = jnp.max(jax.vmap(self.norm)(error[1]))
        else:
            tangent = self.norm(error[1])
        weight = self.ratio if self.gate is None else self.ratio * self.gate
        return jnp.maximum(primal, weight * tangent)


def primal_controller(
    controller, ratio: float | None = None, tangents: bool = False, gate: Any = None
):
    """`controller` with its error norm taken over the primal part of an augmented
    state `(y, extra)`, or (`ratio`) over the tangents in `extra` too, times `gate`
    where given (`_PrimalNorm`); a constant step: unchanged."""
    if isinstance(controller, dfx.PIDController):
        norm = _PrimalNorm(controller.norm, ratio, tangents, gate)
        return eqx.tree_at(lambda c: c.norm, controller, norm)
    return controller


def all_finite(y) -> jax.Array:
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(v)) for v in jtu.tree_leaves(y)]))


class StepState(eqx.Module):
    """The state of one trajectory between two attempted steps.

    Both schedulers carry it: `integrate` one of them, the lane queue
    (`lanes.run_lanes`) one per lane under `vmap`.
    """

    t: jax.Array  # the current time (the end of the last accepted step)
    tnext: jax.Array  # the end of the next attempted step
    y: Any  # the state at t
    solver_state: Any
    controller_state: Any
    num_steps: jax.Array  # attempted steps so far
    num_accepted_steps: jax.Array
    save_index: jax.Array  # how many of the save times have been written
    result: RESULTS


def init_state(term, solver, controller, t0, t1, y0, dt0, args) -> StepState:
    """The `StepState` at the start of a solve."""
    tnext, sstate, cstate = init(term, solver, controller, t0, t1, y0, dt0, args)
    zero = jnp.asarray(0, jnp.int32)
    return StepState(t0, tnext, y0, sstate, cstate, zero, zero, zero, RESULTS.successful)


def advance(term, solver, controller, state: StepState, args, t1, max_steps: int):
    """One attempted step from `state`, with the step counts and the result updated.

    The new state is projected onto the system's configuration manifold (`project`).
    The result becomes the solver's or controller's failure, `non_finite_state` as soon
    as an accepted state is not finite, or `max_steps_reached` when the budget is spent
    before `t1`.

    **Returns:** `(new_state, keep, dense)`: whether the step was accepted, and the
    dense-output information of the attempt over `[state.t, state.tnext]`.
    """
    keep, tprev, tnew, y, sstate, cstate, res, dense = step(
        term,
        solver,
        controller,
        state.t,
        state.tnext,
        state.y,
        args,
        state.solver_state,
        state.controller_state,
        t1,
    )
    y = project(term, y)
    steps = state.num_steps + 1
    result = RESULTS.where(all_finite(_primal_part(term, y)), res, RESULTS.non_finite_state)
    result = stability_check(term, solver, controller, (state.t, tprev), keep, y, args, result)
    out_of_steps = (steps >= max_steps) & (tprev < t1) & (result == RESULTS.successful)
    result = RESULTS.where(out_of_steps, RESULTS.max_steps_reached, result)
    new = StepState(
        tprev,
        tnew,
        y,
        sstate,
        cstate,
        steps,
        state.num_accepted_steps + keep,
        state.save_index,
        result,
    )
    return new, keep, dense


def system_of(term):
    """The system whose vector field `term` holds, through diffrax's wrapping terms, or
    `None` for a term that is not a system's vector field."""
    field = getattr(unwrapped_term(term), "vector_field", None)
    if isinstance(field, WithWork):  # the work carried as state: the field inside
        field = field.field
    return field.system if isinstance(field, LagrangianVectorField) else None


def carries_work(term) -> bool:
    """Whether `term` carries the work as state (`postprocess.WithWork`)."""
    return isinstance(getattr(unwrapped_term(term), "vector_field", None), WithWork)


STABILITY_BOUND = 2.0  # h λ: an explicit method's fixed step on a stiff mode of rate λ


def stiff_system(term, solver, controller):
    """The system whose `stiff_rate` a fixed-step explicit solve checks, or `None`: an
    adaptive or implicit solve, the augmented system of forward sensitivities, or a
    system without stiff forces (`AbstractSystem.stiff_rate` not overridden)."""
    if not isinstance(controller, dfx.ConstantStepSize):
        return None
    if isinstance(solver, (dfx.AbstractImplicitSolver, Variational, Rodas4)):
        return None
    system = system_of(term)
    if system is None or type(system).stiff_rate is _DEFAULT_STIFF_RATE:
        return None
    return system


def stability_check(term, solver, controller, step, keep, y, args, result):
    """`result`, or `RESULTS.step_past_stability_limit` where an accepted fixed step
    `step = (t0, t1)`, `h = t1 − t0`, of an explicit method is past the system's stiff
    forces' stability limit at the new state `y`, `h λ > STABILITY_BOUND`
    ([`stiff_rate`][lagrax.AbstractSystem.stiff_rate])."""
    system = stiff_system(term, solver, controller)
    if system is None:
        return result
    q, v = y[0] if carries_work(term) else y
    h = step[1] - step[0]
    lam = system.stiff_rate(q, v, args[0])
    past = keep & (h * lam > STABILITY_BOUND) & (result == RESULTS.successful)
    return RESULTS.where(past, RESULTS.step_past_stability_limit, result)


def _project_with_tangents(inner, tangents: bool, y):
    """`project(inner, ·)` of the state of an augmented system `(y, s)`, with its tangents
    carried along by the projection's derivative (`s ↦ P'(y) s`, each of them where
    `tangents`): the forward sensitivities of the projected solve."""
    primal, s = y
    system = system_of(inner)
    if system is None or not system.projects:
        return y

    def along(direction):
        return jax.jvp(lambda v: project(inner, v), (primal,), (direction,))

    if tangents:
        return jax.vmap(along, out_axes=(None, 0))(s)
    return along(s)


def project(term, y):
    """The state `(q, v)` with `q` put back onto its manifold by the system's
    [`project_configuration`][lagrax.AbstractSystem.project_configuration] (a floating
    base: its quaternion normalized), after every accepted step; `y` unchanged for a
    term that is not a system's vector field, or a system whose projection is the
    identity (the default)."""
    field = getattr(unwrapped_term(term), "vector_field", None)
    if isinstance(field, TangentLinearField):  # forward sensitivities: `(y, s)`
        return _project_with_tangents(dfx.ODETerm(field.field), field.tangents, y)
    system = system_of(term)
    if system is None or not system.projects:
        return y
    if carries_work(term):
        (q, qd), w = y
        return (system.project_configuration(q), qd), w
    q, qd = y
    return system.project_configuration(q), qd


def interpolate(solver, dense, ta, tb, t):
    """The solver's dense output of the attempted step `[ta, tb]`, evaluated at `t`."""
    return solver.interpolation_cls(t0=ta, t1=tb, **dense).evaluate(t)


def save_due(keep, i, tnext, ts):
    """Whether save time `ts[i]` lies inside the accepted step that ends at `tnext`."""
    n_save = ts.shape[0]
    return keep & (i < n_save) & (ts[jnp.minimum(i, n_save - 1)] <= tnext)


# Gauss–Legendre nodes and weights on [−1, 1] for the work at the saves (`work_at`):
# eighth order in the distance from the step's start
_GAUSS = tuple(np.polynomial.legendre.leggauss(4))


def work_at(term, solver, dense, ta, tb, t, start):
    """The work `W(t)` carried as state (`postprocess.WithWork`) at `t` inside the
    attempted step `[ta, tb]`: `W(ta) + ∫_{ta}^{t} P(s, y(s)) ds`, by four-point
    Gauss–Legendre on the step's dense output `y(s)`, where `start = (W(ta), args)`.

    The dense output of `W` itself is only as good as the method's interpolant of a
    quantity whose rate `P` may vary much faster than the state (a support driven at
    high frequency: its work off by 3e-6 between the steps, where the quadrature on the
    state's interpolant is at the steps' accuracy)."""
    w_a, args = start
    x, weights = (jnp.asarray(v, ta.dtype) for v in _GAUSS)
    nodes = ta + 0.5 * (t - ta) * (x + 1.0)

    def power(s):
        (q, v), _ = interpolate(solver, dense, ta, tb, s)
        return unwrapped_term(term).vector_field.power(s, q, v, args)

    return w_a + 0.5 * (t - ta) * jnp.sum(weights * jax.vmap(power)(nodes))


def save_dense(
    solver,
    dense,
    ta,
    tb,
    t_end,
    keep,
    ts,
    index,
    ys,
    rows=None,
    kind="checkpointed",
    work=None,
):
    """Write the dense output of the attempted step `[ta, tb]` at the save times it
    reached: the one save loop of the three schedulers.

    The save times `ts[index], ts[index + 1], …` not after `t_end` (the step's end
    `tb`, or an earlier time where an event cut the step) are interpolated on the step
    (`interpolate`) and written into `ys`, when the step was accepted (`keep`).

    **Arguments:**

    - `solver`, `dense`: the solver and the dense-output information of the attempt.
    - `ta`, `tb`, `t_end`: the attempt's interval, and the last time to save up to.
    - `keep`: whether the attempt was accepted.
    - `ts`: the sorted save times, shape `(S,)` (may be empty).
    - `index`: how many of `ts` have been written (`StepState.save_index`).
    - `ys`: the saves written so far, a pytree of leaves `(S, ...)`.
    - `rows`: `None` for one trajectory. For the lane queue (`lanes.run_lanes`), the
      member each lane integrates, shape `(L,)` (out of range: an idle lane); then
      `ta`, `tb`, `t_end`, `keep`, `index` and `dense` have the lane axis `L` in
      front, and `ys` holds every member's saves, leaves `(M, S, ...)`, written at
      `ys[rows[l], index[l]]`.

    - `work`: `None`, or for a term that carries the work as state, `(term, start)`
      with `start = (W(ta), args)` (per lane for the lane queue): the work at the saves
      is then `work_at`'s quadrature, not the interpolant's.

    **Returns:** `(index, ys)`, with `index` past the times written.

    One trajectory loops with `equinox.internal.while_loop(kind=kind)`, so that reverse
    mode (`"checkpointed"`) or forward mode (`"lax"`) differentiates through it, and writes
    `ys` in place (a buffer);
    the lanes loop until no lane has a save due, each lane advancing its own index.
    """
    n_save = ts.shape[0]
    if not n_save:
        return index, ys
    if rows is None:

        def body(carry):
            i, out = carry
            y_t = interpolate(solver, dense, ta, tb, ts[i])
            if work is not None:
                y_t = (y_t[0], work_at(work[0], solver, dense, ta, tb, ts[i], work[1]))
            return i + 1, jtu.tree_map(lambda v, o: o.at[i].set(v), y_t, out)

        return eqxi.while_loop(
            lambda carry: save_due(keep, carry[0], t_end, ts),
            body,
            (index, ys),
            max_steps=n_save,
            buffers=lambda carry: carry[1],
            **loop_kind(kind, n_save),
        )
    n_rows = jtu.tree_leaves(ys)[0].shape[0]

    def pending(carry):
        return save_due(keep, carry[1], t_end, ts)

    def lane_body(carry):
        out, i = carry
        go = pending(carry)
        ic = jnp.minimum(i, n_save - 1)
        y_t = jax.vmap(functools.partial(interpolate, solver))(dense, ta, tb, ts[ic])
        if work is not None:
            at = functools.partial(work_at, work[0], solver)
            y_t = (y_t[0], jax.vmap(at)(dense, ta, tb, ts[ic], work[1]))
        r = jnp.where(go, rows, n_rows)  # n_rows: dropped by the scatter
        out = jtu.tree_map(lambda o, v: o.at[r, ic].set(v, mode="drop"), out, y_t)
        return out, jnp.where(go, i + 1, i)

    ys, index = jax.lax.while_loop(lambda c: jnp.any(pending(c)), lane_body, (ys, index))
    return index, ys


def integrate(
    term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps: int, kind="checkpointed"
):
    """Solve `y' = f(t, y, args)` on `[t0, t1]` and save at `ts`: the
    single-trajectory scheduler over `advance`.

    **Arguments:** as `diffrax.diffeqsolve`; `ts` are sorted save times inside
    `[t0, t1]`, `max_steps` the budget of attempted steps, `kind` the loop's kind
    (`LOOP_KINDS`: `"checkpointed"` for reverse mode, `"lax"` for forward mode).

    **Returns:** `(ys, state)`: the states at `ts` (`inf` where not reached) and the
    final `StepState` (the last time and state reached, `t1` on success; the
    `RESULTS` code; the step counts; how many of `ts` were reached).
    """
    state = init_state(term, solver, controller, t0, t1, y0, dt0, args)
    ys = unreached_saves(y0, ts.shape[0])

    def cond(carry):
        s, _ = carry
        return (s.t < t1) & (s.result == RESULTS.successful)

    def body(carry):
        s, ys = carry
        new, keep, dense = advance(term, solver, controller, s, args, t1, max_steps)
        work = (term, (s.y[1], args)) if carries_work(term) else None
        save_i, ys = save_dense(
            solver, dense, s.t, s.tnext, s.tnext, keep, ts, s.save_index, ys, kind=kind, work=work
        )
        return eqx.tree_at(lambda x: x.save_index, new, save_i), ys

    state, ys = eqxi.while_loop(
        cond, body, (state, ys), max_steps=max_steps, buffers=lambda c: c[1], **loop_kind(kind)
    )
    return ys, state


def unreached_saves(y, n_save: int, lead: tuple = ()):
    """Saves not yet written: `inf` of `y`'s structure, leaves `lead + (n_save, ...)`."""
    return jtu.tree_map(lambda a: jnp.full(lead + (n_save,) + jnp.shape(a), jnp.inf, a.dtype), y)


def is_lean(controller: dfx.AbstractStepSizeController | None) -> bool:
    """Whether `integrate` reproduces `diffeqsolve` with this controller."""
    # (diffrax's step_ts / jump_ts live in ClipStepSizeController, which is not lean)
    return controller is None or type(controller) in (dfx.ConstantStepSize, dfx.PIDController)
