"""`sweep`: many trajectories, chunk by chunk, with checkpoints and progress.

`sweep` in named steps: its options checked (`options.sweep_options`), the members
(`grid.Members`), what to keep (`options.what_to_keep`), the solve's configuration
(`_solve_config`), the cut into chunks and lanes for the devices (`_cut`), the
checkpoint (`checkpoint.prepare`), the chunks (`_run`: `chunk.solve_chunk`, each a
`ChunkResult`, written to the checkpoint) and the Dataset (`dataset.dataset`).
"""

import concurrent.futures
import dataclasses
import functools
import itertools
import math
import os
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import diffrax as dfx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np

from .._core.checks import is_namedtuple
from .._core.errors import ArgumentTypeError, ConfigurationError
from .._solve.events import as_events, check_events
from .._solve.methods import configure
from .._solve.postprocess import power_of
from .._solve.simulate import SolveConfig, events_supported
from .._solve.solution import Solution
from .._systems.abstract import AbstractSystem, host_state
from .._systems.vector_field import LagrangianVectorField, split_tau
from .checkpoint import chunk_path, fingerprint, prepare, stored_chunk_size, write_chunk
from .chunk import ChunkSpec, Setup, solve_chunk
from .cluster import client_option, cluster_threads, run_on_cluster
from .dataset import dataset
from .defaults import DeviceInfo, Plan, device_info, lane_bytes, plan
from .devices import device_list, mesh_of
from .grid import Grid, Members
from .observed import observables_option
from .options import Kept, lanes_option, sweep_options, what_to_keep
from .progress import progress_bar, progress_default
from .result import ChunkResult
from .store import SweepStore
from .unused import refuse_unused


def sweep(
    system: AbstractSystem,
    q0: Any,
    qd0: Any,
    params: Any,
    *,
    t1: float,
    t0: float = 0.0,
    keep: str | Sequence[float] | np.ndarray | Callable[[Solution], Any] = "final",
    n_save: int = 101,
    tau: Any = None,
    solver: str | dfx.AbstractSolver | None = None,
    rtol: float = 1e-8,
    atol: float = 1e-8,
    dt: float | None = None,
    dt0: float | None = None,
    max_steps: int | None = None,
    stepsize_controller: dfx.AbstractStepSizeController | None = None,
    chunk_size: int | None = None,
    n_lanes: int | None = None,
    schedule: str = "queue",
    devices: Any = None,
    checkpoint: str | os.PathLike | None = None,
    store: str | os.PathLike | None = None,
    client: Any = None,
    progress: bool | None = None,
    allow_unused: bool = False,
    events: Any = None,
    observables: bool | str | Sequence[str] | None = None,
):
    """Simulate `system` for many parameter sets (and initial states) at once.

    Each member is the solve `simulate(system, q0[i], qd0[i], params[i], t1=t1, ...)`;
    the arguments come in `simulate`'s order.
    The batch is cut into chunks (bounding memory; the unit of progress and of
    checkpoints); each chunk is one compiled call, sharded over `devices`. Inside a
    chunk, members are integrated on `n_lanes` vectorized lanes as a work queue: a lane
    whose member is done takes the next member, so fast members do not wait for slow ones
    (`schedule="queue"`). How many of each is chosen for the device (a CPU, a GPU or a
    TPU: see `chunk_size` and `n_lanes`), and does not change any member's numbers. On
    a CPU, chunks run on every core at once, one chunk a core (a compiled chunk runs on
    one core), so the batch is cut into a multiple of the cores' count of equal chunks.
    `schedule="lockstep"` is a plain `vmap` of `simulate` instead (each member the same
    solve as `simulate`'s, to the batched operations' round-off, but every member of a
    chunk steps until the slowest is done; a stiff contact can turn that round-off into
    other accepted steps, within the tolerances).

    A member that fails (step budget, blow-up, invalid input) is flagged in the result's
    `ok` / `result` / `status` and never stops the sweep; its values past the failure
    are `inf`, as in `Solution`.

    **Arguments:**

    - `system`: a `LagrangianSystem`, or a `ConstrainedSystem` (each
      member's initial state is first projected onto its constraints, as in
      `simulate`; the result then also has `constraint_violation`, `max |φ(q)|` at
      the end, and with velocity constraints `velocity_constraint_violation`,
      `max |A(q) q̇|` at the end).
    - `q0`, `qd0`: initial state, `(n,)` for all members, or one per member
      (`(members, n)`, or the grid's shape + `(n,)`).
    - `params`: a `Grid` from `grid` / `samples`, or a pytree whose
      every leaf has a leading batch axis (one entry per member).
    - `t1`, `t0`: time interval (shared).
    - `keep`: what to keep per member: `"final"` (the state at `t1`; default),
      `"trajectory"` (`n_save` evenly spaced times), an array of times, or a function
      `reduce(solution) -> pytree of arrays` applied to each member's
      `Solution` (saved at `n_save` times) inside the compiled call, so only its
      output is kept, e.g. `lambda s: jnp.max(jnp.abs(s.energy_error))`.
    - `tau`, `solver`, `rtol`, `atol`, `dt`, `dt0`, `max_steps`,
      `stepsize_controller`: as for `lagrax.simulate` (shared by all members).
    - `chunk_size`: members per compiled call. Default, from the device: on a CPU, up
      to 8,192 (fewer when the kept output is large: about 64 MiB of it per chunk, and
      so that every core this process may use gets a chunk); on a
      GPU or TPU, four members a lane (the whole batch when it is smaller), within half
      the device's memory.
    - `n_lanes`: members integrated at once inside a chunk, per device. Default, from
      the device: on a CPU, 16 per device (fewer for a smaller chunk);
      on a GPU or TPU, enough to fill it: as many as there are members, up to 131,072,
      fewer for a model whose lanes would not fit in a quarter of the device's memory.
      The result's `attrs` say what was chosen (`chunk_size`, `n_lanes`, and
      `threads`: the chunks that ran at once); to
      override, pass `chunk_size=` and/or `n_lanes=` (e.g. `n_lanes=4096` to try
      fewer lanes on a small GPU, or a CPU's smaller lanes on a GPU shared with other
      work).
    - `schedule`: `"queue"` (default) or `"lockstep"`, see above.
    - `devices`: devices to shard the batch over: `None` (all of `jax.devices()`),
      a count, or a list. On a multi-host run (after `jax.distributed.initialize()`)
      every process makes the same call; each gets the whole result.
    - `checkpoint`: a directory. Each finished chunk is written there atomically, with
      the sweep's fingerprint (a SHA-256 of the model, parameters, states, solver
      settings and `keep`) and a SHA-256 checksum of its arrays; the same call again
      resumes, computing only what is missing. A chunk file that cannot be trusted
      (unreadable, truncated, empty, a checksum or index that does not match, an older
      format) is never loaded: a `lagrax.CheckpointWarning` names it and why, and
      its members are computed again. A directory of a different sweep definition
      (by its `manifest.json`, or without one by its chunk files) is refused.
    - `store`: a zarr store path (e.g. `"study.zarr"`; needs `lagrax[zarr]`): the
      result is written there chunk by chunk as each finishes, and returned opened
      lazily (dask-backed; see `open_sweep`), so memory is bounded by a chunk, not by
      the sweep. The store is also the sweep's checkpoint, with the guarantees of
      `checkpoint=` (fingerprint, a SHA-256 per chunk written after its data, resume,
      a damaged chunk recomputed with a warning, another sweep's store or an
      unwritable path refused before any work); give one of `store` and `checkpoint`.
    - `client`: a `dask.distributed.Client` (needs `lagrax[cluster]`): the chunks run
      as tasks on its workers (each compiles the chunk program once, on its own
      device), and come back to this process as they finish, to be written into the
      `store` (or `checkpoint`) or assembled in memory. A lost worker loses nothing:
      Dask runs its tasks again elsewhere, and a chunk is written once, by its index, so
      the result equals an uninterrupted local run. Not with `devices=`.
    - `progress`: show a progress bar (tqdm; members/s). Default: on in a terminal or
      notebook, off otherwise.
    - `events`: a `lagrax.Event` or a sequence of them, as for
      `lagrax.simulate`. Each member's events are located as in `simulate` (a
      terminal event ends that member at its root; its `ok` stays true); the result
      gains `event_count` and `first_event_time` (dimensions: the members' and
      `"event"`; `inf` where an event did not occur). A sweep with events runs
      `schedule="lockstep"` (the lane queue has no event handling).
    - `observables`: the system's observables to keep, as `simulate`'s `Solution` has
      them: `True` (all), a name or names, e.g. a `ContactSystem`'s
      `("contact_gap", "contact_force")`. Each becomes a variable at the kept times (at
      the end with `keep="final"`), its own dimensions named by the system (`"contact"`,
      `"axis"`; see `AbstractSystem.observable_dims`). Not with a `keep=` reduction.
    - `allow_unused`: sweep parameters that nothing the solve evaluates reads (energies,
      force, `tau`, constraints, initial-state projection); by default that is an error,
      since a misspelt grid name would otherwise sweep nothing. The test is structural
      (the traced data flow, whichever branch a member takes).

    **Returns:** an `xarray.Dataset` with dimensions the grid's (or `"member"`),
    `"time"` (when kept) and `"dof"` (labelled by the system's `coordinate_names`
    where it has them, e.g. a URDF robot's joint names; else `0 … n−1`), and, where
    `q` and `qd` differ in size (a floating base: `7 + n` and `6 + n`), `"q_dof"` for
    `q` (labelled by `configuration_names`: `base_x … base_qw`, then the joints) while
    `qd` keeps `"dof"` (`base_vx … base_wz`, then the joints); variables
    `q`, `qd`, `energy` (at the kept times, or at `t1` for `keep="final"`; the
    Jacobi integral `h`, see `Solution.energy`), `energy_error` (at the end, as
    `Solution.energy_error`: the balance residual `h − h₀ − W` over the scale
    `max(|h₀|, |T| + |V|)`, where `W` is the work of the explicit time dependence,
    inputs, applied force and dissipation, integrated along the saves; with
    `keep="final"` such a system is saved at `n_save` times for it, which are then
    dropped; with `keep=` times the balance is over the first to the last of them),
    `energy_change` (`h(t_end) − h(t0)`, the change itself), `ok`, `result`
    (code of `lagrax.RESULTS`), `status` (its message), `t_end`, `num_steps`,
    `num_accepted_steps`, `num_rejected_steps` (or the outputs of `reduce`); swept
    parameters and state components as coordinates (with the grid's `units` as their
    `attrs["units"]`; `time` and `t_end` in `s`); `attrs` with the failure
    count, how the batch was cut (`platform`, `chunk_size`, `n_lanes`, and the
    queue's `refill_lanes` and `tail_lanes`) and the share of lane-steps that were
    idle (`lane_idle_fraction`).
    Save it with `save_sweep`.

    **Raises:**

    - `ConfigurationError`: an option with an unusable value (`t1 <= t0`, a
      non-finite time, `dt`/`dt0 <= 0`, negative tolerances or both zero with an
      adaptive step, `chunk_size`/`n_lanes`/`max_steps`/`n_save` not a positive
      integer, `n_lanes` above the members of a chunk per device, an unknown `keep`
      or `schedule` name, a device count JAX does not have), or a swept parameter that
      nothing reads (see `allow_unused`).
    - `ArgumentTypeError`: an option or argument of the wrong kind (a string where a
      number goes, a non-numeric parameter, a `client` that is not a Dask client, ...).
    - `ShapeError`: batched `params` without members, with scalar leaves or leading
      axes that disagree; states of the wrong shape.
    - `CheckpointError`: `checkpoint` (or `store`) is a file, cannot be written
      (raised before any chunk is computed), or holds another sweep's results or
      another format's (a store: also a directory that is not a lagrax sweep store).

    **Example:**

    ```python
    system, params = lagrax.models.planar_2r()
    batch = lagrax.grid(params, m2=np.linspace(0.5, 2, 32), l1=np.linspace(0.5, 1.5, 32))
    ds = lagrax.sweep(system, [0.5, 0.8], [0.0, 0.0], batch, t1=10.0)
    ds.q.sel(dof=1).plot()   # final θ2 over the (m2, l1) grid

    # an amplitude study: the initial θ1 swept, the rest of the state from q0, qd0
    amps = lagrax.grid(params, q0_0=np.linspace(-3.0, 3.0, 61), units={"q0_0": "rad"})
    ds = lagrax.sweep(system, [0.0, 0.0], [0.0, 0.0], amps, t1=2.0)
    ds.q.sel(dof=0).plot()   # final θ1 against the initial θ1
    ```
    """
    system, q0, qd0, params = _argument_order(system, q0, qd0, params)
    # every scalar option, on the host, before anything is traced or written
    t0, t1, chunk_size = sweep_options(
        t0=t0,
        t1=t1,
        keep=keep,
        n_save=n_save,
        rtol=rtol,
        atol=atol,
        dt=dt,
        dt0=dt0,
        max_steps=max_steps,
        stepsize_controller=stepsize_controller,
        chunk_size=chunk_size,
        schedule=schedule,
        devices=devices,
        checkpoint=checkpoint,
        progress=progress,
    )
    members = Members.of(params, q0, qd0)
    q0s, qd0s, dtype = members.q0s, members.qd0s, members.q0s.dtype
    # one member through the eager checks of a single trajectory: shapes, params, tau
    _, qd_probe = host_state(system, q0s[0], qd0s[0])
    tdt = jnp.asarray(0.0, dtype).dtype
    tau_fn, tau_const = split_tau(system, tau, qd_probe)  # (one force per velocity)
    if not allow_unused:
        refuse_unused(system, tau_fn, tau_const, members)
    final = isinstance(keep, str) and keep == "final"
    balance = final and _has_power(system, tau_fn, tau_const, members, t0)
    probe = (t0, q0s[0], qd0s[0], members.first(), tau_const)
    observed = observables_option(system, tau_fn, probe, observables, keep)
    kept = dataclasses.replace(what_to_keep(keep, n_save, t0, t1, balance), observed=observed)
    method = (solver, rtol, atol, dt, dt0, max_steps, stepsize_controller)
    config, dt0_ = _solve_config(system, tau_fn, method, (t0, t1, tdt), events)
    if config.events is not None:
        check_events(config.events, jnp.asarray(t0, tdt), q0s[0], qd0s[0], members.first())
        schedule = "lockstep"  # the lane queue has no event handling
    # --- chunks and devices: defaults from the device (see defaults)
    where = (devices, client, checkpoint, store)
    info, cut, runner, (ckpt, sink) = _placement(where, members, kept, chunk_size, n_lanes)
    names = tuple(n for n, _ in observed)
    setup = Setup(config, kept.reduce, cut.n_lanes, schedule, cut.refill, cut.tail_lanes, names)
    setup = dataclasses.replace(setup, observe_end=bool(names) and kept.mode == "final")
    times = (t0, t1, dt0_, jnp.asarray(kept.ts, tdt))
    spec = ChunkSpec(setup, mesh_of(devices), tau_const, *times, cut.chunk_size, tdt, kept.path)
    # --- checkpoint: what defines the results (the fingerprint), and what is on disk
    settings = _settings(t0, t1, kept, dt0_, members, keep, tau_const)
    defined = [members.params_of(), q0s, qd0s]
    fp = "" if ckpt is None and sink is None else fingerprint(setup, defined, settings)
    run = _how_it_ran(config, rtol, atol, settings, schedule, info, cut)
    return _collect(system, runner, spec, (members, kept, cut), (ckpt, sink, fp), run, progress)


def _placement(where: tuple, members: Members, kept: Kept, chunk_size, n_lanes) -> tuple:
    """`(info, cut, runner, (checkpoint, store))`: the devices (or the Dask cluster's
    worker threads), how the batch is cut into chunks and lanes (a resumed sweep keeps
    the chunks on disk), and the function that runs the chunks."""
    devices, client, checkpoint, store = where
    info = device_info(device_list(devices))
    lanes = lanes_option(n_lanes, chunk_size, info.count)
    ckpt = Path(checkpoint) if checkpoint is not None else None
    sink = _store_option(store, checkpoint)
    client = client_option(client, devices)
    if client is not None:  # chunks run at once: one per worker thread
        info = dataclasses.replace(info, threads=cluster_threads(client))
    if chunk_size is None and ckpt is not None:
        chunk_size = stored_chunk_size(ckpt)  # resume with the chunks on disk
    if chunk_size is None and sink is not None:
        chunk_size = sink.stored_chunk_size()
    cut = _cut(info, members, kept, chunk_size, lanes)
    if client is None:
        runner = functools.partial(_run, threads=cut.threads)
    else:
        runner = functools.partial(run_on_cluster, client)
    return info, cut, runner, (ckpt, sink)


def _collect(system, runner, spec, batch: tuple, storage: tuple, run: dict, progress):
    """Run the chunks and gather the result: written to the zarr store (which is the
    checkpoint, the result staying on disk), or in memory, resuming from and writing to
    the checkpoint directory when there is one."""
    members, kept, cut = batch
    ckpt, sink, fp = storage
    q0s, qd0s = members.q0s, members.qd0s
    n_chunks = -(-members.size // cut.chunk_size)
    dof = dof_labels(system.coordinate_names, qd0s.shape[1])
    q_dof = (
        None
        if q0s.shape[1] == qd0s.shape[1]
        else dof_labels(system.configuration_names, q0s.shape[1])
    )
    if sink is not None:  # the store is the checkpoint; the result stays on disk
        done = sink.prepare(fp, cut.chunk_size, members, n_chunks, dof, q_dof)
        runner(spec, members, dict.fromkeys(done), lambda c, r: sink.write(c, r, kept), progress)
        return sink.finish(run)
    loaded: dict[int, ChunkResult | None] = {}
    save = None
    if ckpt is not None:
        loaded.update(prepare(ckpt, fp, cut.chunk_size, members.size, n_chunks))
        save = _chunk_file_writer(ckpt, fp, cut.chunk_size, members.size)
    chunks = runner(spec, members, loaded, save, progress, collect=True)
    return dataset(chunks, members, kept, dof=dof, attrs=run, q_dof=q_dof)


def _store_option(store, checkpoint) -> SweepStore | None:
    """The sweep's zarr store (`store=`), checked: a path, and not given with
    `checkpoint=` (the store is the checkpoint)."""
    if store is None:
        return None
    if not isinstance(store, str | os.PathLike):
        raise ArgumentTypeError(
            f"store must be a zarr store path (str or os.PathLike) or None; got "
            f"{type(store).__name__}: {store!r}"
        )
    if checkpoint is not None:
        raise ConfigurationError(
            f"pass store={str(store)!r} or checkpoint={str(checkpoint)!r}, not both: a sweep "
            "store is its own checkpoint (the same call resumes from it)"
        )
    return SweepStore(store)


def _chunk_file_writer(directory: Path, fp: str, size: int, n_members: int):
    """A chunk's writer into a checkpoint directory (`checkpoint.write_chunk`)."""

    def save(c: int, chunk: ChunkResult) -> None:
        a, b = c * size, min((c + 1) * size, n_members)
        identity = dict(fingerprint=fp, chunk_size=size, chunk=c, start=a, stop=b)
        write_chunk(chunk_path(directory, c), chunk, **identity)

    return save


def _settings(t0, t1, kept: Kept, dt0, members: Members, keep, tau_const) -> dict[str, Any]:
    """The scalar settings that define a sweep's results beside its setup and arrays
    (part of its checkpoint fingerprint)."""
    return dict(
        t0=float(t0),
        t1=float(t1),
        ts=kept.ts.tolist(),
        dt0=dt0,
        n=members.q0s.shape[1],
        n_members=members.size,
        keep=keep if isinstance(keep, str) else None,
        dtype=str(members.q0s.dtype),
        tau=None if tau_const is None else np.asarray(tau_const).tolist(),
        **({"observables": list(kept.observed)} if kept.observed else {}),
    )


def _how_it_ran(config: SolveConfig, rtol, atol, settings, schedule, info, cut) -> dict[str, Any]:
    """How the sweep ran, for the result's `attrs`: the solver, its tolerances, the
    interval, the schedule, the devices and the cut (`_reported`)."""
    return dict(
        solver=type(config.solver).__name__,
        rtol=float(rtol),
        atol=float(atol),
        t0=settings["t0"],
        t1=settings["t1"],
        schedule=schedule,
        devices=int(info.count),
        **_reported(cut, schedule, info),
    )


def _solve_config(system, tau_fn, method: tuple, times: tuple, events) -> tuple[SolveConfig, Any]:
    """The solve every member runs, and its first step `dt0`.

    `method` is `(solver, rtol, atol, dt, dt0, max_steps, stepsize_controller)` as
    given to `sweep`, `times` is `(t0, t1, dtype)`; the controller is always given
    (`diffrax.PIDController(rtol, atol)` by default). With `events`, they are checked to
    be supported by the method (`simulate.events_supported`)."""
    solver, rtol, atol, dt, dt0, max_steps, stepsize_controller = method
    if solver is None and dt is None:  # (a contact scene's is implicit)
        solver = system.default_method
    t0, t1, tdt = times
    solver_, controller, dt0_, max_steps_ = configure(
        solver, rtol, atol, dt, dt0, max_steps, stepsize_controller, t0, t1, tdt, True
    )
    if controller is None:
        controller = dfx.PIDController(rtol=jnp.asarray(rtol, tdt), atol=jnp.asarray(atol, tdt))
    events = as_events(events)
    if events is not None:
        events_supported(solver_, controller, None, None)
    config = SolveConfig(system, solver_, tau_fn, controller, max_steps=max_steps_, events=events)
    return config, dt0_


def _cut(
    info: DeviceInfo, members: Members, kept: Kept, chunk_size: int | None, lanes: int | None
) -> Plan:
    """Members per chunk and lanes per device (`defaults.plan`), from the device, the
    memory a member's kept output and a lane take, and the user's `chunk_size` and
    `n_lanes` (already checked)."""
    n = members.q0s.shape[1]
    n_kept = max(len(kept.ts), 1)
    member_bytes = 8 * (2 * n * n_kept + n_kept + 4 * n + 8)
    member0 = members.params_of(0, 1)
    n_params = sum(math.prod(np.shape(x)[1:]) for x in jtu.tree_leaves(member0))
    return plan(
        info,
        n_members=members.size,
        member_bytes=member_bytes,
        lane_bytes=lane_bytes(n, n_params, members.q0s.dtype.itemsize),
        chunk_size=chunk_size,
        n_lanes=lanes,
    )


def _run(
    spec: ChunkSpec,
    members: Members,
    loaded: Mapping[int, ChunkResult | None],
    save: Callable[[int, ChunkResult], None] | None,
    progress,
    *,
    collect: bool = False,
    threads: int = 1,
) -> list[ChunkResult]:
    """Solve the chunks not in `loaded` (`solve_chunk`), passing each to `save` as it
    finishes (the checkpoint directory's or the sweep store's writer; `None` for
    neither), with a progress bar of members.

    With `threads > 1` (a CPU device and several cores: a compiled chunk runs on one
    core, and JAX releases the GIL while it runs), `threads` chunks are solved at once,
    on a thread pool; at most `threads` more wait, so memory stays bounded by a few
    chunks. Whatever the order they finish in, each chunk is saved once, by its index,
    from this thread, and its numbers do not depend on the threads.

    `loaded` holds the chunks done before: a checkpoint directory's read back, or
    `None` for those a store holds. **Returns:** with `collect`, every chunk's
    `ChunkResult` in order (loaded or solved); else `[]` (a store's result stays on
    disk)."""
    size, n_members = spec.size, members.size
    n_chunks = -(-n_members // size)
    if progress is None:
        progress = progress_default()
    bar = progress_bar(progress)(total=n_members, unit="member", disable=not progress, desc="sweep")
    results: dict[int, ChunkResult] = {}

    def bounds(c: int) -> tuple[int, int]:
        return c * size, min((c + 1) * size, n_members)

    def solve(c: int) -> ChunkResult:
        a, b = bounds(c)
        return solve_chunk(spec, members.params_of(a, b), members.q0s[a:b], members.qd0s[a:b])

    def done(c: int, chunk: ChunkResult, fresh: bool) -> None:
        if fresh and save is not None:
            save(c, chunk)
        if collect:
            results[c] = chunk
        a, b = bounds(c)
        bar.update(b - a)

    todo = [c for c in range(n_chunks) if c not in loaded]
    try:
        for c, chunk in loaded.items():  # (`None` for a store's: not collected)
            done(c, chunk, False)  # type: ignore[arg-type]
        if threads <= 1 or len(todo) <= 1:
            for c in todo:
                done(c, solve(c), True)
        else:
            _run_threaded(solve, done, todo, threads)
    finally:
        bar.close()
    if not collect:
        return []
    return [results[c] for c in range(n_chunks)]


def _run_threaded(solve, done, todo: list[int], threads: int) -> None:
    """`done(c, solve(c), True)` for every chunk `c` of `todo`: `solve` on a pool of
    `threads` threads (at most `2 * threads` chunks submitted and not yet done),
    `done` on this thread as each finishes.

    A failure (an exception in a chunk or in `done`, or an interrupt) cancels the
    chunks not started; the running ones cannot be stopped, so they finish, and those
    that succeed still go to `done` (saved, when the sweep has a checkpoint or store)
    before the failure is raised."""
    pending: dict[concurrent.futures.Future, int] = {}
    queue = iter(todo)
    with concurrent.futures.ThreadPoolExecutor(threads, thread_name_prefix="lagrax-sweep") as pool:
        try:
            for c in itertools.islice(queue, 2 * threads):
                pending[pool.submit(solve, c)] = c
            while pending:
                finished, _ = concurrent.futures.wait(
                    pending, return_when=concurrent.futures.FIRST_COMPLETED
                )
                for future in sorted(finished, key=pending.__getitem__):
                    c = pending.pop(future)
                    done(c, future.result(), True)
                    nxt = next(queue, None)
                    if nxt is not None:
                        pending[pool.submit(solve, nxt)] = nxt
        except BaseException:
            for future in pending:
                future.cancel()
            for future in sorted(pending, key=pending.__getitem__):
                if future.cancelled() or future.exception() is not None:
                    continue
                done(pending[future], future.result(), True)
            raise


def _reported(cut: Plan, schedule: str, info: DeviceInfo) -> dict[str, Any]:
    """How the batch was cut, for the result's `attrs` (pass `chunk_size` and
    `n_lanes` back to `sweep` to repeat it)."""
    lockstep = schedule == "lockstep"  # then a chunk's members all step at once
    return dict(
        platform=info.platform,
        chunk_size=cut.chunk_size,
        n_lanes=cut.chunk_size // info.count if lockstep else cut.n_lanes,
        refill_lanes=0 if lockstep else cut.refill,
        tail_lanes=0 if lockstep else cut.tail_lanes,
        threads=cut.threads,
    )


def dof_labels(names: tuple[str, ...] | None, n: int) -> np.ndarray:
    """The labels of the result's `dof` (or `q_dof`) coordinate: the system's coordinate
    (configuration) names (a tree's joint names) when it has one per entry, else
    `0 … n−1`."""
    if names is None or len(names) != n:
        return np.arange(n)
    return np.asarray(names, dtype=str)


def _is_state(x: Any) -> bool:
    """Whether `x` reads as an array of numbers (an initial state), not a parameter set."""
    if isinstance(x, Grid | Mapping) or is_namedtuple(x):
        return False
    try:
        return np.asarray(x).dtype.kind in "biuf"
    except (TypeError, ValueError):
        return False


def _argument_order(system, q0, qd0, params):
    """`(system, q0, qd0, params)`, accepting the order before 0.2,
    `sweep(system, params, q0, qd0)`, with a `DeprecationWarning`."""
    if not isinstance(system, AbstractSystem):
        raise ArgumentTypeError(
            "sweep needs a system (lagrax.LagrangianSystem or lagrax.ConstrainedSystem) as "
            f"its first argument, got {type(system).__name__}: {system!r}"
        )
    if not _is_state(q0) and _is_state(params):
        warnings.warn(
            "sweep(system, params, q0, qd0) is deprecated: pass the arguments in simulate's "
            "order, sweep(system, q0, qd0, params); the old order stops working in 0.3",
            DeprecationWarning,
            stacklevel=3,
        )
        return system, qd0, params, q0
    return system, q0, qd0, params


def _has_power(system, tau_fn, tau_const, members: Members, t0) -> bool:
    """Whether anything changes the Jacobi integral of a member (explicit time, inputs,
    applied force, dissipation; see `postprocess.power_of`): traced, not evaluated."""
    field = LagrangianVectorField(system, tau_fn)
    q0, qd0 = jnp.asarray(members.q0s[0]), jnp.asarray(members.qd0s[0])
    power = jax.eval_shape(
        lambda p, a, b: power_of(system, field, p, tau_const, jnp.asarray(t0, a.dtype), a, b),
        members.first(),
        q0,
        qd0,
    )
    return power is not None
