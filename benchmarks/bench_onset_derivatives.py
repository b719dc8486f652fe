"""Derivatives that move an impact's onset (issue 56): the contact guide's dropped ball.

A 0.1 m ball (a point mass carrying a sphere, Hunt–Crossley dissipation 0.05, Hertz's
exponent, the default stiffness) dropped with its centre at 1 m; `y` is its height
0.25 s after the bounce. Two tables:

1. **Accuracy**: `dy/dh` (the drop height) by `jax.grad` and `jax.jacfwd` through
   `lagrax.simulate` at several options, against central differences at `rtol = atol =
   1e-13` (Richardson-extrapolated from the steps 1e-3 and 3e-4, whose own difference
   is printed).
2. **Cost** (compiled, the median of `--repeats` calls): one simulation, `jax.grad`
   (reverse mode) of `y`, and `jax.jacfwd` of `y` with respect to `k = 1, 2, 3` inputs
   (the drop height, the dissipation, the stiffness), as ratios to the simulation, at
   the default tolerances and at 1e-10; the steps each takes.

    python benchmarks/bench_onset_derivatives.py [--repeats 20]

About a minute on 2 cores.
"""

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import lagrax as lx
from lagrax.contact import ContactSystem, Plane, Sphere

jax.config.update("jax_enable_x64", True)

G, R, H = 9.81, 0.1, 1.0
T1 = float(np.sqrt(2.0 * (H - R) / G)) + 0.25


def scene():
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, lambda q, p: G * q[1], n_dof=2)
    ball, floor = Sphere(R, lambda q, p: q), Plane([0.0, 1.0])
    k0 = float(ContactSystem(body, ball, floor).coefficients({}).stiffness)
    return ContactSystem(
        body, ball, floor, dissipation=lambda p: p["c"], stiffness=lambda p: k0 * p["k"]
    )


SCENE = scene()


def solve(x, **options):
    params = {"c": x[1], "k": x[2]}
    q0 = jnp.stack([0.0 * x[0], x[0]])
    return lx.simulate(SCENE, q0, jnp.zeros(2), params, t1=T1, n_save=2, **options)


def height(x, **options):
    return solve(x, **options).q[-1, 1]


def median_time(fn, arg, repeats):
    jax.block_until_ready(fn(arg))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(arg))
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def accuracy():
    x0 = jnp.asarray([H, 0.05, 1.0])
    exact = jax.jit(lambda h: height(x0.at[0].set(h), rtol=1e-13, atol=1e-13))

    def central(dh):
        return (float(exact(H + dh)) - float(exact(H - dh))) / (2.0 * dh)

    coarse, fine = central(1e-3), central(3e-4)
    fd = fine + (fine - coarse) * 0.09 / 0.91
    print(f"1. dy/dh: central differences {fd:.10f} (steps 1e-3, 3e-4: {coarse:.10f}, {fine:.10f})")
    print(f"   {'options':36s} {'jax.grad':>14s} {'jax.jacfwd':>14s} {'rel. error':>10s}")
    cases = [
        ("the defaults", {}),
        ("rtol = atol = 1e-10", {"rtol": 1e-10, "atol": 1e-10}),
        ("rtol = atol = 1e-12", {"rtol": 1e-12, "atol": 1e-12}),
        ("events=scene.events()", {"events": SCENE.events()}),
        ("events=scene.events(), 1e-10", {"events": SCENE.events(), "rtol": 1e-10, "atol": 1e-10}),
    ]
    for name, options in cases:

        def y(h, options=options):
            return height(x0.at[0].set(h), **options)

        g, j = float(jax.grad(y)(H)), float(jax.jacfwd(y)(H))
        print(f"   {name:36s} {g:14.10f} {j:14.10f} {max(abs(g / fd - 1), abs(j / fd - 1)):10.1e}")


def cost(repeats):
    x0 = jnp.asarray([H, 0.05, 1.0])
    print("\n2. cost, the median of", repeats, "calls (ratios to one simulation)")
    for name, options in (("defaults", {}), ("1e-10", {"rtol": 1e-10, "atol": 1e-10})):
        sim = jax.jit(lambda x, o=options: height(x, **o))
        base = median_time(sim, x0, repeats)
        steps = int(jax.jit(lambda x, o=options: solve(x, **o).stats["num_steps"])(x0))
        row = [f"simulate {base * 1e3:.3f} ms ({steps} steps)"]
        grad = jax.jit(jax.grad(lambda x, o=options: height(x, **o)))
        row.append(f"grad (3 inputs) {median_time(grad, x0, repeats) / base:.2f}x")
        for k in (1, 2, 3):
            fwd = jax.jit(
                jax.jacfwd(lambda z, o=options, k=k: height(jnp.concatenate([z, x0[k:]]), **o))
            )
            row.append(f"jacfwd k={k} {median_time(fwd, x0[:k], repeats) / base:.2f}x")
        tangent_steps = jax.jit(
            lambda x, o=options: jax.jvp(
                lambda z: solve(z, **o).stats["num_steps"], (x,), (jnp.ones(3),)
            )[0]
        )
        row.append(f"steps with tangents {int(tangent_steps(x0))}")
        print(f"   {name:9s} " + "; ".join(row))


def main(argv=None):
    ap = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--repeats", type=int, default=20, help="timed calls of each (the median)")
    args = ap.parse_args(argv)
    accuracy()
    cost(args.repeats)


if __name__ == "__main__":
    main()
