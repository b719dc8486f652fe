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

The stepping is diffrax's own, through ``_integrate.step`` (shared with ``simulate``'s
single-trajectory loop): ``solver.step``, ``stepsize_controller.adapt_step_size``, the
same clipping to ``t1`` and the same dense output at the save times, so each member takes
the steps ``diffeqsolve`` would take for it (up to round-off in the controller).
"""

from typing import Any

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu

from . import _integrate
from ._results import RESULTS

_OK = int(RESULTS.successful._value)
_MAX_STEPS = int(RESULTS.max_steps_reached._value)
_NON_FINITE = int(RESULTS.non_finite_state._value)


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

    def args_of(member):
        return (member, extra_args)

    def init_lane(member, y0):
        return _integrate.init(term, solver, controller, t0, t1, y0, dt0, args_of(member))

    def step_lane(t, tnext, y, member, sstate, cstate):
        keep, tprev, tnew, y_next, sstate, cstate, res, dense = _integrate.step(
            term, solver, controller, t, tnext, y, args_of(member), sstate, cstate, t1
        )
        return keep, tprev, tnew, y_next, sstate, cstate, res._value, dense

    # A template lane (member 0) fixes the shapes of the per-lane state.
    member0 = _take(members, 0)
    y00 = _take(y0s, 0)
    tnext0, sstate0, cstate0 = init_lane(member0, y00)

    def lanes(x):
        return jtu.tree_map(lambda a: jnp.broadcast_to(a, (n_lanes,) + jnp.shape(a)), x)

    def outputs(x, extra=()):
        return jtu.tree_map(lambda a: jnp.full((n_members,) + extra + a.shape, jnp.inf, a.dtype), x)

    zeros_i = jnp.zeros(n_lanes, jnp.int32)
    state = dict(
        idx=jnp.full(n_lanes, n_members, jnp.int32),  # n_members: no member
        active=jnp.zeros(n_lanes, bool),
        t=jnp.full(n_lanes, t0, tdt),
        tnext=lanes(tnext0),
        y=lanes(y00),
        member=lanes(member0),
        sstate=lanes(sstate0),
        cstate=lanes(cstate0),
        steps=zeros_i,
        accepted=zeros_i,
        save_i=zeros_i,
        next=jnp.asarray(0, jnp.int32),
        busy=jnp.asarray(0, jnp.int64 if jax.config.jax_enable_x64 else jnp.int32),
        iters=jnp.asarray(0, jnp.int64 if jax.config.jax_enable_x64 else jnp.int32),
        out_ys=outputs(y00, (n_save,)),
        out_y_end=outputs(y00),
        out_t_end=jnp.full(n_members, jnp.inf, tdt),
        out_result=jnp.full(n_members, _OK, jnp.int32),
        out_steps=jnp.zeros(n_members, jnp.int32),
        out_accepted=jnp.zeros(n_members, jnp.int32),
    )

    def refill(s):
        idle = ~s["active"]
        rank = jnp.cumsum(idle, dtype=jnp.int32) - 1
        new_idx = s["next"] + rank
        take = idle & (new_idx < n_members)
        src = jnp.where(take, new_idx, 0)
        member = _take(members, src)
        y0 = _take(y0s, src)
        tnext, sstate, cstate = jax.vmap(init_lane)(member, y0)
        s = dict(s)
        s["idx"] = jnp.where(take, new_idx, s["idx"])
        s["active"] = s["active"] | take
        s["t"] = jnp.where(take, t0, s["t"])
        s["tnext"] = jnp.where(take, tnext, s["tnext"])
        s["y"] = _where(take, y0, s["y"])
        s["member"] = _where(take, member, s["member"])
        s["sstate"] = _where(take, sstate, s["sstate"])
        s["cstate"] = _where(take, cstate, s["cstate"])
        s["steps"] = jnp.where(take, 0, s["steps"])
        s["accepted"] = jnp.where(take, 0, s["accepted"])
        s["save_i"] = jnp.where(take, 0, s["save_i"])
        s["next"] = s["next"] + jnp.sum(take, dtype=jnp.int32)
        return s

    def want_refill(s):
        n_idle = n_lanes - jnp.sum(s["active"])
        return (s["next"] < n_members) & ((n_idle >= refill_at) | (n_idle == n_lanes))

    def body(s):
        s = jax.lax.cond(want_refill(s), refill, lambda x: x, s)
        active = s["active"]
        t, tnext = s["t"], s["tnext"]
        keep, tprev, tnew, y_next, sstate, cstate, res, dense = jax.vmap(step_lane)(
            t, tnext, s["y"], s["member"], s["sstate"], s["cstate"]
        )
        keep = keep & active
        rows = jnp.where(active, s["idx"], n_members)  # n_members: dropped by the scatter

        out_ys, save_i = s["out_ys"], s["save_i"]
        if n_save:
            # dense output at the save times inside the accepted step [t, tnext]
            def interp(dense_i, ta, tb, tt):
                return solver.interpolation_cls(t0=ta, t1=tb, **dense_i).evaluate(tt)

            def pending(carry):
                _, i = carry
                return keep & (i < n_save) & (ts[jnp.minimum(i, n_save - 1)] <= tnext)

            def save_cond(carry):
                return jnp.any(pending(carry))

            def save_body(carry):
                out, i = carry
                go = pending(carry)
                ic = jnp.minimum(i, n_save - 1)
                y_t = jax.vmap(interp)(dense, t, tnext, ts[ic])
                r = jnp.where(go, rows, n_members)
                out = jtu.tree_map(lambda o, v: o.at[r, ic].set(v, mode="drop"), out, y_t)
                return out, jnp.where(go, i + 1, i)

            out_ys, save_i = jax.lax.while_loop(save_cond, save_body, (out_ys, save_i))

        steps = s["steps"] + active
        accepted = s["accepted"] + keep
        t_new = jnp.where(active, tprev, t)
        y_new = _where(active, y_next, s["y"])
        finite = jnp.all(
            jnp.stack([jnp.all(jnp.isfinite(v.reshape(n_lanes, -1)), axis=1)
                       for v in jtu.tree_leaves(y_new)]), axis=0
        )  # fmt: skip
        reached = t_new >= t1
        result = jnp.where(res != _OK, res, _OK)
        result = jnp.where(~finite, _NON_FINITE, result)
        result = jnp.where((steps >= max_steps) & ~reached & (result == _OK), _MAX_STEPS, result)
        end = active & (reached | (result != _OK))
        end_rows = jnp.where(end, rows, n_members)

        s = dict(s)
        s["out_ys"] = out_ys
        s["out_y_end"] = _scatter(s["out_y_end"], end_rows, y_new)
        s["out_t_end"] = s["out_t_end"].at[end_rows].set(t_new, mode="drop")
        s["out_result"] = s["out_result"].at[end_rows].set(result, mode="drop")
        s["out_steps"] = s["out_steps"].at[end_rows].set(steps, mode="drop")
        s["out_accepted"] = s["out_accepted"].at[end_rows].set(accepted, mode="drop")
        s["t"], s["tnext"], s["y"] = t_new, jnp.where(active, tnew, tnext), y_new
        s["sstate"] = _where(active, sstate, s["sstate"])
        s["cstate"] = _where(active, cstate, s["cstate"])
        s["steps"], s["accepted"], s["save_i"] = steps, accepted, save_i
        s["active"] = active & ~end
        s["busy"] = s["busy"] + jnp.sum(active)
        s["iters"] = s["iters"] + 1
        return s

    def cond(s):
        return jnp.any(s["active"]) | (s["next"] < n_members)

    s = jax.lax.while_loop(cond, body, state)
    return LaneOutput(
        ys=s["out_ys"],
        y_end=s["out_y_end"],
        t_end=s["out_t_end"],
        result=s["out_result"],
        num_steps=s["out_steps"],
        num_accepted_steps=s["out_accepted"],
        num_rejected_steps=s["out_steps"] - s["out_accepted"],
        busy_lane_steps=s["busy"],
        lane_steps=s["iters"] * n_lanes,
    )
