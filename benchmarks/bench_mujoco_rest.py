"""Models as MuJoCo runs them: where each comes to rest, lagrax's `from_mujoco` against
MuJoCo's `mj_step`.

Each model is loaded with `lagrax.chains.from_mujoco` (everything on, the defaults) and
started from MuJoCo's initial state (`mj_resetData`) with `ctrl = 0`; lagrax simulates
`--t1` seconds (3 by default) with no options (the default method, `rodas4`: limits are
enforced), MuJoCo steps the same time at the model's own `timestep` and at 5e-4 s
(closer to its converged answer). Each model runs in a process of its own, with the
persistent compilation cache off, so the first call is a cold compile. Printed per
model: what `from_mujoco` names as not simulated, `sol.ok`, steps, the first call and a
warm one, the deepest penetration, the largest speed at the end (at rest?), and the
height coordinate (a free joint's `z`, or the joint named `rootz`) at the end in both
engines. `--chart FILE` draws the heights over time, lagrax against MuJoCo.

Models: gymnasium's `ant`, `humanoid`, `hopper`, `walker2d`, `half_cheetah`, and
dm_control's `cheetah`, `walker`, `quadruped` (`dm:` names dm_control's suite). A model
`from_mujoco` refuses is reported with its message.

    python benchmarks/bench_mujoco_rest.py [--models ant,dm:walker] [--t1 3] \\
        [--save rest.json] [--chart docs/bench/mujoco_rest.png] [--load rest.json]
"""

import argparse
import json
import os
import subprocess
import sys
import time
import warnings

from _optional import asset

MODELS = (
    "ant",
    "humanoid",
    "hopper",
    "walker2d",
    "half_cheetah",
    "dm:cheetah",
    "dm:walker",
    "dm:quadruped",
)


def _path(name: str) -> str:
    """The model file: `dm:` names dm_control's suite, others gymnasium's assets."""
    if name.startswith("dm:"):
        return asset("dm_control", "suite", name[3:] + ".xml")
    return asset("gymnasium", "envs", "mujoco", "assets", name + ".xml")


def _height_address(mujoco, model) -> int | None:
    """`qpos`'s height: a free joint's `z`, else the joint named `rootz`."""
    if model.njnt and model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE:
        return int(model.jnt_qposadr[0]) + 2
    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "rootz")
    return int(model.jnt_qposadr[j]) if j >= 0 else None


def _mujoco_heights(mujoco, path, t1, dt, every, hz):
    """MuJoCo from `mj_resetData` at step `dt`: the height every `every` s, the speed at
    the end."""
    import numpy as np

    model = mujoco.MjModel.from_xml_path(path)
    model.opt.timestep = dt
    data = mujoco.MjData(model)
    n, stride = round(t1 / dt), round(every / dt)
    heights = []
    for k in range(n + 1):
        if k % stride == 0 and hz is not None:
            heights.append(float(data.qpos[hz]))
        if k < n:
            mujoco.mj_step(model, data)
    return heights, float(np.abs(data.qvel).max())


def child(name: str, t1: float) -> dict:
    """One model, in this (fresh) process: the row's figures."""
    t0 = time.perf_counter()
    import jax
    import mujoco
    import numpy as np

    import lagrax as lx

    path = _path(name)
    model = mujoco.MjModel.from_xml_path(path)
    hz = _height_address(mujoco, model)
    every = 0.1
    out: dict = {"model": name, "t": [round(every * k, 10) for k in range(round(t1 / every) + 1)]}
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            scene, params = lx.chains.from_mujoco(path)
    except lx.LagraxError as err:
        out["refused"] = f"{type(err).__name__}: {err}"
        return out
    out["not simulated"] = list(scene.unsupported)
    out["warnings"] = len([w for w in caught if issubclass(w.category, UserWarning)])
    data = mujoco.MjData(model)
    q0, v0 = lx.chains.from_mujoco_state(data.qpos, data.qvel, scene)
    run = dict(t1=t1, n_save=len(out["t"]))
    sol = lx.simulate(scene, q0, v0, params, **run)
    jax.block_until_ready(sol.q)
    out["first"] = time.perf_counter() - t0
    t2 = time.perf_counter()
    jax.block_until_ready(lx.simulate(scene, q0, v0, params, **run).q)
    out["warm"] = time.perf_counter() - t2
    qpos, qvel = (np.asarray(x) for x in lx.chains.to_mujoco_state(sol.q, sol.qd, scene))
    out.update(
        ok=bool(sol.ok),
        steps=int(sol.stats["num_steps"]),
        method=scene.default_method,
        deepest=float(-np.min(np.asarray(sol.contact_gap))),
        speed_end=float(np.abs(qvel[-1]).max()),
        height=None if hz is None else qpos[:, hz].tolist(),
    )
    for dt in (float(model.opt.timestep), 5e-4):  # after lagrax's first call is timed
        heights, speed = _mujoco_heights(mujoco, path, t1, dt, every, hz)
        out[f"mujoco {dt:g}"] = {"height": heights, "speed_end": speed}
    return out


def _row(r: dict) -> str:
    if "refused" in r:
        return f"{r['model']:14s} refused: {r['refused']}"
    mj = [k for k in r if k.startswith("mujoco ")]
    h = f"{r['height'][-1]:.4f}" if r.get("height") else "-"
    mjh = " ".join(f"{r[k]['height'][-1]:.4f}" if r[k]["height"] else "-" for k in mj)
    return (
        f"{r['model']:14s} {str(r['ok']):5s} {r['steps']:7d} {r['first']:7.1f} "
        f"{r['warm']:8.2f} {1e3 * r['deepest']:8.2f} {r['speed_end']:9.1e} {h:>8s} {mjh:>16s}"
        f"  {'; '.join(r['not simulated']) or '-'}"
    )


def _chart(rows: list[dict], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = [r for r in rows if r.get("height")]
    cols = min(4, len(shown))
    nrows = -(-len(shown) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(3.4 * cols, 2.9 * nrows), squeeze=False)
    for ax, r in zip(axes.flat, shown, strict=False):
        ax.plot(r["t"], r["height"], "k-", lw=2, label="lagrax")
        runs = [k for k in r if k.startswith("mujoco ")]
        for k, style in zip(runs, ("C0--", "C1:"), strict=True):
            ax.plot(r["t"], r[k]["height"], style, label=f"MuJoCo, dt {k.split()[1]} s")
        ax.set_title(r["model"], fontsize=10)
        ax.legend(fontsize=7)
    for ax in axes.flat[len(shown) :]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("t (s)")
    for ax in axes[:, 0]:
        ax.set_ylabel("height coordinate (m)")
    fig.suptitle("from_mujoco with the defaults against MuJoCo's mj_step, ctrl = 0", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"chart: {path}")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--models", default=",".join(MODELS), help="comma-separated")
    parser.add_argument("--t1", type=float, default=3.0, help="seconds simulated")
    parser.add_argument("--save", default=None, help="also write the rows to this JSON file")
    parser.add_argument("--chart", default=None, help="draw the heights into this PNG")
    parser.add_argument("--load", default=None, help="redraw (--chart) a run saved by --save")
    parser.add_argument("--child", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        print("ROW " + json.dumps(child(args.child, args.t1)))
        return
    if args.load:
        with open(args.load) as f:
            rows = json.load(f)
        for r in rows:
            print(_row(r))
        if args.chart:
            _chart(rows, args.chart)
        return
    env = dict(os.environ, LAGRAX_COMPILATION_CACHE="0")
    rows = []
    print(
        f"{'model':14s} {'ok':5s} {'steps':>7s} {'first':>7s} {'warm (s)':>8s} "
        f"{'deep(mm)':>8s} {'|v| end':>9s} {'height':>8s} {'MuJoCo (dt, 5e-4)':>16s}  not simulated"
    )
    for name in args.models.split(","):
        proc = subprocess.run(
            [sys.executable, __file__, "--child", name, "--t1", str(args.t1)],
            env=env, capture_output=True, text=True, check=False,
        )  # fmt: skip
        got = [line for line in proc.stdout.splitlines() if line.startswith("ROW ")]
        if not got:
            print(f"{name:14s} failed: {(proc.stderr.strip().splitlines() or ['?'])[-1]}")
            continue
        rows.append(json.loads(got[-1][4:]))
        print(_row(rows[-1]), flush=True)
    if args.save:
        with open(args.save, "w") as f:
            json.dump(rows, f, indent=1)
    if args.chart:
        _chart(rows, args.chart)


if __name__ == "__main__":
    main()
