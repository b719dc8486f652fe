"""A 2R-arm parameter sweep: lagrax against what users would otherwise write.

4,096 parameter sets (a 64 × 64 grid of m2 ∈ [0.5, 2] kg and l1 ∈ [0.5, 1.5] m), the
chaotic start θ = (−π/2 + 1.4, 0.8) at rest, 10 s, final state kept, rtol = atol = 1e-8.
Everything below is measured in one run, after compilation (compile times separately):

1. ``lagrax.sweep`` on the autodiff model, work-queue schedule (the default), and the
   share of lane-steps that were idle padding;
2. the same sweep with ``schedule="lockstep"`` (a plain ``vmap`` of ``simulate``), for
   the padding it wastes;
3. the same work queue on the lecture's closed-form right-hand side (the price of
   autodiff in a sweep);
4. final-state accuracy against Dopri8 at rtol = atol = 1e-12 on a subset;
5. a numba-compiled fixed-step RK4 over the closed form, one thread, at the largest step
   whose median final-state error on that subset is no worse than lagrax's (the
   compiled-code speed limit on one core);
6. SciPy ``solve_ivp`` loops (DOP853, and RK45, its default) over a subset, extrapolated
   to the batch;
7. (``--memory``) peak RSS of a final-state sweep of 10⁴ and 10⁵ members, each in a
   fresh process (horizon 1 s: memory does not depend on it);
8. (``--devices``) throughput on 2 simulated CPU devices against 1, in a fresh process
   (``XLA_FLAGS=--xla_force_host_platform_device_count=2``).

    python benchmarks/bench_sweep.py [--repeats 3] [--memory] [--devices]
"""

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np

import lagrax as lx
from lagrax._solve.lanes import run_lanes

sys.path.insert(0, os.path.dirname(__file__))
from _closed_form import forward_dynamics_2r  # noqa: E402
from _optional import available  # noqa: E402

Q0 = (-math.pi / 2 + 1.4, 0.8)
T1 = 10.0
TOL = 1e-8


def the_grid(params, side):
    return lx.grid(params, m2=np.linspace(0.5, 2.0, side), l1=np.linspace(0.5, 1.5, side))


def timed(fn, repeats):
    t = time.perf_counter()
    out = fn()
    first = time.perf_counter() - t
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return out, first, statistics.median(times)


def closed_form_sweep(batch_params, n_lanes):
    """The lagrax work queue on the closed-form right-hand side (no autodiff)."""
    term = dfx.ODETerm(lambda t, y, args: (y[1], forward_dynamics_2r(y[0], y[1], args[0])))
    ctrl = dfx.PIDController(rtol=TOL, atol=TOL)
    m = next(iter(batch_params.values())).shape[0]
    y0 = (jnp.broadcast_to(jnp.asarray(Q0), (m, 2)), jnp.zeros((m, 2)))

    @jax.jit
    def run(p, y0):
        out = run_lanes(
            term,
            dfx.Tsit5(),
            ctrl,
            p,
            y0,
            None,
            jnp.asarray(0.0),
            jnp.asarray(T1),
            None,
            jnp.zeros(0),
            n_lanes,
            100_000,
        )
        return out.y_end

    return lambda: jax.block_until_ready(run(batch_params, y0))


def numba_rk4(params_np):
    import numba

    @numba.njit(cache=False, fastmath=False)
    def rhs(q1, q2, w1, w2, m1, m2, l1, r1, r2, i1, i2, g):
        s2, c2 = math.sin(q2), math.cos(q2)
        c1, c12 = math.cos(q1), math.cos(q1 + q2)
        h = m2 * l1 * r2
        m11 = i1 + i2 + m1 * r1 * r1 + m2 * (l1 * l1 + r2 * r2) + 2 * h * c2
        m22 = i2 + m2 * r2 * r2
        m12 = m22 + h * c2
        b1 = h * s2 * (2 * w1 + w2) * w2 - m1 * g * r1 * c1 - m2 * g * (l1 * c1 + r2 * c12)
        b2 = -h * s2 * w1 * w1 - m2 * g * r2 * c12
        det = m11 * m22 - m12 * m12
        return (m22 * b1 - m12 * b2) / det, (m11 * b2 - m12 * b1) / det

    @numba.njit(cache=False)
    def run(P, q0, dt, t1):
        n_steps = int(round(t1 / dt))
        out = np.empty((P.shape[0], 4))
        for k in range(P.shape[0]):
            m1, m2, l1, r1, r2, i1, i2, g = P[k]
            y = np.array([q0[0], q0[1], 0.0, 0.0])
            for _ in range(n_steps):
                a1, a2 = rhs(y[0], y[1], y[2], y[3], m1, m2, l1, r1, r2, i1, i2, g)
                k1 = np.array([y[2], y[3], a1, a2])
                z = y + 0.5 * dt * k1
                a1, a2 = rhs(z[0], z[1], z[2], z[3], m1, m2, l1, r1, r2, i1, i2, g)
                k2 = np.array([z[2], z[3], a1, a2])
                z = y + 0.5 * dt * k2
                a1, a2 = rhs(z[0], z[1], z[2], z[3], m1, m2, l1, r1, r2, i1, i2, g)
                k3 = np.array([z[2], z[3], a1, a2])
                z = y + dt * k3
                a1, a2 = rhs(z[0], z[1], z[2], z[3], m1, m2, l1, r1, r2, i1, i2, g)
                k4 = np.array([z[2], z[3], a1, a2])
                y = y + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            out[k] = y
        return out

    keys = ("m1", "m2", "l1", "r1", "r2", "I1", "I2", "g")
    P = np.stack([np.asarray(params_np[k], float) for k in keys], axis=1)
    return lambda dt: run(P, np.asarray(Q0), dt, T1)


def scipy_loop(params_list, method):
    from scipy.integrate import solve_ivp

    sys.path.insert(0, os.path.dirname(__file__))
    from bench_vs_scipy import numpy_rhs

    def run():
        for p in params_list:
            solve_ivp(numpy_rhs(p), (0, T1), [*Q0, 0.0, 0.0], method=method, rtol=TOL, atol=TOL)

    return run


def final_error(q, qd, ref_q, ref_qd):
    return np.max(np.abs(np.concatenate([q - ref_q, qd - ref_qd], axis=-1)), axis=-1)


MEMORY_CHILD = """
import resource, sys, numpy as np, lagrax as lx
n = int(sys.argv[1])
system, params = lx.models.planar_2r()
rng = np.random.default_rng(0)
batch = lx.samples(params, m2=rng.uniform(0.5, 2, n), l1=rng.uniform(0.5, 1.5, n))
ds = lx.sweep(system, [-1.5707963267948966 + 1.4, 0.8], [0.0, 0.0], batch, t1=1.0,
              progress=False)
assert int(ds.attrs["n_failed"]) == 0
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""

DEVICES_CHILD = """
import json, time, numpy as np, jax, lagrax as lx
system, params = lx.models.planar_2r()
batch = lx.grid(params, m2=np.linspace(0.5, 2, 64), l1=np.linspace(0.5, 1.5, 64))
out = {}
for d in (1, 2):
    run = lambda: lx.sweep(system, [-1.5707963267948966 + 1.4, 0.8], [0.0, 0.0], batch,
                           t1=10.0, devices=d, progress=False)
    run()
    ts = []
    for _ in range(REPEATS):
        t = time.perf_counter(); ds = run(); ts.append(time.perf_counter() - t)
    out[d] = (sorted(ts)[len(ts) // 2], ds.q.values.tolist())
a, b = np.asarray(out[1][1]), np.asarray(out[2][1])
close = float(np.median(np.abs(a - b)))
print(json.dumps(dict(t1=out[1][0], t2=out[2][0], diff=close, n=len(jax.devices()))))
"""


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--side", type=int, default=64, help="grid side (members = side²)")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs (median)")
    ap.add_argument("--subset", type=int, default=16, help="SciPy members (extrapolated)")
    ap.add_argument("--memory", action="store_true", help="peak RSS of 10⁴ and 10⁵ members")
    ap.add_argument("--devices", action="store_true", help="2 simulated CPU devices against 1")
    args = ap.parse_args(argv)
    # optional baselines, checked before any work
    have_numba = available("numba", "numba RK4 baseline")
    have_scipy = available("scipy", "SciPy solve_ivp loops")

    system, params = lx.models.planar_2r()
    batch = the_grid(params, args.side)
    n = batch.size
    kw = dict(t1=T1, rtol=TOL, atol=TOL, progress=False)
    rows = []

    def sweep(schedule):
        return lambda: lx.sweep(system, Q0, [0.0, 0.0], batch, schedule=schedule, **kw)

    ds, c_queue, t_queue = timed(sweep("queue"), args.repeats)
    idle_queue = ds.attrs["lane_idle_fraction"]
    ds_lock, c_lock, t_lock = timed(sweep("lockstep"), args.repeats)
    idle_lock = ds_lock.attrs["lane_idle_fraction"]
    assert int(ds.attrs["n_failed"]) == 0
    flat = {k: np.asarray(v) for k, v in batch.params().items()}
    lanes = max(1, min(1024, n // 8))  # the sweep default for one chunk on one device
    _, c_closed, t_closed = timed(closed_form_sweep(batch.params(), lanes), args.repeats)

    # accuracy on a subset, against Dopri8 at 1e-12
    pick = np.linspace(0, n - 1, 64).astype(int)
    sub = lx.samples(params, m2=flat["m2"][pick], l1=flat["l1"][pick])
    ref = lx.sweep(
        system, Q0, [0.0, 0.0], sub, t1=T1, solver="dopri8", rtol=1e-12, atol=1e-12, progress=False
    )
    q = ds.q.values.reshape(n, 2)[pick]
    qd = ds.qd.values.reshape(n, 2)[pick]
    err_lagrax = final_error(q, qd, ref.q.values, ref.qd.values)

    # numba RK4 at the largest step matching lagrax's median error
    dt, err_rk4, t_numba, c_numba = None, None, None, None
    if have_numba:
        rk4 = numba_rk4(flat)
        sub_rk4 = numba_rk4({k: v[pick] for k, v in flat.items()})
        target = float(np.median(err_lagrax))
        for cand in (1e-2, 5e-3, 2.5e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4, 6.25e-5):
            y = sub_rk4(cand)
            e = final_error(y[:, :2], y[:, 2:], ref.q.values, ref.qd.values)
            if np.median(e) <= target:
                dt, err_rk4 = cand, e
                break
        _, c_numba, t_numba = timed(lambda: rk4(dt), max(1, args.repeats - 1))

    # SciPy loop on a subset
    plist = [{k: v[i] for k, v in flat.items()} for i in pick[: args.subset]]
    t_scipy = {}
    for method in ("DOP853", "RK45") if have_scipy else ():
        _, _, t_sub = timed(scipy_loop(plist, method), 1)
        t_scipy[method] = t_sub * n / args.subset

    rows = [
        ("lagrax sweep, autodiff, work queue", t_queue, c_queue),
        ("lagrax sweep, autodiff, lock-step vmap", t_lock, c_lock),
        ("lagrax work queue, closed-form RHS", t_closed, c_closed),
    ]
    if t_numba is not None:
        rows.append((f"numba RK4, closed form, 1 thread, dt={dt:g}", t_numba, c_numba))
    rows += [
        (f"SciPy {m} loop ({args.subset} members, extrapolated)", t, float("nan"))
        for m, t in t_scipy.items()
    ]
    print(f"\n2R sweep: {n} members, {T1:g} s, rtol=atol={TOL:g}, final state kept")
    print(f"{'run':<52} {'time [s]':>9} {'traj/s':>9} {'compile+1st [s]':>16}")
    for name, t, c in rows:
        print(f"{name:<52} {t:9.3f} {n / t:9.0f} {c:16.2f}")
    print("\nratios (throughput of the autodiff work-queue sweep over ...)")
    if t_numba is not None:
        print(f"  numba RK4 (1 thread)            {t_numba / t_queue:6.2f}x")
    for m, t in t_scipy.items():
        print(f"  SciPy {m} loop{'':<{21 - len(m)}}{t / t_queue:6.1f}x")
    print(f"  lock-step vmap                  {t_lock / t_queue:6.2f}x")
    print(f"  price of autodiff (closed/auto) {t_closed / t_queue:6.2f}x")
    print("\nlock-step waste (idle lane-steps / all lane-steps)")
    print(f"  lock-step vmap  {idle_lock:6.1%}")
    print(f"  work queue      {idle_queue:6.1%}")
    print("\nfinal-state error vs Dopri8 1e-12 (64 members): median / max")
    print(f"  lagrax Tsit5 1e-8   {np.median(err_lagrax):.2e} / {np.max(err_lagrax):.2e}")
    if err_rk4 is not None:
        print(f"  numba RK4 dt={dt:g}  {np.median(err_rk4):.2e} / {np.max(err_rk4):.2e}")

    if args.memory:
        print("\npeak RSS, final state only (fresh process each, t1 = 1 s)")
        for m in (10_000, 100_000):
            r = subprocess.run(
                [sys.executable, "-c", MEMORY_CHILD, str(m)],
                check=True,
                capture_output=True,
                text=True,
            )
            print(f"  {m:>7} members: {float(r.stdout.strip().splitlines()[-1]):7.0f} MiB")
    if args.devices:
        env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=2")
        code = DEVICES_CHILD.replace("REPEATS", str(args.repeats))
        r = subprocess.run(
            [sys.executable, "-c", code], check=True, capture_output=True, text=True, env=env
        )
        d = json.loads(r.stdout.strip().splitlines()[-1])
        print(
            f"\n{d['n']} simulated CPU devices: 1 device {d['t1']:.3f} s, 2 devices "
            f"{d['t2']:.3f} s -> {d['t1'] / d['t2']:.2f}x (median |difference| of final "
            f"states {d['diff']:.1e}: round-off, amplified by the chaotic arm)"
        )


if __name__ == "__main__":
    main()
