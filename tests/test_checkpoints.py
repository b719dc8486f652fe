"""Checkpoints that cannot lie: faults in a sweep's checkpoint directory and saved files.

A crash mid-sweep resumes to the uninterrupted result; a damaged chunk file is never
loaded (a CheckpointWarning names it, its members are computed again); another sweep's
chunks are refused with or without a manifest; a directory that cannot be written is
refused before any work; load_sweep names the path and the fault of a damaged file;
NaN and stiff members are reported per member and poison nothing.
"""

import json
import os
import shutil
import threading
import time

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax._sweep import checkpoint as _checkpoint
from lagrax._sweep import defaults as _defaults
from lagrax._sweep import driver as _driver

KS = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
KW = dict(t1=1.0, chunk_size=2)  # three chunks of two members
N_CHUNKS = 3


@pytest.fixture(scope="module")
def oscillator():
    return lx.models.mass_spring_damper()


@pytest.fixture(scope="module")
def batch(oscillator):
    return lx.samples(oscillator[1], k=KS)


def run(oscillator, batch, ckpt=None, **kw):
    return lx.sweep(oscillator[0], [1.0], [0.0], batch, checkpoint=ckpt, **{**KW, **kw})


@pytest.fixture(scope="module")
def reference(oscillator, batch):
    return run(oscillator, batch)


@pytest.fixture(scope="module")
def complete(oscillator, batch, reference, tmp_path_factory):
    """A finished checkpoint directory (copied by the tests that damage it)."""
    ckpt = tmp_path_factory.mktemp("complete") / "ckpt"
    ds = run(oscillator, batch, ckpt)
    assert_same(ds, reference)
    return ckpt


@pytest.fixture
def ckpt(complete, tmp_path):
    target = tmp_path / "ckpt"
    shutil.copytree(complete, target)
    return target


def assert_same(a, b):
    for name in ("q", "qd", "energy", "result", "num_steps", "t_end"):
        np.testing.assert_array_equal(a[name].values, b[name].values)
    assert a.attrs["t1"] == b.attrs["t1"]


def chunk(ckpt, i):
    return ckpt / f"chunk_{i:06d}.npz"


# --------------------------------------------------------------------------- crash, resume


def test_crash_mid_sweep_then_resume_equals_uninterrupted(
    oscillator, batch, reference, tmp_path, monkeypatch
):
    ckpt = tmp_path / "ckpt"
    real = _driver.solve_chunk
    calls = []
    monkeypatch.setattr(_defaults, "host_cores", lambda: 1)  # one chunk after another

    def crash_after_first(*a, **k):
        calls.append(1)
        if len(calls) > 1:
            raise RuntimeError("power cut")
        return real(*a, **k)

    monkeypatch.setattr(_driver, "solve_chunk", crash_after_first)
    with pytest.raises(RuntimeError, match="power cut"):
        run(oscillator, batch, ckpt)
    assert sorted(p.name for p in ckpt.iterdir()) == ["chunk_000000.npz", "manifest.json"]

    calls.clear()
    monkeypatch.setattr(_driver, "solve_chunk", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    resumed = run(oscillator, batch, ckpt)
    assert len(calls) == N_CHUNKS - 1  # the finished chunk is loaded, not recomputed
    assert_same(resumed, reference)
    assert not list(ckpt.glob("*.tmp"))
    for i in range(N_CHUNKS):  # every file verifies
        header, _ = _checkpoint.read_chunk(chunk(ckpt, i))
        assert header["chunk"] == i and header["version"] == _checkpoint.FORMAT_VERSION


def test_crash_on_one_core_keeps_the_chunk_running_on_the_other(
    oscillator, batch, reference, tmp_path, monkeypatch
):
    """Two cores, two chunks at once: the chunk of members 2–3 fails while the first
    chunk is still being solved on the other thread. The failure is raised only once
    that chunk has finished and is saved; the third chunk, not started, is not. The
    resumed sweep solves the two missing chunks and equals the uninterrupted one."""
    ckpt = tmp_path / "ckpt"
    real = _driver.solve_chunk
    first_done = threading.Event()
    started = []

    def second_fails(spec, params, q0s, qd0s):
        k = float(np.asarray(params["k"])[0])
        started.append(k)
        if k == KS[2]:  # the second chunk: fail while the first still runs
            raise RuntimeError("power cut")
        if k == KS[0]:
            time.sleep(0.5)
            first_done.set()
        return real(spec, params, q0s, qd0s)

    monkeypatch.setattr(_defaults, "host_cores", lambda: 2)
    monkeypatch.setattr(_driver, "solve_chunk", second_fails)
    with pytest.raises(RuntimeError, match="power cut"):
        run(oscillator, batch, ckpt, chunk_size=2)
    assert first_done.is_set()
    saved = sorted(p.name for p in ckpt.glob("chunk_*.npz"))
    assert saved == ["chunk_000000.npz"] or saved == ["chunk_000000.npz", "chunk_000002.npz"]
    calls = []
    monkeypatch.setattr(_driver, "solve_chunk", lambda *a, **k: (calls.append(1), real(*a, **k))[1])
    resumed = run(oscillator, batch, ckpt)
    assert len(calls) == N_CHUNKS - len(saved)
    assert_same(resumed, reference)


def test_complete_checkpoint_computes_nothing(oscillator, batch, reference, ckpt, chunk_calls):
    assert_same(run(oscillator, batch, ckpt), reference)
    assert chunk_calls == []


# --------------------------------------------------------------------------- damaged chunks


def truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def flip_a_bit(path):
    """One bit flipped inside the data of the file's largest array (a flip in zip
    metadata such as a time stamp would leave the results intact)."""
    with np.load(path) as z:
        largest = max((np.asarray(z[k]) for k in z.files), key=lambda a: a.nbytes)
    data = bytearray(path.read_bytes())
    at = data.find(largest.tobytes())
    assert at >= 0
    data[at + largest.nbytes // 2] ^= 0x10
    path.write_bytes(bytes(data))


def empty(path):
    path.write_bytes(b"")


def garbage(path):
    path.write_text("not a chunk at all\n")


def old_format(path):
    """A chunk as lagrax wrote it before format 2: the arrays, no header."""
    _, arrays = _checkpoint.read_chunk(path)
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def edit_values(path):
    """Valid zip, valid header, but the arrays were changed afterwards."""
    with np.load(path) as z:
        arrays = {k: np.asarray(z[k]) for k in z.files}
    arrays["q_end"] = arrays["q_end"] + 1.0
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def renamed(path):
    """Another chunk of the same sweep under this chunk's name."""
    shutil.copyfile(path.parent / "chunk_000000.npz", path)


DAMAGE = {
    "truncated": (truncate, "truncated or damaged"),
    "bit flip": (flip_a_bit, "truncated or damaged"),
    "empty": (empty, "empty"),
    "garbage": (garbage, "cannot be read"),
    "old format": (old_format, "no lagrax header"),
    "edited values": (edit_values, "checksum does not match"),
    "renamed": (renamed, "holds chunk 0"),
}


@pytest.mark.parametrize("damage, reason", DAMAGE.values(), ids=list(DAMAGE))
def test_damaged_chunk_is_recomputed_never_loaded(
    oscillator, batch, reference, ckpt, chunk_calls, damage, reason
):
    target = chunk(ckpt, 1)
    damage(target)
    with pytest.warns(lx.CheckpointWarning, match=reason) as record:
        ds = run(oscillator, batch, ckpt)
    messages = [str(w.message) for w in record if w.category is lx.CheckpointWarning]
    assert len(messages) == 1 and str(target) in messages[0]
    assert len(chunk_calls) == 1  # only the damaged chunk
    assert_same(ds, reference)
    _checkpoint.read_chunk(target)  # replaced by a good file
    assert_same(run(oscillator, batch, ckpt), reference)  # and quiet from now on
    assert len(chunk_calls) == 1


def test_damaged_manifest_is_rewritten_chunks_decide(
    oscillator, batch, reference, ckpt, chunk_calls
):
    (ckpt / "manifest.json").write_text("{not json")
    with pytest.warns(lx.CheckpointWarning, match="manifest.json cannot be read"):
        ds = run(oscillator, batch, ckpt)
    assert_same(ds, reference)
    assert chunk_calls == []
    assert json.loads((ckpt / "manifest.json").read_text())["version"] == _checkpoint.FORMAT_VERSION


# --------------------------------------------------------------------------- another sweep


def test_deleted_manifest_and_changed_sweep_is_refused(oscillator, batch, ckpt, chunk_calls):
    """The reported hole: without manifest.json, a sweep with another t1 reused every chunk."""
    (ckpt / "manifest.json").unlink()
    before = {p.name: p.read_bytes() for p in ckpt.iterdir()}
    with pytest.raises(lx.CheckpointError) as info:
        run(oscillator, batch, ckpt, t1=2.0)
    message = str(info.value)
    assert str(ckpt) in message and "different sweep" in message
    assert "fingerprint" in message and "delete this one" in message
    assert chunk_calls == []
    assert {p.name: p.read_bytes() for p in ckpt.iterdir()} == before  # nothing touched


def test_deleted_manifest_same_sweep_reuses_chunks(oscillator, batch, reference, ckpt, chunk_calls):
    (ckpt / "manifest.json").unlink()
    # chunk_size not given: recovered from the chunk files' headers
    ds = lx.sweep(oscillator[0], [1.0], [0.0], batch, t1=1.0, checkpoint=ckpt)
    assert_same(ds, reference)
    assert chunk_calls == []
    assert json.loads((ckpt / "manifest.json").read_text())["chunk_size"] == 2


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(t1=2.0), ["different sweep definition", "fingerprint"]),
        (dict(rtol=1e-9), ["different sweep definition"]),
        (dict(chunk_size=3), ["chunk_size 2 there, 3 here"]),
    ],
    ids=["t1", "rtol", "chunk_size"],
)
def test_changed_sweep_with_manifest_is_refused(
    oscillator, batch, ckpt, chunk_calls, change, words
):
    with pytest.raises(lx.CheckpointError) as info:
        run(oscillator, batch, ckpt, **change)
    assert str(ckpt) in str(info.value)
    for word in words:
        assert word in str(info.value)
    assert chunk_calls == []


def test_stray_chunk_of_another_sweep_is_recomputed(
    oscillator, batch, reference, ckpt, chunk_calls, tmp_path
):
    other = tmp_path / "other"
    run(oscillator, batch, other, t1=0.5)
    shutil.copyfile(chunk(other, 2), chunk(ckpt, 2))
    chunk_calls.clear()
    with pytest.warns(lx.CheckpointWarning, match="belongs to another sweep"):
        ds = run(oscillator, batch, ckpt)
    assert_same(ds, reference)
    assert len(chunk_calls) == 1


def test_old_format_manifest_is_refused(oscillator, batch, ckpt, chunk_calls):
    manifest = ckpt / "manifest.json"
    info = json.loads(manifest.read_text())
    manifest.write_text(json.dumps(dict(info, version=1)))
    with pytest.raises(lx.CheckpointError, match="format 1") as err:
        run(oscillator, batch, ckpt)
    assert str(ckpt) in str(err.value) and "Delete the directory" in str(err.value)
    assert chunk_calls == []


def test_reduction_and_final_maxima_resume_from_disk_unchanged(tmp_path, monkeypatch):
    """A constrained sweep's keep= reduction (a list of 12 leaves, whose paths do not sort
    in leaf order) and its final maxima, read back from the checkpoint alone, give the
    same Dataset, variable for variable and in the same order."""
    system, params = lx.models.cartesian_pendulum()
    batch = lx.samples(params, l=[1.0, 1.2, 1.5])

    def reduce(sol):
        return {"q": [sol.q[-1, 0] * k for k in range(12)], "lam": sol.multipliers[-1]}

    kw = dict(keep=reduce, t1=0.5, n_save=5, chunk_size=2, checkpoint=tmp_path / "ckpt")
    first = lx.sweep(system, [0.6, -0.8], [0.8, 0.6], batch, **kw)
    monkeypatch.setattr(_driver, "solve_chunk", lambda *a, **k: pytest.fail("recomputed"))
    again = lx.sweep(system, [0.6, -0.8], [0.8, 0.6], batch, **kw)
    assert again.identical(first)
    assert list(again.data_vars) == list(first.data_vars)
    assert len(first.data_vars) == 23 and "constraint_violation" in first  # 13 reduced


def test_foreign_files_are_left_alone(oscillator, batch, reference, ckpt, chunk_calls):
    extra = {
        "notes.txt": b"my notes",
        "data.npz": b"whatever",
        "chunk_000001.npz.abc123.tmp": b"half a write",
        "chunk_1.npz": b"not our name",
    }
    for name, data in extra.items():
        (ckpt / name).write_bytes(data)
    (ckpt / "plots").mkdir()
    assert_same(run(oscillator, batch, ckpt), reference)
    assert chunk_calls == []
    for name, data in extra.items():
        assert (ckpt / name).read_bytes() == data


# --------------------------------------------------------------------------- cannot write


@pytest.fixture
def read_only(monkeypatch):
    """Make directories unwritable: by their mode, and (as root ignores modes) by failing
    the temporary file that every checkpoint write starts with."""
    made = []

    def make(path):
        path.mkdir(parents=True, exist_ok=True)
        path.chmod(0o555)
        made.append(path)
        if os.geteuid() == 0:

            def refuse(*a, **k):
                raise PermissionError(13, "Permission denied", str(path))

            monkeypatch.setattr(_checkpoint.tempfile, "mkstemp", refuse)
        return path

    yield make
    for path in made:
        path.chmod(0o755)


def test_read_only_directory_is_refused_before_any_work(
    oscillator, batch, tmp_path, chunk_calls, read_only
):
    ckpt = read_only(tmp_path / "ckpt")
    with pytest.raises(lx.CheckpointError) as info:
        run(oscillator, batch, ckpt)
    message = str(info.value)
    assert str(ckpt) in message and "cannot be written" in message
    assert chunk_calls == []  # refused before the first chunk, not after it


def test_complete_checkpoint_in_read_only_directory_is_read(
    oscillator, batch, reference, ckpt, chunk_calls, read_only
):
    read_only(ckpt)
    assert_same(run(oscillator, batch, ckpt), reference)
    assert chunk_calls == []


def test_checkpoint_that_is_a_file_is_refused(oscillator, batch, tmp_path):
    path = tmp_path / "ckpt"
    path.write_text("")
    with pytest.raises(lx.CheckpointError, match="is a file, not a directory"):
        run(oscillator, batch, path)


# --------------------------------------------------------------------------- load_sweep


@pytest.fixture(scope="module")
def saved(reference, tmp_path_factory):
    return lx.save_sweep(reference, tmp_path_factory.mktemp("saved") / "sweep.npz")


def rewrite_var(path):
    with np.load(path) as z:
        arrays = {k: np.asarray(z[k]) for k in z.files}
    arrays["var/q"] = arrays["var/q"] * 2
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def drop_meta(path):
    with np.load(path) as z:
        arrays = {k: np.asarray(z[k]) for k in z.files if k != "meta"}
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def not_a_sweep(path):
    with open(path, "wb") as f:
        np.savez(f, meta=np.asarray(json.dumps(dict(dims={"x": ["i"]}, attrs={}))), **{
            "var/x": np.arange(3)
        })  # fmt: skip


LOAD_DAMAGE = {
    "truncated": (truncate, "truncated or damaged"),
    "bit flip": (flip_a_bit, "truncated or damaged"),
    "empty": (empty, "empty"),
    "garbage": (garbage, "cannot be read"),
    "edited values": (rewrite_var, "checksum does not match"),
    "no meta": (drop_meta, "no 'meta' entry"),
    "not a sweep": (not_a_sweep, "['ok', 'result']"),
}


@pytest.mark.parametrize("damage, reason", LOAD_DAMAGE.values(), ids=list(LOAD_DAMAGE))
def test_load_sweep_of_damaged_file_names_path_and_fault(saved, tmp_path, damage, reason):
    path = tmp_path / "copy.npz"
    shutil.copyfile(saved, path)
    lx.load_sweep(path)  # the copy is good
    damage(path)
    with pytest.raises(lx.CheckpointError) as info:
        lx.load_sweep(path)
    assert str(path) in str(info.value) and reason in str(info.value)


def test_load_sweep_other_faults(saved, tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        lx.load_sweep(tmp_path / "missing.npz")
    with pytest.raises(lx.ConfigurationError, match="'.txt'"):
        lx.load_sweep(tmp_path / "sweep.txt")
    nc = tmp_path / "sweep.nc"
    nc.write_bytes(b"CDF\x01 cut short")
    with pytest.raises(lx.CheckpointError, match="sweep.nc cannot be read"):
        lx.load_sweep(nc)


# --------------------------------------------------------------------------- bad members


@pytest.fixture(scope="module")
def nan_force():
    """An oscillator whose force turns NaN after t = 0.5 for members with ``a > 0``."""

    def T(q, qd, p):
        return 0.5 * p["m"] * qd[0] ** 2

    def V(q, p):
        return 0.5 * p["k"] * q[0] ** 2

    def F(t, q, qd, p):
        return jnp.where(p["a"] > 0, jnp.log(0.5 - t), 0.0)[None]

    return lx.LagrangianSystem(T, V, force=F)


def test_nan_and_stiff_members_are_reported_and_poison_nothing(nan_force, tmp_path):
    base = dict(m=1.0, k=1.0, a=0.0)
    # good, stiff (step budget), NaN parameter, NaN mid-run, blow-up, good, good
    ks = [1.0, 1e8, 2.0, 3.0, -1e6, 4.0, 5.0]
    ms = [1.0, 1.0, np.nan, 1.0, 1.0, 1.0, 1.0]
    a_s = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
    mixed = lx.samples(base, k=ks, m=ms, a=a_s)
    kw = dict(t1=1.0, max_steps=400, chunk_size=2)
    ckpt = tmp_path / "ckpt"
    ds = lx.sweep(nan_force, [1.0], [0.0], mixed, checkpoint=ckpt, **kw)
    good = [0, 5, 6]
    bad = [1, 2, 3, 4]
    assert ds.ok.values.tolist() == [i in good for i in range(7)]
    r = lx.RESULTS
    assert ds.result.values[2] == r.invalid_input._value  # NaN parameter: not solved
    assert ds.result.values[1] == r.max_steps_reached._value  # stiff: out of steps
    assert all(ds.result.values[i] != r.successful._value for i in bad)
    assert ds.attrs["n_failed"] == 4
    assert not np.isnan(ds.q.values).any() and np.isinf(ds.q.values[bad]).all()
    # the good members equal a sweep of only them (other chunk-mates: round-off at most)
    alone = lx.sweep(
        nan_force, [1.0], [0.0], lx.samples(base, k=[ks[i] for i in good]), t1=1.0, max_steps=400
    )
    np.testing.assert_allclose(ds.q.values[good], alone.q.values, rtol=0, atol=1e-12)
    # the checkpoint holds exactly these results, every chunk verified, resumed unchanged
    for i in range(4):
        _checkpoint.read_chunk(chunk(ckpt, i))
    again = lx.sweep(nan_force, [1.0], [0.0], mixed, checkpoint=ckpt, **kw)
    assert_same(again, ds)
