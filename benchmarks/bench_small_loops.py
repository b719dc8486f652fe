"""XLA:CPU's small-loop limit: batched derivatives against batched solves.

`import lagrax` sets `xla_cpu_small_while_loop_byte_threshold` to 1 MiB: XLA:CPU then
compiles a `while` loop into one kernel when one iteration reads and writes less than
that (`lagrax._core.xla_flags`). This benchmark measures the same programs with that
limit and with `--bytes` (16 MiB by default), each configuration in fresh processes
(`--processes` of each, taken in turn; the medians are reported), because the limit is
read once when JAX starts:

1. `forward_dynamics_derivatives` per state under `jax.vmap` over 4,096 random states,
   against the system's own forward dynamics (the URDF arm, the spatial 7-link chain, the
   two-arm URDF tree, `PlanarChain(20)`, and solo12 where example-robot-data is
   installed): a chain's derivatives call runs in blocks of 64 states, a loop whose
   iteration touches a few MiB;
2. `jax.vmap(jax.grad)` through `simulate` (the URDF arm, 256 initial states, ms a member);
3. `jax.vmap(simulate)` over 4,096 initial states of the 2R arm (ms a member), on all cores
   and on one core: one kernel runs on one core, where the separate kernels of a large
   batch are split across cores.

    python benchmarks/bench_small_loops.py [--processes 3] [--bytes 16777216]

About 6 minutes on 2 cores.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

KEY = "xla_cpu_small_while_loop_byte_threshold"
DEFAULT = 1 << 20
SYSTEMS = ("URDF arm7", 'SpatialChain("R"*7)', "URDF torso_two_arms", "PlanarChain(20)")


def child(one_core: bool) -> dict:
    """The measurements of one process (JAX starts here, after the parent set XLA_FLAGS)."""
    if one_core:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
    os.environ.setdefault("LAGRAX_COMPILATION_CACHE", "0")
    sys.path.insert(0, str(Path(__file__).parent))
    import jax
    import jax.numpy as jnp
    import numpy as np

    import lagrax as lx
    from _robots import SOLO12, floating_inputs, robots_folder
    from bench_derivatives import (
        _losses,
        fastest,
        fastest_interleaved,
        forward_and_derivatives,
        random_states,
        systems,
    )

    out: dict = {}
    table = systems()
    if not one_core:
        cases = [(name, *table[name]) for name in SYSTEMS]
        folder = robots_folder()
        if folder is not None:
            xml = (Path(folder) / SOLO12).read_text()
            robot, params = lx.chains.from_urdf(xml, floating_base=True)
            cases.append(("solo12", robot.system(), params))
        for name, system, params in cases:
            if name == "solo12":
                args = floating_inputs(system.n_dof - 6, 4096)
            else:
                args = random_states(system.n_dof, 4096)
            t = fastest_interleaved(forward_and_derivatives(system, params), args, 20)
            out[name] = (t["fd"] / 4096 * 1e6, t["derivatives"] / 4096 * 1e6)
        system, params = table["URDF arm7"]
        _, loss = _losses(system, params)
        starts = jnp.asarray(np.random.default_rng(0).uniform(-1, 1, (256, 7)))
        out["vmap(grad) URDF arm"] = fastest(jax.jit(jax.vmap(jax.grad(loss))), (starts,), 2) / 256
    system, params = table["2R arm (user energies)"]
    solve, _ = _losses(system, params)
    starts = jnp.asarray(np.random.default_rng(0).uniform(-1, 1, (4096, 2)))
    batched = jax.jit(jax.vmap(lambda a: solve(a, jnp.zeros(2))))
    out["vmap(simulate) 2R arm"] = fastest(batched, (starts,), 5) / 4096
    return {k: v if isinstance(v, tuple) else v * 1e3 for k, v in out.items()}


def run(limit: int, one_core: bool) -> dict:
    env = dict(os.environ, XLA_FLAGS=f"--xla_backend_extra_options={KEY}={limit}")
    cmd = [sys.executable, __file__, "--child", *(["--one-core"] if one_core else [])]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise RuntimeError(f"the measuring process failed:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--processes", type=int, default=3, help="fresh processes per limit")
    ap.add_argument("--bytes", type=int, default=1 << 24, help="the limit to compare")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--one-core", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.one_core)))
        return
    limits = (DEFAULT, args.bytes)
    pinning = hasattr(os, "sched_setaffinity")  # Linux: the one-core row
    if not pinning:
        print("note: the one-core row skipped: this OS cannot pin a process to a core")
    cores = (False, True) if pinning else (False,)
    runs: dict = {(limit, core): [] for limit in limits for core in cores}
    for k in range(args.processes):
        for limit in limits:
            for one_core in cores:
                runs[limit, one_core].append(run(limit, one_core))
        print(f"processes: {k + 1} of {args.processes} per configuration", flush=True)

    def med(limit, one_core, key, part=None):
        values = [r[key] if part is None else r[key][part] for r in runs[limit, one_core]]
        return statistics.median(values)

    def ratio(limit, key):
        return statistics.median(r[key][1] / r[key][0] for r in runs[limit, False])

    print(
        f"\n## The small-loop limit: {DEFAULT >> 20} MiB (lagrax's) against "
        f"{args.bytes / (1 << 20):g} MiB (median of {args.processes} processes each)\n"
    )
    print(f"| | {DEFAULT >> 20} MiB | {args.bytes / (1 << 20):g} MiB |")
    print("|---|---|---|")
    first = runs[DEFAULT, False][0]
    for key in [k for k in first if isinstance(first[k], list)]:
        cells = [f"{med(lim, False, key, 1):.3f} µs ({ratio(lim, key):.2f}× fd)" for lim in limits]
        print(f"| {key}: forward_dynamics_derivatives, 4,096 states | " + " | ".join(cells) + " |")
    key = "vmap(grad) URDF arm"
    print(
        f"| {key}, 256 members (ms a member) | "
        + " | ".join(f"{med(lim, False, key):.3f}" for lim in limits)
        + " |"
    )
    key = "vmap(simulate) 2R arm"
    n_cores = len(os.sched_getaffinity(0)) if pinning else os.cpu_count()
    for one_core, where in zip(cores, (f"{n_cores} cores", "1 core"), strict=False):
        print(
            f"| {key}, 4,096 members, {where} (ms a member) | "
            + " | ".join(f"{med(lim, one_core, key):.4f}" for lim in limits)
            + " |"
        )


if __name__ == "__main__":
    main()
