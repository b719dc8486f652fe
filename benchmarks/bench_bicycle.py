"""The benchmark bicycle's eigenvalues over 1,000 speeds: lagrax against SymPy's KanesMethod.

The Whipple bicycle of Meijaard, Papadopoulos, Ruina & Schwab (2007) at the paper's
Table 1 parameters, its upright steady motion at 1,000 forward speeds in 0–10 m/s.
Measured in one run:

1. **lagrax**: ``lagrax.models.bicycle_eigenvalues`` (the general steady-motion
   linearization of the constrained model, ``ConstrainedSystem.linearize(...,
   independent=...)``, at every speed, ``vmap``ped in one ``jit``), parameters and speeds
   as arguments: trace + compile once, then the median of ``--repeats`` calls. Beside
   it, the route through the matrices: ``bicycle_matrices`` (two linearizations, at
   ``v = 0`` and ``v = 1``) and the eigenvalues of ``A(v) = [[0, 1], [−M⁻¹(g K0 + v²
   K2), −v M⁻¹ C1]]`` at every speed, one compiled call too.
2. **SymPy**: the same model as SymPy's own test builds it
   (``sympy/physics/mechanics/tests/test_kane3.py``, its Autolev-style geometry; the
   builder here is this script's own): ``KanesMethod`` with the front contact's
   configuration constraint and three velocity constraints, ``kanes_equations``, then
   ``KanesMethod.linearize`` about the upright motion with the speed ``v`` and every
   parameter symbolic (as the test does), each timed once; then the lean and steer block
   of ``A`` ``lambdify``-ed (common subexpressions shared) and evaluated at the 1,000
   speeds (NumPy, vectorized), with ``numpy.linalg.eigvals``: the median of
   ``--repeats``. SymPy's symbolic linearization takes minutes; ``--quick`` skips it and
   checks lagrax against the ``A(v)`` that SymPy's test hard-codes instead.

Both give the same eigenvalues (the largest difference over all speeds is printed; the
run stops if it exceeds 1e-9). The ratios: SymPy's derivation (``kanes_equations`` +
``linearize`` + ``lambdify``) over lagrax's compilation; SymPy's evaluation over
lagrax's call; and the first answer (derivation or compilation, then one evaluation).

    python benchmarks/bench_bicycle.py [--speeds 1000] [--repeats 7]
    python benchmarks/bench_bicycle.py --quick    # lagrax only (SymPy's derivation skipped)
"""

import argparse
import math
import os
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import lagrax as lx

sys.path.insert(0, os.path.dirname(__file__))
from _optional import available  # noqa: E402

AGREE = 1e-9  # largest eigenvalue difference, lagrax against SymPy [1/s]


def timed(fns, repeats):
    """Median wall time of each of `fns` (called interleaved, `repeats` rounds)."""
    times = [[] for _ in fns]
    for _ in range(repeats):
        for k, fn in enumerate(fns):
            t = time.perf_counter()
            jax.block_until_ready(fn())
            times[k].append(time.perf_counter() - t)
    return [statistics.median(t) for t in times]


def compiled(fn, *args):
    """`jax.jit(fn)` traced and compiled for `args`, and the seconds that took."""
    t = time.perf_counter()
    program = jax.jit(fn).lower(*args).compile()
    return program, time.perf_counter() - t


# ---------------------------------------------------------------------------- lagrax


def eigenvalues_from_matrices(matrices, g, speeds):
    """The lean/steer eigenvalues at `speeds` from `M, C1, K0, K2` (sorted as
    `bicycle_eigenvalues` sorts them)."""
    m, c1, k0, k2 = matrices
    minv = jnp.linalg.inv(m)

    def one(v):
        lower = jnp.concatenate([-minv @ (g * k0 + v**2 * k2), -v * minv @ c1], axis=1)
        upper = jnp.concatenate([jnp.zeros((2, 2)), jnp.eye(2)], axis=1)
        return jnp.sort(jnp.linalg.eigvals(jnp.concatenate([upper, lower], axis=0)))

    return jax.vmap(one)(speeds)


def lagrax_programs(speeds):
    """The two compiled lagrax programs, their compile times and the parameters."""
    bike, params = lx.models.benchmark_bicycle()
    direct, t_direct = compiled(
        lambda p, v: lx.models.bicycle_eigenvalues(bike, p, v), params, speeds
    )
    via, t_via = compiled(
        lambda p, v: eigenvalues_from_matrices(lx.models.bicycle_matrices(bike, p), p["g"], v),
        params,
        speeds,
    )
    return params, (direct, t_direct), (via, t_via)


# ----------------------------------------------------------------------------- SymPy

# the geometric parameters of SymPy's test (Autolev's names), in its order
SYMPY_NAMES = (
    "WFrad WRrad htangle forkoffset forklength framelength forkcg1 forkcg3 framecg1 "
    "framecg3 Iwr11 Iwr22 Iwf11 Iwf22 Iframe11 Iframe22 Iframe33 Iframe31 Ifork11 Ifork22 "
    "Ifork33 Ifork31 g mframe mfork mwf mwr"
).split()


def sympy_values(p):
    """The paper's Table 1 (`p`, floats) in SymPy's test's geometry: the head tube angle
    from the horizontal, the fork offset, the frame and fork lengths along and normal to
    the steering axis, and both centres of mass in the frame's and fork's axes (the
    test's formulas, for any parameter set); products of inertia change sign."""
    hta = math.pi / 2 - p["lam"]
    s, c = math.sin(hta), math.cos(hta)
    rake = -(p["c"] * s - p["rF"] * c)
    frame_height = -p["zB"] - p["rR"] - p["xB"] / s * c
    fork_up, fork_back = -p["zH"] - p["rF"], p["w"] - p["xH"]
    fork_arm = math.hypot(fork_up, fork_back)
    fork_angle = math.pi / 2 - hta - math.acos(fork_up / fork_arm)
    fork_length = p["w"] * c - (p["rF"] - p["rR"]) * s
    values = {
        "WFrad": p["rF"],
        "WRrad": p["rR"],
        "htangle": hta,
        "forkoffset": rake,
        "forklength": fork_length,
        "framelength": p["w"] * s - (rake - (p["rF"] - p["rR"]) * c),
        "forkcg1": fork_arm * math.cos(fork_angle) - fork_length,
        "forkcg3": rake + fork_arm * math.sin(fork_angle),
        "framecg1": frame_height * s,
        "framecg3": p["xB"] / s + frame_height * c,
        "Iwr11": p["IRxx"],
        "Iwr22": p["IRyy"],
        "Iwf11": p["IFxx"],
        "Iwf22": p["IFyy"],
        "Iframe11": p["IBxx"],
        "Iframe22": p["IByy"],
        "Iframe33": p["IBzz"],
        "Iframe31": -p["IBxz"],
        "Ifork11": p["IHxx"],
        "Ifork22": p["IHyy"],
        "Ifork33": p["IHzz"],
        "Ifork31": -p["IHxz"],
        "g": p["g"],
        "mframe": p["mB"],
        "mfork": p["mH"],
        "mwf": p["mF"],
        "mwr": p["mR"],
    }
    return [values[k] for k in SYMPY_NAMES]


def sympy_bicycle():
    """The Whipple bicycle in SymPy (the model of SymPy's test_kane3): `(KanesMethod,
    bodies, loads, symbols)`. Coordinates yaw q1, roll q2, pitch q4 (dependent), steer
    q5; speeds u1…u6 (yaw, roll, rear wheel, pitch, steer, front wheel rates), u1, u4, u6
    dependent through the front contact's velocity being zero; the front contact on the
    ground the configuration constraint."""
    import sympy as sm
    import sympy.physics.mechanics as me

    q1, q2, q4, q5 = me.dynamicsymbols("q1 q2 q4 q5")
    u1, u2, u3, u4, u5, u6 = me.dynamicsymbols("u1:7")
    s = dict(zip(SYMPY_NAMES, sm.symbols(SYMPY_NAMES), strict=True))

    n = me.ReferenceFrame("N")
    yaw = n.orientnew("Y", "Axis", [q1, n.z])
    roll = yaw.orientnew("R", "Axis", [q2, yaw.x])
    frame = roll.orientnew("Frame", "Axis", [q4 + s["htangle"], roll.y])
    frame_axes = frame.orientnew("TempFrame", "Axis", [-s["htangle"], frame.y])
    fork = frame.orientnew("Fork", "Axis", [q5, frame.x])
    fork_axes = fork.orientnew("TempFork", "Axis", [-s["htangle"], fork.y])
    rear_wheel, front_wheel = me.ReferenceFrame("WR"), me.ReferenceFrame("WF")

    rear_contact = me.Point("WR_cont")
    rear_centre = rear_contact.locatenew("WR_mc", s["WRrad"] * roll.z)
    steer = rear_centre.locatenew("Steer", s["framelength"] * frame.z)
    frame_cm = rear_centre.locatenew("Frame_mc", -s["framecg1"] * frame.x + s["framecg3"] * frame.z)
    fork_cm = steer.locatenew("Fork_mc", -s["forkcg1"] * fork.x + s["forkcg3"] * fork.z)
    front_centre = steer.locatenew("WF_mc", s["forklength"] * fork.x + s["forkoffset"] * fork.z)
    down = (me.dot(fork.y, yaw.z) * fork.y - yaw.z).normalize()
    front_contact = front_centre.locatenew("WF_cont", s["WFrad"] * down)

    yaw.set_ang_vel(n, u1 * yaw.z)
    roll.set_ang_vel(yaw, u2 * roll.x)
    rear_wheel.set_ang_vel(frame, u3 * frame.y)
    frame.set_ang_vel(roll, u4 * frame.y)
    fork.set_ang_vel(frame, u5 * fork.x)
    front_wheel.set_ang_vel(fork, u6 * fork.y)
    rear_contact.set_vel(n, 0)
    rear_centre.v2pt_theory(rear_contact, n, rear_wheel)
    steer.v2pt_theory(rear_centre, n, frame)
    frame_cm.v2pt_theory(rear_centre, n, frame)
    fork_cm.v2pt_theory(steer, n, fork)
    front_centre.v2pt_theory(steer, n, fork)
    front_contact.v2pt_theory(front_centre, n, front_wheel)

    inertia = me.inertia
    bodies = [
        me.RigidBody(
            "frame", frame_cm, frame, s["mframe"],
            (inertia(frame_axes, s["Iframe11"], s["Iframe22"], s["Iframe33"], 0, 0,
                     s["Iframe31"]), frame_cm),
        ),
        me.RigidBody(
            "fork", fork_cm, fork, s["mfork"],
            (inertia(fork_axes, s["Ifork11"], s["Ifork22"], s["Ifork33"], 0, 0,
                     s["Ifork31"]), fork_cm),
        ),
        me.RigidBody(
            "rear wheel", rear_centre, rear_wheel, s["mwr"],
            (inertia(frame, s["Iwr11"], s["Iwr22"], s["Iwr11"]), rear_centre),
        ),
        me.RigidBody(
            "front wheel", front_centre, front_wheel, s["mwf"],
            (inertia(fork, s["Iwf11"], s["Iwf22"], s["Iwf11"]), front_centre),
        ),
    ]  # fmt: skip
    loads = [
        (point, -mass * s["g"] * yaw.z)
        for point, mass in (
            (frame_cm, s["mframe"]),
            (fork_cm, s["mfork"]),
            (front_centre, s["mwf"]),
            (rear_centre, s["mwr"]),
        )
    ]
    kanes = me.KanesMethod(
        n,
        q_ind=[q1, q2, q5],
        q_dependent=[q4],
        configuration_constraints=[front_contact.pos_from(rear_contact) & yaw.z],
        u_ind=[u2, u3, u5],
        u_dependent=[u1, u4, u6],
        velocity_constraints=[front_contact.vel(n) & axis for axis in (yaw.x, yaw.y, yaw.z)],
        kd_eqs=[q.diff() - u for q, u in ((q1, u1), (q2, u2), (q4, u4), (q5, u5))],
        constraint_solver="CRAMER",
    )
    return kanes, bodies, loads, (q1, q2, q4, q5), (u1, u2, u3, u4, u5, u6), s


def sympy_linearized():
    """SymPy's `A(v)` (lean, steer, lean rate, steer rate block), lambdified with every
    parameter symbolic, and the seconds of each step."""
    import sympy as sm

    seconds = {}
    t = time.perf_counter()
    kanes, bodies, loads, qs, us, s = sympy_bicycle()
    kanes.kanes_equations(bodies, loads)
    seconds["KanesMethod + kanes_equations"] = time.perf_counter() - t
    v = sm.Symbol("v")
    op_point = {u.diff(): 0 for u in us}
    op_point.update({q: 0 for q in qs})
    op_point.update({u: 0 for u in us})
    op_point.update({us[2]: v / s["WRrad"], us[5]: v / s["WFrad"]})
    t = time.perf_counter()
    a_mat, _, _ = kanes.linearize(A_and_B=True, op_point=op_point, linear_solver="CRAMER")
    seconds["KanesMethod.linearize"] = time.perf_counter() - t
    t = time.perf_counter()
    block = a_mat.extract([1, 2, 3, 5], [1, 2, 3, 5])  # lean, steer and their rates
    entries = sm.lambdify([v, *s.values()], block.tolist(), modules="numpy", cse=True)
    seconds["lambdify (cse)"] = time.perf_counter() - t
    return entries, seconds, sm.count_ops(block)


def sympy_eigenvalues(entries, values, speeds):
    """SymPy's lambdified `A(v)` at all `speeds` at once, and its eigenvalues."""
    rows = entries(speeds, *values)
    a_mat = np.stack(
        [np.stack([np.broadcast_to(np.asarray(e, float), speeds.shape) for e in r], -1)
         for r in rows],
        -2,
    )  # fmt: skip
    return np.linalg.eigvals(a_mat)


def published_eigenvalues(speeds):
    """The `A(v)` block that SymPy's test_kane3 hard-codes (its `Res`, KanesMethod's
    result at the benchmark parameters, 15 digits), and its eigenvalues."""
    v = np.asarray(speeds)
    one, zero = np.ones_like(v), np.zeros_like(v)
    rows = [
        [zero, zero, one, zero],
        [zero, zero, zero, one],
        [
            9.48977444677355 * one,
            -0.891197738059089 * v**2 - 0.571523173729245,
            -0.105522449805691 * v,
            -0.330515398992311 * v,
        ],
        [
            11.7194768719633 * one,
            -1.97171508499972 * v**2 + 30.9087533932407,
            3.67680523332152 * v,
            -3.08486552743311 * v,
        ],
    ]
    return np.linalg.eigvals(np.stack([np.stack(r, -1) for r in rows], -2))


def largest_difference(ours, theirs):
    """The largest distance from an eigenvalue of `ours` to the nearest of `theirs`, at
    the same speed (both ways)."""
    d = np.abs(np.asarray(ours)[:, :, None] - np.asarray(theirs)[:, None, :])
    return float(max(d.min(axis=2).max(), d.min(axis=1).max()))


def _ms(seconds):
    return f"{1e3 * seconds:,.1f} ms" if seconds < 10 else f"{seconds:,.1f} s"


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--speeds", type=int, default=1000, help="forward speeds in 0–10 m/s")
    ap.add_argument("--repeats", type=int, default=7, help="timed rounds (median)")
    ap.add_argument(
        "--quick",
        action="store_true",
        help="skip SymPy's symbolic derivation (minutes); check against its published A(v)",
    )
    args = ap.parse_args(argv)
    jax.config.update("jax_enable_x64", True)
    speeds = np.linspace(0.0, 10.0, args.speeds)
    with_sympy = not args.quick and available("sympy", "SymPy's KanesMethod baseline")

    params, (direct, t_direct), (via, t_via) = lagrax_programs(jnp.asarray(speeds))
    ours = np.asarray(direct(params, speeds))
    ours_via = np.asarray(via(params, speeds))
    run_direct, run_via = timed(
        [lambda: direct(params, speeds), lambda: via(params, speeds)], args.repeats
    )
    print(f"benchmark bicycle, {args.speeds} speeds in 0–10 m/s (medians of {args.repeats})")
    print("| lagrax | trace + compile | one call (all speeds) |")
    print("|---|---|---|")
    print(f"| bicycle_eigenvalues (a linearization per speed) | {_ms(t_direct)} "
          f"| {_ms(run_direct)} |")  # fmt: skip
    print(f"| bicycle_matrices (two linearizations) + eig A(v) | {_ms(t_via)} "
          f"| {_ms(run_via)} |")  # fmt: skip
    print(f"the two routes agree to {largest_difference(ours, ours_via):.1e} 1/s")

    if not with_sympy:
        diff = largest_difference(ours, published_eigenvalues(speeds))
        print(f"SymPy's derivation skipped; against test_kane3's published A(v): {diff:.1e} 1/s")
        if diff > AGREE:
            raise SystemExit(f"lagrax and SymPy disagree: {diff:.2e} > {AGREE:g}")
        return
    print("SymPy: deriving (minutes) ...", flush=True)
    entries, seconds, size = sympy_linearized()
    values = sympy_values({k: float(x) for k, x in params.items()})
    theirs = sympy_eigenvalues(entries, values, speeds)
    (run_sympy,) = timed([lambda: sympy_eigenvalues(entries, values, speeds)], args.repeats)
    derive = sum(seconds.values())
    print(f"| SymPy (A's lean/steer block: {size:,} operations) | seconds |")
    print("|---|---|")
    for step, t in seconds.items():
        print(f"| {step} | {_ms(t)} |")
    print(f"| evaluate A(v) at all speeds + numpy.linalg.eigvals | {_ms(run_sympy)} |")
    diff = largest_difference(ours, theirs)
    print(f"eigenvalues: lagrax against SymPy, largest difference {diff:.1e} 1/s")
    if diff > AGREE:
        raise SystemExit(f"lagrax and SymPy disagree: {diff:.2e} > {AGREE:g}")
    print("| ratio (SymPy / lagrax) | bicycle_eigenvalues | via the matrices |")
    print("|---|---|---|")
    print(f"| derivation / compilation | {derive / t_direct:.1f} | {derive / t_via:.1f} |")
    print(f"| evaluation at all speeds | {run_sympy / run_direct:.2g} "
          f"| {run_sympy / run_via:.2g} |")  # fmt: skip
    first_sympy = derive + run_sympy
    print(
        f"| first answer | {first_sympy / (t_direct + run_direct):.1f} "
        f"| {first_sympy / (t_via + run_via):.1f} |"
    )


if __name__ == "__main__":
    main()
