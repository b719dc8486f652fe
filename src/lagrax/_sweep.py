"""Many trajectories: ``sweep`` over parameter sets, with ``grid`` and ``samples``."""

import hashlib
import itertools
import json
import math
import os
import re
import sys
import tempfile
import types
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np

from ._errors import ShapeError
from ._lanes import LaneOutput, run_lanes
from ._simulate import RESULTS, Solution, _configure, _solve
from ._system import _pivot_threshold
from ._vector_field import LagrangianVectorField

_FORMAT_VERSION = 1
_OK = int(RESULTS.successful._value)
_INVALID = int(RESULTS.invalid_input._value)
_NOT_PROJECTED = int(RESULTS.constraint_projection_failed._value)


# --------------------------------------------------------------------------- the batch


class Grid:
    """A batch of parameter sets with labels: fixed values plus swept ones.

    Made by :func:`grid` (the Cartesian product of named 1-D ranges: one sweep dimension
    per name) or :func:`samples` (named values taken together, member by member: one
    ``"member"`` dimension, e.g. Monte-Carlo draws). ``sweep`` labels its results with
    these names and values.

    **Attributes:** ``base`` (the fixed parameters), ``axes`` (name → 1-D values),
    ``dims`` (the result's sweep dimensions), ``shape``, ``size`` (number of members).
    """

    def __init__(self, base: Any, axes: Mapping[str, np.ndarray], product: bool):
        if base is None:
            base = {}
        if not (isinstance(base, Mapping) or hasattr(base, "_replace")):
            raise TypeError(
                "grid/samples need the fixed parameters as a dict or a NamedTuple (got "
                f"{type(base).__name__}); for other pytrees pass sweep() params whose "
                "leaves all carry a leading batch axis"
            )
        if not axes:
            raise ValueError("name at least one swept parameter, e.g. grid(params, m2=[1, 2])")
        self.base = base
        self.axes = {}
        for name, values in axes.items():
            v = np.asarray(values)
            if v.ndim != 1 or v.size == 0:
                raise ShapeError(f"swept values of {name!r} must be a non-empty 1-D array, got "
                                 f"shape {v.shape}")  # fmt: skip
            self.axes[name] = v
        self.product = product
        if product:
            self.dims = tuple(self.axes)
            self.shape = tuple(v.size for v in self.axes.values())
        else:
            sizes = {k: v.size for k, v in self.axes.items()}
            if len(set(sizes.values())) != 1:
                raise ShapeError(f"samples() needs values of one length per name, got {sizes}")
            self.dims = ("member",)
            self.shape = (next(iter(sizes.values())),)
        self.size = math.prod(self.shape)

    def __repr__(self) -> str:
        kind = "grid" if self.product else "samples"
        return f"Grid({kind}, dims={self.dims}, shape={self.shape}, swept={list(self.axes)})"

    def columns(self, start: int = 0, stop: int | None = None) -> dict[str, np.ndarray]:
        """The swept values of members ``start:stop`` (C order over the grid)."""
        stop = self.size if stop is None else stop
        if not self.product:
            return {k: v[start:stop] for k, v in self.axes.items()}
        idx = np.unravel_index(np.arange(start, stop), self.shape)
        return {k: v[i] for (k, v), i in zip(self.axes.items(), idx, strict=True)}

    def params(self, start: int = 0, stop: int | None = None) -> Any:
        """Batched parameters of members ``start:stop``: every leaf has a leading axis."""
        stop = self.size if stop is None else stop
        cols = self.columns(start, stop)
        n = stop - start
        fixed = dict(self.base) if isinstance(self.base, Mapping) else self.base._asdict()
        out = {}
        for k, v in fixed.items():
            if k not in cols:
                v = jnp.asarray(v)
                out[k] = jnp.broadcast_to(v, (n,) + v.shape)
        for k, v in cols.items():
            out[k] = jnp.asarray(v)
        if isinstance(self.base, Mapping):
            return out
        unknown = set(cols) - set(fixed)
        if unknown:
            raise ValueError(f"{sorted(unknown)} are not fields of {type(self.base).__name__}")
        return type(self.base)(**out)


def grid(base: Any = None, /, **axes: Any) -> Grid:
    """The Cartesian product of named 1-D parameter ranges, over fixed parameters ``base``.

    ``grid(params, m2=np.linspace(0.5, 2, 64), l1=np.linspace(0.5, 1.5, 64))`` is a
    64 × 64 sweep: every other entry of ``params`` stays fixed, and the result of
    :func:`sweep` gets dimensions ``("m2", "l1")`` labelled by these values. Members are
    ordered C-style (the last name varies fastest).

    **Arguments:** ``base``: the fixed parameters (a dict or NamedTuple, e.g. from
    ``lagrax.models.planar_2r()``); ``**axes``: swept names and their 1-D values.

    **Returns:** a :class:`Grid`.
    """
    return Grid(base, axes, product=True)


def samples(base: Any = None, /, **values: Any) -> Grid:
    """Parameter sets taken member by member (no product), over fixed parameters ``base``.

    ``samples(params, m2=rng.normal(1, 0.1, 1000), r2=rng.normal(0.5, 0.02, 1000))`` is a
    1000-member Monte-Carlo sweep; the result has one ``"member"`` dimension with ``m2``
    and ``r2`` as coordinates along it.
    """
    return Grid(base, values, product=False)


# --------------------------------------------------------------------------- compiled parts


class _Setup(eqx.Module):
    """Everything that fixes the compiled chunk function (static) or feeds it (arrays)."""

    system: Any
    solver: dfx.AbstractSolver
    controller: dfx.AbstractStepSizeController
    tau_fn: Callable | None
    reduce: Callable | None
    n_lanes: int = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)
    schedule: str = eqx.field(static=True)


def _lockstep(setup: _Setup, term, members, y0s, tau_const, t0, t1, dt0, ts) -> LaneOutput:
    """Plain ``vmap`` of ``simulate``'s solve: every member steps until the slowest is done."""
    rtol = atol = jnp.asarray(0.0, t0.dtype)  # unused: the controller is always given
    save_ts = ts if ts.shape[0] else t1[None]

    def one(p, y0):
        s = setup
        return _solve(s.system, s.solver, s.tau_fn, y0, p, tau_const, t0, t1, save_ts, 0,
                      rtol, atol, dt0, s.max_steps, None, s.controller)  # fmt: skip

    sol = jax.vmap(one)(members, y0s)
    steps = sol.stats["num_steps"]
    ys = (sol.q, sol.qd) if ts.shape[0] else (sol.q[:, :0], sol.qd[:, :0])
    return LaneOutput(
        ys=ys,
        y_end=(sol.q_end, sol.qd_end),
        t_end=sol.t_end,
        result=sol.result._value.astype(jnp.int32),
        num_steps=steps,
        num_accepted_steps=sol.stats["num_accepted_steps"],
        num_rejected_steps=sol.stats["num_rejected_steps"],
        busy_lane_steps=jnp.sum(steps),
        lane_steps=jnp.max(steps) * steps.shape[0],
    )


def _per_device(setup: _Setup, members, y0s, tau_const, t0, t1, dt0, ts):
    term = dfx.ODETerm(LagrangianVectorField(setup.system, setup.tau_fn))
    if setup.schedule == "lockstep":
        out = _lockstep(setup, term, members, y0s, tau_const, t0, t1, dt0, ts)
    else:
        out = run_lanes(term, setup.solver, setup.controller, members, y0s, tau_const, t0, t1,
                        dt0, ts, setup.n_lanes, setup.max_steps)  # fmt: skip
    # scalars become (1,) so that shards concatenate
    return eqx.tree_at(lambda o: (o.busy_lane_steps, o.lane_steps), out,
                       (out.busy_lane_steps[None], out.lane_steps[None]))  # fmt: skip


@eqx.filter_jit
def _run_chunk(setup: _Setup, mesh, members, y0s, tau_const, t0, t1, dt0, ts):
    """Solve one chunk of members (sharded over ``mesh`` when given) and post-process it."""
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
    system = setup.system
    energy = jax.vmap(jax.vmap(system.energy, in_axes=(0, 0, None)))
    q, qd = out.ys
    e = energy(q, qd, members) if q.shape[1] else q[..., 0]
    e = jnp.where(jnp.isfinite(e), e, jnp.inf)
    q0, qd0 = y0s
    e0 = jax.vmap(system.energy)(q0, qd0, members)
    q_end, qd_end = out.y_end
    e_end = jax.vmap(system.energy)(q_end, qd_end, members)
    if hasattr(system, "_phi"):  # a ConstrainedSystem: how far the end state is from φ = 0
        violation = jax.vmap(lambda a, p: jnp.max(jnp.abs(system._phi(a, p))))(q_end, members)
    else:
        violation = None
    reduced = None
    if setup.reduce is not None:

        def reduce_one(i_q, i_qd, i_e, res, t_end, qe, qde, st, acc, rej):
            stats = dict(num_steps=st, num_accepted_steps=acc, num_rejected_steps=rej,
                         max_steps=jnp.asarray(setup.max_steps))  # fmt: skip
            reached = jnp.all(jnp.isfinite(i_q), axis=1)
            sol = Solution(jnp.where(reached, ts, jnp.inf), i_q, i_qd, i_e, _result_item(res),
                           stats, t_end, qe, qde)  # fmt: skip
            return setup.reduce(sol)

        reduced = jax.vmap(reduce_one)(q, qd, e, out.result, out.t_end, q_end, qd_end,
                                       out.num_steps, out.num_accepted_steps,
                                       out.num_rejected_steps)  # fmt: skip
    return out, e, e0, e_end, reduced, violation


def _result_item(code):
    from equinox._enum import EnumerationItem  # the item type of diffrax/lagrax RESULTS

    return EnumerationItem(code, RESULTS)


@eqx.filter_jit
def _project_all(system, q0s, qd0s, members):
    """Per member: the initial state projected onto the constraints, and whether it could be."""
    return jax.vmap(system._project)(q0s, qd0s, members)


@eqx.filter_jit
def _mass_check(system, q0s, qd0s, members):
    """Per member: the mass matrix at the initial state (for a positive-definiteness check)."""
    return jax.vmap(lambda q, qd, p: system.mass_matrix(q, p, qd))(q0s, qd0s, members)


# --------------------------------------------------------------------------- helpers


def _batch_size(params: Any) -> int:
    leaves = jtu.tree_leaves_with_path(params)
    if not leaves:
        raise ShapeError("params has no array leaves to sweep over")
    sizes = {jtu.keystr(path): np.shape(x)[0] if np.ndim(x) else None for path, x in leaves}
    bad = [k for k, v in sizes.items() if v is None]
    if bad:
        raise ShapeError(
            f"sweep() params must carry a leading batch axis on every leaf; {bad} are "
            "scalars. Use lagrax.grid(params, name=values) or lagrax.samples(...) for a mix "
            "of fixed and swept parameters."
        )
    if len(set(sizes.values())) != 1:
        raise ShapeError(f"params leaves have different batch sizes: {sizes}")
    return next(iter(sizes.values()))


def _states(x: Any, name: str, n_members: int) -> np.ndarray:
    a = np.asarray(x, dtype=float if np.asarray(x).dtype.kind in "biu" else None)
    if a.ndim == 1:
        return np.broadcast_to(a, (n_members,) + a.shape)
    if a.ndim >= 2 and math.prod(a.shape[:-1]) == n_members:
        return a.reshape(n_members, a.shape[-1])
    raise ShapeError(
        f"{name} must have shape (n,) (shared by all members) or (members, n) / grid shape + "
        f"(n,) with {n_members} members; got {a.shape}"
    )


_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def _stable_repr(obj: Any) -> str:
    """``repr`` without memory addresses (they change from one process to the next)."""
    return _ADDRESS.sub("", repr(obj))


def _code_fingerprint(obj: Any, h: "hashlib._Hash") -> None:
    """Feed what identifies a function (name, bytecode, constants) into ``h``."""
    h.update(repr(getattr(obj, "__qualname__", type(obj).__name__)).encode())
    code = obj if isinstance(obj, types.CodeType) else getattr(obj, "__code__", None)
    if code is None:
        h.update(_stable_repr(obj).encode())
        return
    h.update(code.co_code)
    h.update(repr(code.co_names).encode())
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            _code_fingerprint(const, h)
        else:
            h.update(_stable_repr(const).encode())


def _fingerprint(setup: _Setup, arrays: Sequence[Any], settings: Mapping[str, Any]) -> str:
    """A hash of everything that defines a sweep's results, stable across processes."""
    h = hashlib.sha256()
    h.update(str(_FORMAT_VERSION).encode())
    for leaf in jtu.tree_leaves(setup, is_leaf=callable):
        if callable(leaf) and not eqx.is_array(leaf):
            _code_fingerprint(leaf, h)
            for cell in getattr(leaf, "__closure__", None) or ():
                try:
                    val = cell.cell_contents
                except ValueError:
                    continue
                if callable(val):
                    _code_fingerprint(val, h)
                elif eqx.is_array_like(val):
                    h.update(np.asarray(val).tobytes())
        elif eqx.is_array_like(leaf):
            h.update(np.asarray(leaf).tobytes())
        else:
            h.update(_stable_repr(leaf).encode())
    h.update(_stable_repr(eqx.tree_pformat(setup, short_arrays=False)).encode())
    for a in jtu.tree_leaves(arrays):
        a = np.ascontiguousarray(np.asarray(a))
        h.update(str((a.shape, a.dtype)).encode())
        h.update(a.tobytes())
    h.update(json.dumps(settings, sort_keys=True, default=_stable_repr).encode())
    return h.hexdigest()


def _atomic_write(path: Path, write: Callable[[Any], None]) -> None:
    """Write via a temporary file in the same directory, then rename (atomic on POSIX)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _progress_default() -> bool:
    if "ipykernel" in sys.modules:
        return True
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


def _progress_bar(enabled: bool):
    """tqdm's notebook widget where it can be shown, its text bar elsewhere."""
    from tqdm import std

    if not enabled or "ipykernel" not in sys.modules:
        return std.tqdm
    try:
        import ipywidgets  # noqa: F401  (tqdm's notebook bar needs it)
        from tqdm.notebook import tqdm as notebook_tqdm
    except ImportError:
        return std.tqdm
    return notebook_tqdm


def _mesh(devices) -> jax.sharding.Mesh | None:
    if devices is None:
        devices = jax.devices()
    elif isinstance(devices, int):
        devices = jax.devices()[:devices]
    devices = list(devices)
    if len(devices) <= 1:
        return None
    return jax.sharding.Mesh(np.asarray(devices), ("batch",))


def _to_device(x: np.ndarray, mesh) -> jax.Array:
    if mesh is None:
        return jnp.asarray(x)
    sharding = jax.sharding.NamedSharding(mesh, jax.sharding.PartitionSpec("batch"))
    # each process fills the shards it owns: the same code runs single- and multi-host
    return jax.make_array_from_callback(x.shape, sharding, lambda idx: x[idx])


def _to_host(tree: Any) -> Any:
    if jax.process_count() > 1:
        from jax.experimental import multihost_utils

        tree = multihost_utils.process_allgather(tree, tiled=True)
    return jtu.tree_map(np.asarray, tree)


# --------------------------------------------------------------------------- sweep


def sweep(
    system: Any,
    params: Any,
    q0: Any,
    qd0: Any,
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
    progress: bool | None = None,
):
    """Simulate ``system`` for many parameter sets (and initial states) at once.

    Each member is the solve ``simulate(system, q0[i], qd0[i], params[i], t1=t1, ...)``.
    The batch is cut into chunks (bounding memory; the unit of progress and of
    checkpoints); each chunk is one compiled call, sharded over ``devices``. Inside a
    chunk, members are integrated on ``n_lanes`` vectorized lanes as a work queue: a lane
    whose member is done takes the next member, so fast members do not wait for slow ones
    (``schedule="queue"``). ``schedule="lockstep"`` is a plain ``vmap`` of ``simulate``
    instead (bitwise the same numbers as ``simulate``, but every member of a chunk steps
    until the slowest is done).

    A member that fails (step budget, blow-up, invalid input) is flagged in the result's
    ``ok`` / ``result`` / ``status`` and never stops the sweep; its values past the failure
    are ``inf``, as in :class:`Solution`.

    **Arguments:**

    - ``system``: a :class:`LagrangianSystem`, or a :class:`ConstrainedSystem` (each
      member's initial state is first projected onto its constraints, as in
      ``simulate``; the result then also has ``constraint_violation``, ``max |φ(q)|`` at
      the end).
    - ``params``: a :class:`Grid` from :func:`grid` / :func:`samples`, or a pytree whose
      every leaf has a leading batch axis (one entry per member).
    - ``q0``, ``qd0``: initial state, ``(n,)`` for all members, or one per member
      (``(members, n)``, or the grid's shape + ``(n,)``).
    - ``t1``, ``t0``: time interval (shared).
    - ``keep``: what to keep per member: ``"final"`` (the state at ``t1``; default),
      ``"trajectory"`` (``n_save`` evenly spaced times), an array of times, or a function
      ``reduce(solution) -> pytree of arrays`` applied to each member's
      :class:`Solution` (saved at ``n_save`` times) inside the compiled call, so only its
      output is kept, e.g. ``lambda s: jnp.max(jnp.abs(s.energy_error))``.
    - ``tau``, ``solver``, ``rtol``, ``atol``, ``dt``, ``dt0``, ``max_steps``,
      ``stepsize_controller``: as for :func:`lagrax.simulate` (shared by all members).
    - ``chunk_size``: members per compiled call (default: up to 8,192, fewer when the kept
      output is large: about 64 MiB of it per chunk).
    - ``n_lanes``: members integrated at once inside a chunk, per device (default: an
      eighth of the chunk's members per device, at most 1,024).
    - ``schedule``: ``"queue"`` (default) or ``"lockstep"``, see above.
    - ``devices``: devices to shard the batch over: ``None`` (all of ``jax.devices()``),
      a count, or a list. On a multi-host run (after ``jax.distributed.initialize()``)
      every process makes the same call; each gets the whole result.
    - ``checkpoint``: a directory. Each finished chunk is written there atomically; the
      same call again resumes, computing only what is missing. A different sweep
      definition (model, parameters, states, solver settings, ``keep``) is refused.
    - ``progress``: show a progress bar (tqdm; members/s). Default: on in a terminal or
      notebook, off otherwise.

    **Returns:** an ``xarray.Dataset`` with dimensions the grid's (or ``"member"``),
    ``"time"`` (when kept) and ``"dof"``; variables ``q``, ``qd``, ``energy`` (at the kept
    times, or at ``t1`` for ``keep="final"``), ``energy_error`` (relative change of
    ``T + V`` from ``t0`` to the end), ``ok``, ``result`` (code of ``lagrax.RESULTS``),
    ``status`` (its message), ``t_end``, ``num_steps``, ``num_accepted_steps``,
    ``num_rejected_steps`` (or the outputs of ``reduce``); swept parameters as
    coordinates; ``attrs`` with the failure count and the share of lane-steps that were
    idle (``lane_idle_fraction``). Save it with :func:`save_sweep`.

    **Example:**

    ```python
    system, params = lagrax.models.planar_2r()
    batch = lagrax.grid(params, m2=np.linspace(0.5, 2, 32), l1=np.linspace(0.5, 1.5, 32))
    ds = lagrax.sweep(system, batch, [0.5, 0.8], [0.0, 0.0], t1=10.0)
    ds.q.sel(dof=1).plot()   # final θ2 over the (m2, l1) grid
    ```
    """
    import xarray as xr

    # --- the batch
    if isinstance(params, Grid):
        batch, n_members = params, params.size
        get_params = params.params
    else:
        n_members = _batch_size(params)
        batch = None
        params = jtu.tree_map(jnp.asarray, params)

        def get_params(a, b):
            return jtu.tree_map(lambda x: x[a:b], params)

    q0s = _states(q0, "q0", n_members)
    qd0s = _states(qd0, "qd0", n_members)
    if q0s.shape != qd0s.shape:
        raise ShapeError(f"q0 and qd0 must have the same shape per member, got {q0s.shape[1:]} "
                         f"and {qd0s.shape[1:]}")  # fmt: skip
    dtype = jnp.result_type(q0s.dtype, qd0s.dtype)
    q0s, qd0s = q0s.astype(dtype), qd0s.astype(dtype)
    n = q0s.shape[1]
    # one member through the eager checks of a single trajectory: shapes, params, tau
    q_probe, _ = system._state(q0s[0], qd0s[0])
    tdt = jnp.asarray(0.0, dtype).dtype
    tau_fn = tau if callable(tau) else None
    tau_const = None
    if tau is not None and not callable(tau):
        (tau_const,) = system._state(q_probe, tau=tau)[1:]
        tau_const = system._finite(jnp.asarray(tau_const, dtype), "tau")
    if not float(t1) > float(t0):
        raise ValueError(f"t1 must be greater than t0, got t0={t0}, t1={t1}")

    # --- what to keep
    reduce = None
    if callable(keep):
        reduce, ts = keep, np.linspace(t0, t1, int(n_save))
    elif isinstance(keep, str):
        if keep == "final":
            ts = np.zeros(0)
        elif keep == "trajectory":
            ts = np.linspace(t0, t1, int(n_save))
        else:
            raise ValueError(f"keep must be 'final', 'trajectory', times or a function; got "
                             f"{keep!r}")  # fmt: skip
    else:
        ts = np.asarray(keep, dtype=float)
        if ts.ndim != 1 or ts.size == 0:
            raise ShapeError(f"keep= times must be a non-empty 1-D array, got shape {ts.shape}")
        if np.any(np.diff(ts) < 0) or ts[0] < t0 or ts[-1] > t1:
            raise ValueError(f"keep= times must be sorted and inside [t0, t1] = [{t0}, {t1}]")
    ts_dev = jnp.asarray(ts, tdt)

    solver_, controller, dt0_, max_steps_ = _configure(
        solver, rtol, atol, dt, dt0, max_steps, stepsize_controller, t0, t1, tdt, True
    )
    if controller is None:
        controller = dfx.PIDController(rtol=jnp.asarray(rtol, tdt), atol=jnp.asarray(atol, tdt))
    if schedule not in ("queue", "lockstep"):
        raise ValueError(f"schedule must be 'queue' or 'lockstep', got {schedule!r}")

    # --- chunks and devices
    mesh = _mesh(devices)
    n_dev = 1 if mesh is None else mesh.size
    per_member = 8 * (2 * n * max(len(ts), 1) + max(len(ts), 1) + 4 * n + 8)
    manifest_chunk = None
    ckpt = Path(checkpoint) if checkpoint is not None else None
    if ckpt is not None and (ckpt / "manifest.json").exists():
        manifest_chunk = json.loads((ckpt / "manifest.json").read_text()).get("chunk_size")
    if chunk_size is None:
        chunk_size = manifest_chunk or int(min(8192, max(64, (64 << 20) // per_member)))
    chunk_size = int(min(chunk_size, n_members))
    chunk_size = -(-chunk_size // n_dev) * n_dev  # a whole number of members per device
    # about eight members per lane: enough to refill lanes, few enough to keep the tail short
    lanes = int(n_lanes) if n_lanes is not None else max(1, min(1024, chunk_size // n_dev // 8))
    setup = _Setup(system, solver_, controller, tau_fn, reduce, lanes, max_steps_, schedule)
    n_chunks = -(-n_members // chunk_size)

    # --- checkpoint
    settings = dict(t0=float(t0), t1=float(t1), ts=ts.tolist(), dt0=dt0_, n=n,
                    n_members=n_members, keep=keep if isinstance(keep, str) else None,
                    dtype=str(dtype), tau=None if tau_const is None else
                    np.asarray(tau_const).tolist())  # fmt: skip
    if ckpt is not None:
        swept = batch.params() if batch is not None else params
        fp = _fingerprint(setup, [swept, q0s, qd0s], settings)
        ckpt.mkdir(parents=True, exist_ok=True)
        manifest = ckpt / "manifest.json"
        if manifest.exists():
            old = json.loads(manifest.read_text())
            if old.get("fingerprint") != fp or old.get("chunk_size") != chunk_size:
                raise ValueError(
                    f"the checkpoint at {ckpt} belongs to a different sweep definition "
                    "(model, parameters, initial states, solver settings, keep= or "
                    "chunk_size differ); refusing to mix results. Use another checkpoint "
                    "directory, or delete this one to start over."
                )
        else:
            info = dict(fingerprint=fp, chunk_size=chunk_size, n_members=n_members,
                        n_chunks=n_chunks, version=_FORMAT_VERSION)  # fmt: skip
            _atomic_write(manifest, lambda f: f.write(json.dumps(info, indent=1).encode()))

    if progress is None:
        progress = _progress_default()
    bar = _progress_bar(progress)(total=n_members, unit="member", disable=not progress,
                                  desc="sweep")  # fmt: skip
    results = []
    try:
        for c in range(n_chunks):
            a, b = c * chunk_size, min((c + 1) * chunk_size, n_members)
            path = ckpt / f"chunk_{c:06d}.npz" if ckpt is not None else None
            if path is not None and path.exists():
                with np.load(path, allow_pickle=False) as z:
                    results.append({k: np.asarray(z[k]) for k in z.files})
                bar.update(b - a)
                continue
            chunk = _solve_chunk(setup, mesh, system, get_params(a, b), q0s[a:b], qd0s[a:b],
                                 tau_const, t0, t1, dt0_, ts_dev, chunk_size, tdt)  # fmt: skip
            if path is not None:
                _atomic_write(path, lambda f, c=chunk: np.savez(f, **c))
            results.append(chunk)
            bar.update(b - a)
    finally:
        bar.close()
    return _dataset(xr, results, batch, params if batch is None else None, ts,
                    keep, n, n_members, settings, solver_, rtol, atol, schedule, n_dev)  # fmt: skip


def _solve_chunk(setup, mesh, system, members, q0s, qd0s, tau_const, t0, t1, dt0, ts, size, tdt):
    """Run one chunk (padded to ``size`` members so every chunk reuses one compilation)."""
    m = q0s.shape[0]
    members = jtu.tree_map(lambda x: np.asarray(x), members)
    projected = np.ones(m, bool)
    if getattr(system, "project_initial", False):  # a ConstrainedSystem: start on φ = 0
        q0s, qd0s, projected = _to_host(_project_all(system, jnp.asarray(q0s),
                                                     jnp.asarray(qd0s),
                                                     jtu.tree_map(jnp.asarray, members)))
    # per member: finite inputs and a positive-definite mass matrix at the initial state
    fin = np.isfinite(q0s).all(1) & np.isfinite(qd0s).all(1)
    for leaf in jtu.tree_leaves(members):
        fin &= np.isfinite(leaf.reshape(m, -1)).all(1) if leaf.dtype.kind in "fc" else True
    valid = fin.copy()
    if fin.any():
        mm = np.asarray(_mass_check(system, jnp.asarray(q0s), jnp.asarray(qd0s),
                                    jtu.tree_map(jnp.asarray, members)))  # fmt: skip
        with np.errstate(invalid="ignore"):
            ok_mm = np.all(np.isfinite(mm.reshape(m, -1)), axis=1)
            eig = np.full((m, mm.shape[-1]), -np.inf)
            eig[ok_mm] = np.linalg.eigvalsh(mm[ok_mm])
            scale = np.maximum(np.abs(eig).max(axis=1), np.finfo(mm.dtype).tiny)
            valid &= ok_mm & (eig[:, 0] > _pivot_threshold(mm.dtype) * scale)
    # invalid members are solved as a stand-in (a valid one) and overwritten afterwards
    stand_in = int(np.argmax(valid)) if valid.any() else 0
    src = np.where(valid, np.arange(m), stand_in)
    src = np.concatenate([src, np.full(size - m, src[0] if m else 0)])
    pick = lambda x: np.asarray(x)[src]  # noqa: E731
    members_d = jtu.tree_map(lambda x: _to_device(pick(x), mesh), members)
    y0s = (_to_device(pick(q0s), mesh), _to_device(pick(qd0s), mesh))
    out, e, e0, e_end, reduced, violation = _run_chunk(setup, mesh, members_d, y0s, tau_const,
                                            jnp.asarray(t0, tdt), jnp.asarray(t1, tdt),
                                            None if dt0 is None else jnp.asarray(dt0, tdt),
                                            ts)  # fmt: skip
    out, e, e0, e_end, reduced, violation = _to_host((out, e, e0, e_end, reduced, violation))
    cut = lambda x: x[:m]  # noqa: E731
    q, qd = out.ys
    q_end, qd_end = out.y_end
    res = cut(out.result).copy()
    res[~projected & (res == _OK)] = _NOT_PROJECTED
    res[~valid] = _INVALID
    bad = ~valid

    def blank(x):
        x = cut(x).astype(np.result_type(x.dtype, np.float32), copy=True)
        x[bad] = np.inf
        return x

    chunk = dict(
        q=blank(q), qd=blank(qd), energy=blank(e), energy0=blank(e0), energy_end=blank(e_end),
        q_end=blank(q_end), qd_end=blank(qd_end), t_end=blank(out.t_end), result=res,
        num_steps=np.where(bad, 0, cut(out.num_steps)),
        num_accepted_steps=np.where(bad, 0, cut(out.num_accepted_steps)),
        num_rejected_steps=np.where(bad, 0, cut(out.num_rejected_steps)),
        busy_lane_steps=np.asarray([out.busy_lane_steps.sum()]),
        lane_steps=np.asarray([out.lane_steps.sum()]),
    )  # fmt: skip
    if violation is not None:
        chunk["constraint_violation"] = blank(violation)
    if reduced is not None:
        leaves, _ = jtu.tree_flatten_with_path(reduced)
        for path, leaf in leaves:
            chunk["reduce" + jtu.keystr(path)] = blank(np.asarray(leaf))
        chunk["__reduce_paths__"] = np.asarray([jtu.keystr(p) for p, _ in leaves])
    return chunk


def _dataset(xr, chunks, batch, raw_params, ts, keep, n, n_members, settings, solver, rtol,
             atol, schedule, n_dev):
    cat = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]
           if k not in ("busy_lane_steps", "lane_steps", "__reduce_paths__")}  # fmt: skip
    busy = sum(int(c["busy_lane_steps"].sum()) for c in chunks)
    total = sum(int(c["lane_steps"].sum()) for c in chunks)
    if batch is not None:
        dims, shape = batch.dims, batch.shape
    else:
        dims, shape = ("member",), (n_members,)

    def shaped(x):
        return x.reshape(shape + x.shape[1:])

    sweep_dims = list(dims)
    data = {}
    final = isinstance(keep, str) and keep == "final"
    time_dims = [] if final else ["time"]
    ok = cat["result"] == _OK
    if final:
        at_t1 = ok[:, None]
        data["q"] = (sweep_dims + ["dof"], shaped(np.where(at_t1, cat["q_end"], np.inf)))
        data["qd"] = (sweep_dims + ["dof"], shaped(np.where(at_t1, cat["qd_end"], np.inf)))
        data["energy"] = (sweep_dims, shaped(np.where(ok, cat["energy_end"], np.inf)))
    elif not callable(keep):
        data["q"] = (sweep_dims + time_dims + ["dof"], shaped(cat["q"]))
        data["qd"] = (sweep_dims + time_dims + ["dof"], shaped(cat["qd"]))
        data["energy"] = (sweep_dims + time_dims, shaped(cat["energy"]))
    else:
        paths = [str(p) for p in chunks[0]["__reduce_paths__"]]
        for p in paths:
            name = _reduce_name(p)
            x = shaped(cat["reduce" + p])
            extra = [f"{name}_dim_{k}" for k in range(x.ndim - len(sweep_dims))]
            data[name] = (sweep_dims + extra, x)
    e0 = cat["energy0"]
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = (cat["energy_end"] - e0) / np.maximum(np.abs(e0), np.finfo(float).tiny)
    data["energy_error"] = (sweep_dims, shaped(np.where(ok, rel, np.inf)))
    data["ok"] = (sweep_dims, shaped(ok))
    data["result"] = (sweep_dims, shaped(cat["result"]))
    messages = RESULTS._index_to_message
    status = np.asarray(["ok" if r == _OK else _short(messages[r]) for r in cat["result"]])
    data["status"] = (sweep_dims, shaped(status))
    if "constraint_violation" in cat:
        data["constraint_violation"] = (sweep_dims, shaped(cat["constraint_violation"]))
    for k in ("t_end", "num_steps", "num_accepted_steps", "num_rejected_steps"):
        data[k] = (sweep_dims, shaped(cat[k]))
    coords = {"dof": np.arange(n)}
    if not final and not callable(keep):
        coords["time"] = ts
    if batch is not None:
        if batch.product:
            coords.update({k: v for k, v in batch.axes.items()})
        else:
            coords.update({k: ("member", v) for k, v in batch.axes.items()})
    else:
        coords["member"] = np.arange(n_members)
        if isinstance(raw_params, Mapping):  # per-member scalar parameters label the members
            for k, v in raw_params.items():
                v = np.asarray(v)
                if v.ndim == 1 and not np.all(v == v[0]):
                    coords[k] = ("member", v)
    failed = ~ok
    counts = {}
    for r in np.unique(cat["result"][failed]):
        counts[_short(messages[r])] = int(np.sum(cat["result"] == r))
    attrs = dict(
        n_members=int(n_members),
        n_failed=int(failed.sum()),
        failures=json.dumps(counts),
        solver=type(solver).__name__,
        rtol=float(rtol),
        atol=float(atol),
        t0=settings["t0"],
        t1=settings["t1"],
        schedule=schedule,
        devices=int(n_dev),
        lane_idle_fraction=float(1 - busy / total) if total else 0.0,
    )
    return xr.Dataset(data, coords=coords, attrs=attrs)


def _reduce_name(path: str) -> str:
    name = path.strip("[]'\".").replace("']['", "_").replace("][", "_")
    return name or "value"


def _short(message: str) -> str:
    return message.split("\n")[0].strip()


# --------------------------------------------------------------------------- files


def save_sweep(ds: Any, path: str | os.PathLike) -> Path:
    """Save a sweep result: ``.nc`` (netCDF), ``.zarr`` or ``.npz``, by the file suffix.

    netCDF needs ``netCDF4``, ``h5netcdf`` or SciPy; zarr needs ``zarr``; ``.npz`` needs
    nothing beyond NumPy and is read back by :func:`load_sweep`. The file is written atomically.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        arrays = {f"var/{k}": np.asarray(v.values) for k, v in ds.data_vars.items()}
        arrays.update({f"coord/{k}": np.asarray(v.values) for k, v in ds.coords.items()})
        meta = dict(
            dims={k: list(v.dims) for k, v in itertools.chain(ds.data_vars.items(),
                                                              ds.coords.items())},
            attrs=dict(ds.attrs),
        )  # fmt: skip
        arrays["meta"] = np.asarray(json.dumps(meta))
        _atomic_write(path, lambda f: np.savez(f, **arrays))
    elif suffix in (".nc", ".nc4", ".netcdf"):
        ds.to_netcdf(path)
    elif suffix == ".zarr":
        ds.to_zarr(path, mode="w")
    else:
        raise ValueError(f"unknown format {suffix!r}: use .nc, .zarr or .npz")
    return path


def load_sweep(path: str | os.PathLike):
    """Read a sweep result written by :func:`save_sweep` (any of its formats)."""
    import xarray as xr

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            data = {k[4:]: (meta["dims"][k[4:]], z[k]) for k in z.files if k.startswith("var/")}
            coords = {k[6:]: (meta["dims"][k[6:]], z[k]) for k in z.files
                      if k.startswith("coord/")}  # fmt: skip
        return xr.Dataset(data, coords=coords, attrs=meta["attrs"])
    if suffix == ".zarr":
        return xr.open_zarr(path).load()
    return xr.load_dataset(path)
