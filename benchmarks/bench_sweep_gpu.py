"""GPU sweeps (the 2R arm, or the 7-DOF arm) against MuJoCo MJX, at matched accuracy.

The sweep of ``bench_sweep.py`` (a grid of m2 ∈ [0.5, 2] kg × l1 ∈ [0.5, 1.5] m, the
chaotic start θ = (−π/2 + 1.4, 0.8) at rest, 10 s, final state kept), at batch sizes from
4k to 512k members, in float64 and float32, on one device:

1. ``lagrax.sweep`` with no option but the tolerance (rtol = atol = 1e-8 in float64, 1e-6
   in float32): the chunk size and lane count it chose for the device, its idle
   lane-steps, the first call (compilation included) and the median of the repeats;
2. MuJoCo MJX (``mujoco.mjx``, the ``bench`` extra) on the same arm (an MJCF of two hinge
   links, contacts off, the same masses, centres of mass and inertias), ``jax.vmap`` of
   a ``fori_loop`` of ``mjx.step`` with MuJoCo's RK4 at the largest step in
   {1e-2, 5e-3, …} whose median final-state error on 64 members is no worse than
   lagrax's (both against Dopri8 at rtol = atol = 1e-12, float64).

``--model arm7`` runs the same comparison on the scale issue's 7-DOF spatial arm
(``bench_scale.py``'s ``SpatialChain``, axes z, y, z, y, z, y, z, 1 kg 1 m links, q0 = 0.3
at rest, 2 s) over a grid of the masses of links 4 and 7 ∈ [0.5, 2] kg; lagrax runs its
articulated-body recursions, MJX the same chain in MJCF (nested bodies, hinge joints).

Without a GPU it says so and exits (status 0): the figures are for a GPU. ``--allow-cpu``
runs it on the CPU anyway (with ``--sizes 64``, a check that both code paths work).

``--schedule`` needs no GPU: it counts the idle lane-steps of the lane queue at the GPU
defaults for each batch size, by replaying the schedule on the step counts of a CPU
sweep (``_lane_schedule.py``; a count, not a timing, so exact on any machine).

    python benchmarks/bench_sweep_gpu.py [--sizes 4096 32761 131044 524176] [--repeats 3]
    python benchmarks/bench_sweep_gpu.py --model arm7 [--sizes 4096 32761 131044]
    python benchmarks/bench_sweep_gpu.py --schedule [--side 64]
"""

import argparse
import dataclasses
import math
import os
import sys
from collections.abc import Callable
from functools import partial
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

import lagrax as lx

sys.path.insert(0, os.path.dirname(__file__))
from _optional import available  # noqa: E402

sys.path.insert(0, os.path.dirname(__file__))
from _lane_schedule import idle_fraction  # noqa: E402
from bench_scale import arm_mjcf as arm7_mjcf  # noqa: E402
from bench_scale import chain_of  # noqa: E402
from bench_sweep import timed  # noqa: E402

Q0 = (-math.pi / 2 + 1.4, 0.8)
T1 = 10.0
TOL = {"float64": 1e-8, "float32": 1e-6}
SIZES = (4096, 32761, 131044, 524176)  # grid sides 64, 181, 362, 724
RK4_STEPS = (1e-2, 5e-3, 2.5e-3, 2e-3, 1e-3, 5e-4, 2.5e-4)


def arm_mjcf(params, dt: float) -> str:
    """The lecture's 2R arm as MJCF: θ1 from the x axis, θ2 relative to link 1, both
    about z; gravity along −y; link i's centre of mass at r_i along it, z-inertia I_i
    about that centre. No geoms, contacts, damping or armature: the same ODE as
    ``lagrax.models.planar_2r``."""
    p = {k: float(v) for k, v in params.items()}
    # inertia about the unused x and y axes: any, as long as MuJoCo accepts it (x + y >= z)
    h1, h2 = p["I1"] / 2, p["I2"] / 2
    return f"""
<mujoco model="planar_2r">
  <compiler inertiafromgeom="false" angle="radian"/>
  <option timestep="{dt}" integrator="RK4" gravity="0 {-p["g"]} 0">
    <flag contact="disable" constraint="disable"/>
  </option>
  <worldbody>
    <body name="link1">
      <joint name="q1" type="hinge" axis="0 0 1"/>
      <inertial pos="{p["r1"]} 0 0" mass="{p["m1"]}" diaginertia="{h1} {h1} {p["I1"]}"/>
      <body name="link2" pos="{p["l1"]} 0 0">
        <joint name="q2" type="hinge" axis="0 0 1"/>
        <inertial pos="{p["r2"]} 0 0" mass="{p["m2"]}" diaginertia="{h2} {h2} {p["I2"]}"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


ARM7_SWEPT = (3, 6)  # links 4 and 7: their masses are swept


@dataclasses.dataclass(frozen=True)
class Model:
    """One benchmarked mechanism: the lagrax system, its start, and how a member's two
    swept values ``(a, b)`` enter lagrax's parameters and MJX's model."""

    name: str
    system: Any
    params: dict
    q0: tuple[float, ...]
    t1: float
    ranges: tuple[tuple[float, float], tuple[float, float]]
    batch: Callable[[dict, np.ndarray, np.ndarray], Any]  # lagrax Grid of the members
    mjcf: Callable[[float], str]
    mjx_member: Callable[[Any, Any, Any], Any]  # (mx, a, b) -> mx for one member


def planar_2r_model() -> Model:
    system, params = lx.models.planar_2r()
    return Model(
        name="2R arm, m2 x l1",
        system=system,
        params=params,
        q0=Q0,
        t1=T1,
        ranges=((0.5, 2.0), (0.5, 1.5)),
        batch=lambda p, a, b: lx.samples(p, m2=a, l1=b),
        mjcf=lambda dt: arm_mjcf(params, dt),
        mjx_member=lambda mx, a, b: mx.replace(
            body_mass=jnp.asarray(mx.body_mass).at[2].set(a),
            body_pos=jnp.asarray(mx.body_pos).at[2, 0].set(b),
        ),
    )


def arm7_model() -> Model:
    chain, params = chain_of("spatial", 7)  # bench_scale's arm
    i, j = ARM7_SWEPT

    def batch(p, a, b):  # a pytree with a leading member axis on every leaf
        out = {k: np.broadcast_to(v, (len(a), *np.shape(v))) for k, v in p.items()}
        m = out["m"].copy()
        m[:, i], m[:, j] = a, b
        return {**out, "m": m}

    return Model(
        name="7-DOF arm, m4 x m7",
        system=chain.system(),
        params=params,
        q0=(0.3,) * 7,
        t1=2.0,
        ranges=((0.5, 2.0), (0.5, 2.0)),
        batch=batch,
        mjcf=arm7_mjcf,
        mjx_member=lambda mx, a, b: mx.replace(
            body_mass=jnp.asarray(mx.body_mass).at[i + 1].set(a).at[j + 1].set(b)
        ),
    )


MODELS = {"2r": planar_2r_model, "arm7": arm7_model}


def mjx_sweep(model: Model, dtype):
    """``run(a, b, dt) -> (q, qd)`` at ``t1``: MJX's RK4 at step ``dt``, vmapped over
    the members (each member's swept values set in the model by ``model.mjx_member``).
    One compilation serves every ``dt`` (the step and the step count are traced)."""
    import mujoco
    from mujoco import mjx

    # MJX computes in float32 only with JAX's 64-bit mode off (its constants are
    # float64 otherwise); lagrax turns that mode on, so float32 runs in a context
    x64 = jax.enable_x64(dtype != jnp.float32)
    n = len(model.q0)
    with x64:
        mx = mjx.put_model(mujoco.MjModel.from_xml_string(model.mjcf(RK4_STEPS[0])))
        q0 = jnp.asarray(model.q0, dtype)

    def one(a, b, dt, n_steps):
        m = model.mjx_member(mx, a, b)
        m = m.replace(opt=m.opt.replace(timestep=dt))
        d = mjx.make_data(m).replace(qpos=q0, qvel=jnp.zeros(n, dtype))
        d = jax.lax.fori_loop(0, n_steps, lambda _, d: mjx.step(m, d), d)
        return d.qpos, d.qvel

    run = jax.jit(jax.vmap(one, in_axes=(0, 0, None, None)))

    def sweep(a, b, dt):
        with x64:
            n_steps = jnp.asarray(int(round(model.t1 / dt)), jnp.int32)
            a, b = jnp.asarray(a, dtype), jnp.asarray(b, dtype)
            out = jax.block_until_ready(run(a, b, jnp.asarray(dt, dtype), n_steps))
        return tuple(np.asarray(x, np.float64) for x in out)

    return sweep


def members(n: int, ranges=((0.5, 2.0), (0.5, 1.5))) -> tuple[np.ndarray, np.ndarray, int]:
    """The grid of about ``n`` members (side ⌈√n⌉) over the two ranges, flattened."""
    side = max(2, math.isqrt(n - 1) + 1)
    (a0, a1), (b0, b1) = ranges
    a, b = np.meshgrid(np.linspace(a0, a1, side), np.linspace(b0, b1, side), indexing="ij")
    return a.ravel(), b.ravel(), side


def final_error(q, qd, ref_q, ref_qd):
    return np.max(np.abs(np.concatenate([q - ref_q, qd - ref_qd], axis=-1)), axis=-1)


def compare(args, have_mjx: bool = True) -> None:
    model = MODELS[args.model]()
    system, params, n = model.system, model.params, len(model.q0)
    device = jax.devices()[0]
    print(f"device: {device.device_kind} ({device.platform}), jax {jax.__version__}")
    print(f"model: {model.name}, {model.t1:g} s")
    # the reference: Dopri8 at 1e-12 (float64) on 64 members spread over the grid
    a_all, b_all, _ = members(max(args.sizes), model.ranges)
    pick = np.linspace(0, len(a_all) - 1, 64).astype(int)
    ref = lx.sweep(
        system,
        model.q0,
        np.zeros(n),
        model.batch(params, a_all[pick], b_all[pick]),
        t1=model.t1,
        solver="dopri8",
        rtol=1e-12,
        atol=1e-12,
        progress=False,
    )
    for name in args.dtypes:
        dtype = jnp.dtype(name)
        tol = TOL[name] if args.tol is None else args.tol
        p = {k: np.asarray(v, dtype) for k, v in params.items()}

        def lagrax_run(a, b, p=p, dtype=dtype, tol=tol):
            batch = model.batch(p, np.asarray(a, dtype), np.asarray(b, dtype))
            q0, qd0 = np.asarray(model.q0, dtype), np.zeros(n, dtype)
            return lambda: lx.sweep(
                system, q0, qd0, batch, t1=model.t1, rtol=tol, atol=tol, progress=False
            )

        # matched accuracy: MJX's RK4 step no coarser than lagrax's median error needs
        ds = lagrax_run(a_all[pick], b_all[pick])()
        err_lx = final_error(ds.q.values, ds.qd.values, ref.q.values, ref.qd.values)
        dt, err_mjx = None, None
        run_mjx = mjx_sweep(model, dtype) if have_mjx else None
        for cand in RK4_STEPS if run_mjx is not None else ():
            q, qd = run_mjx(a_all[pick], b_all[pick], cand)
            e = final_error(np.asarray(q), np.asarray(qd), ref.q.values, ref.qd.values)
            if np.median(e) <= np.median(err_lx):
                dt, err_mjx = cand, e
                break
        print(f"\n{name}: final-state error vs Dopri8 1e-12 (64 members): median / max")
        print(f"  lagrax Tsit5 {tol:g}  {np.median(err_lx):.2e} / {np.max(err_lx):.2e}")
        if run_mjx is None:
            pass
        elif dt is None:
            print(f"  MJX RK4: no step in {RK4_STEPS} matches; using the finest")
            dt = RK4_STEPS[-1]
        else:
            print(f"  MJX RK4 dt={dt:g}     {np.median(err_mjx):.2e} / {np.max(err_mjx):.2e}")
        head = (
            f"{'members':>8} {'chunk':>8} {'lanes':>7} {'idle':>6} {'lagrax traj/s':>14} "
            f"{'1st call s':>10} {'MJX traj/s':>11} {'1st call s':>10} {'MJX/lagrax time':>15}"
        )
        print(head)
        for size in args.sizes:
            a, b, _ = members(size, model.ranges)
            ds, first, t = timed(lagrax_run(a, b), args.repeats)
            at = ds.attrs
            mjx_cols = f"{'—':>11} {'—':>10} {'—':>15}"
            if run_mjx is not None:
                _, first_mjx, t_mjx = timed(partial(run_mjx, a, b, dt), args.repeats)
                mjx_cols = f"{len(a) / t_mjx:>11,.0f} {first_mjx:>10.1f} {t_mjx / t:>15.2f}"
            print(
                f"{len(a):>8} {at['chunk_size']:>8} {at['n_lanes']:>7} "
                f"{at['lane_idle_fraction']:>6.1%} {len(a) / t:>14,.0f} {first:>10.1f} " + mjx_cols
            )


def schedule(args) -> None:
    """Idle lane-steps at the GPU defaults, from the step counts of a CPU sweep."""
    from lagrax._sweep import defaults as _defaults

    system, params = lx.models.planar_2r()
    m2, l1, side = members(args.side**2)
    ds = lx.sweep(system, Q0, [0.0, 0.0], lx.samples(params, m2=m2, l1=l1), t1=T1, progress=False)
    steps = ds.num_steps.values
    print(
        f"step counts of {len(steps)} members ({side} x {side} grid, {T1:g} s): "
        f"min {steps.min()}, mean {steps.mean():.0f}, max {steps.max()}"
    )
    rng = np.random.default_rng(0)
    info = _defaults.DeviceInfo("gpu", 80 << 30, 1)  # one H100
    lane = _defaults.lane_bytes(2, len(params), 8)
    member = 8 * (2 * 2 + 1 + 4 * 2 + 8)
    print(
        f"\n{'members':>8} {'chunk':>8} {'lanes':>7} {'refill':>6} {'tail':>6} "
        f"{'idle, default':>14} {'refill L/16, no tail':>21} {'lock-step':>10}"
    )
    for n in args.sizes:
        # the grid's own counts, extended by draws from them beyond its size
        extra = steps[rng.integers(0, len(steps), max(0, n - len(steps)))]
        s = np.concatenate([steps, extra])[:n]
        cut = _defaults.plan(info, n_members=n, member_bytes=member, lane_bytes=lane)
        args_ = (cut.chunk_size, cut.n_lanes)
        now = idle_fraction(s, *args_, cut.refill, cut.tail_lanes)
        before = idle_fraction(s, *args_, max(1, cut.n_lanes // 16), 0)
        lock = idle_fraction(s, cut.chunk_size, cut.chunk_size, cut.chunk_size, 0)
        print(
            f"{n:>8} {cut.chunk_size:>8} {cut.n_lanes:>7} {cut.refill:>6} {cut.tail_lanes:>6} "
            f"{now:>14.1%} {before:>21.1%} {lock:>10.1%}"
        )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--model", choices=list(MODELS), default="2r", help="the mechanism")
    ap.add_argument(
        "--sizes", type=int, nargs="+", default=list(SIZES), help="batch sizes (members)"
    )
    ap.add_argument(
        "--tol", type=float, default=None, help="lagrax rtol = atol (None: 1e-8 / 1e-6 by dtype)"
    )
    ap.add_argument("--repeats", type=int, default=3, help="timed runs (median)")
    ap.add_argument(
        "--dtypes",
        nargs="+",
        default=["float64", "float32"],
        choices=list(TOL),
        help="precisions to run",
    )
    ap.add_argument("--schedule", action="store_true", help="count idle lane-steps (no GPU)")
    ap.add_argument("--side", type=int, default=64, help="--schedule: grid side of the sweep")
    ap.add_argument("--allow-cpu", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.schedule:
        schedule(args)
        return 0
    platforms = sorted({d.platform for d in jax.devices()})
    if "gpu" not in platforms and not args.allow_cpu:
        print(
            f"no GPU found (JAX sees: {', '.join(platforms)}): this benchmark compares "
            "lagrax and MuJoCo MJX on a GPU; nothing measured. (--schedule counts the "
            "work queue's idle lane-steps without one.)"
        )
        return 0
    compare(args, have_mjx=available("mujoco.mjx", "the MuJoCo MJX baseline"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
