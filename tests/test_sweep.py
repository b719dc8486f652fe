"""lagrax.sweep: equal to a loop of simulate, labelled, robust to failures, sharded,
checkpointed and resumable, and bounded in memory by its chunks."""

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax._sweep import chunk as _chunk

Q0_2R = [-np.pi / 2 + 1.4, 0.8]


def damped_oscillator(x0, v0, m, k, c, t):
    """Closed-form x(t), v(t) of m x'' + c x' + k x = 0 (underdamped)."""
    wn = np.sqrt(k / m)
    zeta = c / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta**2)
    a, b = x0, (v0 + zeta * wn * x0) / wd
    e = np.exp(-zeta * wn * t)
    x = e * (a * np.cos(wd * t) + b * np.sin(wd * t))
    v = -zeta * wn * x + e * (-a * wd * np.sin(wd * t) + b * wd * np.cos(wd * t))
    return x, v


@pytest.fixture(scope="module")
def arm():
    return lx.models.planar_2r()


@pytest.fixture(scope="module")
def oscillator():
    return lx.models.mass_spring_damper()


@pytest.fixture(scope="module")
def arm_grid(arm):
    _, params = arm
    return lx.grid(params, m2=[0.7, 1.0, 1.6], l1=[0.8, 1.2])


@pytest.fixture(scope="module")
def arm_traj(arm, arm_grid):
    system, _ = arm
    return lx.sweep(
        system, Q0_2R, [0.0, 0.0], arm_grid, t1=2.0, keep="trajectory", n_save=11, n_lanes=2
    )


def test_sweep_equals_loop_of_simulate(arm, arm_grid, arm_traj):
    assert arm_traj.time.attrs["units"] == "s"
    system, params = arm
    ds = arm_traj
    assert ds.q.dims == ("m2", "l1", "time", "dof") and ds.q.shape == (3, 2, 11, 2)
    assert bool(ds.ok.all()) and ds.attrs["n_failed"] == 0
    for i, m2 in enumerate(arm_grid.axes["m2"]):
        for j, l1 in enumerate(arm_grid.axes["l1"]):
            p = dict(params, m2=m2, l1=l1)
            sol = lx.simulate(system, Q0_2R, [0.0, 0.0], p, t1=2.0, ts=ds.time.values)
            member = ds.isel(m2=i, l1=j)
            # the same steps as simulate: equal up to vectorized round-off
            np.testing.assert_allclose(member.q.values, sol.q, rtol=0, atol=1e-11)
            np.testing.assert_allclose(member.qd.values, sol.qd, rtol=0, atol=1e-10)
            np.testing.assert_allclose(member.energy.values, sol.energy, rtol=0, atol=1e-11)
            assert int(member.num_steps) == int(sol.stats["num_steps"])


def test_lockstep_schedule_matches_queue(arm, arm_grid, arm_traj):
    system, _ = arm
    ds = lx.sweep(
        system,
        Q0_2R,
        [0.0, 0.0],
        arm_grid,
        t1=2.0,
        keep="trajectory",
        n_save=11,
        schedule="lockstep",
    )
    np.testing.assert_allclose(ds.q.values, arm_traj.q.values, rtol=0, atol=1e-11)
    np.testing.assert_array_equal(ds.num_steps.values, arm_traj.num_steps.values)
    # lock-step pads the fast members: its idle share is at least the work queue's on
    # the same chunk (on its default lanes)
    size = arm_grid.size
    kw = dict(t1=2.0, keep="trajectory", n_save=11, chunk_size=size, progress=False)
    queue = lx.sweep(system, Q0_2R, [0.0, 0.0], arm_grid, **kw)
    lock = lx.sweep(system, Q0_2R, [0.0, 0.0], arm_grid, schedule="lockstep", **kw)
    assert queue.attrs["n_lanes"] == min(16, size) and lock.attrs["n_lanes"] == size
    assert lock.attrs["lane_idle_fraction"] >= queue.attrs["lane_idle_fraction"]


def test_final_state_against_closed_form(oscillator):
    """A (k, c) grid of damped oscillators against the analytic solution."""
    system, params = oscillator
    ks, cs = np.array([0.5, 1.0, 4.0, 9.0]), np.array([0.0, 0.1, 0.5])
    batch = lx.grid(params, k=ks, c=cs)
    ds = lx.sweep(system, [1.0], [0.0], batch, t1=3.0, rtol=1e-10, atol=1e-10)
    assert ds.q.dims == ("k", "c", "dof")
    np.testing.assert_array_equal(ds.k.values, ks)
    np.testing.assert_array_equal(ds.c.values, cs)
    K, C = np.meshgrid(ks, cs, indexing="ij")
    x, v = damped_oscillator(1.0, 0.0, 1.0, K, C, 3.0)
    np.testing.assert_allclose(ds.q.values[..., 0], x, atol=1e-8)
    np.testing.assert_allclose(ds.qd.values[..., 0], v, atol=1e-8)
    # energy: E(t) = ½(m v² + k x²) against the closed form; its change, and the balance
    # residual (the damper's work accounted for) as the error
    e0, e1 = 0.5 * K, 0.5 * (v**2 + K * x**2)
    np.testing.assert_allclose(ds.energy.values, e1, rtol=1e-7, atol=1e-12)
    np.testing.assert_allclose(ds.energy_change.values, e1 - e0, atol=1e-8)
    assert np.abs(ds.energy_error.values).max() < 1e-8


def test_grid_and_samples_shapes_and_labels(arm):
    _, params = arm
    g = lx.grid(params, m2=[1.0, 2.0, 3.0], l1=[0.5, 1.5])
    assert (g.dims, g.shape, g.size) == (("m2", "l1"), (3, 2), 6)
    p = g.params()
    # C order: l1 varies fastest; fixed entries broadcast to the batch
    np.testing.assert_array_equal(p["m2"], [1, 1, 2, 2, 3, 3])
    np.testing.assert_array_equal(p["l1"], [0.5, 1.5] * 3)
    np.testing.assert_array_equal(p["g"], np.full(6, float(params["g"])))
    np.testing.assert_array_equal(g.params(2, 4)["m2"], [2, 2])
    s = lx.samples(params, m2=[1.0, 2.0], r2=[0.3, 0.4])
    assert (s.dims, s.shape) == (("member",), (2,))
    np.testing.assert_array_equal(s.params()["r2"], [0.3, 0.4])
    with pytest.raises(lx.ShapeError, match="one length"):
        lx.samples(params, m2=[1.0, 2.0], r2=[0.3])
    with pytest.raises(lx.ShapeError, match="1-D"):
        lx.grid(params, m2=np.ones((2, 2)))
    with pytest.raises(ValueError, match="at least one"):
        lx.grid(params)


def test_keep_times_and_reduction(oscillator):
    system, params = oscillator
    batch = lx.samples(params, k=[1.0, 4.0])
    times = np.array([0.0, 0.5, 2.0])
    ds = lx.sweep(system, [1.0], [0.0], batch, t1=2.0, keep=times, rtol=1e-10, atol=1e-10)
    assert ds.q.dims == ("member", "time", "dof")
    np.testing.assert_array_equal(ds.time.values, times)
    np.testing.assert_array_equal(ds.k.values, [1.0, 4.0])
    x, _ = damped_oscillator(1.0, 0.0, 1.0, np.array([[1.0], [4.0]]), 0.0, times)
    np.testing.assert_allclose(ds.q.values[..., 0], x, atol=1e-8)

    def reduce(sol):
        return {
            "x_max": jnp.max(sol.q[:, 0]),
            "x_min": jnp.min(sol.q[:, 0]),
            "e_err": jnp.max(jnp.abs(sol.energy_error)),
        }

    red = lx.sweep(
        system, [1.0], [0.0], batch, t1=2.0, keep=reduce, n_save=201, rtol=1e-10, atol=1e-10
    )
    assert set(red.data_vars) >= {"x_max", "x_min", "e_err", "ok"}
    assert "q" not in red.data_vars
    tt = np.linspace(0, 2, 201)
    for i, k in enumerate([1.0, 4.0]):
        xs, _ = damped_oscillator(1.0, 0.0, 1.0, k, 0.0, tt)
        assert float(red.x_min[i]) == pytest.approx(xs.min(), abs=1e-8)
        assert float(red.x_max[i]) == pytest.approx(1.0, abs=1e-12)
        assert float(red.e_err[i]) < 1e-8


def test_failed_members_are_flagged_not_fatal(oscillator):
    """A stiff member runs out of steps, a massless one is invalid; the rest finish."""
    system, params = oscillator
    batch = lx.samples(params, k=[1.0, 1e8, 2.0, 3.0], m=[1.0, 1.0, 0.0, 1.0])
    ds = lx.sweep(system, [1.0], [0.0], batch, t1=1.0, max_steps=2000)
    codes = ds.result.values
    assert codes.tolist() == [
        lx.RESULTS.successful._value,
        lx.RESULTS.max_steps_reached._value,
        lx.RESULTS.invalid_input._value,
        lx.RESULTS.successful._value,
    ]
    assert ds.ok.values.tolist() == [True, False, False, True]
    assert ds.attrs["n_failed"] == 2
    failures = json.loads(ds.attrs["failures"])
    assert sum(failures.values()) == 2 and any("maximum number" in k for k in failures)
    assert "max" in str(ds.status.values[1]).lower() and "not solved" in str(ds.status.values[2])
    # failed members: inf, never NaN; the stiff one says where it stopped
    assert not np.isnan(ds.q.values).any()
    assert np.isinf(ds.q.values[1:3]).all()
    assert 0 < float(ds.t_end[1]) < 1.0 and int(ds.num_steps[1]) == 2000
    for i, k in [(0, 1.0), (3, 3.0)]:
        x, _ = damped_oscillator(1.0, 0.0, 1.0, k, 0.0, 1.0)
        assert float(ds.q[i, 0]) == pytest.approx(x, abs=1e-6)


def test_batched_pytree_params_and_states(arm):
    """Params as a pytree with a leading batch axis, one initial state per member."""
    system, params = arm
    m2 = np.array([0.8, 1.4])
    batch = {k: np.full(2, float(v)) for k, v in params.items()}
    batch["m2"] = m2
    q0 = np.array([[0.3, 0.2], [0.1, -0.4]])
    ds = lx.sweep(system, q0, np.zeros((2, 2)), batch, t1=1.0, keep="final", n_lanes=2)
    assert ds.q.dims == ("member", "dof")
    np.testing.assert_array_equal(ds.m2.values, m2)
    for i in range(2):
        sol = lx.simulate(system, q0[i], [0.0, 0.0], dict(params, m2=m2[i]), t1=1.0)
        np.testing.assert_allclose(ds.q.values[i], sol.q_end, atol=1e-11)
    with pytest.raises(lx.ShapeError, match="leading batch axis"):
        lx.sweep(system, Q0_2R, [0.0, 0.0], params, t1=1.0)
    with pytest.raises(lx.ShapeError, match="q0"):
        lx.sweep(system, np.zeros((3, 2)), [0.0, 0.0], batch, t1=1.0)


def test_chunks_bound_the_compiled_batch(oscillator, monkeypatch):
    system, params = oscillator
    ks = np.linspace(0.5, 5.0, 10)
    batch = lx.samples(params, k=ks)
    whole = lx.sweep(system, [1.0], [0.0], batch, t1=1.0, chunk_size=16)
    sizes = []
    real = _chunk._run_chunk

    def spy(setup, mesh, members, y0s, *rest):
        sizes.append(int(y0s[0].shape[0]))
        return real(setup, mesh, members, y0s, *rest)

    monkeypatch.setattr(_chunk, "_run_chunk", spy)
    chunked = lx.sweep(system, [1.0], [0.0], batch, t1=1.0, chunk_size=4)
    assert sizes == [4, 4, 4]  # the last chunk is padded: one compiled size
    np.testing.assert_array_equal(chunked.q.values, whole.q.values)
    np.testing.assert_array_equal(chunked.k.values, ks)


def test_save_and_load_roundtrip(arm_traj, tmp_path):
    path = lx.save_sweep(arm_traj, tmp_path / "sweep.npz")
    back = lx.load_sweep(path)
    for name in ("q", "qd", "energy", "ok", "result", "status", "num_steps"):
        np.testing.assert_array_equal(back[name].values, arm_traj[name].values)
        assert back[name].dims == arm_traj[name].dims
    np.testing.assert_array_equal(back.m2.values, arm_traj.m2.values)
    assert back.attrs["n_members"] == arm_traj.attrs["n_members"]
    with pytest.raises(ValueError, match="unknown format"):
        lx.save_sweep(arm_traj, tmp_path / "sweep.txt")


def test_progress_bar(oscillator, capsys):
    system, params = oscillator
    lx.sweep(system, [1.0], [0.0], lx.samples(params, k=[1.0, 2.0]), t1=0.5, progress=True)
    err = capsys.readouterr().err
    assert "member" in err and "2/2" in err
    lx.sweep(system, [1.0], [0.0], lx.samples(params, k=[1.0, 2.0]), t1=0.5, progress=False)
    assert capsys.readouterr().err == ""


SHARDED = textwrap.dedent(
    """
    import json, numpy as np, jax, lagrax as lx
    system, params = lx.models.planar_2r()
    batch = lx.grid(params, m2=np.linspace(0.5, 2, 5), l1=np.linspace(0.5, 1.5, 3))
    kw = dict(t1=1.0, keep="trajectory", n_save=5, progress=False)
    one = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, devices=1, **kw)
    four = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, devices=4, **kw)
    print(json.dumps(dict(n=len(jax.devices()), devices=four.attrs["devices"],
                          diff=float(np.max(np.abs(one.q.values - four.q.values))),
                          same_steps=bool(np.array_equal(one.num_steps, four.num_steps)),
                          ok=bool(four.ok.all()))))
    """
)


def test_sharded_equals_unsharded():
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4")
    r = subprocess.run(
        [sys.executable, "-c", SHARDED], env=env, capture_output=True, text=True, timeout=600
    )
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    # the same steps on every member; values equal up to round-off of the vector width
    assert out.pop("diff") < 1e-12
    assert out == dict(n=4, devices=4, same_steps=True, ok=True)


CHECKPOINTED = textwrap.dedent(
    """
    import sys, time, numpy as np, lagrax as lx
    from lagrax._sweep import driver as _driver
    real = _driver.solve_chunk
    def slow(*a, **k):  # give the test time to kill us between chunks
        out = real(*a, **k)
        time.sleep(0.5)
        return out
    _driver.solve_chunk = slow
    system, params = lx.models.planar_2r()
    batch = lx.grid(params, m2=np.linspace(0.5, 2, 6), l1=np.linspace(0.5, 1.5, 4))
    lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, t1=1.0, chunk_size=4,
             checkpoint=sys.argv[1], progress=False)
    """
)


@pytest.mark.slow
def test_kill_and_resume_equals_uninterrupted(arm, tmp_path, chunk_calls):
    system, params = arm
    batch = lx.grid(params, m2=np.linspace(0.5, 2, 6), l1=np.linspace(0.5, 1.5, 4))
    ckpt = tmp_path / "ckpt"
    proc = subprocess.Popen(
        [sys.executable, "-c", CHECKPOINTED, str(ckpt)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    deadline = time.time() + 300
    while time.time() < deadline and len(list(ckpt.glob("chunk_*.npz"))) < 2:
        if proc.poll() is not None:
            _, err = proc.communicate()
            pytest.fail(f"the sweep ended before it was killed: {err.decode()[-2000:]}")
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.communicate()  # reap it and close its pipes
    done = sorted(p.name for p in ckpt.glob("chunk_*.npz"))
    assert 2 <= len(done) < 6 and not list(ckpt.glob("*.tmp"))

    calls = chunk_calls
    kw = dict(t1=1.0, chunk_size=4)
    resumed = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, checkpoint=ckpt, **kw)
    assert len(calls) == 6 - len(done)  # nothing finished is recomputed
    fresh = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, **kw)
    for name in ("q", "qd", "energy", "num_steps", "result"):
        np.testing.assert_array_equal(resumed[name].values, fresh[name].values)

    again = len(calls)
    lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, checkpoint=ckpt, **kw)
    assert len(calls) == again  # all chunks on disk now
    with pytest.raises(ValueError, match="different sweep definition"):
        lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, checkpoint=ckpt, rtol=1e-9, **kw)
    other = lx.grid(params, m2=np.linspace(0.5, 2.5, 6), l1=np.linspace(0.5, 1.5, 4))
    with pytest.raises(ValueError, match="different sweep definition"):
        lx.sweep(system, [0.3, 0.8], [0.0, 0.0], other, checkpoint=ckpt, **kw)


@pytest.mark.slow
def test_multihost_example_matches_single_process(arm, tmp_path):
    """examples/multihost_sweep.py with two CPU processes == one process."""
    import socket

    with socket.socket() as s:
        s.bind(("localhost", 0))
        port = s.getsockname()[1]
    script = os.path.join(os.path.dirname(__file__), "..", "examples", "multihost_sweep.py")
    out = tmp_path / "multi.npz"
    common = [
        sys.executable,
        script,
        "--coordinator",
        f"localhost:{port}",
        "--num-processes",
        "2",
        "--out",
        str(out),
    ]
    procs = [
        subprocess.Popen(
            common + ["--process-id", str(i)],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        for i in (0, 1)
    ]
    logs = [p.communicate(timeout=600)[0] for p in procs]
    assert all(p.returncode == 0 for p in procs), logs[0][-2000:] + logs[1][-2000:]
    assert all("process" in log and "2 devices" in log for log in logs)
    multi = lx.load_sweep(out)
    system, params = arm
    batch = lx.grid(params, m2=np.linspace(0.5, 2.0, 16), l1=np.linspace(0.5, 1.5, 16))
    single = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, t1=5.0)
    np.testing.assert_array_equal(multi.num_steps.values, single.num_steps.values)
    # same steps; values agree up to round-off (the per-device loops are compiled for
    # different lane counts), amplified by the chaotic arm over 5 s: median ~1e-12
    np.testing.assert_allclose(multi.q.values, single.q.values, rtol=1e-7, atol=1e-8)
    assert np.median(np.abs(multi.q.values - single.q.values)) < 1e-10


def test_constrained_system_sweep_matches_simulate():
    """A ConstrainedSystem: initial states projected per member, violation reported."""
    system, params = lx.models.cartesian_pendulum()
    lengths = np.array([0.5, 1.0, 2.0])
    q0 = np.array([0.6, -0.9])  # off the circle for every length: projected first
    ds = lx.sweep(
        system, q0, [0.0, 0.0], lx.samples(params, l=lengths), t1=2.0, rtol=1e-10, atol=1e-10
    )
    assert bool(ds.ok.all())
    assert float(ds.constraint_violation.max()) < 1e-8
    for i, length in enumerate(lengths):
        sol = lx.simulate(
            system, q0, [0.0, 0.0], dict(params, l=length), t1=2.0, rtol=1e-10, atol=1e-10
        )
        np.testing.assert_allclose(ds.q.values[i], sol.q_end, atol=1e-9)
        assert float(np.hypot(*ds.q.values[i])) == pytest.approx(length, rel=1e-8)


def _pendulum():
    """A hand-written simple pendulum, angle from the downward vertical."""

    def kinetic(q, qd, p):
        return 0.5 * p["m"] * p["l"] ** 2 * qd[0] ** 2

    def potential(q, p):
        return -p["m"] * p["g"] * p["l"] * jnp.cos(q[0])

    return lx.LagrangianSystem(kinetic, potential, n_dof=1), {"m": 1.0, "l": 1.0, "g": 9.81}


@pytest.fixture(scope="module")
def amplitude_study():
    system, params = _pendulum()
    batch = lx.grid(
        params,
        q0_0=np.linspace(0.2, 3.0, 5),
        l=np.array([0.5, 1.0]),
        units={"q0_0": "rad", "l": "m"},
    )
    return system, params, batch, lx.sweep(system, [0.0], [0.0], batch, t1=1.5, progress=False)


def test_amplitude_study_matches_simulate(amplitude_study):
    system, params, batch, ds = amplitude_study
    # one labelled dimension per swept quantity, no anonymous "member"
    assert ds.q.dims == ("q0_0", "l", "dof") and "member" not in ds.dims
    np.testing.assert_array_equal(ds.q0_0.values, np.linspace(0.2, 3.0, 5))
    assert ds.q0_0.attrs == {"units": "rad", "long_name": "initial q[0]"}
    assert ds.l.attrs["units"] == "m" and ds.t_end.attrs["units"] == "s"
    assert batch.states == {"q0_0": ("q0", 0)}
    for a in ds.q0_0.values:
        for length in ds.l.values:
            sol = lx.simulate(system, [a], [0.0], {**params, "l": length}, t1=1.5)
            member = ds.sel(q0_0=a, l=length)
            np.testing.assert_allclose(member.q.values, sol.q[-1], rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(member.qd.values, sol.qd[-1], rtol=1e-9, atol=1e-12)
    # and against the closed form of the pendulum released from rest at θ0, any amplitude:
    # sin(θ/2) = k cd(ω t | k²), k = sin(θ0/2), ω = sqrt(g/l) (Jacobi elliptic functions)
    from scipy.special import ellipj

    for length in ds.l.values:
        k = np.sin(ds.q0_0.values / 2)
        sn, cn, dn, _ = ellipj(np.sqrt(9.81 / length) * 1.5, k**2)
        theta = 2 * np.arcsin(k * cn / dn)
        np.testing.assert_allclose(ds.q.sel(l=length, dof=0).values, theta, atol=1e-6)


def test_samples_of_velocities_and_bad_state_axes():
    system, params = _pendulum()
    qd0s = np.array([0.5, -1.0, 2.0])
    batch = lx.samples(params, qd0_0=qd0s, m=np.array([1.0, 2.0, 3.0]))
    ds = lx.sweep(system, [0.1], [0.0], batch, t1=0.5, progress=False)
    assert ds.q.dims == ("member", "dof") and list(ds.qd0_0.values) == list(qd0s)
    for i, v in enumerate(qd0s):
        sol = lx.simulate(system, [0.1], [v], {**params, "m": float(i + 1)}, t1=0.5)
        np.testing.assert_allclose(ds.q.values[i], sol.q[-1], rtol=1e-9, atol=1e-12)
    with pytest.raises(lx.ShapeError, match=r"q0_3.*1 coordinates"):
        lx.sweep(system, [0.1], [0.0], lx.grid(params, q0_3=[0.1, 0.2]), t1=0.5)
    with pytest.raises(lx.ConfigurationError, match="'r2'"):
        lx.grid(params, q0_0=[0.1, 0.2], units={"r2": "m"})
    # a parameter that happens to be called q0_0 stays a parameter
    assert lx.grid({**params, "q0_0": 1.0}, q0_0=[0.1, 0.2]).states == {}
