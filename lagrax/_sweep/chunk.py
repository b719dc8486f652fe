"""The compiled chunk of a sweep: members solved on lanes (or in lock-step) on devices."""

from collections.abc import Callable

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np

from .._core.checks import pivot_threshold
from .._core.results import RESULTS, code_of, from_code
from .._solve.lanes import LaneOutput, run_lanes
from .._solve.postprocess import energy_scale, observables, power_of, work_along
from .._solve.simulate import SolveConfig, SolveInputs, solve_from
from .._solve.solution import Solution
from .._systems.vector_field import LagrangianVectorField
from .devices import to_device, to_host

_OK = int(code_of(RESULTS.successful))
_INVALID = int(code_of(RESULTS.invalid_input))
_NOT_PROJECTED = int(code_of(RESULTS.constraint_projection_failed))
_EVENT = int(code_of(RESULTS.event_occurred))


class Setup(eqx.Module):
    """What fixes the compiled chunk function: the solve's configuration (its controller
    always given), the `keep=` reduction, the lane count and the schedule.

    `n_lanes`, `refill` and `tail_lanes` (see `lanes.run_lanes`) change how
    members are scheduled onto lanes, not their steps or values (bitwise, but for a
    single lane's round-off): they are left out of the repr, and so out of a checkpoint's
    fingerprint, so that a sweep resumes on another kind of device, whose default lanes
    differ."""

    config: SolveConfig
    reduce: Callable | None
    n_lanes: int = eqx.field(static=True, repr=False)
    schedule: str = eqx.field(static=True)
    refill: int | None = eqx.field(static=True, default=None, repr=False)
    tail_lanes: int = eqx.field(static=True, default=0, repr=False)


def _lockstep(setup: Setup, members, y0s, tau_const, t0, t1, dt0, ts) -> LaneOutput:
    """Plain `vmap` of `simulate`'s solve: every member steps until the slowest is done."""
    rtol = atol = jnp.asarray(0.0, t0.dtype)  # unused: the controller is always given
    save_ts = ts if ts.shape[0] else t1[None]

    def one(p, y0):
        # y0 is already the system's initial state (solve_chunk formed it and flags the
        # members where it could not be): integrate from it, as the lane queue does
        inputs = SolveInputs(y0, p, tau_const, t0, t1, save_ts, rtol, atol, dt0)
        return solve_from(setup.config, inputs, y0, jnp.asarray(True))

    sol = jax.vmap(one)(members, y0s)
    steps = sol.stats["num_steps"]
    count = first = None
    if sol.events is not None:
        count = jnp.stack([r.count for r in sol.events], axis=1)
        first = jnp.stack([r.times[:, 0] for r in sol.events], axis=1)
    ys = (sol.q, sol.qd) if ts.shape[0] else (sol.q[:, :0], sol.qd[:, :0])
    return LaneOutput(
        ys=ys,
        y_end=(sol.q_end, sol.qd_end),
        t_end=sol.t_end,
        result=code_of(sol.result).astype(jnp.int32),
        num_steps=steps,
        num_accepted_steps=sol.stats["num_accepted_steps"],
        num_rejected_steps=sol.stats["num_rejected_steps"],
        busy_lane_steps=jnp.sum(steps),
        lane_steps=jnp.max(steps) * steps.shape[0],
        event_count=count,
        event_first=first,
    )


def _per_device(setup: Setup, members, y0s, tau_const, t0, t1, dt0, ts):
    if setup.schedule == "lockstep":
        out = _lockstep(setup, members, y0s, tau_const, t0, t1, dt0, ts)
    else:
        c = setup.config
        term = dfx.ODETerm(LagrangianVectorField(c.system, c.tau_fn))
        out = run_lanes(
            term,
            c.solver,
            c.stepsize_controller,
            members,
            y0s,
            tau_const,
            t0,
            t1,
            dt0,
            ts,
            setup.n_lanes,
            c.max_steps,
            refill=setup.refill,
            tail_lanes=setup.tail_lanes,
        )
    # scalars become (1,) so that shards concatenate
    return eqx.tree_at(
        lambda o: (o.busy_lane_steps, o.lane_steps),
        out,
        (out.busy_lane_steps[None], out.lane_steps[None]),
    )


@eqx.filter_jit
def _run_chunk(setup: Setup, mesh, members, y0s, tau_const, t0, t1, dt0, ts):
    """Solve one chunk of members (sharded over `mesh` when given) and post-process it."""
    if mesh is None:
        out = _per_device(setup, members, y0s, tau_const, t0, t1, dt0, ts)
    else:
        spec = jax.sharding.PartitionSpec("batch")
        fn = jax.shard_map(
            lambda m, y: _per_device(setup, m, y, tau_const, t0, t1, dt0, ts),
            mesh=mesh,
            in_specs=(spec, spec),
            out_specs=spec,
            check_vma=False,
        )
        out = fn(members, y0s)
    system = setup.config.system
    field = LagrangianVectorField(system, setup.config.tau_fn)
    # the Jacobi integral h at the saves, the start and the end (see Solution.energy)
    # (with |T| + |V| there, for the scale of energy_error)
    energy = jax.vmap(
        jax.vmap(system.energy_and_magnitude, in_axes=(0, 0, 0, None)), in_axes=(None, 0, 0, 0)
    )
    q, qd = out.ys
    e, mag = energy(ts, q, qd, members) if q.shape[1] else (q[..., 0], q[..., 0])
    e = jnp.where(jnp.isfinite(e), e, jnp.inf)
    q0, qd0 = y0s
    at_start = jax.vmap(system.energy_and_magnitude, in_axes=(None, 0, 0, 0))
    e0, m0 = at_start(t0, q0, qd0, members)
    q_end, qd_end = out.y_end
    e_end, m_end = jax.vmap(system.energy_and_magnitude)(out.t_end, q_end, qd_end, members)
    balance, scale = _energy_balance(
        system,
        field,
        members,
        tau_const,
        t0,
        ts,
        q,
        qd,
        (e, mag),
        (q0, qd0, e0, m0),
        (e_end, m_end),
    )
    # the system's observables at the end state (a constrained system: max |φ(q)| there)
    at_end = jax.vmap(
        lambda t, a, b, p: system.observables(t, a, b, p, field.tau(t, a, b, tau_const))
    )(jnp.minimum(out.t_end, t1), q_end, qd_end, members)
    # max |φ(q)| and max |A(q) q̇| at the end state (each present when the system has them)
    violation = {
        k: jnp.max(jnp.abs(at_end[k]), axis=1)
        for k in ("constraint_violation", "velocity_constraint_violation")
        if k in at_end
    }
    reduced = None
    if setup.reduce is not None:

        def reduce_one(p, i_q, i_qd, i_e, i_m, res, t_end, qe, qde, st, acc, rej):
            stats = dict(
                num_steps=st,
                num_accepted_steps=acc,
                num_rejected_steps=rej,
                max_steps=jnp.asarray(setup.config.max_steps),
            )
            reached = jnp.all(jnp.isfinite(i_q), axis=1)
            i_ts = jnp.where(reached, ts, jnp.inf)
            extras = observables(system, field, p, tau_const, i_ts, i_q, i_qd)
            work = work_along(system, field, p, tau_const, i_ts, i_q, i_qd)
            sol = Solution(
                i_ts,
                i_q,
                i_qd,
                i_e,
                from_code(res),
                stats,
                t_end,
                qe,
                qde,
                **extras,
                work=work,
                energy_scale=energy_scale(i_ts, i_e, i_m),
            )
            return setup.reduce(sol)

        reduced = jax.vmap(reduce_one)(
            members,
            q,
            qd,
            e,
            mag,
            out.result,
            out.t_end,
            q_end,
            qd_end,
            out.num_steps,
            out.num_accepted_steps,
            out.num_rejected_steps,
        )
    return out, e, e0, e_end, reduced, violation, balance, scale


def _energy_balance(system, field, members, tau_const, t0, ts, q, qd, saved, start, end):
    """Per member: the energy balance residual and its scale, as `Solution.energy_error`
    computes them (its numerator and denominator).

    Without inputs, dissipation or time dependence the residual is `h(t_end) − h(t0)`.
    With them it is `h − h₀ − W` over the saves (the first to the last reached one),
    `W` the work integrated along them (`sweep` saves internally for that when
    `keep="final"`); NaN when there are no saves. The scale is
    `max(|h(t0)|, |T| + |V|)` over the start, the saves and the end (`h` and
    `|T| + |V|` given there: `saved`, `start`, `end`)."""
    e, mag = saved
    q0, qd0, e0, m0 = start
    e_end, m_end = end
    first = jtu.tree_map(lambda x: x[0], members)
    has_power = power_of(system, field, first, tau_const, t0, q0[0], qd0[0]) is not None
    scale = jnp.maximum(jnp.abs(e0), m0)
    scale = jnp.maximum(scale, jnp.where(jnp.isfinite(m_end), m_end, 0.0))
    if ts.shape[0]:
        reached = jnp.all(jnp.isfinite(q), axis=2)  # (members, T)
        member_ts = jnp.where(reached, ts, jnp.inf)
        scale = jnp.maximum(scale, jax.vmap(energy_scale)(member_ts, e, mag))
    if not has_power:
        return e_end - e0, scale
    if not ts.shape[0]:
        return jnp.full_like(e0, jnp.nan), scale
    work = jax.vmap(lambda p, s, a, b: work_along(system, field, p, tau_const, s, a, b))(
        members, member_ts, q, qd
    )
    ok = jnp.isfinite(work)
    last = ts.shape[0] - 1 - jnp.argmax(ok[:, ::-1], axis=1)
    pick = lambda x: jnp.take_along_axis(x, last[:, None], axis=1)[:, 0]  # noqa: E731
    return pick(e) - e[:, 0] - pick(work), scale


@eqx.filter_jit
def _initial_states(system, q0s, qd0s, members, t0):
    """Per member: the system's initial state (e.g. projected onto its constraints),
    whether it could be formed, and the mass matrix there (for a positive-definiteness
    check): one compiled program, not two."""
    q0s, qd0s, projected = jax.vmap(system.initial_state)(q0s, qd0s, members)
    mass = jax.vmap(lambda q, qd, p: system.mass_matrix(q, p, qd, t=t0))(q0s, qd0s, members)
    return q0s, qd0s, projected, mass


def solve_chunk(
    setup, mesh, system, members, q0s, qd0s, tau_const, t0, t1, dt0, ts, size, tdt, keep_path=True
):
    """Run one chunk (padded to `size` members so every chunk reuses one compilation).

    `keep_path=False`: the saves at `ts` only serve the energy balance (`keep="final"`
    with inputs, dissipation or time dependence) and are not returned."""
    m = q0s.shape[0]
    members = jtu.tree_map(lambda x: np.asarray(x), members)
    # every process computes the whole chunk's initial states (not sharded: no gather)
    start = _initial_states(
        system,
        jnp.asarray(q0s),
        jnp.asarray(qd0s),
        jtu.tree_map(jnp.asarray, members),
        jnp.asarray(t0, tdt),
    )
    q0s, qd0s, projected, mm = (np.asarray(x) for x in start)
    # per member: finite inputs and a positive-definite mass matrix at the initial state
    fin = np.isfinite(q0s).all(1) & np.isfinite(qd0s).all(1)
    for leaf in jtu.tree_leaves(members):
        fin &= np.isfinite(leaf.reshape(m, -1)).all(1) if leaf.dtype.kind in "fc" else True
    valid = fin.copy()
    if fin.any():
        with np.errstate(invalid="ignore"):
            ok_mm = np.all(np.isfinite(mm.reshape(m, -1)), axis=1)
            eig = np.full((m, mm.shape[-1]), -np.inf)
            eig[ok_mm] = np.linalg.eigvalsh(mm[ok_mm])
            scale = np.maximum(np.abs(eig).max(axis=1), np.finfo(mm.dtype).tiny)
            valid &= ok_mm & (eig[:, 0] > pivot_threshold(mm.dtype) * scale)
    # invalid members are solved as a stand-in (a valid one) and overwritten afterwards
    stand_in = int(np.argmax(valid)) if valid.any() else 0
    src = np.where(valid, np.arange(m), stand_in)
    src = np.concatenate([src, np.full(size - m, src[0] if m else 0)])
    pick = lambda x: np.asarray(x)[src]  # noqa: E731
    members_d = jtu.tree_map(lambda x: to_device(pick(x), mesh), members)
    y0s = (to_device(pick(q0s), mesh), to_device(pick(qd0s), mesh))
    out, e, e0, e_end, reduced, violation, balance, scale = _run_chunk(
        setup,
        mesh,
        members_d,
        y0s,
        tau_const,
        jnp.asarray(t0, tdt),
        jnp.asarray(t1, tdt),
        None if dt0 is None else jnp.asarray(dt0, tdt),
        ts,
    )
    out, e, e0, e_end, reduced, violation, balance, scale = to_host(
        (out, e, e0, e_end, reduced, violation, balance, scale)
    )
    cut = lambda x: x[:m]  # noqa: E731
    q, qd = out.ys
    if not keep_path:
        q, qd, e = q[:, :0], qd[:, :0], e[:, :0]
    q_end, qd_end = out.y_end
    res = cut(out.result).copy()
    res[~projected & ((res == _OK) | (res == _EVENT))] = _NOT_PROJECTED
    res[~valid] = _INVALID
    bad = ~valid

    def blank(x):
        x = cut(x).astype(np.result_type(x.dtype, np.float32), copy=True)
        x[bad] = np.inf
        return x

    chunk = dict(
        q=blank(q),
        qd=blank(qd),
        energy=blank(e),
        energy0=blank(e0),
        energy_end=blank(e_end),
        energy_balance=blank(balance),
        energy_scale=blank(scale),
        q_end=blank(q_end),
        qd_end=blank(qd_end),
        t_end=blank(out.t_end),
        result=res,
        num_steps=np.where(bad, 0, cut(out.num_steps)),
        num_accepted_steps=np.where(bad, 0, cut(out.num_accepted_steps)),
        num_rejected_steps=np.where(bad, 0, cut(out.num_rejected_steps)),
        busy_lane_steps=np.asarray([out.busy_lane_steps.sum()]),
        lane_steps=np.asarray([out.lane_steps.sum()]),
    )
    for k, v in violation.items():
        chunk[k] = blank(v)
    if out.event_count is not None:
        chunk["event_count"] = np.where(np.asarray(bad)[:, None], 0, cut(out.event_count))
        chunk["first_event_time"] = blank(out.event_first)
    if reduced is not None:
        leaves, _ = jtu.tree_flatten_with_path(reduced)
        for path, leaf in leaves:
            chunk["reduce" + jtu.keystr(path)] = blank(np.asarray(leaf))
        chunk["__reduce_paths__"] = np.asarray([jtu.keystr(p) for p, _ in leaves])
    return chunk
