"""No more than the scene needs: a planar arm from planar bodies vs the same arm in 3-D.

Three descriptions of one planar n-link arm (default n = 2, the lecture's 2R arm), with
identical equations (checked here before timing):

- ``planar bodies``: ``PlanarChain(n).system()``, one batched ``PlanarBody``: two position
  components and one angle per link (the baseline);
- ``spatial bodies``: ``PlanarChain(n).system(bodies="spatial")``, the same links as
  ``SpatialBody``: three position components and a 3×3 rotation matrix per link, angular
  velocity from ``Rᵀ Ṙ``;
- ``spatial, fwd-fwd``: the same, with ``scalar_derivatives=True`` (the scalar
  forward-over-forward derivatives that planar scenes of n <= 6 use; scenes with spatial
  bodies default to forward-over-reverse, which compiles faster);
- ``spatial chain``: ``PlanarChain(n).to_spatial(params)``, a ``SpatialChain`` with all
  axes along z: forward kinematics as a product of rotation matrices.

For each: the compile time (trace + lower + XLA compile) and the median run time of
``forward_dynamics`` vmapped over a batch of random states under ``jit``, and of a short
``simulate`` (first call, which compiles, then the median of repeated calls). Runs are
interleaved so machine noise is shared; ratios are against the planar bodies measured in
the same process.

    python benchmarks/bench_planar_vs_spatial.py [--n 2] [--batch 4096] [--repeats 51]
"""

import argparse
import dataclasses
import statistics
import time

import jax
import jax.numpy as jnp
import numpy as np

import lagrax as lx


def variants(n):
    chain = lx.chains.PlanarChain(n)
    params = chain.params(m=np.linspace(1.0, 0.6, n), l=np.linspace(1.0, 0.7, n))
    spatial_chain, spatial_params = chain.to_spatial(params)
    spatial_scene = chain.scene(bodies="spatial")
    return {
        "planar bodies": (chain.system(), params),
        "spatial bodies": (spatial_scene.system(), params),
        "spatial, fwd-fwd": (
            dataclasses.replace(spatial_scene, scalar_derivatives=True).system(),
            params,
        ),
        "spatial chain": (spatial_chain.system(), spatial_params),
    }


def timed(fn, *args):
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn(*args))
    return out, time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--n", type=int, default=2, help="number of links")
    ap.add_argument("--batch", type=int, default=4096, help="states per vmapped call")
    ap.add_argument("--repeats", type=int, default=51, help="timed calls (median)")
    ap.add_argument("--sim-repeats", type=int, default=11, help="timed simulate calls")
    ap.add_argument("--t1", type=float, default=2.0, help="simulated time span")
    args = ap.parse_args(argv)

    systems = variants(args.n)
    k1, k2, k3 = jax.random.split(jax.random.PRNGKey(0), 3)
    q = jax.random.uniform(k1, (args.batch, args.n), minval=-jnp.pi, maxval=jnp.pi)
    qd = jax.random.uniform(k2, (args.batch, args.n), minval=-3.0, maxval=3.0)
    tau = jax.random.uniform(k3, (args.batch, args.n), minval=-5.0, maxval=5.0)

    # ---- forward dynamics, vmapped: compile, check, then time interleaved
    compiled, compile_s, outs = {}, {}, {}
    for name, (system, params) in systems.items():
        fn = jax.jit(jax.vmap(lambda a, b, u, s=system, p=params: s.forward_dynamics(a, b, p, u)))
        t0 = time.perf_counter()
        compiled[name] = fn.lower(q, qd, tau).compile()
        compile_s[name] = time.perf_counter() - t0
        outs[name] = compiled[name](q, qd, tau).block_until_ready()
    ref = outs["planar bodies"]
    for name, out in outs.items():
        err = float(jnp.max(jnp.abs(out - ref)) / jnp.max(jnp.abs(ref)))
        assert err < 1e-10, f"{name} differs from the planar bodies by {err:.1e}"
    times = {k: [] for k in compiled}
    for _ in range(args.repeats):
        for name, fn in compiled.items():
            times[name].append(timed(fn, q, qd, tau)[1])

    # ---- a short simulate: first call (compiles), then repeated calls
    q0 = jnp.linspace(0.3, -0.2, args.n)
    qd0 = jnp.zeros(args.n)
    sim_first, sim_times, finals = {}, {k: [] for k in systems}, {}
    for name, (system, params) in systems.items():
        sol, sim_first[name] = timed(
            lambda s=system, p=params: lx.simulate(s, q0, qd0, p, t1=args.t1).q[-1]
        )
        finals[name] = sol
    for name, fin in finals.items():
        np.testing.assert_allclose(
            fin, finals["planar bodies"], rtol=1e-6, atol=1e-6, err_msg=f"simulate: {name}"
        )
    for _ in range(args.sim_repeats):
        for name, (system, params) in systems.items():
            sim_times[name].append(
                timed(lambda s=system, p=params: lx.simulate(s, q0, qd0, p, t1=args.t1).q)[1]
            )

    base = statistics.median(times["planar bodies"])
    base_c = compile_s["planar bodies"]
    print(
        f"planar {args.n}-link arm; forward_dynamics vmapped over {args.batch} states, median "
        f"of {args.repeats} interleaved calls ({jax.devices()[0].platform}):"
    )
    for name in systems:
        med = statistics.median(times[name])
        print(
            f"  {name:17s} run {med * 1e3:8.2f} ms ({med / args.batch * 1e9:6.0f} ns/state) "
            f"ratio {med / base:5.2f}   compile {compile_s[name]:6.2f} s ratio "
            f"{compile_s[name] / base_c:5.2f}"
        )
    base_s = statistics.median(sim_times["planar bodies"])
    base_f = sim_first["planar bodies"]
    print(
        f"\nsimulate over t1 = {args.t1} s (Tsit5, rtol = atol = 1e-8), median of "
        f"{args.sim_repeats} calls after the first:"
    )
    for name in systems:
        med = statistics.median(sim_times[name])
        print(
            f"  {name:17s} run {med * 1e3:8.2f} ms ratio {med / base_s:5.2f}   first call "
            f"(compile + run) {sim_first[name]:6.2f} s ratio {sim_first[name] / base_f:5.2f}"
        )


if __name__ == "__main__":
    main()
