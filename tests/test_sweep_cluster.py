"""A sweep's chunks as tasks on a Dask cluster (`sweep(..., client=)`): a local cluster of
two single-threaded worker processes gives the local sweep's result, with or without a
store, also when a worker is killed mid-sweep."""

import os
import signal
from typing import Any

import numpy as np
import pytest

distributed = pytest.importorskip(
    "distributed", reason="chunks on a cluster need the cluster extra (lagrax[cluster])"
)
pytest.importorskip("zarr", reason="the store needs the zarr extra")
xr = pytest.importorskip("xarray")

import lagrax as lx  # noqa: E402
from lagrax._sweep import store as _store  # noqa: E402

KS = np.linspace(1.0, 6.0, 8)
KW: dict[str, Any] = dict(t1=1.0, chunk_size=2, progress=False)  # four chunks
N_CHUNKS = 4


@pytest.fixture(scope="module")
def oscillator():
    return lx.models.mass_spring_damper()


@pytest.fixture(scope="module")
def batch(oscillator):
    return lx.samples(oscillator[1], k=KS)


def run(oscillator, batch, **kw: Any):
    return lx.sweep(oscillator[0], [1.0], [0.0], batch, **{**KW, **kw})


@pytest.fixture(scope="module")
def reference(oscillator, batch):
    return run(oscillator, batch)


@pytest.fixture(scope="module")
def cluster_client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    )
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


@pytest.fixture
def client(cluster_client):
    """The cluster with both workers in: a test that killed one leaves its nanny
    restarting it, and a sweep started before it is back sees one thread, not two (the
    `threads` its dataset records; CI once ran the next test in that window)."""
    cluster_client.wait_for_workers(2, timeout=120)
    return cluster_client


def _compiled_chunk_programs() -> int:
    from lagrax._sweep import chunk

    return chunk._run_chunk._cached._cache_size()  # jax's count of compiled programs


def test_cluster_sweep_equals_local(oscillator, batch, reference, client):
    xr.testing.assert_identical(run(oscillator, batch, client=client), reference)
    # four chunks on two workers: each worker compiled the chunk program once at most
    compiled = client.run(lambda: _compiled_chunk_programs())
    assert len(compiled) == 2 and all(n <= 1 for n in compiled.values())


def test_killed_worker_loses_nothing(oscillator, batch, reference, client, tmp_path, monkeypatch):
    real = _store.SweepStore.write
    written = []

    def kill_a_worker_once(self, c, chunk, kept):
        if not written:  # the first chunk is back: kill a worker while others run
            pid = next(iter(client.run(os.getpid).values()))
            os.kill(pid, signal.SIGKILL)
        written.append(c)
        return real(self, c, chunk, kept)

    monkeypatch.setattr(_store.SweepStore, "write", kill_a_worker_once)
    ds = run(oscillator, batch, client=client, store=tmp_path / "study.zarr")
    assert sorted(written) == list(range(N_CHUNKS))  # every chunk written once
    xr.testing.assert_identical(ds.load(), reference)


def test_lost_definition_is_scattered_again(oscillator, batch, reference, client, tmp_path):
    """The chunk program's definition held by one worker only (a worker that joined
    after the scatter has none) and that worker killed before the tasks ran: Dask cancels
    the tasks waiting for it ("lose scattered data, which can't be recovered"; this
    failed the test above now and then), and the sweep scatters it again and resubmits
    them. Every chunk is written once, and the result is the local sweep's."""
    import time

    real_scatter, real_write = client.scatter, _store.SweepStore.write
    written, scatters = [], []

    def scatter_to_one_worker_then_kill_it(data, **kw):
        scatters.append(1)
        if len(scatters) > 1:
            return real_scatter(data, **kw)
        workers = sorted(client.scheduler_info()["workers"])
        out = real_scatter(data, workers=workers[:1], broadcast=False, hash=False)
        pid = client.run(os.getpid, workers=workers[:1])[workers[0]]
        os.kill(pid, signal.SIGKILL)
        deadline = time.monotonic() + 30
        while workers[0] in client.scheduler_info()["workers"] and time.monotonic() < deadline:
            time.sleep(0.05)  # until the scheduler has removed it (and lost the data)
        return out

    def write(self, c, chunk, kept):
        written.append(c)
        return real_write(self, c, chunk, kept)

    client.scatter = scatter_to_one_worker_then_kill_it
    try:
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(_store.SweepStore, "write", write)
            ds = run(oscillator, batch, client=client, store=tmp_path / "study.zarr")
    finally:
        del client.scatter  # the bound method again
    assert len(scatters) >= 2  # the definition was scattered again
    assert sorted(written) == list(range(N_CHUNKS))
    xr.testing.assert_identical(ds.load(), reference)


def test_bad_client(oscillator, batch, client):
    with pytest.raises(lx.ArgumentTypeError, match="dask.distributed.Client"):
        run(oscillator, batch, client="tcp://localhost:8786")
    with pytest.raises(lx.ConfigurationError, match="devices="):
        run(oscillator, batch, client=client, devices=1)
