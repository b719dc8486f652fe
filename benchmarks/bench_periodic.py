"""Periodic orbits: one orbit solve against one step's simulation, and a stability map.

The compass-gait walker of Goswami, Thuilot & Espiau (m = 5 kg legs, M = 10 kg hip,
a = b = 0.5 m) from its energies, with the heel strike as the Poincaré section and the
impact as its reset (``_compass_gait.py``; the model of ``tests/test_periodic.py``).
Measured in one run, after compilation (medians of interleaved repeats):

1. **one orbit solve**: ``lagrax.periodic_orbit`` at a 3° slope from a nearby guess
   (the fixed point to 4 digits), compiled, at ``rtol = atol = 1e-10``; against **one
   step's simulation**: ``lagrax.simulate`` from the fixed point over one step, to the
   heel strike (a terminal event, as the return map is) and to ``t1 = period`` (no event),
   compiled, at the same tolerances. The ratio is the orbit solve's time over the
   simulation's. The breakdown: Newton's return-map evaluations (iterations + 1), each a
   ``jax.jacfwd`` of the return map (the step and its 4 tangents), timed alone;
2. **a stability map** over slope × hip-to-leg mass ratio ``M / m`` (m = 5 kg fixed):
   ``lagrax.orbit_map`` over a ``--grid`` × ``--grid`` grid (members one after another in
   one compiled ``lax.map``, its default), and ``jax.vmap(periodic_orbit)`` over a
   ``--vmap-grid`` × ``--vmap-grid`` one (under ``vmap`` every member waits for the
   slowest), every member from
   the 3° gait's fixed point (a step of 0.73 s: `t_max = 2 s`, at most 1000 solver steps
   and 12 Newton steps, so that a member whose walker falls stops early: under `vmap`
   every member waits for the slowest); wall time, the shares of members whose orbit
   was found and that are stable.

    python benchmarks/bench_periodic.py [--grid 64] [--vmap-grid 8] [--repeats 7]
"""

import argparse
import os
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import lagrax as lx

sys.path.insert(0, os.path.dirname(__file__))
from _compass_gait import GOSWAMI, GUESS, HEEL_STRIKE, WALKER  # noqa: E402

TOL = 1e-10


def timed(fns, repeats):
    """Median wall time of each of `fns` (called interleaved, `repeats` rounds)."""
    times = [[] for _ in fns]
    for _ in range(repeats):
        for k, fn in enumerate(fns):
            t = time.perf_counter()
            jax.block_until_ready(fn())
            times[k].append(time.perf_counter() - t)
    return [statistics.median(t) for t in times]


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--slope", type=float, default=3.0, help="the orbit solve's slope [deg]")
    ap.add_argument("--grid", type=int, default=64, help="orbit_map's points per axis")
    ap.add_argument(
        "--vmap-grid", type=int, default=8, help="jax.vmap(periodic_orbit)'s points per axis"
    )
    ap.add_argument(
        "--slopes", type=float, nargs=2, default=(2.5, 5.0), help="the map's slopes [deg]"
    )
    ap.add_argument(
        "--ratios", type=float, nargs=2, default=(1.0, 3.0), help="the map's M / m range"
    )
    ap.add_argument("--repeats", type=int, default=7, help="timed rounds (median)")
    args = ap.parse_args(argv)

    # ------------------------------------------------------------ 1. one orbit solve
    params = {**GOSWAMI, "slope": jnp.deg2rad(args.slope)}
    q0, qd0 = jnp.asarray(GUESS[0]), jnp.asarray(GUESS[1])
    solve = jax.jit(
        lambda q, qd, p: lx.periodic_orbit(
            WALKER, q, qd, p, section=HEEL_STRIKE, rtol=TOL, atol=TOL
        )
    )
    t = time.perf_counter()
    orbit = jax.block_until_ready(solve(q0, qd0, params))
    compile_orbit = time.perf_counter() - t
    if not bool(orbit.ok):
        print(f"the {args.slope:g}° gait was not found: {lx.RESULTS[orbit.result]}")
        return
    step = lx.Event(HEEL_STRIKE.condition, direction=1, terminal=True)
    to_strike = jax.jit(
        lambda q, qd, p: (
            lx.simulate(
                WALKER, q, qd, p, t1=2.0, events=step, n_save=2, rtol=TOL, atol=TOL, throw=False
            ).q_end
        )
    )
    to_period = jax.jit(
        lambda q, qd, p, t1: (
            lx.simulate(WALKER, q, qd, p, t1=t1, n_save=2, rtol=TOL, atol=TOL, throw=False).q_end
        )
    )

    def return_map(x, p):  # one evaluation of Newton's: the step, then the impact
        sol = lx.simulate(
            WALKER, x[:2], x[2:], p, t1=2.0, events=step, n_save=2, rtol=TOL, atol=TOL,
            throw=False,
        )  # fmt: skip
        q, qd = HEEL_STRIKE.reset(sol.t_end, sol.q_end, sol.qd_end, p)
        return jnp.concatenate([q, qd])

    jac = jax.jit(jax.jacfwd(return_map))
    x = orbit.state
    period = orbit.period
    for fn in (lambda: to_strike(orbit.q, orbit.qd, params),
               lambda: to_period(orbit.q, orbit.qd, params, period),
               lambda: jac(x, params)):  # fmt: skip
        jax.block_until_ready(fn())  # compile
    t_orbit, t_strike, t_period, t_jac = timed(
        [
            lambda: solve(q0, qd0, params),
            lambda: to_strike(orbit.q, orbit.qd, params),
            lambda: to_period(orbit.q, orbit.qd, params, period),
            lambda: jac(x, params),
        ],
        args.repeats,
    )
    evaluations = int(orbit.iterations) + 1
    print(
        f"compass gait at {args.slope:g}°: step period {float(orbit.period):.6f} s, "
        f"|μ| = {np.round(np.abs(np.asarray(orbit.multipliers)), 4).tolist()}, "
        f"{int(orbit.iterations)} Newton steps from the guess; rtol = atol = {TOL:g}; "
        f"medians of {args.repeats}"
    )
    print(f"{'':44s} {'time':>9s} {'ratio':>7s}")
    rows = [
        ("simulate, one step to the heel strike", t_strike),
        ("simulate, t1 = period (no event)", t_period),
        ("jacfwd of the return map (one evaluation)", t_jac),
        ("periodic_orbit (compiled)", t_orbit),
    ]
    for name, value in rows:
        print(f"{name:44s} {value * 1e3:7.3f}ms {value / t_strike:6.1f}×")
    print(
        f"  = {evaluations} evaluations × jacfwd ({evaluations * t_jac * 1e3:.3f} ms) + "
        f"the rest ({(t_orbit - evaluations * t_jac) * 1e3:.3f} ms: projections, solves, "
        f"eigenvalues); compile {compile_orbit:.1f} s"
    )

    # ---------------------------------------------------------- 2. a stability map
    options = dict(rtol=TOL, atol=TOL, t_max=2.0, max_steps=1000, max_iter=12)

    def axes(side):
        slopes = np.deg2rad(np.linspace(*args.slopes, side))
        return slopes, np.linspace(*args.ratios, side) * GOSWAMI["m"]

    def report(name, side, t_map, first, ok, stable, iterations):
        print(
            f"  {name}, {side} × {side} = {side * side} orbits: wall time {t_map:.2f} s "
            f"({t_map / (side * side) * 1e3:.2f} ms per orbit; first call with compilation "
            f"{first:.1f} s); found {ok.mean():.1%}, stable {stable.mean():.1%} of all "
            f"({stable.sum() / max(ok.sum(), 1):.1%} of those found); Newton steps: median "
            f"{int(np.median(iterations))}, max {int(np.max(iterations))}"
        )

    print(
        f"\nstability maps, slope {args.slopes[0]:g}–{args.slopes[1]:g}° × M/m "
        f"{args.ratios[0]:g}–{args.ratios[1]:g}, every member from the {args.slope:g}° gait:"
    )
    slopes, masses = axes(args.grid)
    walkers = lx.grid(params, slope=slopes, M=masses)

    def run_map():
        return lx.orbit_map(WALKER, orbit.q, orbit.qd, walkers, section=HEEL_STRIKE, **options)

    t = time.perf_counter()
    ds = run_map()
    first = time.perf_counter() - t
    (t_map,) = timed([run_map], max(1, args.repeats // 3))
    report(
        "lagrax.orbit_map", args.grid, t_map, first, ds.ok.values, ds.stable.values,
        ds.iterations.values,
    )  # fmt: skip

    side = args.vmap_grid
    slopes, masses = axes(side)
    s, m = (jnp.asarray(a.reshape(-1)) for a in np.meshgrid(slopes, masses, indexing="ij"))

    def member(slope, mass):
        p = {**params, "M": mass, "slope": slope}
        return lx.periodic_orbit(WALKER, orbit.q, orbit.qd, p, section=HEEL_STRIKE, **options)

    batch = jax.jit(jax.vmap(member))
    t = time.perf_counter()
    out = jax.block_until_ready(batch(s, m))
    first = time.perf_counter() - t
    (t_vmap,) = timed([lambda: batch(s, m)], max(1, args.repeats // 3))
    report(
        "jax.vmap(periodic_orbit)", side, t_vmap, first, np.asarray(out.ok),
        np.asarray(out.stable), np.asarray(out.iterations),
    )  # fmt: skip


if __name__ == "__main__":
    main()
