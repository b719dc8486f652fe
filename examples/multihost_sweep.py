"""The same sweep on several hosts: every process runs this script.

On a cluster, start one process per host (e.g. with ``srun``/``mpirun``, or by hand) and
call ``jax.distributed.initialize`` first; ``lagrax.sweep`` then shards the members over
the devices of all processes (``jax.devices()``) and every process gets the whole result.

To try it on one machine, with two CPU processes talking over localhost:

    python examples/multihost_sweep.py --num-processes 2 --process-id 0 &
    python examples/multihost_sweep.py --num-processes 2 --process-id 1

(On a Slurm or Cloud TPU cluster ``jax.distributed.initialize()`` needs no arguments.)
"""

import argparse

import jax
import numpy as np


def main():
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--coordinator", default="localhost:12355", help="host:port of process 0")
    ap.add_argument("--num-processes", type=int, default=1, help="processes in all")
    ap.add_argument("--process-id", type=int, default=0, help="this process's index")
    ap.add_argument("--out", default="multihost_sweep.npz", help="result file")
    args = ap.parse_args()

    # CPU processes exchange data through gloo (no effect on GPU/TPU devices)
    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(args.coordinator, args.num_processes, args.process_id)

    import lagrax as lx

    system, params = lx.models.planar_2r()
    batch = lx.grid(params, m2=np.linspace(0.5, 2.0, 16), l1=np.linspace(0.5, 1.5, 16))
    ds = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, t1=5.0, progress=False)
    print(
        f"process {jax.process_index()}/{jax.process_count()}: {len(jax.devices())} devices, "
        f"{ds.attrs['n_members']} members, {ds.attrs['n_failed']} failed, "
        f"mean final θ2 = {float(ds.q.sel(dof=1).mean()):.6f}"
    )
    if jax.process_index() == 0:
        lx.save_sweep(ds, args.out)
    jax.distributed.shutdown()


if __name__ == "__main__":
    main()
