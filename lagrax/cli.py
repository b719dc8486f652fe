"""The `lagrax` command."""

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
    tau_l = jax.jit(jax.vmap(lambda a, b, c: system.inverse_dynamics(a, b, c, params)))(q, qd, qdd)
    tau_ne = jax.jit(jax.vmap(lambda a, b, c: lx.newton_euler.planar_2r(a, b, c, params)))(
        q, qd, qdd
    )
    rel = float(jnp.max(jnp.abs(tau_l - tau_ne)) / jnp.max(jnp.abs(tau_ne)))
    qdd_back = jax.jit(jax.vmap(lambda a, b, u: system.forward_dynamics(a, b, params, u)))(
        q, qd, tau_ne
    )
    rel_fd = float(jnp.max(jnp.abs(qdd_back - qdd)) / jnp.max(jnp.abs(qdd)))
    print(
        f"  Lagrangian vs Newton-Euler torques at {n} random states: "
        f"max relative difference {rel:.1e}"
    )
    print(f"  forward_dynamics(Newton-Euler torques) vs the accelerations: {rel_fd:.1e}")

    # 2. simulate 10 s from a chaotic start, at rest, torque-free
    q0 = jnp.array([-jnp.pi / 2 + 1.4, 0.8])
    qd0 = jnp.zeros(2)
    t0 = time.perf_counter()
    sol = lx.simulate(
        system, q0, qd0, params, t1=args.t1, rtol=args.rtol, atol=args.rtol, n_save=1001
    )
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    sol = lx.simulate(
        system, q0, qd0, params, t1=args.t1, rtol=args.rtol, atol=args.rtol, n_save=1001
    )
    jax.block_until_ready(sol.q)
    t_again = time.perf_counter() - t0
    e_err = float(jnp.max(jnp.abs(sol.energy_error)))
    print(
        f"  simulated {args.t1:g} s (Tsit5, rtol=atol={args.rtol:g}): "
        f"{int(sol.stats['num_accepted_steps'])} steps, first call {t_first:.2f} s "
        f"(with compile), again {t_again * 1e3:.1f} ms"
    )
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


def _bench_work_precision(args) -> int:
    import jax.numpy as jnp
    import matplotlib

    matplotlib.use("Agg")
    import lagrax as lx
    from lagrax.bench import precision as wp
    from lagrax.bench.stability import CHAOTIC_START

    system, params = lx.models.planar_2r()
    q0, qd0 = jnp.array(CHAOTIC_START), jnp.zeros(2)
    ladders = wp.QUICK_LADDERS if args.quick else wp.DEFAULT_LADDERS
    if args.methods:
        ladders = {m: wp.DEFAULT_LADDERS[m] for m in args.methods.split(",")}
    print(f"work-precision: 2R arm, chaotic start θ = (−π/2 + 1.4, 0.8), {args.t1:g} s")
    points, ref_err = wp.work_precision(
        system, q0, qd0, params, t1=args.t1, ladders=ladders, repeats=args.repeats, progress=True
    )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = wp.write_csv(points, out / "work_precision.csv")
    fig = wp.plot_work_precision(
        points,
        reference_error=ref_err,
        title=f"2R arm, chaotic start, {args.t1:g} s (reference error ≈ {ref_err:.0e})",
    )
    png = out / "work_precision.png"
    fig.savefig(png, dpi=110)
    print(f"reference (Dopri8, rtol=atol=1e-13) error estimate {ref_err:.1e}")
    print(f"wrote {csv_path.resolve()} and {png.resolve()}")
    return 0


def _bench_stability(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    from lagrax.bench import stability as st

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    periods = 300 if args.quick else 1e4
    print(f"stability atlas ({'quick' if args.quick else 'full'}):")
    rows, sols = st.long_horizon(periods)
    st.plot_long_horizon(sols).savefig(out / "stability_long_horizon.png", dpi=110)
    print("  long horizon done", flush=True)
    rows += st.stiff()
    print("  stiff done", flush=True)
    chaos_rows, curves = st.chaos(t1=20.0 if args.quick else 30.0)
    rows += chaos_rows
    st.plot_chaos(curves).savefig(out / "stability_chaos.png", dpi=110)
    print("  chaos done", flush=True)
    rows += st.singular()
    st.write_table(rows, out / "stability.md", out / "stability.csv")
    print((out / "stability.md").read_text())
    print(f"wrote {(out / 'stability.md').resolve()}, stability.csv and charts")
    return 0


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """`--help` shows each option's default, except an empty or off one."""

    def _get_help_string(self, action):
        default = action.default
        if default is None or default is False or default == "" or default is argparse.SUPPRESS:
            return action.help
        return super()._get_help_string(action)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="lagrax",
        description="Equations of motion from energies, with JAX.",
        formatter_class=_HelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser(
        "demo",
        help="derive the 2R arm, check it against Newton-Euler, simulate it, draw it",
        description="Derive the 2R arm from its energies, check it against Newton-Euler at "
        "random states, simulate it and draw it.",
        formatter_class=_HelpFormatter,
    )
    demo.add_argument("--out", default="lagrax-output", help="output folder for the figure")
    demo.add_argument("--t1", type=float, default=10.0, help="simulated time [s]")
    demo.add_argument("--rtol", type=float, default=1e-10, help="rtol = atol of the solve")
    demo.add_argument("--states", type=int, default=1000, help="random states to compare")
    demo.add_argument("--seed", type=int, default=0, help="seed of the random states")
    bench = sub.add_parser(
        "bench", help="accuracy and cost studies", formatter_class=_HelpFormatter
    )
    bench_sub = bench.add_subparsers(dest="study", required=True)
    wp = bench_sub.add_parser(
        "work-precision",
        help="error vs wall time per method and tolerance (CSV + PNG)",
        formatter_class=_HelpFormatter,
    )
    wp.add_argument("--out", default="lagrax-output", help="output folder")
    wp.add_argument("--t1", type=float, default=10.0, help="simulated time [s]")
    wp.add_argument("--repeats", type=int, default=5, help="timed runs per point (median)")
    wp.add_argument(
        "--methods", default="", help="comma-separated subset, e.g. tsit5,dopri8 (default: all)"
    )
    wp.add_argument("--quick", action="store_true", help="a few points only")
    stab = bench_sub.add_parser(
        "stability",
        help="where methods fail, and how it is reported",
        formatter_class=_HelpFormatter,
    )
    stab.add_argument("--out", default="lagrax-output", help="output folder")
    stab.add_argument("--quick", action="store_true", help="shorter horizons")
    args = parser.parse_args(argv)
    if args.command == "demo":
        return _demo(args)
    if args.command == "bench" and args.study == "work-precision":
        return _bench_work_precision(args)
    if args.command == "bench" and args.study == "stability":
        return _bench_stability(args)
    return 2  # pragma: no cover


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
