"""The price of autodiff: lagrax forward dynamics vs a hand-written closed form.

The 2R arm's ``forward_dynamics``, ``vmap``-ped over 4,096 random states under ``jit``,
against the lecture's closed-form right-hand side written by hand in JAX (explicit 2×2
solve). Both are compiled first, then timed interleaved (to share machine noise); the
report is the median time per call and its ratio to the closed form, measured in this run.

    python benchmarks/bench_autodiff_price.py [--batch 4096] [--repeats 301]
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp

sys.path.insert(0, str(Path(__file__).parent))
import lagrax as lx  # noqa: E402
from _closed_form import forward_dynamics_2r  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--batch", type=int, default=4096, help="states per vmapped call")
    ap.add_argument("--repeats", type=int, default=301, help="timed calls (median)")
    args = ap.parse_args(argv)

    system, params = lx.models.planar_2r()
    k1, k2, k3 = jax.random.split(jax.random.PRNGKey(0), 3)
    q = jax.random.uniform(k1, (args.batch, 2), minval=-jnp.pi, maxval=jnp.pi)
    qd = jax.random.uniform(k2, (args.batch, 2), minval=-3.0, maxval=3.0)
    tau = jax.random.uniform(k3, (args.batch, 2), minval=-5.0, maxval=5.0)

    T = system.kinetic
    V = system.potential

    def naive(q, qd, tau):
        """The textbook autodiff right-hand side: Hessians and a LAPACK solve."""
        m = jax.hessian(T, argnums=1)(q, qd, params)
        mixed = jax.jacfwd(jax.grad(T, argnums=1), argnums=0)(q, qd, params)
        rhs = tau + jax.grad(T, argnums=0)(q, qd, params) - mixed @ qd
        rhs = rhs - jax.grad(V)(q, params)
        return jnp.linalg.solve(m, rhs)

    variants = {
        "closed form (hand-written JAX)": lambda a, b, u: forward_dynamics_2r(a, b, params, u),
        "lagrax forward_dynamics (checked)": lambda a, b, u: system.forward_dynamics(
            a, b, params, u
        ),
        "lagrax, unchecked (as inside simulate)": lambda a, b, u: system.accelerations(
            0.0, a, b, params, u
        ),
        "naive autodiff (hessian + linalg.solve)": naive,
    }
    fns = {k: jax.jit(jax.vmap(f)) for k, f in variants.items()}
    compile_s, outs = {}, {}
    for name, f in fns.items():
        t0 = time.perf_counter()
        outs[name] = f(q, qd, tau).block_until_ready()
        compile_s[name] = time.perf_counter() - t0
    ref = outs["closed form (hand-written JAX)"]
    for name, out in outs.items():
        err = float(jnp.max(jnp.abs(out - ref)) / jnp.max(jnp.abs(ref)))
        print(f"{name:42s} max rel. difference from closed form {err:.1e}")
    times = {k: [] for k in fns}
    for _ in range(args.repeats):
        for name, f in fns.items():
            t0 = time.perf_counter()
            f(q, qd, tau).block_until_ready()
            times[name].append(time.perf_counter() - t0)
    base = statistics.median(times["closed form (hand-written JAX)"])
    print(
        f"\nforward dynamics of the 2R arm, vmap over {args.batch} states, "
        f"median of {args.repeats} interleaved calls ({jax.devices()[0].platform}):"
    )
    for name, ts in times.items():
        med = statistics.median(ts)
        print(
            f"  {name:42s} {med * 1e6:9.1f} µs  {med / args.batch * 1e9:6.1f} ns/state  "
            f"ratio {med / base:5.2f}  (compile+first call {compile_s[name]:.2f} s)"
        )


if __name__ == "__main__":
    main()
