"""Cost against mechanism size: chains of n links, and the 7-DOF arm against MuJoCo.

Measured in one run, on this machine:

1. Per-state forward dynamics under ``jax.vmap`` over 4,096 random states, for planar and
   spatial revolute chains of n = 2, 4, 7, 10, 20 links: lagrax's chain systems
   (Featherstone's articulated-body algorithm), the same chains as scenes of bodies with
   the pose-map equations (n <= 10), and, for n <= 7, by autodiff of their energies
   (``equations=None``, the definition); a hand-written planar ``T`` (the generic autodiff
   path) for every n; with compile times. Pinocchio's ABA per call from Python when
   ``pinocchio`` is installed (``pip install -e ".[bench]"``).
2. One trajectory of the scale issue's 7-DOF arm (``SpatialChain``, axes z, y, z, y, z, y,
   z; 1 kg, 1 m links; q0 = 0.3, at rest; 2 s; 501 saved states): lagrax Tsit5 and
   Dopri8 over half-decade tolerance ladders against ``mujoco.rollout`` RK4 over a step
   ladder, errors against lagrax Dopri8 at rtol = atol = 1e-13, and the ratio at matched
   final-state error. MuJoCo is optional (``pip install -e ".[bench]"``).
3. lagrax's URDF arm (``lagrax/models/urdf/arm7.urdf``, damped joints): per-state forward
   dynamics against Pinocchio loading the same file, and one trajectory (as in 2) against
   MuJoCo loading the same file.

4. Floating bases from example-robot-data (``from_urdf(..., floating_base=True)``: a
   quadruped, solo12, and humanoids, G1 (29 joints) and TALOS (reduced, 32 joints)):
   per-state forward dynamics under ``jax.vmap`` over 4,096 random states (random unit
   quaternions) against Pinocchio's ABA per call from Python on its free-flyer model of
   the same file. Skipped where Pinocchio or example-robot-data is missing.
5. dm_control's ``humanoid_CMU`` (a floating base, 56 joints) and ``dog`` (two free
   bodies, the dog and its ball: a ``Forest``, 85 velocities) read by ``from_mjcf``:
   per-state forward dynamics under ``jax.vmap`` over 4,096 random states against
   MuJoCo's own ``mj_forward`` per call on the same files, timed in C through
   ``mujoco.rollout`` (Euler, one forward per step, over the same states) with contact,
   constraints (limits, friction loss, equality), actuation and sensors off, on one
   thread and on every core; ``q̈`` and ``qacc`` checked to agree (1e-10) first. Neither
   model exists as URDF, so Pinocchio has no line here (section 4's humanoids have).
   Skipped where MuJoCo or dm_control is missing.

Writes a log-log chart of cost against n with ``--chart PATH``.

    python benchmarks/bench_scale.py [--quick] [--chart scale.png] [--sections 4 5]
"""

import argparse
import dataclasses
import os
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import lagrax as lx
from lagrax.chains import PlanarChain, SpatialChain

sys.path.insert(0, os.path.dirname(__file__))
from _optional import available  # noqa: E402
from _robots import floating_states, robots_folder  # noqa: E402

B = 4096
ARM_AXES = [(0, 0, 1), (0, 1, 0)] * 3 + [(0, 0, 1)]
ARM_INERTIA = np.diag([0.5 * 0.05**2, (3 * 0.05**2 + 1) / 12, (3 * 0.05**2 + 1) / 12])
T1 = 2.0


def chain_of(kind, n):
    if kind == "planar":
        chain = PlanarChain(n)
        return chain, chain.params()
    axes = [ARM_AXES[i % 2] for i in range(n)]
    chain = SpatialChain("R" * n, axes=axes)
    return chain, chain.params(inertia=ARM_INERTIA)


def per_state(system, params, n, repeats):
    """(compile seconds, microseconds per state) of vmapped forward dynamics."""
    fn = jax.jit(jax.vmap(lambda q, qd: system.accelerations(0.0, q, qd, params, None)))
    rng = np.random.default_rng(0)
    q, qd = jnp.asarray(rng.normal(size=(B, n))), jnp.asarray(rng.normal(size=(B, n)))
    t0 = time.perf_counter()
    fn(q, qd).block_until_ready()
    compile_s = time.perf_counter() - t0
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(q, qd).block_until_ready()
        times.append(time.perf_counter() - t0)
    return compile_s, min(times) / B * 1e6


def handwritten(n):
    """A planar chain of uniform 1 kg, 1 m rods written as a user would: ``T`` from one
    ``jax.jvp`` of the centres of mass and link angles, ``V`` of their heights. It takes
    the generic autodiff path (scalar derivatives for n <= 6, forward-over-reverse above)."""

    def pose(q):
        ang = jnp.cumsum(q)
        tips = jnp.cumsum(jnp.stack([jnp.cos(ang), jnp.sin(ang)], axis=1), axis=0)
        com = tips - 0.5 * jnp.stack([jnp.cos(ang), jnp.sin(ang)], axis=1)
        return com, ang

    def kinetic(q, qd, p):
        _, (v, w) = jax.jvp(pose, (q,), (qd,))
        return 0.5 * jnp.sum(v**2) + 0.5 / 12 * jnp.sum(w**2)

    def potential(q, p):
        return 9.81 * jnp.sum(pose(q)[0][:, 1])

    return lx.LagrangianSystem(kinetic, potential, n_dof=n, name=f"hand-written {n}-link")


def _pinocchio_time(model, n, repeats):
    import pinocchio as pin

    data = model.createData()
    q, v, tau = np.full(n, 0.3), np.full(n, 0.1), np.zeros(n)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(1000):
            pin.aba(model, data, q, v, tau)
        times.append((time.perf_counter() - t0) / 1000)
    return min(times) * 1e6


def pinocchio_aba(kind, n, repeats):
    """Pinocchio ABA per call (µs) on the same chain, or None without Pinocchio."""
    try:
        import pinocchio as pin
    except ImportError:
        return None
    model = pin.Model()
    parent = 0
    for i in range(n):
        placement = pin.SE3(np.eye(3), np.array([0.0 if i == 0 else 1.0, 0, 0]))
        if kind == "planar":  # about z, gravity along −y: PlanarChain's uniform rods
            joint, inertia = pin.JointModelRZ(), np.diag([1e-9, 1 / 12, 1 / 12])
        else:
            joint = pin.JointModelRZ() if ARM_AXES[i % 2][2] else pin.JointModelRY()
            inertia = ARM_INERTIA
        parent = model.addJoint(parent, joint, placement, f"j{i}")
        model.appendBodyToJoint(
            parent, pin.Inertia(1.0, np.array([0.5, 0, 0]), inertia), pin.SE3.Identity()
        )
    if kind == "planar":
        model.gravity.linear = np.array([0.0, -9.81, 0.0])
    return _pinocchio_time(model, n, repeats)


def arm_mjcf(dt=None):
    """The 7-DOF arm as nested MJCF bodies (hinges, link CoM at 0.5 m, gravity −z), at
    MuJoCo's default step or at `dt`."""
    d = np.diag(ARM_INERTIA)
    body, close = "", ""
    for i, axis in enumerate(ARM_AXES):
        pos = "0 0 0" if i == 0 else "1 0 0"
        body += (
            f'<body pos="{pos}"><joint type="hinge" axis="{axis[0]} {axis[1]} {axis[2]}"/>'
            f'<inertial pos="0.5 0 0" mass="1" diaginertia="{d[0]} {d[1]} {d[2]}"/>'
        )
        close += "</body>"
    step = "" if dt is None else f' timestep="{dt}"'
    return (
        f'<mujoco><option{step} gravity="0 0 -9.81" integrator="RK4">'
        '<flag contact="disable" constraint="disable"/></option>'
        f"<worldbody>{body}{close}</worldbody></mujoco>"
    )


def timed(fn, repeats):
    """`(fn(), the fastest of repeats timed calls)`: the minimum, as `timeit` advises,
    since on a shared machine noise only ever adds time (it is the same for lagrax and
    MuJoCo)."""
    out = fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return out, min(times)


LADDERS = {  # half-decade tolerance ladders, over the errors MuJoCo's steps reach
    "tsit5": (1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9, 1e-9, 3e-10, 1e-10),
    "dopri8": (1e-6, 3e-7, 1e-7, 3e-8, 1e-8, 3e-9, 1e-9),
}


def trajectory_vs_mujoco(title, system, params, q0, mujoco_model, repeats):
    """One 2 s trajectory from rest at ``q0``, 501 saved states (MuJoCo returns its
    500): lagrax Tsit5 and Dopri8 over half-decade tolerance ladders and
    ``mujoco.rollout`` RK4 over a step ladder (``mujoco_model()`` builds the MjModel),
    errors against lagrax Dopri8 at 1e-13; the ratio at matched final-state error takes
    the fastest lagrax run whose error is no larger than MuJoCo's."""
    n = q0.shape[0]
    qd0 = np.zeros(n)
    t0 = time.perf_counter()
    lx.simulate(system, q0, qd0, params, t1=T1, rtol=1e-8, atol=1e-8)
    first = time.perf_counter() - t0
    ref = lx.simulate(system, q0, qd0, params, t1=T1, solver="dopri8", rtol=1e-13, atol=1e-13)
    y_ref = np.concatenate([np.asarray(ref.q_end), np.asarray(ref.qd_end)])

    def err(y):
        return float(np.max(np.abs(y - y_ref)))

    print(f"\n{title}, one 2 s trajectory (first simulate call {first:.2f} s)")
    runs = []
    for method, ladder in LADDERS.items():
        for tol in ladder:
            sol, t = timed(
                lambda tol=tol, method=method: lx.simulate(
                    system, q0, qd0, params, t1=T1, solver=method, rtol=tol, atol=tol
                ),
                repeats,
            )
            y = np.concatenate([np.asarray(sol.q_end), np.asarray(sol.qd_end)])
            runs.append((err(y), t, f"{method} {tol:.0e}"))
            steps = int(sol.stats["num_steps"])
            print(
                f"   lagrax {method:6s} rtol {tol:.0e}: {t * 1e3:8.3f} ms  error {err(y):.1e}"
                f"  {steps} steps"
            )
    try:
        import mujoco
        from mujoco import rollout
    except ImportError:
        print("   MuJoCo not installed (pip install -e '.[bench]'): comparison skipped")
        return
    model = mujoco_model()
    data = mujoco.MjData(model)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.zeros((1, mujoco.mj_stateSize(model, spec)))
    data.qpos[:] = q0
    mujoco.mj_forward(model, data)
    mujoco.mj_getState(model, data, state0[0], spec)
    for dt in (4e-3, 2e-3, 1e-3):
        model.opt.timestep = dt
        nstep = round(T1 / dt)
        (state, _), t = timed(
            lambda nstep=nstep: rollout.rollout(model, data, state0, nstep=nstep), repeats
        )
        y = state[0, -1, 1 : 1 + 2 * n]
        e = err(y)
        match = [(tl, label) for el, tl, label in runs if el <= e]
        ratio = ""
        if match:
            tl, label = min(match)
            ratio = f"  lagrax/MuJoCo at matched error: {tl / t:.2f}x ({label})"
        print(f"   mujoco.rollout RK4 dt {dt:.0e}: {t * 1e3:8.3f} ms  error {e:.1e}{ratio}")


def arm_trajectory(repeats):
    chain, params = chain_of("spatial", 7)

    def model():
        import mujoco

        return mujoco.MjModel.from_xml_string(arm_mjcf())

    trajectory_vs_mujoco(
        "2. the 7-DOF arm", chain.system(), params, np.full(7, 0.3), model, repeats
    )


def _urdf_for_mujoco(text):
    """The URDF without geometry (MuJoCo would load the meshes lagrax ignores)."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(text)
    for link in root.iter("link"):
        for tag in ("visual", "collision"):
            for el in link.findall(tag):
                link.remove(el)
    return ET.tostring(root, encoding="unicode")


def urdf_arm(repeats):
    """lagrax's 7-DOF URDF arm (``lagrax/models/urdf/arm7.urdf``, with joint damping):
    per-state forward dynamics against Pinocchio on the same file, and one trajectory
    against MuJoCo loading the same file."""
    from lagrax.chains import from_urdf
    from lagrax.models import urdf_path

    path = urdf_path("arm7")
    tree, params = from_urdf(path)
    system, n = tree.system(), tree.n
    c, t = per_state(system, params, n, repeats)
    line = f"\n3. the URDF arm (arm7.urdf, {n} DOF): forward dynamics {t:.3f} µs per state"
    try:
        import pinocchio as pin

        model = pin.buildModelFromXML(path.read_text())
        line += f", Pinocchio ABA {_pinocchio_time(model, n, repeats):.3f} µs per call"
    except ImportError:
        line += ", Pinocchio not installed"
    print(line + f" (compile {c:.1f} s)")

    def mujoco_model():
        import mujoco

        model = mujoco.MjModel.from_xml_string(_urdf_for_mujoco(path.read_text()))
        model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
        model.opt.disableflags |= (
            mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
        )
        return model

    q0 = np.full(n, 0.3)
    trajectory_vs_mujoco("   the URDF arm", system, params, q0, mujoco_model, repeats)


# Section 4's robots: (label, path under example-robot-data's robots/)
FLOATING_ROBOTS = (
    ("solo12 (quadruped)", "solo_description/robots/solo12.urdf"),
    ("G1 (humanoid)", "g1_description/urdf/g1_29dof_rev_1_0.urdf"),
    ("TALOS reduced (humanoid)", "talos_data/robots/talos_reduced.urdf"),
)


def floating_bases(repeats):
    """Section 4: floating-base robots, lagrax (vmap over B states) against Pinocchio's
    ABA per call on its free-flyer model of the same URDF."""
    print(f"\n4. floating bases, forward dynamics per state (vmap over {B} states)")
    folder = robots_folder()
    if folder is None:
        print("   skipped: example-robot-data is not installed (pip install example-robot-data)")
        return
    try:
        import pinocchio as pin
    except ImportError:
        pin = None
    from lagrax.chains import from_urdf

    for label, rel in FLOATING_ROBOTS:
        path = os.path.join(folder, rel)
        robot, params = from_urdf(path, floating_base=True)
        params = {**params, "damping": jnp.zeros_like(params["damping"])}  # as Pinocchio's
        system, n = robot.system(), robot.n
        fn = jax.jit(jax.vmap(lambda q, v, s=system, p=params: s.accelerations(0.0, q, v, p, None)))
        q, v = (jnp.asarray(x) for x in floating_states(np.random.default_rng(0), n, B))
        t0 = time.perf_counter()
        fn(q, v).block_until_ready()
        compile_s = time.perf_counter() - t0
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn(q, v).block_until_ready()
            times.append(time.perf_counter() - t0)
        ours = min(times) / B * 1e6
        line = f"   {label:26s} {6 + n:2d} DOF: lagrax {ours:7.3f} µs per state"
        if pin is None:
            line += ", Pinocchio not installed"
        else:
            model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())
            data = model.createData()
            qp = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
            vp, tau = np.full(model.nv, 0.1), np.zeros(model.nv)
            best = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                for _ in range(1000):
                    pin.aba(model, data, qp, vp, tau)
                best.append((time.perf_counter() - t0) / 1000)
            theirs = min(best) * 1e6
            line += f", Pinocchio ABA {theirs:7.3f} µs per call ({ours / theirs:.2f}x)"
        print(line + f" (compile {compile_s:.1f} s)")


SUITE_MODELS = ("humanoid_CMU", "dog")  # section 5's dm_control files


def _suite_mujoco(path):
    """MuJoCo's model of a suite file for the bare forward dynamics: contact,
    constraints (limits, friction loss, equality), actuation and sensors off, Euler
    without its implicit damping (one `mj_forward` and an explicit update per step)."""
    import mujoco

    model = mujoco.MjModel.from_xml_path(path)
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= (
        off.mjDSBL_CONTACT
        | off.mjDSBL_CONSTRAINT
        | off.mjDSBL_EQUALITY
        | off.mjDSBL_ACTUATION
        | off.mjDSBL_SENSOR
        | off.mjDSBL_EULERDAMP
    )
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_EULER
    return model


def _suite_states(model, size):
    """`size` random MuJoCo `(qpos, qvel)`: `qpos0` moved by up to ±0.5, each free
    joint to a random pose, velocities in [-1, 1]."""
    import mujoco

    rng = np.random.default_rng(0)
    qpos = np.array(model.qpos0) + rng.uniform(-0.5, 0.5, (size, model.nq))
    for j in np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE):
        a = int(model.jnt_qposadr[j])
        quat = rng.normal(size=(size, 4))
        qpos[:, a + 3 : a + 7] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    return qpos, rng.uniform(-1.0, 1.0, (size, model.nv))


def _suite_check(model, robot, fn, q, v, qpos, qvel):
    """The largest relative difference of lagrax's `q̈` (as MuJoCo's `qacc`, by
    `lagrax.chains.to_mujoco_acceleration`) from `mj_forward`'s `qacc`, at 4 states."""
    import mujoco

    from lagrax.chains import to_mujoco_acceleration

    data = mujoco.MjData(model)
    # the compiled batch (a batch of 4 would compile again), converted as MuJoCo's qacc
    acc = np.asarray(to_mujoco_acceleration(q[:4], v[:4], fn(q, v)[:4], robot))
    worst = 0.0
    for i in range(4):
        data.qpos[:], data.qvel[:] = qpos[i], qvel[i]
        mujoco.mj_forward(model, data)
        a, ref = acc[i], np.asarray(data.qacc)
        worst = max(worst, float(np.max(np.abs(a - ref)) / max(np.max(np.abs(ref)), 1.0)))
    return worst


def _rollout_time(model, qpos, qvel, threads, repeats, nstep):
    """µs per `mj_forward` (and Euler update) of `mujoco.rollout` from the states."""
    import mujoco
    from mujoco import rollout

    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    data = mujoco.MjData(model)
    states = np.zeros((len(qpos), mujoco.mj_stateSize(model, spec)))
    for i in range(len(qpos)):
        data.qpos[:], data.qvel[:] = qpos[i], qvel[i]
        mujoco.mj_getState(model, data, states[i], spec)
    datas = [mujoco.MjData(model) for _ in range(threads)]
    out = np.zeros((len(qpos), nstep, states.shape[1]))

    def run():
        rollout.rollout(model, datas, states, nstep=nstep, state=out)

    _, t = timed(run, repeats)
    return t / (len(qpos) * nstep) * 1e6


def suite_models(repeats, quick):
    """Section 5: dm_control's humanoid_CMU and dog, lagrax (vmap over B states)
    against `mj_forward` through `mujoco.rollout`, on the same states."""
    print(f"\n5. dm_control suite models, forward dynamics per state (vmap over {B} states)")
    if not (available("mujoco", "section 5") and available("dm_control", "section 5")):
        return
    import importlib.util

    from lagrax.chains import from_mjcf, from_mujoco_state

    folder = os.path.join(os.path.dirname(importlib.util.find_spec("dm_control").origin), "suite")
    threads = os.cpu_count() or 1
    nstep = 1 if quick else 4  # each state steps nstep times: B * nstep forwards a call
    for name in SUITE_MODELS:
        path = os.path.join(folder, f"{name}.xml")
        robot, params = from_mjcf(path)
        system, model = robot.system(), _suite_mujoco(path)
        fn = jax.jit(jax.vmap(lambda q, v, s=system, p=params: s.accelerations(0.0, q, v, p, None)))
        qpos, qvel = _suite_states(model, B)
        q, v = from_mujoco_state(jnp.asarray(qpos), jnp.asarray(qvel), robot)
        t0 = time.perf_counter()
        fn(q, v).block_until_ready()
        compile_s = time.perf_counter() - t0
        err = _suite_check(model, robot, fn, q, v, qpos, qvel)
        if not err < 1e-10:
            print(f"   {name}: q̈ differs from MuJoCo's qacc by {err:.1e}: not timed")
            continue
        _, t = timed(lambda f=fn, a=q, b=v: f(a, b).block_until_ready(), repeats)
        ours = t / B * 1e6
        one = _rollout_time(model, qpos, qvel, 1, repeats, nstep)
        every = _rollout_time(model, qpos, qvel, threads, repeats, nstep)
        print(
            f"   {name:12s} {model.nv:2d} DOF: lagrax {ours:7.3f} µs per state, MuJoCo "
            f"mj_forward {one:7.3f} µs per call ({ours / one:.2f}x), on {threads} threads "
            f"{every:7.3f} ({ours / every:.2f}x); q̈ vs qacc {err:.0e} (compile {compile_s:.1f} s)"
        )


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument(
        "--quick", action="store_true", help="n = 2, 7, 20 only (instead of 2, 4, 7, 10, 20)"
    )
    ap.add_argument("--repeats", type=int, default=5, help="timing repeats")
    ap.add_argument("--chart", default=None, help="write a log-log chart to this path")
    ap.add_argument(
        "--sections",
        type=int,
        nargs="+",
        default=[1, 2, 3, 4, 5],
        choices=[1, 2, 3, 4, 5],
        help="which sections to run",
    )
    args = ap.parse_args(argv)
    # optional baselines, checked before any work (their rows and lines say so again)
    available("pinocchio", "Pinocchio ABA baseline")
    available("mujoco", "mujoco.rollout trajectories")
    sizes = (2, 7, 20) if args.quick else (2, 4, 7, 10, 20)
    if 1 in args.sections:
        table = forward_dynamics(sizes, args.repeats)
        if args.chart:
            chart(table, sizes, args.chart)
            print(f"\nchart written to {args.chart}")
    if 2 in args.sections:
        arm_trajectory(args.repeats)
    if 3 in args.sections:
        urdf_arm(args.repeats)
    if 4 in args.sections:
        floating_bases(args.repeats)
    if 5 in args.sections:
        suite_models(args.repeats, args.quick)


def forward_dynamics(sizes, repeats):
    """Section 1: the table of per-state cost (printed), returned for the chart."""
    print(f"1. forward dynamics per state, vmap over {B} states ({jax.default_backend()})")
    print(
        "   µs per state (compile s):\n"
        "   kind      n   recursions        bodies' poses     autodiff          pinocchio"
    )
    table = {}

    def cell(system, params, n, key):
        compile_s, t = per_state(system, params, n, repeats)
        table.setdefault(key, []).append((n, t))
        return f"{t:8.3f} ({compile_s:4.1f})"

    for kind in ("planar", "spatial", "hand-written"):
        for n in sizes:
            if kind == "hand-written":  # the generic path of a user's planar T
                fast = cell(handwritten(n), {}, n, (kind, "autodiff"))
                print(f"   {kind:12s} {n:2d}   {'—':16s}  {'—':16s}  {fast}")
                continue
            chain, params = chain_of(kind, n)
            system = chain.system()
            fast = cell(system, params, n, (kind, "recursions"))
            scene = chain.scene(**({"bodies": "planar"} if kind == "planar" else {}))
            poses = dataclasses.replace(scene, equations="poses").system()
            pose_s = cell(poses, params, n, (kind, "poses")) if n <= 10 else "—"
            auto = "—"
            if n <= 7:
                generic = dataclasses.replace(system, equations=None)
                auto = cell(generic, params, n, (kind, "autodiff"))
            pin = pinocchio_aba(kind, n, repeats)
            pin_s = f"{pin:8.3f}" if pin is not None else "not installed"
            table.setdefault((kind, "pinocchio"), []).append((n, pin))
            print(f"   {kind:12s} {n:2d}   {fast}  {pose_s:16s}  {auto:16s}  {pin_s}")
    return table


def chart(table, sizes, path):
    """A log-log chart of cost per state against n, one line per kind and path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter, ScalarFormatter

    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    colors = {"planar": "tab:blue", "spatial": "tab:red", "hand-written": "tab:green"}
    styles = {"recursions": "o-", "poses": "d-.", "autodiff": "s--", "pinocchio": "^:"}
    for (kind, method), points in table.items():
        points = [(n, t) for n, t in points if t is not None]
        if not points:
            continue
        ns, ts = zip(*points, strict=True)
        label = f"{kind}, {'Pinocchio ABA per call' if method == 'pinocchio' else method}"
        ax.loglog(ns, ts, styles[method], color=colors[kind], label=label)
    ax.set_xticks(sizes)
    ax.xaxis.set_major_formatter(ScalarFormatter())
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("links n")
    ax.set_ylabel("forward dynamics per state (µs)")
    ax.set_title(f"cost against size (lagrax: vmap over {B} states)")
    ax.legend(loc="center left", bbox_to_anchor=(1.02, 0.5), fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
