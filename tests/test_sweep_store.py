"""A zarr store as a sweep's output and its checkpoint (`sweep(..., store=)`,
`open_sweep`).

The store's result, opened lazily, is identical to the in-memory sweep's; a sweep killed
mid-way resumes without recomputing its finished chunks (counted), also when the kill
came between a chunk's data and its done marker; another sweep's store is refused by its
fingerprint; a chunk modified in the store is recomputed with a warning; a path that
cannot be written is refused before any work.
"""

import json
import shutil
from typing import Any

import numpy as np
import pytest

pytest.importorskip("zarr", reason="the store needs the zarr extra (pip install 'lagrax[zarr]')")
dask_array = pytest.importorskip("dask.array", reason="the store is opened through dask")
xr = pytest.importorskip("xarray")
import zarr  # noqa: E402

import lagrax as lx  # noqa: E402
from lagrax._sweep import checkpoint as _checkpoint  # noqa: E402
from lagrax._sweep import defaults as _defaults  # noqa: E402
from lagrax._sweep import driver as _driver  # noqa: E402
from lagrax._sweep import store as _store  # noqa: E402

KS = [1.0, 2.0, 3.0, 4.0, 5.0]
KW: dict[str, Any] = dict(t1=1.0, chunk_size=2, progress=False)  # three chunks: 2, 2 and 1 members
N_CHUNKS = 3


@pytest.fixture(scope="module", autouse=True)
def one_chunk_at_a_time():
    """The kill tests count chunks in the order they are solved: one core, one chunk
    after another (chunks on several cores: test_checkpoints, test_sweep_defaults)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(_defaults, "host_cores", lambda: 1)
        yield


@pytest.fixture(scope="module")
def oscillator():
    return lx.models.mass_spring_damper()


@pytest.fixture(scope="module")
def batch(oscillator):
    return lx.samples(oscillator[1], k=KS)


def run(oscillator, batch, store: Any = None, **kw: Any):
    return lx.sweep(oscillator[0], [1.0], [0.0], batch, store=store, **{**KW, **kw})


@pytest.fixture(scope="module")
def reference(oscillator, batch):
    return run(oscillator, batch)


@pytest.fixture(scope="module")
def complete(oscillator, batch, tmp_path_factory):
    """A finished store (copied by the tests that change it)."""
    path = tmp_path_factory.mktemp("complete") / "study.zarr"
    run(oscillator, batch, path)
    return path


@pytest.fixture
def study(complete, tmp_path):
    target = tmp_path / "study.zarr"
    shutil.copytree(complete, target)
    return target


def is_lazy(ds) -> bool:
    return all(isinstance(v.data, dask_array.Array) for v in ds.data_vars.values())


# --------------------------------------------------------------------------- the result


def test_store_result_is_lazy_and_identical_to_in_memory(oscillator, batch, reference, tmp_path):
    ds = run(oscillator, batch, tmp_path / "study.zarr")
    assert is_lazy(ds)
    xr.testing.assert_identical(ds.load(), reference)
    reopened = lx.open_sweep(tmp_path / "study.zarr")
    assert is_lazy(reopened)
    xr.testing.assert_identical(reopened.compute(), reference)


def test_grid_trajectory_store_has_the_grid_layout(arm, tmp_path):
    system, params = arm
    batch = lx.grid(params, m2=[0.5, 1.0, 1.5], l1=[0.8, 1.2], units={"m2": "kg"})
    kw: dict[str, Any] = dict(t1=0.5, chunk_size=4, keep="trajectory", n_save=5, progress=False)
    reference = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, **kw)
    ds = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, store=tmp_path / "g.zarr", **kw)
    assert is_lazy(ds) and ds.q.dims == ("m2", "l1", "time", "dof")
    xr.testing.assert_identical(ds.load(), reference)
    # load_sweep reads the store with the same layout, into memory
    loaded = lx.load_sweep(tmp_path / "g.zarr")
    assert not is_lazy(loaded)
    xr.testing.assert_identical(loaded, reference)
    # and open_sweep opens save_sweep's .zarr result lazily
    lx.save_sweep(reference, tmp_path / "saved.zarr")
    saved = lx.open_sweep(tmp_path / "saved.zarr")
    assert is_lazy(saved)
    xr.testing.assert_equal(saved.load(), reference)


def test_complete_store_computes_nothing(oscillator, batch, reference, study, chunk_calls):
    xr.testing.assert_identical(run(oscillator, batch, study).load(), reference)
    assert chunk_calls == []


# --------------------------------------------------------------------------- kill, resume


def test_killed_sweep_resumes_without_recomputing_finished_chunks(
    oscillator, batch, reference, tmp_path, monkeypatch
):
    path = tmp_path / "study.zarr"
    real = _driver.solve_chunk
    calls = []

    def killed_after_first(*a, **k):
        calls.append(1)
        if len(calls) > 1:
            raise KeyboardInterrupt("killed")
        return real(*a, **k)

    monkeypatch.setattr(_driver, "solve_chunk", killed_after_first)
    with pytest.raises(KeyboardInterrupt):
        run(oscillator, batch, path)
    with pytest.raises(lx.CheckpointError, match="not complete"):
        lx.open_sweep(path)  # an interrupted store is not a result

    calls.clear()
    monkeypatch.setattr(_driver, "solve_chunk", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    resumed = run(oscillator, batch, path)
    assert len(calls) == N_CHUNKS - 1  # the finished chunk is not recomputed
    xr.testing.assert_identical(resumed.load(), reference)


def test_kill_between_data_and_done_marker_recomputes_that_chunk(
    oscillator, batch, reference, tmp_path, monkeypatch, chunk_calls
):
    """A chunk whose data reached the store but not its digest is not done."""
    path = tmp_path / "study.zarr"
    real = _store.checksum
    digests = []

    def killed_at_second_marker(arrays, header):
        digests.append(header["chunk"])
        if len(digests) == 2:
            raise KeyboardInterrupt("killed")
        return real(arrays, header)

    monkeypatch.setattr(_store, "checksum", killed_at_second_marker)
    with pytest.raises(KeyboardInterrupt):
        run(oscillator, batch, path)
    monkeypatch.setattr(_store, "checksum", real)
    group: Any = zarr.open_group(str(path), mode="r")
    written = np.asarray(group["q"][2:4])
    assert np.all(np.isfinite(written))  # chunk 1's data is there, its marker is not

    chunk_calls.clear()
    resumed = run(oscillator, batch, path)
    assert len(chunk_calls) == N_CHUNKS - 1  # chunks 1 and 2, silently
    xr.testing.assert_identical(resumed.load(), reference)


# --------------------------------------------------------------------------- refusals


def test_store_of_another_sweep_is_refused(oscillator, study, chunk_calls):
    other = lx.samples(oscillator[1], k=[1.0, 2.0, 3.0, 4.0, 6.0])
    with pytest.raises(lx.CheckpointError, match="different sweep definition") as info:
        run(oscillator, other, study)
    message = str(info.value)
    assert "fingerprint" in message and str(study) in message
    assert chunk_calls == []


def test_store_of_another_chunk_size_is_refused(oscillator, batch, study, chunk_calls):
    with pytest.raises(lx.CheckpointError, match="chunk_size 2 there, 3 here"):
        run(oscillator, batch, study, chunk_size=3)
    assert chunk_calls == []


def test_modified_chunk_is_recomputed_with_a_warning(
    oscillator, batch, reference, study, chunk_calls
):
    q: Any = zarr.open_group(str(study), mode="r+")["q"]
    q[2:3] = 99.0  # part of chunk 1's data
    with pytest.warns(lx.CheckpointWarning, match=r"chunk 1 \(members 2:4\).*SHA-256"):
        ds = run(oscillator, batch, study)
    assert len(chunk_calls) == 1
    xr.testing.assert_identical(ds.load(), reference)


def test_unreadable_chunk_is_recomputed_with_a_warning(
    oscillator, batch, reference, study, chunk_calls
):
    for f in (study / "energy").rglob("*"):
        if f.is_file() and f.name != "zarr.json" and "0" in f.parts[-1]:
            f.write_bytes(b"garbage")  # chunk 0's energy
    with pytest.warns(lx.CheckpointWarning, match="chunk 0"):
        ds = run(oscillator, batch, study)
    assert len(chunk_calls) == 1
    xr.testing.assert_identical(ds.load(), reference)


def test_read_only_path_is_refused_before_any_work(
    oscillator, batch, tmp_path, monkeypatch, chunk_calls
):
    parent = tmp_path / "ro"
    parent.mkdir()
    parent.chmod(0o555)

    def refuse(*a, **k):  # root ignores modes: fail the probe's file as the mode would
        raise PermissionError(13, "Permission denied", str(parent))

    monkeypatch.setattr(_checkpoint.tempfile, "mkstemp", refuse)
    try:
        with pytest.raises(lx.CheckpointError, match="cannot be written") as info:
            run(oscillator, batch, parent / "study.zarr")
    finally:
        parent.chmod(0o755)
    assert "study.zarr" in str(info.value)
    assert chunk_calls == []


def test_bad_store_arguments(oscillator, batch, tmp_path, study, chunk_calls):
    a_file = tmp_path / "file.zarr"
    a_file.write_text("not a store")
    with pytest.raises(lx.CheckpointError, match="is a file"):
        run(oscillator, batch, a_file)
    foreign = tmp_path / "foreign.zarr"
    zarr.open_group(str(foreign), mode="w").attrs["title"] = "someone else's"
    with pytest.raises(lx.CheckpointError, match="not a lagrax sweep's"):
        run(oscillator, batch, foreign)
    with pytest.raises(lx.ConfigurationError, match="not both"):
        run(oscillator, batch, study, checkpoint=tmp_path / "ckpt")
    with pytest.raises(lx.ArgumentTypeError, match="store must be"):
        run(oscillator, batch, 3)
    meta = json.loads((study / "zarr.json").read_text())
    meta["attributes"][_store.ATTR]["version"] = _store.STORE_VERSION + 1
    (study / "zarr.json").write_text(json.dumps(meta))
    with pytest.raises(lx.CheckpointError, match="newer lagrax"):
        run(oscillator, batch, study)
    with pytest.raises(lx.CheckpointError, match="newer lagrax"):
        lx.open_sweep(study)
    with pytest.raises(FileNotFoundError):
        lx.open_sweep(tmp_path / "missing.zarr")
    assert chunk_calls == []
