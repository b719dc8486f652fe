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
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

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
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child()))
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
