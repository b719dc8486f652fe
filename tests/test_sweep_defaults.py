"""How a sweep cuts its batch: defaults from the device (CPU as before, GPU/TPU filled),
the lane queue's schedule counted exactly, and the same numbers whatever the schedule."""

import math
import os
import sys
import threading

import numpy as np
import pytest

import lagrax as lx
from lagrax._sweep import defaults as _defaults
from lagrax._sweep import driver as _driver
from lagrax._sweep.defaults import DeviceInfo, Plan, device_info, lane_bytes, plan

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "benchmarks"))
from _lane_schedule import chunk_lane_steps, idle_fraction  # noqa: E402

Q0_2R = [-np.pi / 2 + 1.4, 0.8]
GPU = DeviceInfo("gpu", 80 << 30, 1)  # one H100
ARM_LANE = lane_bytes(2, 9, 8)  # the 2R arm in float64
ARM_MEMBER = 8 * (2 * 2 + 1 + 4 * 2 + 8)  # its final state kept


def cpu_choice(n_members, member_bytes, chunk_size, n_lanes, count):
    """The chunk size and lane count of one CPU core, written out: chunks of up to
    8,192 members and 64 MiB of kept output, a whole number per device, 16 lanes."""
    if chunk_size is None:
        chunk_size = int(min(8192, max(64, (64 << 20) // member_bytes)))
    chunk_size = int(min(chunk_size, n_members))
    chunk_size = -(-chunk_size // count) * count
    per_device = chunk_size // count
    lanes = n_lanes if n_lanes is not None else 16
    return chunk_size, min(lanes, per_device)


@pytest.mark.parametrize("count", [1, 3])
def test_cpu_choices(count):
    for n_members in (1, 7, 64, 1000, 8192, 50_000, 10**6):
        for member_bytes in (56, 8 * 1000, 8 * 10**6):
            for chunk_size, n_lanes in [(None, None), (100, None), (None, 5), (64, 2)]:
                cut = plan(
                    DeviceInfo("cpu", None, count),
                    n_members=n_members,
                    member_bytes=member_bytes,
                    lane_bytes=ARM_LANE,
                    chunk_size=chunk_size,
                    n_lanes=n_lanes,
                )
                chunk, lanes = cpu_choice(n_members, member_bytes, chunk_size, n_lanes, count)
                assert (cut.chunk_size, cut.n_lanes) == (chunk, lanes)
                assert cut.refill == max(1, lanes // 16) and cut.tail_lanes == 0


def test_gpu_fills_the_device_for_the_2r_arm():
    # the best H100 setting at 524k members: 131k lanes, 4 members a lane
    big = plan(GPU, n_members=524_176, member_bytes=ARM_MEMBER, lane_bytes=ARM_LANE)
    assert big == Plan(524_176, 1 << 17, 1 << 12, 1 << 15)
    # more members: chunks of four members a lane
    huge = plan(GPU, n_members=10**7, member_bytes=ARM_MEMBER, lane_bytes=ARM_LANE)
    assert (huge.chunk_size, huge.n_lanes) == (4 << 17, 1 << 17)
    # fewer members than lanes would fill: one lane each, one chunk, no tail loop
    for n in (1, 2, 100, 4096, 32_761):
        small = plan(GPU, n_members=n, member_bytes=ARM_MEMBER, lane_bytes=ARM_LANE)
        assert (small.chunk_size, small.n_lanes, small.tail_lanes) == (n, n, 0)
        assert 1 <= small.refill <= max(1, n // 32)


def test_gpu_lanes_bounded_by_memory_and_model_size():
    # a 100-dof model: megabytes a lane, so memory bounds the lanes (a power of two)
    per_lane = lane_bytes(100, 50, 8)
    cut = plan(GPU, n_members=10**6, member_bytes=8 * 1000, lane_bytes=per_lane)
    assert cut.n_lanes < _defaults.MAX_LANES
    assert cut.n_lanes & (cut.n_lanes - 1) == 0
    budget = GPU.memory * _defaults.MEMORY_SHARE / 2
    assert budget / 2 < cut.n_lanes * per_lane <= budget
    assert cut.chunk_size == 4 * cut.n_lanes
    # float32 halves the memory a lane needs: twice the lanes
    assert plan(GPU, n_members=10**6, member_bytes=8000, lane_bytes=per_lane // 2).n_lanes == (
        2 * cut.n_lanes
    )
    # a kept trajectory of 10 MB a member bounds the chunk, not the lanes below it
    heavy = plan(GPU, n_members=10**6, member_bytes=10**7, lane_bytes=ARM_LANE)
    assert heavy.chunk_size == int(budget) // 10**7 and heavy.n_lanes == heavy.chunk_size


def test_gpu_without_memory_statistics_and_on_several_devices():
    blind = plan(DeviceInfo("gpu", None, 1), n_members=10**6, member_bytes=56, lane_bytes=per_mb(1))
    fit = _defaults.FALLBACK_MEMORY * _defaults.MEMORY_SHARE / 2 / per_mb(1)
    assert blind.n_lanes == 2 ** int(math.log2(fit))
    four = plan(
        DeviceInfo("tpu", 32 << 30, 4), n_members=10**6, member_bytes=56, lane_bytes=ARM_LANE
    )
    assert four.chunk_size == 10**6 and four.chunk_size % 4 == 0  # 250k a device: one chunk
    assert four.n_lanes == _defaults.MAX_LANES  # lanes are per device
    odd = plan(DeviceInfo("gpu", 80 << 30, 3), n_members=10, member_bytes=56, lane_bytes=ARM_LANE)
    assert (odd.chunk_size, odd.n_lanes) == (12, 4)  # padded to a whole number a device
    # the user's choices stand; lanes never exceed a chunk's members per device
    mine = plan(GPU, n_members=10**6, member_bytes=56, lane_bytes=ARM_LANE, n_lanes=1000)
    assert (mine.chunk_size, mine.n_lanes, mine.tail_lanes) == (4000, 1000, 0)
    mine = plan(GPU, n_members=10**6, member_bytes=56, lane_bytes=ARM_LANE, chunk_size=5000)
    assert (mine.chunk_size, mine.n_lanes) == (5000, 5000)


def per_mb(n):
    return n << 20


class FakeDevice:
    def __init__(self, platform, stats):
        self.platform, self._stats = platform, stats

    def memory_stats(self):
        if isinstance(self._stats, Exception):
            raise self._stats
        return self._stats


def test_device_info_reads_platform_and_memory():
    gpu = [FakeDevice("gpu", {"bytes_limit": 80 << 30, "bytes_in_use": 0})] * 2
    assert device_info(gpu) == DeviceInfo("gpu", 80 << 30, 2)
    assert device_info([FakeDevice("cuda", None)]) == DeviceInfo("gpu", None, 1)
    assert device_info([FakeDevice("tpu", {})]) == DeviceInfo("tpu", None, 1)
    no_stats = FakeDevice("cpu", NotImplementedError("no memory stats"))
    # one CPU device runs chunks on every core this process may use
    cores = _defaults.host_cores()
    assert cores == len(os.sched_getaffinity(0))
    assert device_info([no_stats]) == DeviceInfo("cpu", None, 1, cores)
    assert device_info([no_stats] * 2) == DeviceInfo("cpu", None, 2, 1)  # devices share them


@pytest.mark.parametrize("threads", [2, 3])
def test_cpu_cores_get_equal_chunks(threads):
    """With several cores, the batch is cut into a multiple of the cores' count of
    chunks of equal size (no chunk mostly padding), each on 16 lanes."""
    for n_members in (1, 7, 64, 1000, 8192, 50_000, 10**6):
        for member_bytes in (56, 8 * 10**6):
            one = plan(
                DeviceInfo("cpu", None, 1),
                n_members=n_members,
                member_bytes=member_bytes,
                lane_bytes=ARM_LANE,
            )
            cut = plan(
                DeviceInfo("cpu", None, 1, threads),
                n_members=n_members,
                member_bytes=member_bytes,
                lane_bytes=ARM_LANE,
            )
            n_chunks = -(-n_members // cut.chunk_size)
            assert cut.threads == threads and cut.chunk_size <= one.chunk_size
            if n_members >= threads:
                assert n_chunks % threads == 0 or n_chunks == -(-n_members // one.chunk_size)
                assert n_chunks >= threads
            # padding: less than a member per chunk
            assert n_chunks * cut.chunk_size - n_members < n_chunks
            assert cut.n_lanes == min(16, cut.chunk_size)
    # the user's chunk size is kept
    mine = plan(
        DeviceInfo("cpu", None, 1, threads),
        n_members=1000,
        member_bytes=56,
        lane_bytes=ARM_LANE,
        chunk_size=300,
    )
    assert (mine.chunk_size, mine.threads) == (300, threads)


def test_schedule_count_by_hand():
    # 2 lanes, 4 members of 3, 1, 2, 5 steps, refilled one at a time: lanes run
    # [3 | 1, 2, 5]: lane A 3 steps, lane B 1+2 steps, then A takes the 5-step member
    assert chunk_lane_steps(np.array([3, 1, 2, 5]), 2, 1) == (11, 2 * 8)
    # refilled two at a time: both lanes wait for the 3-step member, then 2 and 5
    assert chunk_lane_steps(np.array([3, 1, 2, 5]), 2, 2) == (11, 2 * 8)
    # lock-step: 4 lanes for 5 steps
    assert chunk_lane_steps(np.array([3, 1, 2, 5]), 4, 4) == (11, 4 * 5)
    # tail: 4 lanes step until 2 members are left (2 steps), then 2 lanes for 3 more
    assert chunk_lane_steps(np.array([3, 1, 2, 5]), 4, 4, tail_lanes=2) == (11, 4 * 2 + 2 * 3)


@pytest.fixture(scope="module")
def arm_batch(arm):
    system, params = arm
    return system, lx.grid(params, m2=np.linspace(0.5, 2.0, 12), l1=np.linspace(0.5, 1.5, 8))


def test_cpu_sweep_reports_its_cut_and_its_idle_count(arm_batch, monkeypatch):
    system, batch = arm_batch
    monkeypatch.setattr(_defaults, "host_cores", lambda: 1)
    ds = lx.sweep(system, Q0_2R, [0.0, 0.0], batch, t1=2.0, progress=False)
    a = ds.attrs
    assert (a["platform"], a["chunk_size"], a["n_lanes"]) == ("cpu", 96, 16)
    assert (a["refill_lanes"], a["tail_lanes"], a["threads"]) == (1, 0, 1)
    steps = ds.num_steps.values.ravel()
    assert a["lane_idle_fraction"] == idle_fraction(steps, 96, 16, 1, 0)
    # chunks of 40 (the last padded with copies of its first member), 5 lanes
    ds = lx.sweep(
        system, Q0_2R, [0.0, 0.0], batch, t1=2.0, chunk_size=40, n_lanes=5, progress=False
    )
    assert (ds.attrs["chunk_size"], ds.attrs["n_lanes"]) == (40, 5)
    assert ds.attrs["lane_idle_fraction"] == idle_fraction(steps, 40, 5, 1, 0)


def test_chunks_on_several_cores_give_the_same_numbers(arm_batch, monkeypatch):
    """Two cores: the 96 members in two chunks of 48, solved at once on two threads (as
    the worker threads' identities show), bitwise the numbers of the same cut run one
    chunk after the other."""
    system, batch = arm_batch
    kw = dict(t1=2.0, keep="trajectory", n_save=5, progress=False)
    threads_seen = set()
    solve = _driver.solve_chunk

    def spy(*args, **kwargs):
        threads_seen.add(threading.get_ident())
        return solve(*args, **kwargs)

    monkeypatch.setattr(_defaults, "host_cores", lambda: 1)
    one = lx.sweep(system, Q0_2R, [0.0, 0.0], batch, chunk_size=48, **kw)
    monkeypatch.setattr(_defaults, "host_cores", lambda: 2)
    monkeypatch.setattr(_driver, "solve_chunk", spy)
    two = lx.sweep(system, Q0_2R, [0.0, 0.0], batch, **kw)
    assert (two.attrs["chunk_size"], two.attrs["threads"], one.attrs["threads"]) == (48, 2, 1)
    assert len(threads_seen) == 2 and threading.get_ident() not in threads_seen
    for name in ("q", "qd", "energy", "num_steps", "t_end", "energy_error", "result"):
        np.testing.assert_array_equal(two[name].values, one[name].values)
    assert two.attrs["lane_idle_fraction"] == one.attrs["lane_idle_fraction"]


def test_gpu_schedule_on_cpu_gives_the_same_numbers(arm_batch, monkeypatch):
    """The accelerator schedule (block refills, a tail loop), forced on the CPU: every
    member's states and steps bitwise those of lock-step, and the idle count as
    predicted."""
    system, batch = arm_batch
    kw = dict(t1=2.0, keep="trajectory", n_save=5, progress=False)
    lock = lx.sweep(system, Q0_2R, [0.0, 0.0], batch, schedule="lockstep", **kw)
    monkeypatch.setattr(_driver, "device_info", lambda devices: DeviceInfo("gpu", 8 << 30, 1))
    monkeypatch.setattr(_defaults, "TAIL_MIN_LANES", 16)
    ds = lx.sweep(system, Q0_2R, [0.0, 0.0], batch, n_lanes=32, **kw)
    a = ds.attrs
    assert (a["platform"], a["chunk_size"], a["n_lanes"]) == ("gpu", 96, 32)
    assert (a["refill_lanes"], a["tail_lanes"]) == (1, 8)
    for name in ("q", "qd", "num_steps", "num_accepted_steps", "t_end"):
        np.testing.assert_array_equal(ds[name].values, lock[name].values)
    # (the energy is evaluated after the solve, in a program that differs by schedule)
    np.testing.assert_allclose(ds.energy.values, lock.energy.values, rtol=1e-13)
    steps = ds.num_steps.values.ravel()
    assert a["lane_idle_fraction"] == idle_fraction(steps, 96, 32, 1, 8)
    assert a["lane_idle_fraction"] < idle_fraction(steps, 96, 32, 2, 0)  # CPU's refill
    assert a["lane_idle_fraction"] < lock.attrs["lane_idle_fraction"]


def test_checkpoint_from_a_cpu_resumes_on_a_gpu(arm_batch, tmp_path, monkeypatch):
    """Lanes do not define a sweep's results: a checkpoint written with the CPU's
    defaults is complete for the same sweep on a GPU, whose default lanes differ."""
    system, batch = arm_batch
    kw = dict(t1=1.0, chunk_size=48, checkpoint=tmp_path / "ckpt", progress=False)
    cpu = lx.sweep(system, Q0_2R, [0.0, 0.0], batch, **kw)
    assert cpu.attrs["n_lanes"] == 16
    calls = []
    monkeypatch.setattr(_driver, "solve_chunk", lambda *a, **k: calls.append(1))
    monkeypatch.setattr(_driver, "device_info", lambda devices: DeviceInfo("gpu", 8 << 30, 1))
    gpu = lx.sweep(system, Q0_2R, [0.0, 0.0], batch, **kw)
    assert calls == [] and gpu.attrs["n_lanes"] == 48
    np.testing.assert_array_equal(gpu.q.values, cpu.q.values)
    # other results still refuse the directory
    with pytest.raises(lx.CheckpointError, match="different sweep definition"):
        lx.sweep(system, Q0_2R, [0.0, 0.0], batch, **{**kw, "t1": 2.0})


def test_sweep_docstring_says_how_to_override():
    doc = lx.sweep.__doc__ or ""
    assert "chunk_size=" in doc and "n_lanes=" in doc and "GPU" in doc


def test_gpu_benchmark_without_a_gpu_says_so(capsys):
    import bench_sweep_gpu

    assert bench_sweep_gpu.main(["--sizes", "64"]) == 0
    out = capsys.readouterr().out
    assert "no GPU found" in out and "cpu" in out


def test_gpu_benchmark_mjcf_is_the_lagrax_arm(arm):
    """The MJCF arm of bench_sweep_gpu.py against lagrax (MuJoCo's own C stepper)."""
    mujoco = pytest.importorskip("mujoco")
    import bench_sweep_gpu

    system, params = arm
    params = dict(params, m2=1.6, l1=0.7)
    dt, t1 = 1e-3, 1.0
    model = mujoco.MjModel.from_xml_string(bench_sweep_gpu.arm_mjcf(params, dt))
    data = mujoco.MjData(model)
    data.qpos[:] = Q0_2R
    for _ in range(round(t1 / dt)):
        mujoco.mj_step(model, data)
    sol = lx.simulate(system, Q0_2R, [0.0, 0.0], params, t1=t1, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(data.qpos, sol.q_end, atol=1e-9)
    np.testing.assert_allclose(data.qvel, sol.qd_end, atol=1e-8)
