"""Which method should a contact scene default to? Each candidate on the contact
guide's textbook scenes (closed forms) and on gymnasium's ant dropped for 1 s.

Each (scene, method) runs in a process of its own, so that its first call is a cold
compile (run from the repository root with `PYTHONPATH=.`, for this checkout's lagrax):
each prints one JSON line (steps taken, `sol.ok`, the error against the closed form,
the lowered program's lines, the first call's and a warm call's wall time):
`python benchmarks/bench_contact_methods.py [--scenes rolling,ant]`.

Scenes: `rolling` (a sphere on 15°, μ = 0.5, μ_s = 1: `a = 5/7 g sin θ`),
`sliding` (30°, μ = μ_s = 0.1: `a = g (sin θ − μ cos θ)`), `sticking` (a box of four
corners on 15°, μ = 0.5: it stays, `|Δx| ≤ 1 mm` over 5 s), `bounce` (an elastic drop
from 1 m, `dissipation=0`: the apex after the bounce is 1 m), `ant`
(`from_mjcf(ant.xml, contact=True)`, dropped from 0.75 m for 1 s) and `ant_limits`
(`from_mujoco(ant.xml)`: the limits enforced, `ctrl = 0`).
Methods: `default` (no `solver=`), `tsit5`, `kvaerno3`, `kvaerno4`, `kvaerno5` (as
lagrax configures it: Newton with a fresh Jacobian each iteration, a PI controller),
`rodas4` (linearly implicit: one Jacobian a step, the default since it was measured here)
and `kvaerno5_chord` (`diffrax.Kvaerno5()` as diffrax configures it: a chord iteration);
`--methods tsit5,rodas4` picks some.
"""

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import time
import warnings

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)
# every first call a cold compile, in this process and in the children it starts
os.environ.setdefault("LAGRAX_COMPILATION_CACHE", "0")

import lagrax as lx  # noqa: E402
from lagrax._solve import methods  # noqa: E402
from lagrax.contact import Box, ContactSystem, Plane, Sphere  # noqa: E402

G, R = 9.81, 0.1
FLOOR = Plane([0.0, 1.0])
SCENES = ("rolling", "sliding", "sticking", "bounce", "ant", "ant_limits")
METHODS = ("tsit5", "kvaerno3", "kvaerno4", "kvaerno5", "rodas4", "default")

# the lower-order ESDIRKs, configured as lagrax configures kvaerno5 (measured here only)
for _name, _cls in (("kvaerno3", dfx.Kvaerno3), ("kvaerno4", dfx.Kvaerno4)):
    methods.METHODS.setdefault(_name, methods.MethodInfo(_cls, True, True, _name))


def _gravity(angle):
    return {"gx": G * np.sin(angle), "gy": -G * np.cos(angle)}


def _potential(q, p):
    return -p["m"] * (p["gx"] * q[0] + p["gy"] * q[1])


def _ball(angle, mu, mus):
    def kinetic(q, qd, p):
        return 0.5 * p["m"] * (qd[0] ** 2 + qd[1] ** 2) + 0.2 * p["m"] * R**2 * qd[2] ** 2

    body = lx.LagrangianSystem(kinetic, _potential, n_dof=3)
    sphere = Sphere(R, lambda q, p: q[:2], angle=lambda q, p: q[2])
    scene = ContactSystem(body, sphere, FLOOR, friction=mu, static_friction=mus)
    params = {"m": 1.0, **_gravity(angle)}
    rest = (G * np.cos(angle) / float(scene.coefficients(params).stiffness)) ** (1 / 1.5)
    return scene, [0.0, R - rest, 0.0], [0.0, 0.0, 0.0], params


def _ant_xml():
    root = importlib.util.find_spec("gymnasium").submodule_search_locations[0]
    return os.path.join(root, "envs", "mujoco", "assets", "ant.xml")


def case(name):
    """`(scene, q0, v0, params, t1, ts, error(sol))` of a scene."""
    if name in ("rolling", "sliding"):
        rolling = name == "rolling"
        angle, mu, mus = (np.deg2rad(15.0), 0.5, 1.0) if rolling else (np.deg2rad(30.0), 0.1, 0.1)
        t1 = 1.0 if name == "rolling" else 0.5
        expected = (
            5 / 7 * G * np.sin(angle)
            if name == "rolling"
            else G * (np.sin(angle) - mu * np.cos(angle))
        )
        scene, q0, v0, params = _ball(angle, mu, mus)
        ts = np.linspace(0.0, t1, 201)

        def error(sol):
            keep = ts > 0.2 * t1
            accel = 2.0 * np.polyfit(ts[keep], np.asarray(sol.q[keep, 0]), 2)[0]
            return abs(accel / expected - 1.0)

        return scene, q0, v0, params, t1, ts, error
    if name == "sticking":
        a, b = 0.1, 0.05
        inertia = (4 * a**2 + 4 * b**2) / 12

        def kinetic(q, qd, p):
            return 0.5 * p["m"] * (qd[0] ** 2 + qd[1] ** 2) + 0.5 * inertia * qd[2] ** 2

        body = lx.LagrangianSystem(kinetic, _potential, n_dof=3)
        box = ContactSystem(
            body, Box((a, b), lambda q, p: q[:2], angle=lambda q, p: q[2]), FLOOR, friction=0.5
        )
        params = {"m": 1.0, **_gravity(np.deg2rad(15.0))}

        def error(sol):  # the creep, in metres over 5 s (a stuck box: 0)
            return abs(float(sol.q[-1, 0] - sol.q[0, 0]))

        return box, [0.0, b, 0.0], [0.0, 0.0, 0.0], params, 5.0, None, error
    if name == "bounce":
        body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * p["m"] * qd @ qd, _potential, n_dof=2)
        point = ContactSystem(body, Sphere(R, lambda q, p: q), FLOOR, dissipation=0.0)

        def error(sol):
            apex = float(sol.q[-1, 1]) + float(sol.qd[-1, 1]) ** 2 / (2 * G) - R
            return abs(apex - 1.0)

        params = {"m": 1.0, **_gravity(0.0)}
        return point, [0.0, 1.0 + R], [0.0, 0.0], params, 0.7, None, error
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if name == "ant":
            scene, params = lx.chains.from_mjcf(_ant_xml(), contact=True)
        else:
            scene, params = lx.chains.from_mujoco(_ant_xml())
    robot = scene.system
    q0 = jnp.zeros(robot.n_configuration).at[2].set(0.75).at[6].set(1.0)

    def error(sol):  # the base's height at 1 s (no closed form)
        return float(sol.q[-1, 2])

    return scene, q0, jnp.zeros(robot.n_dof), params, 1.0, None, error


def run(scene_name, method):
    scene, q0, v0, params, t1, ts, error = case(scene_name)
    kw = {"t1": t1}
    if ts is not None:
        kw["ts"] = ts
    if method == "kvaerno5_chord":  # diffrax's own: a chord iteration, its controller
        kw["solver"] = dfx.Kvaerno5()
    elif method != "default":
        kw["solver"] = method
    start = time.perf_counter()
    sol = lx.simulate(scene, q0, v0, params, **kw)
    jax.block_until_ready(sol.q)
    first = time.perf_counter() - start
    start = time.perf_counter()
    jax.block_until_ready(lx.simulate(scene, q0, v0, params, **kw).q)
    warm = time.perf_counter() - start
    size = len(
        jax.jit(lambda a, b, p: lx.simulate(scene, a, b, p, **kw).q)
        .lower(jnp.asarray(q0, float), jnp.asarray(v0, float), params)
        .as_text()
        .splitlines()
    )
    return {
        "scene": scene_name,
        "method": method,
        "ok": bool(sol.ok),
        "steps": int(sol.stats["num_steps"]),
        "accepted": int(sol.stats["num_accepted_steps"]),
        "error": float(error(sol)) if bool(sol.ok) else None,
        "lines": size,
        "first_s": round(first, 1),
        "warm_s": round(warm, 2),
    }


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--scenes", default="all", help="comma-separated, or all")
    parser.add_argument(
        "--methods", default=",".join(METHODS), help="comma-separated, of " + ", ".join(METHODS)
    )
    parser.add_argument("--child", nargs=2, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:  # one scene and method, in a fresh process
        scene, method = args.child
        try:
            print(json.dumps(run(scene, method)))
        except Exception as err:  # a failed solve is a row of the table
            failed = str(err).splitlines()[0][:200]
            print(json.dumps({"scene": scene, "method": method, "failed": failed}))
        return
    for scene in SCENES if args.scenes == "all" else args.scenes.split(","):
        for method in args.methods.split(","):
            out = subprocess.run(
                [sys.executable, __file__, "--child", scene, method],
                capture_output=True,
                text=True,
                check=False,
            )
            print(out.stdout.strip() or out.stderr.strip().splitlines()[-1], flush=True)


if __name__ == "__main__":
    main()
