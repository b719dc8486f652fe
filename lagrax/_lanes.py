"""A work queue of ODE solves on a fixed number of vectorized lanes.

Under ``vmap``, ``diffrax.diffeqsolve`` steps every member of a batch until the slowest
one has finished; members that are done ride along as masked padding. For a sweep of a
chaotic or stiff model the step counts differ by large factors, and that padding is a
large share of the work.

``run_lanes`` instead keeps ``L`` lanes busy: each lane integrates one member; when a
member finishes (reaches ``t1``, runs out of steps, or blows up) its results are written
to the output and the lane is refilled with the next member of the queue, inside one
compiled ``lax.while_loop``. Lanes sit idle only at the end of the queue, and while
waiting for a batch of refills (refilling costs about one step, so it is done when a
sixteenth of the lanes are free).

The stepping is diffrax's own, through ``_integrate.advance`` (shared with ``simulate``'s
single-trajectory loop): ``solver.step``, ``stepsize_controller.adapt_step_size``, the
same clipping to ``t1`` and the same dense output at the save times, so each member takes
the steps ``diffeqsolve`` would take for it (up to round-off in the controller).
"""

from functools import partial
from typing import Any

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu

from . import _integrate
from ._results import RESULTS, code_of

_OK = int(code_of(RESULTS.successful))


class LaneOutput(eqx.Module):
    """What ``run_lanes`` returns, indexed by member (leading axis ``M``)."""

    ys: Any  # pytree of (M, S, ...): the state at the save times (inf where not reached)
    y_end: Any  # pytree of (M, ...): the last state reached
    t_end: jax.Array  # (M,)
    result: jax.Array  # (M,) int code of lagrax.RESULTS
    num_steps: jax.Array  # (M,)
    num_accepted_steps: jax.Array  # (M,)
    num_rejected_steps: jax.Array  # (M,)
    busy_lane_steps: jax.Array  # () lane-steps spent on members
    lane_steps: jax.Array  # () lane-steps in all (busy + idle)


class _Queue(eqx.Module):
    """The lanes and the queue position (the loop state of ``run_lanes``)."""

    lane: _integrate.StepState  # (L,): one trajectory per lane
    member: Any  # (L, ...): each lane's member arguments
    idx: jax.Array  # (L,) which member each lane integrates (M: none)
    active: jax.Array  # (L,) whether the lane holds an unfinished member
    next: jax.Array  # () the next member to start
    busy: jax.Array  # () lane-steps spent on members so far
    iters: jax.Array  # () loop iterations so far


class _Outputs(eqx.Module):
    """Per-member results, written when a member finishes (leading axis ``M``)."""

    ys: Any
    y_end: Any
    t_end: jax.Array
    result: jax.Array
    num_steps: jax.Array
    num_accepted_steps: jax.Array


_where = _integrate.tree_where


def _take(tree, idx):
    return jtu.tree_map(lambda a: a[idx], tree)


def _scatter(out, rows, vals):
    return jtu.tree_map(lambda o, v: o.at[rows].set(v, mode="drop"), out, vals)


def run_lanes(
    term: dfx.AbstractTerm,
    solver: dfx.AbstractSolver,
    controller: dfx.AbstractStepSizeController,
    members: Any,
    y0s: Any,
    extra_args: Any,
    t0: jax.Array,
    t1: jax.Array,
    dt0: jax.Array | None,
    ts: jax.Array,
    n_lanes: int,
    max_steps: int,
) -> LaneOutput:
    """Solve ``y' = f(t, y, (member, extra_args))`` for every member on ``n_lanes`` lanes.

    **Arguments:**

    - ``term``, ``solver``, ``controller``: as for ``diffrax.diffeqsolve``.
    - ``members``: pytree whose leaves have a leading axis ``M`` (per-member arguments).
    - ``y0s``: pytree of initial states with leading axis ``M``.
    - ``extra_args``: arguments shared by all members.
    - ``t0``, ``t1``, ``dt0``: the interval, and the first step (``None``: chosen by the
      controller, as in diffrax).
    - ``ts``: save times, sorted, inside ``[t0, t1]``; may be empty.
    - ``n_lanes``: number of members integrated at once.
    - ``max_steps``: step budget per member (accepted + rejected).

    **Returns:** a :class:`LaneOutput`.
    """
    n_members = jtu.tree_leaves(y0s)[0].shape[0]
    n_lanes = max(1, min(n_lanes, n_members))
    n_save = ts.shape[0]
    tdt = t0.dtype
    refill_at = max(1, n_lanes // 16)

    def init_lane(member, y0):
        return _integrate.init_state(
            term, solver, controller, t0, t1, y0, dt0, (member, extra_args)
        )

    def advance_lane(state, member):
        return _integrate.advance(
            term, solver, controller, state, (member, extra_args), t1, max_steps
        )

    # A template lane (member 0) fixes the shapes of the per-lane state.
    member0 = _take(members, 0)
    lane0 = init_lane(member0, _take(y0s, 0))

    def lanes(x):
        return jtu.tree_map(lambda a: jnp.broadcast_to(a, (n_lanes,) + jnp.shape(a)), x)

    def outputs(x, extra=()):
        return jtu.tree_map(lambda a: jnp.full((n_members,) + extra + a.shape, jnp.inf, a.dtype), x)

    count = jnp.int64 if jax.config.jax_enable_x64 else jnp.int32
    queue = _Queue(
        lane=lanes(lane0),
        member=lanes(member0),
        idx=jnp.full(n_lanes, n_members, jnp.int32),  # n_members: no member
        active=jnp.zeros(n_lanes, bool),
        next=jnp.asarray(0, jnp.int32),
        busy=jnp.asarray(0, count),
        iters=jnp.asarray(0, count),
    )
    out = _Outputs(
        ys=outputs(lane0.y, (n_save,)),
        y_end=outputs(lane0.y),
        t_end=jnp.full(n_members, jnp.inf, tdt),
        result=jnp.full(n_members, _OK, jnp.int32),
        num_steps=jnp.zeros(n_members, jnp.int32),
        num_accepted_steps=jnp.zeros(n_members, jnp.int32),
    )

    def refill(q: _Queue) -> _Queue:
        idle = ~q.active
        rank = jnp.cumsum(idle, dtype=jnp.int32) - 1
        new_idx = q.next + rank
        take = idle & (new_idx < n_members)
        src = jnp.where(take, new_idx, 0)
        member = _take(members, src)
        fresh = jax.vmap(init_lane)(member, _take(y0s, src))
        return _Queue(
            lane=_where(take, fresh, q.lane),
            member=_where(take, member, q.member),
            idx=jnp.where(take, new_idx, q.idx),
            active=q.active | take,
            next=q.next + jnp.sum(take, dtype=jnp.int32),
            busy=q.busy,
            iters=q.iters,
        )

    def want_refill(q: _Queue):
        n_idle = n_lanes - jnp.sum(q.active)
        return (q.next < n_members) & ((n_idle >= refill_at) | (n_idle == n_lanes))

    def body(carry):
        q, out = carry
        q = jax.lax.cond(want_refill(q), refill, lambda x: x, q)
        active, old = q.active, q.lane
        new, keep, dense = jax.vmap(advance_lane)(old, q.member)
        keep = keep & active
        rows = jnp.where(active, q.idx, n_members)  # n_members: dropped by the scatter

        ys, save_i = out.ys, new.save_index
        if n_save:
            # dense output at the save times inside the accepted step [t, tnext]
            def pending(carry):
                return _integrate.save_due(keep, carry[1], old.tnext, ts)

            def save_body(carry):
                ys, i = carry
                go = pending(carry)
                ic = jnp.minimum(i, n_save - 1)
                y_t = jax.vmap(partial(_integrate.interpolate, solver))(
                    dense, old.t, old.tnext, ts[ic]
                )
                r = jnp.where(go, rows, n_members)
                ys = jtu.tree_map(lambda o, v: o.at[r, ic].set(v, mode="drop"), ys, y_t)
                return ys, jnp.where(go, i + 1, i)

            ys, save_i = jax.lax.while_loop(lambda c: jnp.any(pending(c)), save_body, (ys, save_i))
        new = eqx.tree_at(lambda x: x.save_index, new, save_i)
        lane = _where(active, new, old)  # idle lanes stay as they are
        code = code_of(lane.result)
        end = active & ((lane.t >= t1) | (code != _OK))
        end_rows = jnp.where(end, rows, n_members)
        out = _Outputs(
            ys=ys,
            y_end=_scatter(out.y_end, end_rows, lane.y),
            t_end=out.t_end.at[end_rows].set(lane.t, mode="drop"),
            result=out.result.at[end_rows].set(code, mode="drop"),
            num_steps=out.num_steps.at[end_rows].set(lane.num_steps, mode="drop"),
            num_accepted_steps=out.num_accepted_steps.at[end_rows].set(
                lane.num_accepted_steps, mode="drop"
            ),
        )
        q = _Queue(
            lane=lane,
            member=q.member,
            idx=q.idx,
            active=active & ~end,
            next=q.next,
            busy=q.busy + jnp.sum(active),
            iters=q.iters + 1,
        )
        return q, out

    def cond(carry):
        q, _ = carry
        return jnp.any(q.active) | (q.next < n_members)

    q, out = jax.lax.while_loop(cond, body, (queue, out))
    return LaneOutput(
        ys=out.ys,
        y_end=out.y_end,
        t_end=out.t_end,
        result=out.result,
        num_steps=out.num_steps,
        num_accepted_steps=out.num_accepted_steps,
        num_rejected_steps=out.num_steps - out.num_accepted_steps,
        busy_lane_steps=q.busy,
        lane_steps=q.iters * n_lanes,
    )
