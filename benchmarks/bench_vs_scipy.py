"""One 2R trajectory: lagrax against SciPy ``solve_ivp`` (and MuJoCo, if installed).

The 2R arm from the chaotic start θ = (−π/2 + 1.4, 0.8), at rest, torque-free, 10 s.
SciPy integrates the lecture's closed-form right-hand side written in NumPy; lagrax
integrates the autodiff equations from T and V. Errors are the max-norm of the final
state (q, q̇) against Dopri8 at rtol = atol = 1e-14. Everything is measured in this run:

1. the same tolerance (rtol = atol = 1e-10) for SciPy DOP853 / RK45 / Radau and lagrax;
2. matched accuracy: for each SciPy method, the cheapest lagrax run (Tsit5 or Dopri8
   over a tolerance ladder) whose final-state error is at least as small;
3. MuJoCo's RK4 at a fixed step (optional; ``pip install mujoco``), on the same arm;
4. a work–precision summary: at each error level 1e-4 … 1e-10, the fastest run of each
   tool that reaches it, and lagrax's speed-up over it.

Times are medians of repeated runs after compilation; lagrax's compile time is reported
separately.

    python benchmarks/bench_vs_scipy.py [--repeats 5]
"""

import argparse
import math
import os
import statistics
import subprocess
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import lagrax as lx
from _optional import available

Q0 = (-math.pi / 2 + 1.4, 0.8)
T1 = 10.0


def numpy_rhs(params):
    """Closed-form 2R right-hand side (lecture's M, C q̇, G; explicit 2×2 solve)."""
    m1, m2, l1, r1, r2 = (float(params[k]) for k in ("m1", "m2", "l1", "r1", "r2"))
    i1, i2, g = float(params["I1"]), float(params["I2"]), float(params["g"])
    h = m2 * l1 * r2
    m22 = i2 + m2 * r2**2
    m11_0 = i1 + i2 + m1 * r1**2 + m2 * (l1**2 + r2**2)
    sin, cos = math.sin, math.cos

    def rhs(t, y):
        q1, q2, w1, w2 = y
        s2, c2 = sin(q2), cos(q2)
        c1, c12 = cos(q1), cos(q1 + q2)
        m11 = m11_0 + 2 * h * c2
        m12 = m22 + h * c2
        b1 = h * s2 * (2 * w1 + w2) * w2 - m1 * g * r1 * c1 - m2 * g * (l1 * c1 + r2 * c12)
        b2 = -h * s2 * w1 * w1 - m2 * g * r2 * c12
        det = m11 * m22 - m12 * m12
        return np.array([w1, w2, (m22 * b1 - m12 * b2) / det, (m11 * b2 - m12 * b1) / det])

    return rhs


FIRST_CALL = """
import time
import lagrax as lx
import jax, jax.numpy as jnp
system, params = lx.models.planar_2r()
jnp.zeros(1).block_until_ready()  # start the backend: not part of the call
t0 = time.perf_counter()
sol = lx.simulate(system, [-1.5707963267948966 + 1.4, 0.8], [0.0, 0.0], params, t1=10.0)
jax.block_until_ready(sol.q)
print(time.perf_counter() - t0)
"""


def first_call_in_fresh_process() -> float:
    out = subprocess.run(
        [sys.executable, "-c", FIRST_CALL], capture_output=True, text=True, check=True
    )
    return float(out.stdout.strip().splitlines()[-1])


def timed(fn, repeats):
    out = fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times)


def mujoco_model(params):
    import mujoco

    p = {k: float(v) for k, v in params.items()}
    xml = f"""
<mujoco>
  <option gravity="0 0 -{p["g"]}" integrator="RK4">
    <flag contact="disable" energy="enable"/>
  </option>
  <worldbody>
    <body name="link1">
      <joint name="j1" type="hinge" axis="0 -1 0"/>
      <inertial pos="{p["r1"]} 0 0" mass="{p["m1"]}"
                diaginertia="{p["I1"]} {p["I1"]} {p["I1"]}"/>
      <body name="link2" pos="{p["l1"]} 0 0">
        <joint name="j2" type="hinge" axis="0 -1 0"/>
        <inertial pos="{p["r2"]} 0 0" mass="{p["m2"]}"
                  diaginertia="{p["I2"]} {p["I2"]} {p["I2"]}"/>
      </body>
    </body>
  </worldbody>
</mujoco>"""
    return mujoco.MjModel.from_xml_string(xml)


def mujoco_run(model, dt):
    import mujoco

    model.opt.timestep = dt
    data = mujoco.MjData(model)
    data.qpos[:] = Q0
    data.qvel[:] = 0.0
    n = round(T1 / dt)
    for _ in range(n):
        mujoco.mj_step(model, data)
    return np.concatenate([data.qpos, data.qvel])


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--repeats", type=int, default=5, help="timed runs per point (median)")
    args = ap.parse_args(argv)
    if not available("scipy", "the whole benchmark (SciPy solve_ivp is its baseline)"):
        return
    from scipy.integrate import solve_ivp

    have_mujoco = available("mujoco", "MuJoCo RK4 (part 3)")

    system, params = lx.models.planar_2r()
    q0, qd0 = jnp.array(Q0), jnp.zeros(2)
    # the reference is not on the ladder below, so no run is compared with itself
    ref = lx.simulate(
        system,
        q0,
        qd0,
        params,
        t1=T1,
        solver="dopri8",
        rtol=1e-14,
        atol=1e-14,
        n_save=2,
        max_steps=1_000_000,
    )
    y_ref = np.concatenate([np.asarray(ref.q_end), np.asarray(ref.qd_end)])

    def err(y):
        return float(np.max(np.abs(np.asarray(y) - y_ref)))

    def lagrax_run(method, tol):
        def run():
            sol = lx.simulate(
                system, q0, qd0, params, t1=T1, solver=method, rtol=tol, atol=tol, n_save=2
            )
            jax.block_until_ready(sol.q_end)
            return np.concatenate([np.asarray(sol.q_end), np.asarray(sol.qd_end)]), sol

        return run

    rhs = numpy_rhs(params)
    y0 = [*Q0, 0.0, 0.0]
    print(f"2R arm, chaotic start, {T1:g} s; errors vs Dopri8 at 1e-14 (max-norm of q, qd)\n")

    # the first call of simulate (trace + compile + run), each in a fresh process
    firsts = sorted(first_call_in_fresh_process() for _ in range(3))
    print(
        f"lagrax first call of simulate (trace + compile + run, default Tsit5), three fresh "
        f"processes: {', '.join(f'{t:.2f}' for t in firsts)} s (median {firsts[1]:.2f} s)"
    )
    small_loops = "small_while_loop" in os.environ.get("XLA_FLAGS", "")
    print(f"XLA:CPU small-loop kernels (see lagrax/_core/xla_flags.py): {small_loops}")

    print("\n1. same tolerance, rtol = atol = 1e-10")
    scipy_res = {}
    for method in ("DOP853", "RK45", "Radau"):
        reps = 1 if method == "Radau" else args.repeats
        sol, t = timed(
            lambda m=method: solve_ivp(rhs, (0, T1), y0, method=m, rtol=1e-10, atol=1e-10), reps
        )
        scipy_res[method] = (err(sol.y[:, -1]), t)
        print(
            f"   scipy {method:7s} {t * 1e3:9.2f} ms  error {err(sol.y[:, -1]):.1e}  "
            f"nfev {sol.nfev}"
        )
    base = scipy_res["DOP853"][1]
    for method in ("tsit5", "dopri8"):
        (y, sol), t = timed(lagrax_run(method, 1e-10), args.repeats)
        print(
            f"   lagrax {method:6s} {t * 1e3:9.2f} ms  error {err(y):.1e}  "
            f"steps {int(sol.stats['num_steps'])}   DOP853 time / this = {base / t:.1f}x"
        )
    # The same ratios from interleaved rounds (DOP853, Tsit5, Dopri8 back to back), so
    # that a change in machine load during the run hits all three alike.
    rounds = {"DOP853": [], "tsit5": [], "dopri8": []}
    dop853 = lambda: solve_ivp(rhs, (0, T1), y0, method="DOP853", rtol=1e-10, atol=1e-10)  # noqa: E731
    for _ in range(args.repeats):
        for name, fn in (
            ("DOP853", dop853),
            ("tsit5", lagrax_run("tsit5", 1e-10)),
            ("dopri8", lagrax_run("dopri8", 1e-10)),
        ):
            t0 = time.perf_counter()
            fn()
            rounds[name].append(time.perf_counter() - t0)
    for method in ("tsit5", "dopri8"):
        ratios = sorted(a / b for a, b in zip(rounds["DOP853"], rounds[method], strict=True))
        print(
            f"   interleaved, {args.repeats} rounds: DOP853 / lagrax {method}: median "
            f"{statistics.median(ratios):.1f}x (range {ratios[0]:.1f}x - {ratios[-1]:.1f}x)"
        )

    print("\n2. matched final-state accuracy")
    ladder = [10.0 ** (-k / 2) for k in range(8, 27)]  # 1e-4 ... 1e-13
    runs = []
    for method in ("tsit5", "dopri8"):
        for tol in ladder:
            (y, _), t = timed(lagrax_run(method, tol), max(args.repeats // 2, 1))
            runs.append((method, tol, err(y), t))
    for smethod, (serr, st) in scipy_res.items():
        ok = [r for r in runs if r[2] <= serr]
        if not ok:
            print(f"   scipy {smethod}: no lagrax run reached error {serr:.1e}")
            continue
        best = min(ok, key=lambda r: r[3])
        print(
            f"   scipy {smethod:7s} error {serr:.1e} in {st * 1e3:8.2f} ms; lagrax "
            f"{best[0]} tol {best[1]:.0e}: error {best[2]:.1e} in {best[3] * 1e3:6.2f} ms"
            f"  -> {st / best[3]:.1f}x faster"
        )

    mujoco_runs = []
    model = mujoco_model(params) if have_mujoco else None
    if model is not None:
        print("\n3. MuJoCo RK4 at fixed steps (same arm; Python loop over mj_step)")
        for dt in (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4):
            y, t = timed(lambda dt=dt: mujoco_run(model, dt), 3)
            mujoco_runs.append((dt, err(y), t))
            better = [r for r in runs if r[2] <= err(y)]
            best = min(better, key=lambda r: r[3]) if better else None
            extra = (
                (
                    f"; lagrax {best[0]} tol {best[1]:.0e}: {best[3] * 1e3:.2f} ms -> "
                    f"{t / best[3]:.1f}x faster"
                )
                if best
                else ""
            )
            print(f"   mujoco RK4 dt {dt:.1e}: {t * 1e3:8.2f} ms  error {err(y):.1e}{extra}")

    print("\n4. work-precision: fastest run reaching each error level (best of each tool)")
    scipy_runs = []
    for method, tols in (("DOP853", range(4, 13)), ("RK45", range(4, 11)), ("Radau", range(4, 9))):
        for k in tols:
            tol = 10.0**-k
            reps = 1 if method == "Radau" else max(args.repeats // 2, 1)
            sol, t = timed(
                lambda m=method, tol=tol: solve_ivp(rhs, (0, T1), y0, method=m, rtol=tol, atol=tol),
                reps,
            )
            scipy_runs.append((method, tol, err(sol.y[:, -1]), t))

    def fastest(rows, level, err_i, time_i):
        ok = [r for r in rows if r[err_i] <= level]
        return min(ok, key=lambda r: r[time_i]) if ok else None

    print(
        f"   {'error':>7s} {'lagrax':>22s} {'SciPy best':>24s} {'ratio':>7s} "
        f"{'MuJoCo RK4':>20s} {'ratio':>7s}"
    )
    for k in range(4, 11):
        level = 10.0**-k
        lg = fastest(runs, level, 2, 3)
        sp = fastest(scipy_runs, level, 2, 3)
        mj = fastest(mujoco_runs, level, 1, 2)
        lg_s = f"{lg[0]} {lg[3] * 1e3:6.2f} ms" if lg else "-"
        sp_s = f"{sp[0]} {sp[3] * 1e3:7.2f} ms" if sp else "-"
        mj_s = f"dt {mj[0]:.1e} {mj[2] * 1e3:6.1f} ms" if mj else "-"
        r_sp = f"{sp[3] / lg[3]:6.1f}x" if lg and sp else "-"
        r_mj = f"{mj[2] / lg[3]:6.1f}x" if lg and mj else "-"
        print(f"   {level:7.0e} {lg_s:>22s} {sp_s:>24s} {r_sp:>7s} {mj_s:>20s} {r_mj:>7s}")


if __name__ == "__main__":
    main()
