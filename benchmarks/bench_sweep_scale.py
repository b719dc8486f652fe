"""Sweeps beyond one process: the CPU's cores, a zarr store, a Dask cluster.

Three sections, each measured in one run on this machine (pick with ``--sections``):

1. ``arm7``: the 7-DOF arm of ``bench_scale`` (``SpatialChain``, axes z, y, z, y, z, y, z),
   every link's mass and inertia scaled by U(0.8, 1.2), 2,048 members from q = 0.3 at
   rest for 2 s, final state: ``lagrax.sweep`` (Dopri8 and Tsit5 over a tolerance ladder,
   chunks on every core) against ``mujoco.rollout`` (one MjModel per member, one MjData
   per thread, RK4 over a step ladder) on the same cores. Errors are the largest
   final-state error over the members against ``sweep`` at rtol = atol = 1e-12; the
   ratio at matched error takes the fastest lagrax run whose error is no larger than
   MuJoCo's. Also one member's ``simulate`` (one core) against the sweep's wall time
   and core time per member.
2. ``store``: peak resident memory (each run in a fresh process) of a trajectory sweep of
   the 2R arm (501 saves) written into a zarr store, at a size whose result is at least
   4× a memory cap, against the cap; and throughput into the store against the in-memory
   sweep at a size that fits.
3. ``dask``: a ``LocalCluster`` of 2 single-threaded worker processes against one process
   over both cores (``sweep`` runs a chunk per core), 65,536 members, final state, for the
   2R arm and the 7-DOF arm; the results compared bitwise. Twice: with each worker pinned
   to its own core (what a batch system's one-core jobs get), and not pinned (each
   worker's XLA then sizes its thread pool to every core, and the two compete).

    python benchmarks/bench_sweep_scale.py [--sections arm7 store dask] [--repeats 3]
        [--cap-mib 1024] [--quick]

MuJoCo (``pip install -e ".[bench]"``), zarr and Dask (``pip install -e ".[cluster]"``)
are optional: a missing one skips its section with a note.
"""

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time

import numpy as np

import lagrax as lx

sys.path.insert(0, os.path.dirname(__file__))
from _optional import available  # noqa: E402
from bench_scale import ARM_AXES, arm_mjcf, chain_of  # noqa: E402

Q0_2R = (-math.pi / 2 + 1.4, 0.8)
T_ARM = 2.0


def median_time(fn, repeats):
    """`(first call's seconds, the median of `repeats` more, the last output)`."""
    t = time.perf_counter()
    out = fn()
    first = time.perf_counter() - t
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return first, statistics.median(times), out


def arm_members(n, seed=0):
    """The 7-DOF arm, its parameters, and `samples` of `n` members whose every link's
    mass and inertia are scaled by U(0.8, 1.2); also the scales."""
    chain, params = chain_of("spatial", 7)
    scale = np.random.default_rng(seed).uniform(0.8, 1.2, (n, 7))
    m = np.asarray(params["m"])[None] * scale
    inertia = np.asarray(params["inertia"])[None] * scale[:, :, None, None]
    return chain.system(), params, lx.samples(params, m=m, inertia=inertia), scale


def final_state(ds):
    return np.concatenate([ds.q.values, ds.qd.values], axis=-1)


# --------------------------------------------------------------------------- 1. arm7


def arm7(repeats, n):
    print(f"\n1. the 7-DOF arm, {n} members (masses, inertias x U(0.8, 1.2)), 2 s, final state")
    system, params, batch, scale = arm_members(n)
    q0, qd0 = np.full(7, 0.3), np.zeros(7)

    def run(solver, tol):
        return lambda: lx.sweep(
            system, q0, qd0, batch, t1=T_ARM, solver=solver, rtol=tol, atol=tol, progress=False
        )

    ref = final_state(run("dopri8", 1e-12)())
    runs = []
    for solver, tols in (
        ("dopri8", (1e-6, 1e-7, 1e-8, 1e-9, 1e-10)),
        ("tsit5", (1e-6, 1e-7, 1e-8)),
    ):
        for tol in tols:
            first, t, ds = median_time(run(solver, tol), repeats)
            err = float(np.max(np.abs(final_state(ds) - ref)))
            runs.append((err, t, f"{solver} {tol:.0e}"))
            print(
                f"   lagrax sweep {solver:6s} rtol {tol:.0e}: {t:7.3f} s  error {err:.1e}  "
                f"({t / n * 1e3:.3f} ms a member; first call {first:.1f} s; chunks of "
                f"{ds.attrs['chunk_size']} on {ds.attrs['threads']} threads, "
                f"{ds.attrs['n_lanes']} lanes)"
            )
    threads = int(ds.attrs["threads"])
    # one member's simulate, one core, at the tolerance of the fastest run within 1e-7
    p0 = {**params, "m": np.asarray(params["m"]) * scale[0]}
    p0["inertia"] = np.asarray(params["inertia"]) * scale[0][:, None, None]
    for tol in (1e-7, 1e-8):
        _, t_sim, _ = median_time(
            lambda tol=tol: lx.simulate(
                system, q0, qd0, p0, t1=T_ARM, solver="dopri8", rtol=tol, atol=tol, n_save=2
            ),
            max(5, repeats),
        )
        t_sweep = next(t for e, t, label in runs if label == f"dopri8 {tol:.0e}")
        per = t_sweep / n
        print(
            f"   one simulate (dopri8 {tol:.0e}, one core): {t_sim * 1e3:.3f} ms; the sweep: "
            f"{per * 1e3:.3f} ms of wall time a member ({per / t_sim:.2f}x), "
            f"{per * threads * 1e3:.3f} ms of core time ({per * threads / t_sim:.2f}x)"
        )
    if not available("mujoco", "mujoco.rollout (section 1)"):
        return
    import mujoco
    from mujoco import rollout

    base = mujoco.MjModel.from_xml_string(arm_mjcf())
    models = []
    for s in scale:
        model = mujoco.MjModel.from_xml_string(arm_mjcf())
        model.body_mass[1:] = base.body_mass[1:] * s
        model.body_inertia[1:] = base.body_inertia[1:] * s[:, None]
        models.append(model)
    datas = [mujoco.MjData(base) for _ in range(threads)]
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state0 = np.zeros((n, mujoco.mj_stateSize(base, spec)))
    for i, model in enumerate(models):
        d = mujoco.MjData(model)
        d.qpos[:] = q0
        mujoco.mj_forward(model, d)
        mujoco.mj_getState(model, d, state0[i], spec)
    assert len(ARM_AXES) == 7
    for dt in (4e-3, 2e-3, 1e-3):
        for model in models:
            model.opt.timestep = dt
        nstep = round(T_ARM / dt)
        _, t, (state, _) = median_time(
            lambda nstep=nstep: rollout.rollout(models, datas, state0, nstep=nstep), repeats
        )
        err = float(np.max(np.abs(state[:, -1, 1:15] - ref)))
        match = [(tl, label) for el, tl, label in runs if el <= err]
        ratio = ""
        if match:
            tl, label = min(match)
            ratio = f"  lagrax/MuJoCo at matched error: {tl / t:.2f}x ({label})"
        print(
            f"   mujoco.rollout RK4 dt {dt:.0e} ({threads} threads): {t:7.3f} s  error "
            f"{err:.1e}{ratio}"
        )


# --------------------------------------------------------------------------- 2. store

# members per chunk in section 2: 2,500 trajectories of 501 saves, 48 MiB
STORE_CHUNK = 2500

STORE_CHILD = """
import json, resource, shutil, sys, time, numpy as np, lagrax as lx
n, where = int(sys.argv[1]), sys.argv[2]
system, params = lx.models.planar_2r()
rng = np.random.default_rng(0)
batch = lx.samples(params, m2=rng.uniform(0.5, 2, n), l1=rng.uniform(0.5, 1.5, n))
kw = dict(t1=1.0, keep="trajectory", n_save=501, progress=False, chunk_size=CHUNK)
# compiled first, on one chunk of the same size (the timed run then reuses it)
warm = lx.samples(params, m2=np.full(CHUNK, 1.0), l1=np.full(CHUNK, 1.0))
lx.sweep(system, Q0, [0.0, 0.0], warm, **kw)
store = None if where == "memory" else where
if store is not None:
    shutil.rmtree(store, ignore_errors=True)
t = time.perf_counter()
ds = lx.sweep(system, Q0, [0.0, 0.0], batch, store=store, **kw)
seconds = time.perf_counter() - t
size = sum(v.nbytes for v in ds.data_vars.values())
worst = float(ds.energy_error.max()) if store is None else float(ds.energy_error.max().compute())
failed = int(ds.attrs["n_failed"])
rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(dict(seconds=seconds, result_mib=size / 2**20, rss_mib=rss, failed=failed,
                      worst=worst, chunk=ds.attrs["chunk_size"])))
if store is not None:
    shutil.rmtree(store, ignore_errors=True)
"""


def _child(code, *args):
    r = subprocess.run(
        [
            sys.executable,
            "-c",
            code.replace("Q0", repr(list(Q0_2R))).replace("CHUNK", str(STORE_CHUNK)),
            *map(str, args),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    if r.returncode != 0:
        raise RuntimeError(r.stderr[-3000:])
    return json.loads(r.stdout.strip().splitlines()[-1])


def store(cap_mib, quick, folder):
    print(
        "\n2. a zarr store: 2R arm trajectories (501 saves, 1 s), peak RSS against a "
        f"{cap_mib} MiB cap"
    )
    if not (available("zarr", "the zarr store (section 2)") and available("dask", "section 2")):
        return
    path = os.path.join(folder, "bench_sweep_scale.zarr")
    fits = 5_000 if quick else 20_000
    mem = _child(STORE_CHILD, fits, "memory")
    disk = _child(STORE_CHILD, fits, path)
    print(
        f"   {fits} members in memory: {mem['seconds']:.2f} s ({fits / mem['seconds']:,.0f} "
        f"members/s), result {mem['result_mib']:.0f} MiB, peak RSS {mem['rss_mib']:.0f} MiB"
    )
    print(
        f"   {fits} members into the store: {disk['seconds']:.2f} s ({fits / disk['seconds']:,.0f} "
        f"members/s, {mem['seconds'] / disk['seconds']:.2f}x the in-memory throughput), "
        f"peak RSS {disk['rss_mib']:.0f} MiB"
    )
    member_mib = mem["result_mib"] / fits
    big = int(math.ceil(4 * cap_mib / member_mib / 1000) * 1000)
    if quick:
        big = fits * 4
    out = _child(STORE_CHILD, big, path)
    verdict = "within" if out["rss_mib"] <= cap_mib else "OVER"
    print(
        f"   {big} members into the store: result {out['result_mib']:,.0f} MiB "
        f"({out['result_mib'] / cap_mib:.1f}x the cap), peak RSS {out['rss_mib']:.0f} MiB "
        f"({verdict} the cap), {out['seconds']:.1f} s ({big / out['seconds']:,.0f} members/s, "
        f"{(big / out['seconds']) / (fits / mem['seconds']):.2f}x the in-memory throughput), "
        f"chunks of {out['chunk']}, {out['failed']} failed"
    )


# --------------------------------------------------------------------------- 3. dask


def _models(n):
    two_r, p2 = lx.models.planar_2r()
    rng = np.random.default_rng(1)
    b2 = lx.samples(p2, m2=rng.uniform(0.5, 2, n), l1=rng.uniform(0.5, 1.5, n))
    arm, _, b7, _ = arm_members(n, seed=1)
    return (
        ("2R arm, 5 s", two_r, Q0_2R, (0.0, 0.0), b2, 5.0),
        ("7-DOF arm, 2 s", arm, np.full(7, 0.3), np.zeros(7), b7, T_ARM),
    )


def dask_cluster(n, repeats, pinned):
    where = "each pinned to a core" if pinned else "not pinned"
    print(
        f"\n3. Dask: a LocalCluster of 2 single-threaded workers ({where}) against one "
        f"process, {n} members"
    )
    if not available("distributed", "the Dask cluster (section 3)"):
        return
    from distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    )
    with Client(cluster) as client:
        if pinned:  # each worker on its own core, as a batch job's cgroup would give it
            cores = sorted(os.sched_getaffinity(0))
            for i, worker in enumerate(sorted(client.scheduler_info()["workers"])):
                core = cores[i % len(cores)]
                client.run(lambda core=core: os.sched_setaffinity(0, {core}), workers=[worker])
        for label, system, q0, qd0, batch, t1 in _models(n):

            def run(c=None, system=system, q0=q0, qd0=qd0, batch=batch, t1=t1):
                return lambda: lx.sweep(
                    system, q0, qd0, batch, t1=t1, solver="dopri8", client=c, progress=False
                )

            first_l, t_local, local = median_time(run(), repeats)
            first_d, t_dask, on_cluster = median_time(run(client), repeats)
            same = all(
                np.array_equal(local[k].values, on_cluster[k].values)
                for k in ("q", "qd", "num_steps", "result")
            )
            print(
                f"   {label}: one process {t_local:.2f} s ({n / t_local:,.0f} members/s, "
                f"{local.attrs['threads']} threads), Dask {t_dask:.2f} s "
                f"({n / t_dask:,.0f} members/s): Dask throughput {t_local / t_dask:.2f}x; "
                f"first calls {first_l:.1f} s and {first_d:.1f} s; results bitwise equal: {same}"
            )
    cluster.close()


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument(
        "--sections",
        nargs="+",
        default=["arm7", "store", "dask"],
        choices=["arm7", "store", "dask"],
    )
    ap.add_argument("--repeats", type=int, default=3, help="timed runs (median)")
    ap.add_argument("--cap-mib", type=int, default=1024, help="memory cap for section 2")
    ap.add_argument("--members", type=int, default=65_536, help="members in section 3")
    ap.add_argument("--folder", default=".", help="where section 2 writes its store")
    ap.add_argument("--quick", action="store_true", help="small sizes (a smoke run)")
    args = ap.parse_args(argv)
    print(f"lagrax {lx.__version__}, {os.cpu_count()} CPUs")
    if "arm7" in args.sections:
        arm7(args.repeats, 256 if args.quick else 2048)
    if "store" in args.sections:
        store(args.cap_mib, args.quick, args.folder)
    if "dask" in args.sections:
        for pinned in (True, False):
            dask_cluster(4096 if args.quick else args.members, args.repeats, pinned)


if __name__ == "__main__":
    main()
