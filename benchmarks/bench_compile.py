"""XLA:CPU's fusion emitters: compile time and run time of lagrax's programs with and
without them.

jaxlib 0.9.1 and later compile a fused group of elementwise operations on the CPU with
new ("fusion") emitters. On lagrax's programs, which are long chains of small scalar
operations (the recursions written out link by link, their derivatives), these take
much longer to compile than XLA:CPU's older loop emitter. `--xla_cpu_use_fusion_emitters=false`
selects the older one. This benchmark measures what that changes for a user: the first
call (tracing, compiling and running once, with the persistent compilation cache off)
and the time of later calls, for

1. `simulate` of the 2R arm (2 s, the default method) and of the URDF arm (1 s);
2. the URDF arm's `forward_dynamics_derivatives` under `jax.vmap` over 4,096 states;
3. solo12's floating-base forward dynamics under `jax.vmap` over 4,096 states, where
   example-robot-data is installed;
4. second derivatives of the damped 2R arm's accelerations: `jax.jacfwd(jax.jacrev(·))`
   (a Hessian) and `jax.jacrev(jax.jacrev(·))` (reverse over reverse).

Each configuration runs in fresh processes (`--processes` of each, taken in turn; the
medians are reported), since XLA reads its flags once. lagrax's own XLA setting (the
small-loop limit, `lagrax._core.xla_flags`) is on in both.

    python benchmarks/bench_compile.py [--processes 3]

About 4 minutes on 2 cores.

**First result** (`--first-result`): the time from before `import lagrax` to the first
result, in a fresh process with the persistent compilation cache off (load the model,
trace, compile, run once), and the same call again in that process ("warm"), for the
2R arm (1 s), the URDF arm7 (1 s), dm_control's `humanoid_CMU.xml` (62 dof, no contact,
1 s), gymnasium's `ant.xml` with `contact=True` dropped for 1 s, and solo12 on its four
feet under joint PD for 2 s (the contact guide's scene); MJX (`mujoco-mjx`, the `bench`
extra) beside the ant where it is installed: a `jax.jit` of a `lax.scan` of `mjx.step`
over the same second. `--chart PATH` draws the table. About 3 minutes on 2 cores.

    python benchmarks/bench_compile.py --first-result [--processes 1] [--chart PATH]
        [--json PATH] [--baseline PATH]

**One-trajectory options** (`--one-shot-options`): `simulate`'s compiled program with
lagrax's XLA options for a program that runs one trajectory
(`lagrax._core.xla_flags.one_shot_options`: XLA:CPU's loop emitter) and with XLA's
defaults (`LAGRAX_ONE_SHOT_XLA=0`), for the first-result table's models: in one process,
the settings alternating `--processes` times each, every compiled program dropped
between calls, so that the machine's drift (up to 40 % an hour across processes) falls on
both alike. About 4 minutes on 2 cores.

    python benchmarks/bench_compile.py --one-shot-options [--processes 2]

**Program sizes** (`--sizes`): the lines of the lowered program (StableHLO text) and
XLA's flop estimate of each part of the ant's contact simulation: the kinematics, the
spheres' placement, the contact forces with `Σ Jᵢᵀ Fᵢ`, the default coefficients'
scaling, the recursions, the vector field, the postprocessing at the saves, the
checks and the whole solve. Nothing is compiled; about 30 s.

    python benchmarks/bench_compile.py --sizes
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

from _optional import asset

OFF = "--xla_cpu_use_fusion_emitters=false"


def _first_and_later(fn, repeats=5):
    """`(first, later)`: the first call's wall time (trace, compile, run) and the
    median of `repeats` later calls, in seconds, each waited for."""
    import jax

    t0 = time.perf_counter()
    jax.block_until_ready(fn())
    first = time.perf_counter() - t0
    later = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn())
        later.append(time.perf_counter() - t0)
    return first, statistics.median(later)


def child() -> dict:
    """One process's figures: `{name: (first s, later s)}`."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    import lagrax as lx

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from _robots import SOLO12, floating_inputs, robots_folder

    out = {}
    arm, p2 = lx.models.planar_2r()
    out["simulate, 2R arm"] = _first_and_later(
        lambda: lx.simulate(arm, jnp.array([0.3, 0.8]), jnp.zeros(2), p2, t1=2.0).q
    )
    tree, p7 = lx.chains.from_urdf(lx.models.urdf_path("arm7"))
    arm7 = tree.system()
    n = arm7.n_dof
    out["simulate, URDF arm"] = _first_and_later(
        lambda: lx.simulate(arm7, jnp.full(n, 0.2), jnp.zeros(n), p7, t1=1.0).q
    )
    rng = np.random.default_rng(0)
    q, qd, tau = (jnp.asarray(rng.uniform(-1, 1, (4096, n))) for _ in range(3))
    derivs = jax.jit(jax.vmap(lambda a, b, c: arm7.forward_dynamics_derivatives(a, b, p7, c).dq))
    out["derivatives, URDF arm, vmap 4096"] = _first_and_later(lambda: derivs(q, qd, tau))
    folder = robots_folder()
    if folder is not None:
        solo, ps = lx.chains.from_urdf(os.path.join(folder, SOLO12), floating_base=True)
        solo_sys = solo.system()
        qs, vs, ts = floating_inputs(solo.n, 4096)
        fd = jax.jit(jax.vmap(lambda a, b, c: solo_sys.forward_dynamics(a, b, ps, c)))
        out["forward dynamics, solo12, vmap 4096"] = _first_and_later(lambda: fd(qs, vs, ts))

    def damped(q, qd, p):
        return 0.5 * p["c"] * (qd[0] ** 2 + qd[1] ** 2 + qd[0] * qd[1] * jnp.cos(q[1]))

    system = lx.LagrangianSystem(arm.kinetic, arm.potential, n_dof=2, dissipation=damped)
    pd = {**p2, "c": 0.3}
    x0 = jnp.array([0.3, -0.5, 0.7, 0.2, 0.1, -0.4])

    def acc(x):
        return system.forward_dynamics(x[:2], x[2:4], pd, x[4:])

    for name, outer in (("Hessian", jax.jacfwd), ("reverse over reverse", jax.jacrev)):
        second = jax.jit(outer(jax.jacrev(acc)))
        out[f"{name}, damped 2R arm"] = _first_and_later(lambda s=second: s(x0))
    return out


# ------------------------------------------------------------------ first result
FIRST_ROWS = ("2R arm, 1 s", "arm7, 1 s", "humanoid_CMU, 1 s", "ant, contact, 1 s",
              "solo12 on four feet, 2 s", "ant, MJX, 1 s")  # fmt: skip


def _first_child(row: str) -> dict:
    """One row of the first-result table, timed from before `import lagrax` (or, for
    MJX, `import mujoco.mjx`): `{"first": s, "again": s}`."""
    t0 = time.perf_counter()
    if row == "ant, MJX, 1 s":
        import jax
        import mujoco
        from mujoco import mjx

        model = mujoco.MjModel.from_xml_path(asset("gymnasium", "envs/mujoco/assets/ant.xml"))
        steps = round(1.0 / model.opt.timestep)
        mx, dx = mjx.put_model(model), mjx.put_data(model, mujoco.MjData(model))

        @jax.jit
        def second(d):
            return jax.lax.scan(lambda d, _: (mjx.step(mx, d), None), d, None, length=steps)[0]

        def fn():
            return second(dx).qpos
    else:
        import jax
        import jax.numpy as jnp
        import numpy as np

        import lagrax as lx

        fn = _first_scene(row, lx, jnp, np)
    jax.block_until_ready(fn())
    first = time.perf_counter() - t0
    again = []
    for _ in range(3):
        t1 = time.perf_counter()
        jax.block_until_ready(fn())
        again.append(time.perf_counter() - t1)
    return {"first": first, "again": min(again)}


def _first_scene(row, lx, jnp, np):
    """`fn() -> array`: the row's load and simulation (the load runs now)."""
    if row == "2R arm, 1 s":
        arm, p = lx.models.planar_2r()
        return lambda: lx.simulate(arm, jnp.array([0.3, 0.8]), jnp.zeros(2), p, t1=1.0).q
    if row == "arm7, 1 s":
        tree, p = lx.chains.from_urdf(lx.models.urdf_path("arm7"))
        arm = tree.system()
        n = arm.n_dof
        return lambda: lx.simulate(arm, jnp.full(n, 0.2), jnp.zeros(n), p, t1=1.0).q
    import mujoco

    if row == "solo12 on four feet, 2 s":
        return _solo12_standing(lx, jnp, np)
    if row == "humanoid_CMU, 1 s":
        path = asset("dm_control", "suite", "humanoid_CMU.xml")
        model, p = lx.chains.from_mjcf(path)
        system = robot = model.system()
    else:
        path = asset("gymnasium", "envs/mujoco/assets/ant.xml")
        system, p = lx.chains.from_mjcf(path, contact=True)
        robot = system.system
    mj = mujoco.MjModel.from_xml_path(path)
    data = mujoco.MjData(mj)
    q0, v0 = lx.chains.from_mujoco_state(data.qpos, data.qvel, robot)
    return lambda: lx.simulate(system, q0, v0, p, t1=1.0).q


def _solo12_standing(lx, jnp, np):
    """solo12 dropped from 0.3 m in its `standing` posture under joint PD, its four
    feet's coefficients chosen for `tsit5` (the contact guide's scene, 2 s)."""
    from lagrax.contact import ContactSystem

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from _robots import SOLO12, robots_folder

    feet, p = lx.chains.from_urdf(
        os.path.join(robots_folder(), SOLO12),
        floating_base=True,
        contact=["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"],
    )
    weight = 9.81 * float(p["base_m"] + jnp.sum(p["m"]))
    depth = 5e-4
    scene = ContactSystem(
        feet.system, feet.spheres, feet.plane, friction=feet.friction,
        stiffness=(weight / 4) / depth**1.5, dissipation=4 / 3 * np.sqrt(1.5 / (9.81 * depth)),
        stiction_velocity=0.01,
    )  # fmt: skip
    stance = jnp.asarray([0.1, 0.8, -1.6, -0.1, 0.8, -1.6, 0.1, -0.8, 1.6, -0.1, -0.8, 1.6])

    def pd(t, q, v):
        return jnp.concatenate([jnp.zeros(6), 10.0 * (stance - q[7:]) - 0.3 * v[6:]])

    q0 = jnp.concatenate([jnp.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 1.0]), stance])
    run = dict(t1=2.0, tau=pd, rtol=1e-5, atol=1e-5, n_save=201, solver="tsit5")  # chosen for it
    return lambda: lx.simulate(scene, q0, jnp.zeros(18), p, **run).q


def first_result(processes: int, chart: str | None, save=None, baseline=None) -> None:
    """Print (and draw) the first-result table: medians over `processes` fresh processes
    (`save`: also into this JSON file; `baseline`: a JSON file so saved, drawn beside)."""
    env = dict(os.environ, LAGRAX_COMPILATION_CACHE="0")
    rows = {}
    for row in FIRST_ROWS:
        got = []
        for _ in range(processes):
            proc = subprocess.run(
                [sys.executable, __file__, "--first-child", row],
                env=env, capture_output=True, text=True, check=False,
            )  # fmt: skip
            if proc.returncode != 0:
                print(f"{row}: not measured ({proc.stderr.strip().splitlines()[-1]})")
                break
            got.append(json.loads(proc.stdout.strip().splitlines()[-1]))
        if got:
            rows[row] = {k: statistics.median(g[k] for g in got) for k in ("first", "again")}
    print(f"medians of {processes} fresh processes; persistent compilation cache off")
    print(f"{'model':28s} {'first result (s)':>17s} {'again (ms)':>12s}")
    for row, r in rows.items():
        print(f"{row:28s} {r['first']:17.1f} {1e3 * r['again']:12.1f}")
    if save:
        with open(save, "w") as f:
            json.dump(rows, f, indent=1)
    if chart:
        before = None
        if baseline:
            with open(baseline) as f:
                before = json.load(f)
        draw(rows, before, chart)
        print(f"wrote {chart}")


def one_shot_options(rounds: int) -> None:
    """Print the first call and a later call of each first-result model (MJX aside) with
    lagrax's one-trajectory XLA options and with XLA's defaults, alternating."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    import lagrax as lx
    from lagrax._solve import compiled

    rows = [r for r in FIRST_ROWS if "MJX" not in r]
    fns = {row: _first_scene(row, lx, jnp, np) for row in rows}
    got: dict = {}
    for _ in range(rounds):
        for setting in ("1", "0"):
            os.environ["LAGRAX_ONE_SHOT_XLA"] = setting
            for row in rows:
                compiled.compiled.cache_clear()
                compiled._FRONT.clear()
                jax.clear_caches()
                t0 = time.perf_counter()
                jax.block_until_ready(fns[row]())
                t1 = time.perf_counter()
                jax.block_until_ready(fns[row]())
                t2 = time.perf_counter()
                got.setdefault((row, setting), []).append((t1 - t0, t2 - t1))
    os.environ.pop("LAGRAX_ONE_SHOT_XLA")
    print(f"medians of {rounds} rounds, alternating; the model loaded once, traced each time")
    print(f"{'model':28s} {'first call (s)':>24s} {'again (ms)':>22s}")
    print(
        f"{'':28s} {'options':>8s} {'defaults':>9s} {'ratio':>6s} {'options':>8s} {'defaults':>9s}"
    )
    for row in rows:
        (a, a2), (b, b2) = (
            [statistics.median(x[i] for x in got[(row, s)]) for i in (0, 1)] for s in "10"
        )
        print(f"{row:28s} {a:8.2f} {b:9.2f} {a / b:6.2f} {1e3 * a2:8.1f} {1e3 * b2:9.1f}")


def draw(rows: dict, before: dict | None, path: str) -> None:
    """The first-result chart: a bar per row (`before`'s beside it, in grey, where given)."""
    import matplotlib.pyplot as plt

    names = list(rows)
    fig, ax = plt.subplots(figsize=(7.5, 0.55 * len(names) + 1.2))
    y = list(range(len(names)))
    if before:
        ax.barh([i + 0.2 for i in y], [before.get(n, {}).get("first", 0) for n in names],
                height=0.4, color="0.75", label="before")  # fmt: skip
    width = 0.4 if before else 0.8
    shift = -0.2 if before else 0.0
    ax.barh([i + shift for i in y], [rows[n]["first"] for n in names], height=width,
            color="tab:blue", label="now")  # fmt: skip
    for i, n in enumerate(names):
        r = rows[n]
        ax.text(r["first"], i + shift, f" {r['first']:.1f} s (again {1e3 * r['again']:.0f} ms)",
                va="center", fontsize=8)  # fmt: skip
        if before and n in before:
            b = before[n]
            ax.text(b["first"], i + 0.2, f" {b['first']:.1f} s", va="center", fontsize=8)
    ax.set_yticks(y, names)
    ax.invert_yaxis()
    ax.set_xlabel("from the import to the first result (s), cold, 2-core CPU")
    top = max([r["first"] for r in rows.values()] + [b["first"] for b in (before or {}).values()])
    ax.set_xlim(0, 1.3 * top)
    if before:
        ax.legend(loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


# ------------------------------------------------------------------ program sizes
def sizes() -> None:
    """The table of `--sizes`: lines of each part's lowered program and XLA's flops."""
    import jax
    import jax.numpy as jnp

    import lagrax as lx
    from lagrax.contact import ContactSystem

    scene, p = lx.chains.from_mjcf(asset("gymnasium", "envs/mujoco/assets/ant.xml"), contact=True)
    robot = scene.system
    fixed = ContactSystem(
        robot, scene.spheres, scene.plane, friction=lambda x: x["contact_friction"],
        stiffness=1e5, dissipation=1.0, stiction_velocity=1e-3,
    )  # fmt: skip
    n = 501  # the default saves of a 1 s solve
    q = jnp.zeros(robot.n_configuration).at[2].set(0.75).at[6].set(1.0)
    v = jnp.zeros(robot.n_dof)
    qs, vs, ts = jnp.tile(q, (n, 1)), jnp.tile(v, (n, 1)), jnp.linspace(0.0, 1.0, n)

    def saves(fn):
        return lambda a, b, c: jax.vmap(fn)(a, b, c)

    parts = {
        "kinematics (the tree's frames)": (lambda a: robot.robot.tree.frames(a[7:], p), (q,)),
        "the 25 spheres' centres": (lambda a: scene.centres(a, p), (q,)),
        "contact forces and Σ Jᵢᵀ Fᵢ": (
            lambda a, b: fixed.contact_state(a, b, p)["generalized"], (q, v)),
        "the default coefficients' scaling": (
            lambda a: scene.coefficients(p, a.dtype).stiffness, (q,)),
        "the recursions (robot's accelerations)": (
            lambda a, b: robot.accelerations(0.0, a, b, p, None), (q, v)),
        "vector field (contact, prepared)": (
            lambda a, b: fixed.accelerations(0.0, a, b, p, None), (q, v)),
        "energy at the saves": (
            saves(lambda t, a, b: fixed.energy_and_magnitude(t, a, b, p)), (ts, qs, vs)),
        "input power at the saves": (
            saves(lambda t, a, b: fixed.input_power(t, a, b, p, None)), (ts, qs, vs)),
        "observables at the saves": (
            saves(lambda t, a, b: fixed.observables(t, a, b, p, None)), (ts, qs, vs)),
        "forward_dynamics (checks included)": (
            lambda a, b: scene.forward_dynamics(a, b, p), (q, v)),
        "simulate 1 s (the solve)": (
            lambda a, b: lx.simulate(scene, a, b, p, t1=1.0).q, (q, v)),
        "simulate 1 s, fixed coefficients": (
            lambda a, b: lx.simulate(fixed, a, b, p, t1=1.0).q, (q, v)),
    }  # fmt: skip
    print("gymnasium's ant with contact=True (25 spheres), lowered, not compiled")
    print(f"{'part':42s} {'lines':>8s} {'flops':>12s}")
    for name, (fn, args) in parts.items():
        lowered = jax.jit(fn).lower(*args)
        cost = lowered.cost_analysis() or {}
        flops = cost.get("flops", float("nan")) if isinstance(cost, dict) else float("nan")
        print(f"{name:42s} {len(lowered.as_text().splitlines()):8,d} {flops:12,.0f}")


def run(off: bool) -> dict:
    env = dict(os.environ, LAGRAX_COMPILATION_CACHE="0")
    if off:
        env["XLA_FLAGS"] = f"{env.get('XLA_FLAGS', '')} {OFF}".strip()
    proc = subprocess.run(
        [sys.executable, __file__, "--child"], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=" ".join(__doc__.split("\n\n")[0].split()),
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--processes", type=int, default=3, help="fresh processes per setting")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--first-child", default=None, help=argparse.SUPPRESS)
    parser.add_argument(
        "--first-result", action="store_true", help="the first-result table (see above)"
    )
    parser.add_argument("--chart", default=None, help="--first-result: draw it into this PNG")
    parser.add_argument("--json", default=None, help="--first-result: save it into this file")
    parser.add_argument(
        "--baseline", default=None, help="--first-result: a --json file to draw beside"
    )
    parser.add_argument(
        "--one-shot-options",
        action="store_true",
        help="simulate's first call with lagrax's one-trajectory XLA options and with "
        "XLA's defaults, alternating in one process",
    )
    parser.add_argument("--sizes", action="store_true", help="the program-size table")
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child()))
        return
    if args.first_child:
        print(json.dumps(_first_child(args.first_child)))
        return
    if args.first_result:
        processes = args.processes if "--processes" in (argv or sys.argv) else 1
        first_result(processes, args.chart, args.json, args.baseline)
        return
    if args.sizes:
        sizes()
        return
    if args.one_shot_options:
        one_shot_options(args.processes)
        return
    runs = {False: [], True: []}
    for _ in range(args.processes):
        for off in (False, True):
            runs[off].append(run(off))
    print(f"medians of {args.processes} processes each; first call: trace + compile + run")
    print(f"{'program':40s} {'first call (s)':>22s} {'later calls (ms)':>24s}")
    head = ("emitters", 9), ("off", 6), ("ratio", 5), ("emitters", 9), ("off", 7), ("ratio", 6)
    print(f"{'':40s} " + " ".join(f"{h:>{w}s}" for h, w in head))
    for name in runs[False][0]:

        def med(off, k, name=name):
            return statistics.median(r[name][k] for r in runs[off])

        f_on, f_off, l_on, l_off = med(False, 0), med(True, 0), med(False, 1), med(True, 1)
        print(
            f"{name:40s} {f_on:9.2f} {f_off:6.2f} {f_off / f_on:5.2f} "
            f"{1e3 * l_on:9.2f} {1e3 * l_off:7.2f} {l_off / l_on:6.2f}"
        )


if __name__ == "__main__":
    main()
