"""The compiled chunk of a sweep: members solved on lanes (or in lock-step) on devices,
then post-processed (`postprocess.summary`, and `postprocess.solution` for a `keep=`
reduction) into a `ChunkResult`.

`solve_chunk` is a chunk's whole run, on the host: the members' initial states and
their validity (`_start`), the compiled program (`_run_chunk`: the solves, `_lockstep`
or `lanes.run_lanes` per device, and the post-processing) and the clean-up of its
output (`_on_host`).
"""

import dataclasses
from collections.abc import Callable
from typing import Any

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np

from .._core.checks import pivot_threshold
from .._core.results import RESULTS, code_of, from_code
from .._solve.integrate import primal_controller
from .._solve.lanes import LaneOutput, run_lanes
from .._solve.postprocess import Summary, WithWork, relative_work, solution, summary
from .._solve.simulate import SolveConfig, SolveInputs, solve_from, work_as_state
from .._systems.vector_field import LagrangianVectorField
from .devices import to_device, to_host
from .observed import observe
from .result import ChunkResult, NamedArrays

_OK = int(code_of(RESULTS.successful))
_INVALID = int(code_of(RESULTS.invalid_input))
_NOT_PROJECTED = int(code_of(RESULTS.constraint_projection_failed))
_EVENT = int(code_of(RESULTS.event_occurred))


class Setup(eqx.Module):
    """What fixes the compiled chunk function: the solve's configuration (its controller
    always given), the `keep=` reduction, the lane count, the schedule, and the
    observables kept (`observed`: their names; `observe_end`: at the end, not the saves).

    `n_lanes`, `refill` and `tail_lanes` (see `lanes.run_lanes`) change how
    members are scheduled onto lanes, not their steps or values (bitwise, but for a
    single lane's round-off): they are left out of the repr, and so out of a checkpoint's
    fingerprint, so that a sweep resumes on another kind of device, whose default lanes
    differ. `observed` and `observe_end` are left out too: the sweep's settings carry
    them (where there are any, so that the fingerprints of sweeps without observables
    stay as they were)."""

    config: SolveConfig
    reduce: Callable | None
    n_lanes: int = eqx.field(static=True, repr=False)
    schedule: str = eqx.field(static=True)
    refill: int | None = eqx.field(static=True, default=None, repr=False)
    tail_lanes: int = eqx.field(static=True, default=0, repr=False)
    observed: tuple[str, ...] = eqx.field(static=True, default=(), repr=False)
    observe_end: bool = eqx.field(static=True, default=False, repr=False)


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
        field = LagrangianVectorField(c.system, c.tau_fn)
        term, controller = dfx.ODETerm(field), c.stepsize_controller
        first = jtu.tree_map(lambda x: x[0], (members, y0s))
        carried = work_as_state(c.solver, field, (first[0], tau_const), t0, first[1])
        if carried:  # the work integrated with the state, as simulate's loop does
            term, controller = dfx.ODETerm(WithWork(field)), primal_controller(controller)
            y0s = (y0s, jnp.zeros(jtu.tree_leaves(y0s)[0].shape[:1], t0.dtype))
        out = run_lanes(
            term,
            c.solver,
            controller,
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
        if carried:
            (ys, work), (y_end, work_end) = out.ys, out.y_end
            out = eqx.tree_at(
                lambda o: (o.ys, o.y_end, o.work, o.work_end),
                out,
                (ys, y_end, work, work_end),
                is_leaf=lambda x: x is None,
            )
    # scalars become (1,) so that shards concatenate
    return eqx.tree_at(
        lambda o: (o.busy_lane_steps, o.lane_steps),
        out,
        (out.busy_lane_steps[None], out.lane_steps[None]),
    )


@eqx.filter_jit
def _run_chunk(setup: Setup, mesh, members, y0s, tau_const, t0, t1, dt0, ts) -> ChunkResult:
    """Solve one chunk of members (sharded over `mesh` when given) and post-process it
    (`postprocess.summary`; `keep=reduce` through `_reduce`): the chunk's
    `ChunkResult` as the devices hold it, padded, before `_on_host`."""
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
    end = (out.t_end, *out.y_end)
    measured = summary(
        system, field, members, tau_const, (t0, t1, ts), y0s, out.ys, end, out.work_end
    )
    reduced = None
    if setup.reduce is not None:
        reduced = _reduce(setup, field, members, tau_const, ts, out, measured)
    observed = observe(setup, field, members, tau_const, ts, t1, out) if setup.observed else None
    (q, qd), (q_end, qd_end), maxima = out.ys, out.y_end, measured.final_maxima
    return ChunkResult(
        q=q,
        qd=qd,
        energy=measured.energy,
        energy0=measured.energy0,
        energy_end=measured.energy_end,
        energy_balance=measured.energy_balance,
        energy_scale=measured.energy_scale,
        q_end=q_end,
        qd_end=qd_end,
        t_end=out.t_end,
        result=out.result,
        num_steps=out.num_steps,
        num_accepted_steps=out.num_accepted_steps,
        num_rejected_steps=out.num_rejected_steps,
        busy_lane_steps=out.busy_lane_steps,
        lane_steps=out.lane_steps,
        final_maxima=NamedArrays(tuple(maxima), tuple(maxima.values())),
        event_count=out.event_count,
        first_event_time=out.event_first,
        reduced=reduced,
        observed=observed,
    )


def _reduce(setup: Setup, field, members, tau_const, ts, out: LaneOutput, measured: Summary):
    """`keep=reduce` inside the compiled chunk: each member's
    [`Solution`][lagrax.Solution] at the saves (`postprocess.solution`, as `simulate`
    makes it) through the user's `reduce`; its outputs as `NamedArrays`, one per leaf,
    named by the leaf's path (`jax.tree_util.keystr`)."""
    system = setup.config.system

    def one(p, i_q, i_qd, i_e, i_m, res, t_end, qe, qde, st, acc, rej, w):
        stats = dict(
            num_steps=st,
            num_accepted_steps=acc,
            num_rejected_steps=rej,
            max_steps=jnp.asarray(setup.config.max_steps),
        )
        reached = jnp.all(jnp.isfinite(i_q), axis=1)
        i_ts = jnp.where(reached, ts, jnp.inf)
        saves, end = (i_ts, i_q, i_qd), (t_end, qe, qde)
        work = None if w is None else relative_work(i_ts, w)
        sol = solution(
            system, field, (p, tau_const), saves, (i_e, i_m), end, from_code(res), stats, None, work
        )
        return setup.reduce(sol)

    (q, qd), (q_end, qd_end) = out.ys, out.y_end
    reduced = jax.vmap(one)(
        members,
        q,
        qd,
        measured.energy,
        measured.magnitude,
        out.result,
        out.t_end,
        q_end,
        qd_end,
        out.num_steps,
        out.num_accepted_steps,
        out.num_rejected_steps,
        out.work,
    )
    leaves, _ = jtu.tree_flatten_with_path(reduced)
    return NamedArrays(tuple(jtu.keystr(p) for p, _ in leaves), tuple(x for _, x in leaves))


@eqx.filter_jit
def _initial_states(system, q0s, qd0s, members, t0):
    """Per member: the system's initial state (e.g. projected onto its constraints),
    whether it could be formed, and the mass matrix there (for a positive-definiteness
    check): one compiled program, not two."""
    q0s, qd0s, projected = jax.vmap(system.initial_state)(q0s, qd0s, members)
    mass = jax.vmap(lambda q, qd, p: system.mass_matrix(q, p, qd, t=t0))(q0s, qd0s, members)
    return q0s, qd0s, projected, mass


@dataclasses.dataclass(frozen=True)
class ChunkSpec:
    """What every chunk of a sweep shares: the compiled `setup`, the device `mesh`
    (`None`: one device), the constant input `tau_const` (or `None`), the interval
    `t0`, `t1`, the first step `dt0` (or `None`), the save times `ts` (a device array,
    maybe empty), the padded chunk `size`, the time `dtype`, and `keep_path`: whether
    the saves are kept (`False` when they only serve the energy balance, with
    `keep="final"` and inputs, dissipation or time dependence)."""

    setup: Setup
    mesh: Any
    tau_const: Any
    t0: float
    t1: float
    dt0: float | None
    ts: Any
    size: int
    dtype: Any
    keep_path: bool = True


def solve_chunk(spec: ChunkSpec, members, q0s, qd0s) -> ChunkResult:
    """Run one chunk of members (parameters `members`, initial states `q0s`, `qd0s`,
    each with a leading member axis), padded to `spec.size` members so that every
    chunk reuses one compilation.

    Members whose input is invalid (non-finite, or a mass matrix that is not
    positive-definite at the initial state) are solved as a stand-in (a valid member)
    and blanked afterwards.

    **Returns:** the chunk's `ChunkResult` on the host (see `_on_host`).
    """
    m = q0s.shape[0]
    members = jtu.tree_map(lambda x: np.asarray(x), members)
    system = spec.setup.config.system
    q0s, qd0s, projected, valid = _start(system, members, q0s, qd0s, spec.t0, spec.dtype)
    # invalid members are solved as a stand-in (a valid one) and overwritten afterwards
    stand_in = int(np.argmax(valid)) if valid.any() else 0
    src = np.where(valid, np.arange(m), stand_in)
    src = np.concatenate([src, np.full(spec.size - m, src[0] if m else 0)])
    pick = lambda x: np.asarray(x)[src]  # noqa: E731
    members_d = jtu.tree_map(lambda x: to_device(pick(x), spec.mesh), members)
    y0s = (to_device(pick(q0s), spec.mesh), to_device(pick(qd0s), spec.mesh))
    raw = _run_chunk(
        spec.setup,
        spec.mesh,
        members_d,
        y0s,
        spec.tau_const,
        jnp.asarray(spec.t0, spec.dtype),
        jnp.asarray(spec.t1, spec.dtype),
        None if spec.dt0 is None else jnp.asarray(spec.dt0, spec.dtype),
        spec.ts,
    )
    return _on_host(to_host(raw), m, valid, projected, spec.keep_path)


def _start(system, members, q0s, qd0s, t0, dtype):
    """Per member, on the host: `(q0, q̇0, projected, valid)`, the state its solve
    starts from, whether it could be formed (`AbstractSystem.initial_state`), and whether
    the member's input is valid: finite parameters and state, and a finite mass matrix
    there, positive-definite beyond `pivot_threshold`. Every process computes the whole
    chunk's (not sharded: no gather)."""
    m = q0s.shape[0]
    start = _initial_states(
        system,
        jnp.asarray(q0s),
        jnp.asarray(qd0s),
        jtu.tree_map(jnp.asarray, members),
        jnp.asarray(t0, dtype),
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
    return q0s, qd0s, projected, valid


def _on_host(raw: ChunkResult, m: int, valid, projected, keep_path: bool) -> ChunkResult:
    """The chunk's `m` members of `raw` (the padding cut): an invalid member's values
    `inf`, its counters `0` and its result `RESULTS.invalid_input`; a member whose
    initial state could not be formed `RESULTS.constraint_projection_failed`; the lane
    counters summed over the devices; and without `keep_path`, no saves."""
    bad = ~valid

    def blank(x):
        x = np.asarray(x)[:m].astype(np.result_type(x.dtype, np.float32), copy=True)
        x[bad] = np.inf
        return x

    def counted(x):
        return np.where(bad, 0, x[:m])

    res = raw.result[:m].copy()
    res[~projected & ((res == _OK) | (res == _EVENT))] = _NOT_PROJECTED
    res[bad] = _INVALID
    q, qd, e = raw.q, raw.qd, raw.energy
    if not keep_path:
        q, qd, e = q[:, :0], qd[:, :0], e[:, :0]
    events = raw.event_count is not None
    return ChunkResult(
        q=blank(q),
        qd=blank(qd),
        energy=blank(e),
        energy0=blank(raw.energy0),
        energy_end=blank(raw.energy_end),
        energy_balance=blank(raw.energy_balance),
        energy_scale=blank(raw.energy_scale),
        q_end=blank(raw.q_end),
        qd_end=blank(raw.qd_end),
        t_end=blank(raw.t_end),
        result=res,
        num_steps=counted(raw.num_steps),
        num_accepted_steps=counted(raw.num_accepted_steps),
        num_rejected_steps=counted(raw.num_rejected_steps),
        busy_lane_steps=np.asarray([raw.busy_lane_steps.sum()]),
        lane_steps=np.asarray([raw.lane_steps.sum()]),
        final_maxima=jtu.tree_map(blank, raw.final_maxima),
        event_count=np.where(bad[:, None], 0, raw.event_count[:m]) if events else None,
        first_event_time=blank(raw.first_event_time) if events else None,
        reduced=None if raw.reduced is None else jtu.tree_map(blank, raw.reduced),
        observed=None if raw.observed is None else jtu.tree_map(blank, raw.observed),
    )
