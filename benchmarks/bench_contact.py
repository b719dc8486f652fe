"""Contact: a ball and a box dropped on the floor and settling, lagrax against MuJoCo.

The scene both engines model: in the vertical (x, z) plane, a ball (radius 0.05 m,
0.2 kg) launched at 1 m/s and a box (0.2 m × 0.1 m, 1 kg) tilted by 0.3 rad and thrown
back at 0.5 m/s, both dropped from a height h (0.3 m by default) onto the floor with the
friction coefficient μ (0.5), 2 s. The two bodies do not touch each other (MuJoCo's
collision masks; lagrax has no pair between them). lagrax: a ``LagrangianSystem`` in
``(x, z, θ)`` per body with a ``Sphere`` and a ``Box`` (its 4 corners) on a ``Plane``,
the default (scene-scaled) stiffness, dissipation and stiction. MuJoCo: the same bodies
on slide–slide–hinge joints, its default soft contact (``solref`` 0.02 s), the
``implicitfast`` integrator (MuJoCo's recommended one).

Measured in one run, after compilation:

1. **Accuracy against cost**, each engine against its own converged solution (its own
   model: lagrax Kvaerno5 at rtol = atol = 1e-9, MuJoCo at dt = 2.5e-6): lagrax Kvaerno5
   over a tolerance ladder, ``mujoco.rollout`` over a step ladder; the error is the
   largest final-state difference (positions and velocities). The time each engine
   takes to reach a 1e-3 final-state error, and their ratio.
2. **A sweep** over drop height × friction (64 × 64 = 4,096 members; ``--quick``: 4 × 4),
   final state kept, each engine at its setting that reached 1e-3 in section 1:
   ``lagrax.sweep`` against ``mujoco.rollout`` with 2 threads (``--threads``), and the
   ratio.

MuJoCo is optional (``pip install -e ".[bench]"``); without it, lagrax's figures only.

    python benchmarks/bench_contact.py [--quick] [--side 64] [--repeats 3] [--threads 2]
"""

import argparse
import os
import sys
import time

import jax.numpy as jnp
import numpy as np

import lagrax as lx
from lagrax.contact import Box, ContactSystem, Plane, Sphere

sys.path.insert(0, os.path.dirname(__file__))
from _optional import available  # noqa: E402

G = 9.81
T1 = 2.0
RADIUS, M_BALL = 0.05, 0.2
HALF, M_BOX = (0.1, 0.05), 1.0  # the box's half-extents in (x, z), and its mass
I_BALL = 0.4 * M_BALL * RADIUS**2
I_BOX = M_BOX * (HALF[0] ** 2 + HALF[1] ** 2) / 3
TARGET = 1e-3  # the final-state error each engine is timed to reach
# lagrax's tolerances (at 3e-7 and below Kvaerno5 takes 10⁴–10⁵ steps through the
# stick–slip transitions: its Newton iterations and error estimate at the stiction's scale)
LADDER = (1e-3, 3e-4, 1e-4, 3e-5, 1e-5, 3e-6, 1e-6)
REFERENCE = 1e-9  # lagrax's converged solution
STEPS = tuple(4e-3 / 2**k for k in range(9))  # MuJoCo's steps, 4 ms … 15.6 µs
MUJOCO_REFERENCE = 2.5e-6  # MuJoCo's converged solution (800,000 steps)


def initial_state(height):
    """`(q0, qd0)` of the scene, q = (x, z, θ) of the ball then of the box."""
    q0 = np.array([0.0, height + RADIUS, 0.0, 0.5, height + HALF[1] + 0.05, 0.3])
    qd0 = np.array([1.0, 0.0, 0.0, -0.5, 0.0, 0.0])
    return q0, qd0


def lagrax_scene():
    """The scene as a lagrax `ContactSystem`; params `{"mu": μ}`."""
    masses = jnp.array([M_BALL, M_BALL, I_BALL, M_BOX, M_BOX, I_BOX])

    def kinetic(q, qd, p):
        return 0.5 * jnp.sum(masses * qd * qd)

    def potential(q, p):
        return G * (M_BALL * q[1] + M_BOX * q[4])

    body = lx.LagrangianSystem(kinetic, potential, n_dof=6)
    ball = Sphere(RADIUS, lambda q, p: q[0:2], angle=lambda q, p: q[2])
    box = Box(HALF, lambda q, p: q[3:5], angle=lambda q, p: q[5])
    return ContactSystem(body, [ball, box], Plane([0.0, 1.0]), friction=lambda p: p["mu"])


MJCF = """<mujoco>
  <option timestep="0.001" integrator="implicitfast" gravity="0 0 -9.81"/>
  <default><geom contype="1" conaffinity="0" friction="{mu} 0.005 0.0001"/></default>
  <worldbody>
    <geom type="plane" size="20 20 0.1" contype="0" conaffinity="1"/>
    <body>
      <joint type="slide" axis="1 0 0"/><joint type="slide" axis="0 0 1"/>
      <joint type="hinge" axis="0 -1 0"/>
      <geom type="sphere" size="{r}" mass="{mb}"/>
    </body>
    <body>
      <joint type="slide" axis="1 0 0"/><joint type="slide" axis="0 0 1"/>
      <joint type="hinge" axis="0 -1 0"/>
      <geom type="box" size="{a} 0.1 {c}" mass="{mc}"/>
    </body>
  </worldbody>
</mujoco>"""


def mujoco_model(mu):
    import mujoco

    text = MJCF.format(mu=mu, r=RADIUS, mb=M_BALL, a=HALF[0], c=HALF[1], mc=M_BOX)
    return mujoco.MjModel.from_xml_string(text)


def mujoco_states(model, heights):
    """MuJoCo's full-physics initial states, one per drop height, `(len, nstate)`."""
    import mujoco

    data = mujoco.MjData(model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    out = np.zeros((len(heights), mujoco.mj_stateSize(model, spec)))
    for i, h in enumerate(heights):
        mujoco.mj_resetData(model, data)
        data.qpos[:], data.qvel[:] = initial_state(h)
        mujoco.mj_forward(model, data)
        mujoco.mj_getState(model, data, out[i], spec)
    return out


def mujoco_final(model, datas, states, dt):
    """The final `(qpos, qvel)` of `mujoco.rollout` from `states` at the step `dt`
    (`model` one model or one per state; `datas` one per thread)."""
    from mujoco import rollout

    for m in model if isinstance(model, list) else [model]:
        m.opt.timestep = dt
    state, _ = rollout.rollout(model, datas, states, nstep=round(T1 / dt))
    return np.asarray(state)[:, -1, 1:13]


def timed(fn, repeats):
    """`(fn(), the fastest of repeats timed calls)` (noise only ever adds time)."""
    out = fn()
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def accuracy(height, mu, repeats):
    """Section 1: `(lagrax's rtol, MuJoCo's dt)` that reached `TARGET` (or `None`)."""
    scene, params = lagrax_scene(), {"mu": mu}
    q0, qd0 = initial_state(height)

    def run(tol, max_steps=None):
        return lx.simulate(
            scene,
            q0,
            qd0,
            params,
            t1=T1,
            n_save=2,
            solver="kvaerno5",
            rtol=tol,
            atol=tol,
            max_steps=max_steps,
        )

    t0 = time.perf_counter()
    ref = run(REFERENCE, 10**6)
    print(f"1. one drop (h = {height} m, μ = {mu}), {T1} s; errors against each engine's own")
    print(f"   converged solution (lagrax reference: {time.perf_counter() - t0:.1f} s)")
    y_ref = np.concatenate([np.asarray(ref.q_end), np.asarray(ref.qd_end)])
    chosen = [None, None]
    times = [np.inf, np.inf]
    for tol in LADDER:
        sol, t = timed(lambda tol=tol: run(tol), repeats)
        y = np.concatenate([np.asarray(sol.q_end), np.asarray(sol.qd_end)])
        err = float(np.max(np.abs(y - y_ref)))
        steps = int(sol.stats["num_steps"])
        print(
            f"   lagrax kvaerno5 rtol {tol:.0e}: {t * 1e3:9.2f} ms  error {err:.1e}  {steps} steps"
        )
        if err <= TARGET and t < times[0]:
            chosen[0], times[0] = tol, t
    if available("mujoco", "mujoco.rollout baseline"):
        import mujoco

        model = mujoco_model(mu)
        data = [mujoco.MjData(model)]
        states = mujoco_states(model, [height])
        y_mj = mujoco_final(model, data, states, MUJOCO_REFERENCE)[0]
        for dt in STEPS:
            y, t = timed(lambda dt=dt: mujoco_final(model, data, states, dt)[0], repeats)
            err = float(np.max(np.abs(y - y_mj)))
            print(f"   mujoco.rollout implicitfast dt {dt:.2e}: {t * 1e3:9.2f} ms  error {err:.1e}")
            if err <= TARGET and t < times[1]:
                chosen[1], times[1] = dt, t
    label = [f"lagrax {times[0] * 1e3:.2f} ms", f"MuJoCo {times[1] * 1e3:.2f} ms"]
    ratio = times[0] / times[1] if np.isfinite(times).all() else float("nan")
    print(
        f"   time to a {TARGET:.0e} final-state error: {label[0]}, {label[1]}: "
        f"lagrax/MuJoCo = {ratio:.2f}x"
    )
    return chosen


def sweep(side, rtol, dt, threads, repeats):
    """Section 2: drop height × friction, `side × side` members."""
    heights = np.linspace(0.2, 0.6, side)
    mus = np.linspace(0.2, 1.0, side)
    hh, mm = (x.ravel() for x in np.meshgrid(heights, mus, indexing="ij"))
    n = hh.size
    print(f"\n2. a sweep of {n} drops (height {heights[0]}–{heights[-1]} m × μ {mus[0]}–{mus[-1]})")
    scene = lagrax_scene()
    q0, qd0 = initial_state(0.0)
    members = lx.samples({"mu": 0.5}, mu=mm, q0_1=hh + RADIUS, q0_4=hh + HALF[1] + 0.05)
    t_lx = np.inf
    if rtol is not None:
        kw = dict(t1=T1, solver="kvaerno5", rtol=rtol, atol=rtol, progress=False)
        ds, t_lx = timed(lambda: lx.sweep(scene, q0, qd0, members, **kw), repeats)
        print(
            f"   lagrax.sweep kvaerno5 rtol {rtol:.0e}: {t_lx:8.2f} s "
            f"({ds.attrs['n_failed']} failed)"
        )
    if dt is None or not available("mujoco", "mujoco.rollout sweep"):
        return
    import mujoco

    models = {mu: mujoco_model(mu) for mu in mus}
    per_member = [models[mu] for mu in mm]
    states = np.concatenate([mujoco_states(models[mu], [h]) for h, mu in zip(hh, mm, strict=True)])
    datas = [mujoco.MjData(per_member[0]) for _ in range(threads)]
    _, t_mj = timed(lambda: mujoco_final(per_member, datas, states, dt), repeats)
    print(f"   mujoco.rollout implicitfast dt {dt:.2e}, {threads} threads: {t_mj:8.2f} s")
    print(f"   lagrax/MuJoCo = {t_lx / t_mj:.2f}x")


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--quick", action="store_true", help="a 4 × 4 sweep (instead of 64 × 64)")
    ap.add_argument("--repeats", type=int, default=3, help="timing repeats")
    ap.add_argument("--threads", type=int, default=2, help="mujoco.rollout's threads")
    ap.add_argument("--height", type=float, default=0.3, help="section 1's drop height (m)")
    ap.add_argument("--mu", type=float, default=0.5, help="section 1's friction coefficient")
    ap.add_argument(
        "--side", type=int, default=None, help="the sweep's grid side (None: 64; --quick: 4)"
    )
    args = ap.parse_args(argv)
    available("mujoco", "mujoco.rollout baseline")  # checked before any work
    rtol, dt = accuracy(args.height, args.mu, args.repeats)
    side = args.side if args.side is not None else 4 if args.quick else 64
    sweep(side, rtol, dt, args.threads, args.repeats if side <= 8 else 1)


if __name__ == "__main__":
    main()
