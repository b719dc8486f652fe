"""A work queue of ODE solves on a fixed number of vectorized lanes.

Under `vmap`, `diffrax.diffeqsolve` steps every member of a batch until the slowest
one has finished; members that are done ride along as masked padding. For a sweep of a
chaotic or stiff model the step counts differ by large factors, and that padding is a
large share of the work.

`run_lanes` instead keeps `L` lanes busy: each lane integrates one member; when a
member finishes (reaches `t1`, runs out of steps, or blows up) its results are written
to the output and the lane is refilled with the next member of the queue, all inside one
compiled program. The schedule, in three phases:

1. the lanes start free, and the first members fill them, `refill` at a time;
2. while members are left to start: lanes step until `refill` of them are free (or
   as many as there are members left), then one block of `refill` members is started
   on them. A refill initializes only those `refill` members (a fraction of a step's
   work), so it can be frequent; the stepping loop has no branch inside, so each step
   is one loop iteration with a single loop test (on an accelerator: one device-to-host
   read of the predicate), and the refill branch is taken once per block;
3. when the queue is empty, the lanes still busy finish. This tail is where lanes idle:
   with `tail_lanes` (`2 <= tail_lanes < L`), once no more than `tail_lanes`
   members are left, they are gathered into a second, narrower loop of `tail_lanes`
   lanes (one extra compiled loop body), so the slowest members no longer drag `L`
   lanes along.

Every member takes the same steps whatever its lane, block or phase: the arithmetic is
elementwise over lanes, so its numbers do not depend on the schedule (bitwise, for loops
of two lanes and more: a one-lane loop may round differently, so the tail loop is never
narrower than two).

The stepping is diffrax's own, through `integrate.advance` (shared with `simulate`'s
single-trajectory loop): `solver.step`, `stepsize_controller.adapt_step_size`, the
same clipping to `t1` and the same dense output at the save times, so each member takes
the steps `diffeqsolve` would take for it (up to round-off in the controller).
"""

import dataclasses
from typing import Any

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu

from .._core.results import RESULTS, code_of
from . import integrate

_OK = int(code_of(RESULTS.successful))


class LaneOutput(eqx.Module):
    """What `run_lanes` returns, indexed by member (leading axis `M`)."""

    ys: Any  # pytree of (M, S, ...): the state at the save times (inf where not reached)
    y_end: Any  # pytree of (M, ...): the last state reached
    t_end: jax.Array  # (M,)
    result: jax.Array  # (M,) int code of lagrax.RESULTS
    num_steps: jax.Array  # (M,)
    num_accepted_steps: jax.Array  # (M,)
    num_rejected_steps: jax.Array  # (M,)
    busy_lane_steps: jax.Array  # () lane-steps spent on members
    lane_steps: jax.Array  # () lane-steps in all (busy + idle)
    event_count: Any = None  # (M, E) with events (lock-step schedule only)
    event_first: Any = None  # (M, E) the first crossing time of each event (inf: none)
    # with the work carried as state (`postprocess.WithWork`): `W` from `t0` at the
    # saves, (M, S) (inf where not reached), and at the end, (M,); else None
    work: Any = None
    work_end: Any = None


class _Queue(eqx.Module):
    """The lanes and the queue position (the loop state of `run_lanes`)."""

    lane: integrate.StepState  # (L,): one trajectory per lane
    member: Any  # (L, ...): each lane's member arguments
    idx: jax.Array  # (L,) which member each lane integrates (M: none)
    active: jax.Array  # (L,) whether the lane holds an unfinished member
    next: jax.Array  # () the next member to start
    busy: jax.Array  # () lane-steps spent on members so far
    lane_steps: jax.Array  # () lane-steps in all so far (loop iterations x their width)


class _Outputs(eqx.Module):
    """Per-member results, written when a member finishes (leading axis `M`)."""

    ys: Any
    y_end: Any
    t_end: jax.Array
    result: jax.Array
    num_steps: jax.Array
    num_accepted_steps: jax.Array


def _take(tree, idx):
    return jtu.tree_map(lambda a: a[idx], tree)


def _scatter(out, rows, vals):
    return jtu.tree_map(lambda o, v: o.at[rows].set(v, mode="drop"), out, vals)


def default_refill(n_lanes: int) -> int:
    """The refill block of `run_lanes` when none is given: a sixteenth of the lanes."""
    return max(1, n_lanes // 16)


def _scatter_rows(tree, rows, vals):
    """`tree[rows] = vals` over matching pytrees (rows out of range are dropped); static
    (Python) leaves pass through."""

    def put(a, v):
        if not (eqx.is_array(a) or eqx.is_array(v)):
            return a
        return jnp.asarray(a).at[rows].set(v, mode="drop")

    return jtu.tree_map(put, tree, vals)


def _gather_rows(tree, rows):
    return jtu.tree_map(lambda a: a[rows] if eqx.is_array(a) else a, tree)


def _n_active(q: _Queue):
    return jnp.sum(q.active, dtype=jnp.int32)


@dataclasses.dataclass(frozen=True, eq=False)
class _Schedule:
    """The fixed parts of one `run_lanes` call (the problem, the queue of members, the
    block and tail sizes) and the named steps of its schedule: `start` (all lanes
    free), `start_block` (a refill), `step` (every lane one attempt), `wide` (phase 2)
    and `narrow` (the move to the tail loop of phase 3)."""

    term: dfx.AbstractTerm
    solver: dfx.AbstractSolver
    controller: dfx.AbstractStepSizeController
    members: Any  # (M, ...)
    y0s: Any  # (M, ...)
    extra_args: Any
    t0: jax.Array
    t1: jax.Array
    dt0: jax.Array | None
    ts: jax.Array
    max_steps: int
    n_members: int
    block: int  # members started per refill
    tail: int  # lanes of the tail loop (0: none)

    def init_lane(self, member, y0) -> integrate.StepState:
        return integrate.init_state(
            self.term,
            self.solver,
            self.controller,
            self.t0,
            self.t1,
            y0,
            self.dt0,
            (member, self.extra_args),
        )

    def _work(self, lanes: integrate.StepState, members):
        """`save_dense`'s `work` for lanes that carry the work as state, else `None`:
        each lane's `(W(ta), args)`."""
        if not integrate.carries_work(self.term):
            return None
        extra = jtu.tree_map(
            lambda x: jnp.broadcast_to(x, (lanes.t.shape[0], *jnp.shape(x))), self.extra_args
        )
        return self.term, (lanes.y[1], (members, extra))

    def advance_lane(self, state, member):
        return integrate.advance(
            self.term,
            self.solver,
            self.controller,
            state,
            (member, self.extra_args),
            self.t1,
            self.max_steps,
        )

    def start(self, n_lanes: int) -> tuple[_Queue, _Outputs]:
        """The queue with every lane free, and the outputs before any member finished."""
        n_members = self.n_members
        # A template lane (member 0) fixes the shapes of the per-lane state; all lanes
        # start free, and the first refills (before any step) fill them block by block.
        member0 = _take(self.members, 0)
        lane0 = self.init_lane(member0, _take(self.y0s, 0))

        def lanes(x):
            return jtu.tree_map(lambda a: jnp.broadcast_to(a, (n_lanes,) + jnp.shape(a)), x)

        def outputs(x):
            return jtu.tree_map(lambda a: jnp.full((n_members,) + a.shape, jnp.inf, a.dtype), x)

        count = jnp.int64 if jax.config.jax_enable_x64 else jnp.int32
        queue = _Queue(
            lane=lanes(lane0),
            member=lanes(member0),
            idx=jnp.full(n_lanes, n_members, jnp.int32),  # n_members: no member
            active=jnp.zeros(n_lanes, bool),
            next=jnp.asarray(0, jnp.int32),
            busy=jnp.asarray(0, count),
            lane_steps=jnp.asarray(0, count),
        )
        out = _Outputs(
            ys=integrate.unreached_saves(lane0.y, self.ts.shape[0], (n_members,)),
            y_end=outputs(lane0.y),
            t_end=jnp.full(n_members, jnp.inf, self.t0.dtype),
            result=jnp.full(n_members, _OK, jnp.int32),
            num_steps=jnp.zeros(n_members, jnp.int32),
            num_accepted_steps=jnp.zeros(n_members, jnp.int32),
        )
        return queue, out

    def want_refill(self, q: _Queue):
        # a block of free lanes, or as many as there are members left to start
        left = self.n_members - q.next
        return (left > 0) & (q.active.shape[0] - _n_active(q) >= jnp.minimum(self.block, left))

    def start_block(self, q: _Queue) -> _Queue:
        # the first `block` free lanes take the next members; only those are initialized
        width = q.active.shape[0]
        free = jnp.nonzero(~q.active, size=self.block, fill_value=width)[0]
        j = jnp.arange(self.block, dtype=jnp.int32)
        new_idx = q.next + j
        take = (free < width) & (new_idx < self.n_members)
        src = jnp.where(take, new_idx, 0)
        member = _take(self.members, src)
        fresh = jax.vmap(self.init_lane)(member, _take(self.y0s, src))
        dst = jnp.where(take, free, width)  # width: dropped by the scatter
        return _Queue(
            lane=_scatter_rows(q.lane, dst, fresh),
            member=_scatter_rows(q.member, dst, member),
            idx=q.idx.at[dst].set(new_idx, mode="drop"),
            active=q.active.at[dst].set(True, mode="drop"),
            next=q.next + jnp.sum(take, dtype=jnp.int32),
            busy=q.busy,
            lane_steps=q.lane_steps,
        )

    def step(self, carry: tuple[_Queue, _Outputs]) -> tuple[_Queue, _Outputs]:
        """Every busy lane one attempted step, its saves written; a member that
        finished (reached `t1` or failed) has its results written and frees its lane."""
        q, out = carry
        n_members = self.n_members
        active, old = q.active, q.lane
        new, keep, dense = jax.vmap(self.advance_lane)(old, q.member)
        keep = keep & active
        rows = jnp.where(active, q.idx, n_members)  # n_members: dropped by the scatter
        save_i, ys = integrate.save_dense(
            self.solver,
            dense,
            old.t,
            old.tnext,
            old.tnext,
            keep,
            self.ts,
            new.save_index,
            out.ys,
            rows,
            work=self._work(old, q.member),
        )
        new = eqx.tree_at(lambda x: x.save_index, new, save_i)
        lane = integrate.tree_where(active, new, old)  # idle lanes stay as they are
        code = code_of(lane.result)
        end = active & ((lane.t >= self.t1) | (code != _OK))
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
            lane_steps=q.lane_steps + active.shape[0],
        )
        return q, out

    def keep_wide(self, q: _Queue):
        # the wide loop runs while members are left to start, then (with a tail loop)
        # until no more than `tail` members are unfinished
        return (q.next < self.n_members) | (_n_active(q) > self.tail)

    def wide(self, carry: tuple[_Queue, _Outputs]) -> tuple[_Queue, _Outputs]:
        """Phase 2: step until a refill is due (or the wide phase is over), refill."""

        def stepping(c):
            return self.keep_wide(c[0]) & ~self.want_refill(c[0])

        q, out = jax.lax.while_loop(stepping, self.step, carry)
        q = jax.lax.cond(self.want_refill(q), self.start_block, lambda x: x, q)
        return q, out

    def narrow(self, q: _Queue) -> _Queue:
        """Phase 3: the (at most `tail`) unfinished members gathered onto `tail` lanes."""
        rows = jnp.nonzero(q.active, size=self.tail, fill_value=0)[0]
        return _Queue(
            lane=_gather_rows(q.lane, rows),
            member=_gather_rows(q.member, rows),
            idx=q.idx[rows],
            active=q.active[rows] & (jnp.arange(self.tail) < _n_active(q)),
            next=q.next,
            busy=q.busy,
            lane_steps=q.lane_steps,
        )


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
    *,
    refill: int | None = None,
    tail_lanes: int = 0,
) -> LaneOutput:
    """Solve `y' = f(t, y, (member, extra_args))` for every member on `n_lanes` lanes.

    **Arguments:**

    - `term`, `solver`, `controller`: as for `diffrax.diffeqsolve`.
    - `members`: pytree whose leaves have a leading axis `M` (per-member arguments).
    - `y0s`: pytree of initial states with leading axis `M`.
    - `extra_args`: arguments shared by all members.
    - `t0`, `t1`, `dt0`: the interval, and the first step (`None`: chosen by the
      controller, as in diffrax).
    - `ts`: save times, sorted, inside `[t0, t1]`; may be empty.
    - `n_lanes`: number of members integrated at once.
    - `max_steps`: step budget per member (accepted + rejected).
    - `refill`: members started per refill (default `default_refill`).
    - `tail_lanes`: width of the narrower loop the last members finish on once the
      queue is empty (none when below 2 or not below `n_lanes`).

    **Returns:** a `LaneOutput`.
    """
    n_members = jtu.tree_leaves(y0s)[0].shape[0]
    n_lanes = max(1, min(n_lanes, n_members))
    block = default_refill(n_lanes) if refill is None else max(1, min(refill, n_lanes))
    # (a one-lane loop may round differently from a vectorized one: never narrower than 2)
    tail = tail_lanes if 2 <= tail_lanes < n_lanes else 0
    schedule = _Schedule(
        term,
        solver,
        controller,
        members,
        y0s,
        extra_args,
        t0,
        t1,
        dt0,
        ts,
        max_steps,
        n_members,
        block,
        tail,
    )
    queue, out = schedule.start(n_lanes)
    # phases 1 and 2 (the first refills fill the free lanes before any step)
    q, out = jax.lax.while_loop(lambda c: schedule.keep_wide(c[0]), schedule.wide, (queue, out))
    if tail:  # phase 3: the last (at most `tail`) members finish on `tail` lanes
        q = schedule.narrow(q)
        q, out = jax.lax.while_loop(lambda c: jnp.any(c[0].active), schedule.step, (q, out))
    return LaneOutput(
        ys=out.ys,
        y_end=out.y_end,
        t_end=out.t_end,
        result=out.result,
        num_steps=out.num_steps,
        num_accepted_steps=out.num_accepted_steps,
        num_rejected_steps=out.num_steps - out.num_accepted_steps,
        busy_lane_steps=q.busy,
        lane_steps=q.lane_steps,
    )
