"""Long-horizon energy: the variational integrator against Tsit5, at equal cost.

The torque-free 2R arm (regular motion from θ = (−π/2 + 0.6, 0.4), at rest) over 10⁴ s
(≈ 4,300 periods of its slowest mode). Tsit5 at rtol = atol = 1e-8 drifts secularly in
energy; the midpoint variational integrator at a fixed step keeps a bounded, oscillating
energy error. For each run: the least-squares energy trend per 1000 s, the max relative
energy error, the trend's share of it over the run, steps, and the median wall time
after compilation; the ratio is each run's time over Tsit5's, measured in this run.

    python benchmarks/bench_energy_drift.py [--t1 10000] [--repeats 3]
"""

import argparse
import math
import statistics
import time

import jax
import jax.numpy as jnp

import lagrax as lx
from lagrax.bench.stability import energy_trend


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--t1", type=float, default=1e4, help="simulated time [s]")
    ap.add_argument("--repeats", type=int, default=3, help="timed runs (median)")
    args = ap.parse_args(argv)

    system, params = lx.models.planar_2r()
    q0, qd0 = jnp.array([-math.pi / 2 + 0.6, 0.4]), jnp.zeros(2)
    runs = [("tsit5, rtol = atol = 1e-8", dict(solver="tsit5", rtol=1e-8, atol=1e-8))]
    runs += [
        (f"variational, dt = {dt:g}", dict(solver="variational", dt=dt))
        for dt in (0.02, 0.025, 0.03)
    ]

    def go(kw):
        sol = lx.simulate(
            system, q0, qd0, params, t1=args.t1, n_save=2001, max_steps=50_000_000, **kw
        )
        jax.block_until_ready(sol.q)
        return sol

    print(f"torque-free 2R arm, {args.t1:g} s; times: median of {args.repeats} after compiling")
    print(
        f"{'run':28s} {'time':>9s} {'ratio':>6s} {'steps':>9s} {'trend/1000 s':>13s} "
        f"{'max |dE/E|':>11s} {'trend share':>11s}"
    )
    base = None
    for name, kw in runs:
        go(kw)  # compile
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            sol = go(kw)
            times.append(time.perf_counter() - t0)
        t = statistics.median(times)
        base = base or t
        slope, emax = energy_trend(sol.ts, sol.energy_error)
        share = abs(slope) * args.t1 / emax  # > ~0.5: the drift dominates the error
        print(
            f"{name:28s} {t:8.3f}s {t / base:6.2f} {int(sol.stats['num_steps']):9d} "
            f"{slope * 1000:+13.1e} {emax:11.1e} {share:11.2f}"
        )


if __name__ == "__main__":
    main()
