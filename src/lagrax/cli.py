"""The ``lagrax`` command."""

import argparse
import sys
import time
from pathlib import Path


def _demo(args) -> int:
    import jax
    import jax.numpy as jnp
    import matplotlib

    matplotlib.use("Agg")
    import lagrax as lx

    t_start = time.perf_counter()
    system, params = lx.models.planar_2r()
    print("lagrax demo: the planar 2R arm (double pendulum) from T and V")
    print("  params:", {k: round(float(v), 4) for k, v in params.items()})

    # 1. autodiff Lagrangian vs the free-body Newton-Euler derivation at random states
    key = jax.random.PRNGKey(args.seed)
    kq, kqd, kqdd = jax.random.split(key, 3)
    n = args.states
    q = jax.random.uniform(kq, (n, 2), minval=-jnp.pi, maxval=jnp.pi)
    qd = jax.random.uniform(kqd, (n, 2), minval=-5.0, maxval=5.0)
    qdd = jax.random.uniform(kqdd, (n, 2), minval=-20.0, maxval=20.0)
    tau_l = jax.jit(jax.vmap(lambda a, b, c: system.inverse_dynamics(a, b, c, params)))(
        q, qd, qdd
    )
    tau_ne = jax.jit(jax.vmap(lambda a, b, c: lx.newton_euler.planar_2r(a, b, c, params)))(
        q, qd, qdd
    )
    rel = float(jnp.max(jnp.abs(tau_l - tau_ne)) / jnp.max(jnp.abs(tau_ne)))
    qdd_back = jax.jit(
        jax.vmap(lambda a, b, u: system.forward_dynamics(a, b, params, u))
    )(q, qd, tau_ne)
    rel_fd = float(jnp.max(jnp.abs(qdd_back - qdd)) / jnp.max(jnp.abs(qdd)))
    print(f"  Lagrangian vs Newton-Euler torques at {n} random states: "
          f"max relative difference {rel:.1e}")
    print(f"  forward_dynamics(Newton-Euler torques) vs the accelerations: {rel_fd:.1e}")

    # 2. simulate 10 s from a chaotic start, at rest, torque-free
    q0 = jnp.array([-jnp.pi / 2 + 1.4, 0.8])
    qd0 = jnp.zeros(2)
    t0 = time.perf_counter()
    sol = lx.simulate(system, q0, qd0, params, t1=args.t1, rtol=args.rtol, atol=args.rtol,
                      n_save=1001)
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    sol = lx.simulate(system, q0, qd0, params, t1=args.t1, rtol=args.rtol, atol=args.rtol,
                      n_save=1001)
    jax.block_until_ready(sol.q)
    t_again = time.perf_counter() - t0
    e_err = float(jnp.max(jnp.abs(sol.energy_error)))
    print(f"  simulated {args.t1:g} s (Tsit5, rtol=atol={args.rtol:g}): "
          f"{int(sol.stats['num_accepted_steps'])} steps, first call {t_first:.2f} s "
          f"(with compile), again {t_again * 1e3:.1f} ms")
    print(f"  max relative energy error |E(t)-E(0)|/|E(0)|: {e_err:.1e}")

    # 3. figure
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fig = lx.plot.summary(
        sol,
        [float(params["l1"]), float(params["l2"])],
        title=f"planar 2R arm, {args.t1:g} s torque-free from θ=({float(q0[0]):.2f}, "
        f"{float(q0[1]):.2f}) rad; Lagrangian vs Newton-Euler {rel:.0e}",
    )
    path = out / "demo_2r.png"
    fig.savefig(path, dpi=110)
    print(f"  figure written to {path.resolve()}")
    print(f"  total {time.perf_counter() - t_start:.1f} s")
    ok = rel < 1e-10 and rel_fd < 1e-10 and e_err < 1e-5
    if not ok:
        print("  CHECK FAILED: the derivations disagree or energy drifted", file=sys.stderr)
    return 0 if ok else 1


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="lagrax", description="Equations of motion from energies, with JAX."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser(
        "demo",
        help="derive the 2R arm, check it against Newton-Euler, simulate it, draw it",
    )
    demo.add_argument("--out", default="lagrax-output", help="output folder for the figure")
    demo.add_argument("--t1", type=float, default=10.0, help="simulated time [s]")
    demo.add_argument("--rtol", type=float, default=1e-10, help="rtol = atol of the solve")
    demo.add_argument("--states", type=int, default=1000, help="random states to compare")
    demo.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.command == "demo":
        return _demo(args)
    return 2  # pragma: no cover


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
