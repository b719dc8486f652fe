"""Memory per model: what a process keeps of the robots it touched.

A user exploring robots in one session loads a URDF, evaluates `M(q)`, the inverse
dynamics and the forward dynamics once (eagerly), and moves on to the next. This
benchmark does that for the first `--robots` URDFs of example-robot-data that load on a
fixed base (24 by default), each run in a fresh process, and reports the resident memory
(RSS):

- after each robot, and the process's peak;
- with `jax.clear_caches()` after each robot (`--clear`), the floor the caches allow;
- after the loop, when every model is deleted and `gc.collect()` has run: what the
  models' compiled programs still hold once the user has let go of them.

    python benchmarks/bench_memory.py [--robots 24]

Each process compiles every robot's three programs: 5-15 minutes on 2 cores (30 on a
loaded machine); it measures memory, not time. Measured (24 robots, peak RSS): 3.4 GB
before models' programs were freed with them, 0.66 GB then with `--clear`'s
`jax.clear_caches()`; now 0.63 GB without clearing, 0.66 GB with.
"""

import argparse
import gc
import json
import os
import resource
import subprocess
import sys
import warnings
from pathlib import Path


def _rss_mb() -> float:
    """This process's resident memory now, MB (Linux `/proc`, without psutil)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e3  # kB on Linux


def _urdfs(n: int) -> list[Path]:
    """The first `n` URDFs (sorted by path) of example-robot-data that load fixed."""
    sys.path.insert(0, str(Path(__file__).parent))
    import lagrax as lx
    from _robots import robots_folder

    folder = robots_folder()
    if folder is None:
        sys.exit('example-robot-data is not installed (pip install -e ".[bench]")')
    found = []
    for path in sorted(Path(folder).rglob("*.urdf")):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", lx.URDFWarning)
                lx.chains.from_urdf(path)
        except lx.LagraxError:
            continue  # not a fixed-base robot (a single body, an empty file)
        found.append(path)
        if len(found) == n:
            break
    return found


def _touch(path: Path) -> None:
    """Load one robot and evaluate `M`, the inverse and the forward dynamics eagerly."""
    import jax.numpy as jnp

    import lagrax as lx

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lx.URDFWarning)
        tree, params = lx.chains.from_urdf(path)
    system = tree.system()
    q = jnp.linspace(-0.5, 0.5, system.n_dof)
    qd = jnp.linspace(0.3, -0.3, system.n_dof)
    system.mass_matrix(q, params).block_until_ready()
    system.inverse_dynamics(q, qd, qd, params).block_until_ready()
    system.forward_dynamics(q, qd, params, qd).block_until_ready()


def child(n: int, clear: bool) -> dict:
    import jax

    paths = _urdfs(n)
    gc.collect()
    start = _rss_mb()
    after = []
    for path in paths:
        _touch(path)  # the model is dropped on return: only caches keep it
        if clear:
            jax.clear_caches()
        gc.collect()
        after.append(_rss_mb())
    peak = _peak_mb()
    gc.collect()
    return {
        "robots": len(paths),
        "start_mb": start,
        "after_each_mb": after,
        "peak_mb": peak,
        "end_mb": _rss_mb(),
        "names": [p.stem for p in paths],
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--robots", type=int, default=24, help="how many URDFs")
    parser.add_argument("--child", choices=["keep", "clear"], help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(child(args.robots, args.child == "clear")))
        return
    env = {**os.environ, "LAGRAX_COMPILATION_CACHE": "0"}  # memory, not the disk cache
    for mode in ("keep", "clear"):
        out = subprocess.run(
            [sys.executable, __file__, "--robots", str(args.robots), "--child", mode],
            env=env,
            capture_output=True,
            text=True,
            check=True,
        )
        r = json.loads(out.stdout.strip().splitlines()[-1])
        grow = (r["after_each_mb"][-1] - r["start_mb"]) / r["robots"]
        label = "jax.clear_caches() after each" if mode == "clear" else "no clearing"
        print(
            f"{label:32s} {r['robots']} robots: start {r['start_mb']:.0f} MB, "
            f"peak {r['peak_mb']:.0f} MB, after the last {r['after_each_mb'][-1]:.0f} MB "
            f"({grow:.1f} MB a robot)",
            flush=True,
        )
        steps = ", ".join(f"{m:.0f}" for m in r["after_each_mb"])
        print(f"  RSS after each robot (MB): {steps}", flush=True)


if __name__ == "__main__":
    main()
