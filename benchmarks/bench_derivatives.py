"""Derivatives at the price of the dynamics: ∂q̈/∂(q, q̇, τ) against the forward dynamics,
against Pinocchio, and gradients through `simulate` against the solve.

Five tables, each a ratio against a baseline measured in this run:

1. **Per state** (`jax.vmap` over `--batch` random states, compiled; the fastest of
   `--repeats` calls, per state, the three calls of a system taken in turn): each
   system's forward dynamics, its Jacobian `jax.jacfwd(forward_dynamics)` with respect
   to `(q, q̇, τ)`, and
   `forward_dynamics_derivatives` (the same numbers in one call), for the 2R arm (user
   energies), planar chains of 7 and 20 links, the spatial 7-link chain (alternating z/y
   axes), the URDF arm `arm7` and the URDF tree `torso_two_arms`.
2. **Pinocchio** (where `pin` is installed; one call from Python, the fastest of repeated
   loops of 1,000 calls): `aba`, `computeABADerivatives` and `computeRNEADerivatives` on
   the two URDF models, against lagrax's `forward_dynamics_derivatives` and
   `inverse_dynamics_derivatives` per state (batched).
3. **Through `simulate`** (1 s, rtol = atol = 1e-8, two saves, loss `|q(t1)|²` with
   respect to `q0`): the forward solve, `jax.grad`, `jax.jacfwd` (forward mode) and
   `jax.vmap(jax.grad)` over `--sweep` (2R arm) or `--sweep-urdf` initial states, per
   member.
4. **Floating bases** (the URDF arm on a free base, and solo12 where example-robot-data
   is installed): the derivatives call against the forward dynamics per state (batched),
   and against Pinocchio's free-flyer `aba` and `computeABADerivatives`.
5. **Compile times** (a fresh trace each, the persistent cache off for this process): the
   URDF arm's first `linearize`, its first forward `simulate` and its first gradient.

    python benchmarks/bench_derivatives.py [--batch 4096] [--repeats 20] [--sweep 4096]

About 5–7 minutes on 2 cores.
"""

import argparse
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("LAGRAX_COMPILATION_CACHE", "0")  # compile times: measured cold

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
import lagrax as lx  # noqa: E402
from _optional import available  # noqa: E402
from _robots import SOLO12, floating_inputs, robots_folder  # noqa: E402

ARM_AXES = [(0, 0, 1), (0, 1, 0)] * 4


def systems():
    """`{name: (system, params)}` of the per-state table."""
    out = {"2R arm (user energies)": lx.models.planar_2r()}
    for n in (7, 20):
        chain = lx.chains.PlanarChain(n)
        out[f"PlanarChain({n})"] = (chain.system(), chain.params())
    spatial = lx.chains.SpatialChain("R" * 7, axes=ARM_AXES[:7])
    inertia = np.diag([0.5 * 0.05**2, (3 * 0.05**2 + 1) / 12, (3 * 0.05**2 + 1) / 12])
    out['SpatialChain("R"*7)'] = (spatial.system(), spatial.params(inertia=inertia))
    for name in ("arm7", "torso_two_arms"):
        tree, params = lx.chains.from_urdf(lx.models.urdf_path(name))
        out[f"URDF {name}"] = (tree.system(), params)
    return out


def fastest(fn, args, repeats):
    """Seconds of the fastest of `repeats` calls of `fn(*args)` (after one warm-up)."""
    jax.block_until_ready(fn(*args))
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(*args))
        times.append(time.perf_counter() - t0)
    return min(times)


def random_states(n, batch, seed=0):
    rng = np.random.default_rng(seed)
    return tuple(jnp.asarray(rng.uniform(-1.5, 1.5, (batch, n))) for _ in range(3))


def forward_and_derivatives(system, params):
    """`{"fd": …, "derivatives": …}`: `system`'s `forward_dynamics` and
    `forward_dynamics_derivatives` at `params`, vmapped over `(q, qd, tau)` and compiled."""
    return {
        "fd": jax.jit(jax.vmap(lambda a, b, c: system.forward_dynamics(a, b, params, c))),
        "derivatives": jax.jit(
            jax.vmap(lambda a, b, c: system.forward_dynamics_derivatives(a, b, params, c))
        ),
    }


def per_state(system, params, batch, repeats):
    """Microseconds per state of the forward dynamics, `jacfwd` of it with respect to
    `(q, q̇, τ)`, and `forward_dynamics_derivatives`."""
    n = system.n_dof
    q, qd, tau = random_states(n, batch)

    def fd(a, b, c):
        return system.forward_dynamics(a, b, params, c)

    calls = {
        "fd": jax.jit(jax.vmap(fd)),
        "jacfwd": jax.jit(jax.vmap(jax.jacfwd(fd, argnums=(0, 1, 2)))),
        "derivatives": jax.jit(
            jax.vmap(lambda a, b, c: system.forward_dynamics_derivatives(a, b, params, c))
        ),
    }
    times = fastest_interleaved(calls, (q, qd, tau), repeats)
    return {k: t / batch * 1e6 for k, t in times.items()}


def fastest_interleaved(calls, args, repeats):
    """`{name: seconds}`, the fastest of `repeats` calls of each `calls[name](*args)`,
    the calls taken in turn (one of each per round, after one warm-up each), so that the
    machine's slower and faster spells fall on all of them alike and their ratios hold."""
    for f in calls.values():
        jax.block_until_ready(f(*args))
    best = dict.fromkeys(calls, float("inf"))
    for _ in range(repeats):
        for name, f in calls.items():
            t0 = time.perf_counter()
            jax.block_until_ready(f(*args))
            best[name] = min(best[name], time.perf_counter() - t0)
    return best


def per_state_table(batch, repeats):
    print(f"\n## Per state (vmap over {batch:,} states, µs per state)\n")
    print("| system | forward dynamics | jacfwd (q, q̇, τ) | ratio | derivatives call | ratio |")
    print("|---|---|---|---|---|---|")
    out = {}
    for name, (system, params) in systems().items():
        t = per_state(system, params, batch, repeats)
        out[name] = t
        print(
            f"| {name} | {t['fd']:.3f} | {t['jacfwd']:.3f} | {t['jacfwd'] / t['fd']:.1f}× "
            f"| {t['derivatives']:.3f} | {t['derivatives'] / t['fd']:.1f}× |",
            flush=True,
        )
    return out


def _pin_loop(fn, args, repeats, calls=1000):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn(*args)
        times.append((time.perf_counter() - t0) / calls)
    return min(times) * 1e6


def _pin_inputs(pin, model):
    """`(data, q, v, tau)` for timing Pinocchio on `model`: a random configuration in
    [-1, 1] (a unit quaternion for a free flyer) and normal `v`, `tau` (seed 1)."""
    rng = np.random.default_rng(1)
    q = pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq))
    return model.createData(), q, rng.normal(size=model.nv), rng.normal(size=model.nv)


def pinocchio_table(ours, batch, repeats):
    if not available("pinocchio", "Pinocchio's derivatives"):
        return
    import pinocchio as pin

    print("\n## Against Pinocchio (µs per call from Python; lagrax per state, batched)\n")
    print(
        "| model | pin aba | pin computeABADerivatives | lagrax derivatives | ratio "
        "| pin computeRNEADerivatives | lagrax inverse_dynamics_derivatives | ratio |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for name in ("arm7", "torso_two_arms"):
        path = lx.models.urdf_path(name)
        model = pin.buildModelFromXML(path.read_text())
        data, q, v, tau = _pin_inputs(pin, model)
        aba = _pin_loop(pin.aba, (model, data, q, v, tau), repeats)
        d_aba = _pin_loop(pin.computeABADerivatives, (model, data, q, v, tau), repeats)
        d_rnea = _pin_loop(pin.computeRNEADerivatives, (model, data, q, v, tau), repeats)
        system, params = systems()[f"URDF {name}"]
        qs, qds, qdds = random_states(system.n_dof, batch)
        inv = jax.jit(
            jax.vmap(lambda a, b, c, s=system, p=params: s.inverse_dynamics_derivatives(a, b, c, p))
        )
        ours_inv = fastest(inv, (qs, qds, qdds), repeats) / batch * 1e6
        ours_fwd = ours[f"URDF {name}"]["derivatives"]
        print(
            f"| {name} | {aba:.2f} | {d_aba:.2f} | {ours_fwd:.2f} | {ours_fwd / d_aba:.2f}× "
            f"| {d_rnea:.2f} | {ours_inv:.2f} | {ours_inv / d_rnea:.2f}× |",
            flush=True,
        )


def floating_table(batch, repeats):
    """Floating bases: the derivatives call against the forward dynamics (per state,
    batched, taken in turn), and against Pinocchio's free-flyer `aba` and
    `computeABADerivatives` (one call from Python) where `pin` is installed."""
    print(f"\n## Floating bases (vmap over {batch:,} states, µs per state)\n")
    robots = [("URDF arm7 on a free base", lx.models.urdf_path("arm7").read_text())]
    folder = robots_folder()
    if folder is None:
        print(
            'note: solo12 skipped: example-robot-data is not installed (pip install -e ".[bench]")'
        )
    else:
        path = Path(folder) / SOLO12
        robots.append(("solo12 (example-robot-data)", path.read_text()))
    pin = None
    if available("pinocchio", "Pinocchio's free-flyer derivatives"):
        import pinocchio as pin
    print(
        "| robot | forward dynamics | derivatives call | ratio | pin aba "
        "| pin computeABADerivatives | lagrax / Pinocchio |"
    )
    print("|---|---|---|---|---|---|---|")
    for label, xml in robots:
        robot, params = lx.chains.from_urdf(xml, floating_base=True)
        params = dict(params, damping=jnp.zeros_like(params["damping"]))  # as Pinocchio's
        system, n = robot.system(), robot.n
        calls = forward_and_derivatives(system, params)
        inputs = floating_inputs(n, batch)
        t = {k: s / batch * 1e6 for k, s in fastest_interleaved(calls, inputs, repeats).items()}
        fd, der = t["fd"], t["derivatives"]
        line = f"| {label} | {fd:.2f} | {der:.2f} | {der / fd:.1f}× "
        if pin is None:
            print(line + "| | | |", flush=True)
            continue
        model = pin.buildModelFromXML(xml, pin.JointModelFreeFlyer())
        data, qp, vp, taup = _pin_inputs(pin, model)
        aba = _pin_loop(pin.aba, (model, data, qp, vp, taup), repeats)
        d_aba = _pin_loop(pin.computeABADerivatives, (model, data, qp, vp, taup), repeats)
        print(line + f"| {aba:.2f} | {d_aba:.2f} | {der / d_aba:.2f}× |", flush=True)


def _losses(system, params, n_save=2):
    n = system.n_dof

    def solve(q0, qd0):
        sol = lx.simulate(system, q0, qd0, params, t1=1.0, n_save=n_save)
        return sol.q[-1]

    def loss(q0):
        return jnp.sum(solve(q0, jnp.zeros(n)) ** 2)

    return solve, loss


def simulate_table(repeats, sweep, sweep_urdf):
    print("\n## Through simulate (1 s, rtol = atol = 1e-8; ms, ratio to the forward solve)\n")
    print(
        "| system | forward solve | jax.grad | ratio | jax.jacfwd | ratio | vmap(grad) per member |"
    )
    print("|---|---|---|---|---|---|---|")
    cases = {
        "2R arm": lx.models.planar_2r(),
        "URDF arm7": systems()["URDF arm7"],
    }
    for name, (system, params) in cases.items():
        n = system.n_dof
        members = sweep if name == "2R arm" else sweep_urdf
        solve, loss = _losses(system, params)
        q0 = jnp.full(n, 0.3)
        forward = jax.jit(loss)
        grad = jax.jit(jax.grad(loss))
        jacfwd = jax.jit(jax.jacfwd(loss))
        batch = jnp.asarray(np.random.default_rng(2).uniform(-0.5, 0.5, (members, n))) + q0
        vgrad = jax.jit(jax.vmap(jax.grad(loss)))
        t_f = fastest(forward, (q0,), repeats)
        t_g = fastest(grad, (q0,), repeats)
        t_j = fastest(jacfwd, (q0,), repeats)
        t_v = fastest(vgrad, (batch,), max(1, repeats // 10)) / members
        print(
            f"| {name} | {t_f * 1e3:.3f} | {t_g * 1e3:.3f} | {t_g / t_f:.1f}× | "
            f"{t_j * 1e3:.3f} | {t_j / t_f:.1f}× | {t_v * 1e3:.3f} ({members:,} members) |",
            flush=True,
        )


def first_call(fn, *args):
    t0 = time.perf_counter()
    jax.block_until_ready(fn(*args))
    return time.perf_counter() - t0


def compile_table():
    print("\n## Compile times (s, first call in this process, persistent cache off)\n")
    tree, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"))
    system = tree.system()
    q = jnp.full(tree.n, 0.3)
    lin = first_call(lambda: system.linearize(q, jnp.zeros(tree.n), params))
    _, loss = _losses(system, params)
    fwd = first_call(jax.jit(loss), q)
    grad = first_call(jax.jit(jax.grad(loss)), q)
    print("| URDF arm7 | first linearize | first forward simulate | first grad | ratio |")
    print("|---|---|---|---|---|")
    print(f"| | {lin:.2f} | {fwd:.2f} | {grad:.2f} | {grad / fwd:.1f}× |", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--batch", type=int, default=4096, help="states per vmapped call")
    ap.add_argument("--repeats", type=int, default=20, help="timed calls (the fastest)")
    ap.add_argument("--sweep", type=int, default=4096, help="2R arm: members of vmap(grad)")
    ap.add_argument("--sweep-urdf", type=int, default=256, help="URDF arm: members of vmap(grad)")
    ap.add_argument(
        "--only",
        choices=("all", "compile", "per-state", "floating", "simulate"),
        default="all",
        help="run one table (compile times need a fresh process: run them first)",
    )
    args = ap.parse_args(argv)
    print(f"devices: {jax.devices()}; lagrax {lx.__version__}, jax {jax.__version__}")
    if args.only in ("all", "compile"):
        compile_table()
    if args.only in ("all", "per-state"):
        ours = per_state_table(args.batch, args.repeats)
        pinocchio_table(ours, args.batch, args.repeats)
    if args.only in ("all", "floating"):
        floating_table(args.batch, args.repeats)
    if args.only in ("all", "simulate"):
        simulate_table(args.repeats, args.sweep, args.sweep_urdf)


if __name__ == "__main__":
    main()
