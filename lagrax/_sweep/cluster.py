"""A sweep's chunks as tasks on a Dask cluster (`sweep(..., client=...)`).

The client process plans the sweep and checks its checkpoint or store as without a
cluster; the chunks not done are submitted as tasks (`solve_chunk` on a worker). The
chunk program's definition (`ChunkSpec`: the system, solver, lanes, times) is pickled
and scattered to every worker once, so that every task on a worker receives the same
object, and the compiled program that `solve_chunk` caches for it is compiled once per
worker and reused; a worker keeps the definitions it has seen by their digest, so a
later sweep of the same definition (another batch) reuses its compiled program too.
Each finished chunk comes back to the client, which writes it (into the store,
the checkpoint directory, or the in-memory result) as it arrives: the only writer, so a
task that Dask runs again after losing its worker changes nothing (a chunk is written
once, by its index).

A killed worker may take the only copy of the scattered definition with it (a worker
that joined after the scatter has none), and Dask then cancels the tasks waiting for it:
the client scatters the definition again and resubmits those chunks (`_RESUBMITS` times
each at most).
"""

import collections
import dataclasses
import hashlib
import pickle
from collections.abc import Callable, Mapping
from typing import Any

import jax.tree_util as jtu
import numpy as np

from .._core.errors import ArgumentTypeError, ConfigurationError, SimulationError
from .chunk import ChunkSpec, solve_chunk
from .grid import Members
from .progress import progress_bar, progress_default
from .result import ChunkResult


def client_option(client: Any, devices: Any) -> Any:
    """`client=` checked: a `dask.distributed.Client` (the `cluster` extra installed),
    and no `devices=` beside it (each worker runs its chunks on its own devices)."""
    if client is None:
        return None
    try:
        from distributed import Client
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ConfigurationError(
            "client= needs dask.distributed: pip install 'lagrax[cluster]'"
        ) from err
    if not isinstance(client, Client):
        raise ArgumentTypeError(
            "client must be a dask.distributed.Client (e.g. Client(LocalCluster()) or a "
            f"dask-jobqueue cluster's client) or None; got {type(client).__name__}: {client!r}"
        )
    if devices is not None:
        raise ConfigurationError(
            f"devices={devices!r} cannot be combined with client=: each Dask worker runs its "
            "chunks on its own devices (start one worker per device instead)"
        )
    return client


def cluster_threads(client: Any) -> int:
    """How many chunks `client`'s workers run at once (their threads; at least 1, for
    a cluster whose workers have not joined yet): the sweep cuts its batch into a
    multiple of it (`defaults.plan`)."""
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # a scheduler that cannot be asked: chunks as on one process
        return 1


# On a worker: the chunk programs (`ChunkSpec`) it has received, by the SHA-256 of
# their pickle, the latest last. A sweep that sends the same definition again (the same
# model and settings, another batch) gets the object it compiled for, and with it the
# compiled program: no tracing or compiling again.
_SPECS: "collections.OrderedDict[str, ChunkSpec]" = collections.OrderedDict()
_SPECS_KEPT = 8
# How often a chunk whose task Dask cancelled (its inputs lost with a worker) is submitted
# again before the sweep gives up.
_RESUBMITS = 3


def _spec_on_worker(digest: str, payload: bytes) -> ChunkSpec:
    """The chunk program of `payload` (its pickle, whose SHA-256 is `digest`): the one
    this worker already holds for `digest`, else `payload` unpickled and kept."""
    spec = _SPECS.get(digest)
    if spec is None:
        spec = pickle.loads(payload)
        _SPECS[digest] = spec
        while len(_SPECS) > _SPECS_KEPT:
            _SPECS.popitem(last=False)
    _SPECS.move_to_end(digest)
    return spec


def _solve(spec: tuple[str, bytes], params: Any, q0s: np.ndarray, qd0s: np.ndarray) -> ChunkResult:
    """One chunk, on a worker (the task): `spec` is the chunk program's `(digest,
    pickle)` (see `_spec_on_worker`)."""
    return solve_chunk(_spec_on_worker(*spec), params, q0s, qd0s)


def run_on_cluster(
    client: Any,
    spec: ChunkSpec,
    members: Members,
    loaded: Mapping[int, ChunkResult | None],
    save: Callable[[int, ChunkResult], None] | None,
    progress: bool | None,
    *,
    collect: bool = False,
) -> list[ChunkResult]:
    """As the driver's `_run`, the chunks not in `loaded` solved as tasks on `client`'s
    workers; each is passed to `save` as it completes (in any order), with a progress
    bar of members. **Returns:** with `collect`, every chunk's `ChunkResult` in order."""
    import cloudpickle
    from distributed import as_completed

    size, n_members = spec.size, members.size
    n_chunks = -(-n_members // size)
    # one device per worker: the chunk is not sharded (a worker's own mesh is its device)
    spec = dataclasses.replace(spec, mesh=None)
    if progress is None:
        progress = progress_default()
    bar = progress_bar(progress)(total=n_members, unit="member", disable=not progress, desc="sweep")
    results: dict[int, ChunkResult] = {}
    index: dict[Any, int] = {}
    try:
        for c, chunk in loaded.items():
            if chunk is not None:
                results[c] = chunk
            bar.update(min((c + 1) * size, n_members) - c * size)
        todo = [c for c in range(n_chunks) if c not in loaded]
        if todo:
            payload = cloudpickle.dumps(spec)
            digest = hashlib.sha256(payload).hexdigest()
            remote: list[Any] = []  # the scattered definition (scattered again if lost)
            resubmits = dict.fromkeys(todo, 0)

            def submit(c: int) -> Any:
                if not remote or remote[0].status != "finished":
                    remote[:] = client.scatter([(digest, payload)], broadcast=True, hash=False)
                a, b = c * size, min((c + 1) * size, n_members)
                params = jtu.tree_map(np.asarray, members.params_of(a, b))
                future = client.submit(
                    _solve,
                    remote[0],
                    params,
                    np.asarray(members.q0s[a:b]),
                    np.asarray(members.qd0s[a:b]),
                    pure=False,
                )
                index[future] = c
                return future

            for c in todo:
                submit(c)
            pending = as_completed(list(index))
            for future in pending:
                c = index.pop(future)
                if future.cancelled():  # its inputs went with a killed worker
                    resubmits[c] += 1
                    if resubmits[c] > _RESUBMITS:
                        raise SimulationError(
                            f"the sweep's chunk {c} was cancelled by the cluster "
                            f"{resubmits[c]} times (its workers lost): the chunks finished "
                            "so far are kept (in the store or checkpoint, if any); run the "
                            "sweep again to resume"
                        )
                    remote.clear()  # the definition may have been lost with the worker
                    pending.add(submit(c))
                    continue
                chunk = future.result()
                if save is not None:
                    save(c, chunk)
                if collect:
                    results[c] = chunk
                future.release()
                bar.update(min((c + 1) * size, n_members) - c * size)
    finally:
        for future in index:
            future.cancel()
        bar.close()
    return [results[c] for c in range(n_chunks)] if collect else []
