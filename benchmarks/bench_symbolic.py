"""Where the symbolic equations stop: time and expression size of `lagrax.symbolic.equations`.

For each system: the wall time of `lx.symbolic.equations(system, params)` (interpreting
`T` and `V`, differentiating, simplifying `M`, `C q̇`, `G`, the Christoffel `C` and `τ`;
one run, in a fresh SymPy cache, after a warm-up on the 2R arm so that imports and JAX's
first traces are not counted), the size of the kinetic energy as interpreted (nodes of its
expression tree, before simplification) and the size of `M`, `C q̇` and `G` together
after simplification (`Equations.size`). Systems past the default budget (`max_size`
nodes, `timeout` seconds) report the error they raise, and how long it took to raise it.

The table in `docs/symbolic.md` comes from this script:

    python benchmarks/bench_symbolic.py            # the docs' systems
    python benchmarks/bench_symbolic.py --more     # and larger ones, to find where it stops
"""

import argparse
import inspect
import time

import jax.numpy as jnp

import lagrax as lx


def _cart_pole():  # the README's example
    def kinetic(q, qd, p):
        v_bob_sq = qd[0] ** 2 + 2 * p["l"] * qd[0] * qd[1] * jnp.cos(q[1]) + (p["l"] * qd[1]) ** 2
        return 0.5 * p["M"] * qd[0] ** 2 + 0.5 * p["m"] * v_bob_sq

    def potential(q, p):
        return -p["m"] * p["g"] * p["l"] * jnp.cos(q[1])

    system = lx.LagrangianSystem(kinetic, potential, n_dof=2, name="cart-pole")
    return system, {"M": 1.0, "m": 0.3, "l": 0.5, "g": 9.81}


def _elastic_pendulum():  # q = (r, θ): a bob on a spring, θ from straight down
    def kinetic(q, qd, p):
        return 0.5 * p["m"] * (qd[0] ** 2 + (q[0] * qd[1]) ** 2)

    def potential(q, p):
        return -p["m"] * p["g"] * q[0] * jnp.cos(q[1]) + 0.5 * p["k"] * (q[0] - p["L"]) ** 2

    system = lx.LagrangianSystem(kinetic, potential, n_dof=2, name="elastic pendulum")
    return system, {"m": 1.0, "g": 9.81, "k": 40.0, "L": 1.0}


def _planar(n):
    chain = lx.chains.PlanarChain(n)
    return chain.system(), chain.params()


def _spatial(types, axes):
    chain = lx.chains.SpatialChain(types, axes=axes)
    return chain.system(), chain.params()


Z, Y, X = (0, 0, 1), (0, 1, 0), (1, 0, 0)
NUMERIC = {"numeric": ("offset", "com", "inertia")}
CASES = {
    "2R arm (lx.models.planar_2r)": (lx.models.planar_2r, {}),
    "cart-pole (README)": (_cart_pole, {}),
    "elastic pendulum": (_elastic_pendulum, {}),
    "3-link planar chain": (lambda: _planar(3), {}),
    "spatial RR chain, offsets and inertias numeric": (lambda: _spatial("RR", [Z, Y]), NUMERIC),
    "spatial RR chain, all symbolic": (lambda: _spatial("RR", [Z, Y]), {}),
}
MORE = {
    "5-link planar chain": (lambda: _planar(5), {}),
    "6-link planar chain": (lambda: _planar(6), {}),
    "8-link planar chain": (lambda: _planar(8), {}),
    "spatial RRR chain, all symbolic": (lambda: _spatial("RRR", [Z, Y, Y]), {}),
    "spatial RRRRRR chain, numeric": (lambda: _spatial("RRRRRR", [Z, Y, Y, X, Y, X]), NUMERIC),
    "7-DOF arm (lx.models.arm7), numeric": (
        lambda: lx.models.arm7(),
        {"numeric": ("offset", "com", "inertia", "damping")},
    ),
}


# lagrax.symbolic.equations' own defaults
MAX_SIZE = inspect.signature(lx.symbolic.equations).parameters["max_size"].default
TIMEOUT = inspect.signature(lx.symbolic.equations).parameters["timeout"].default


def measure(name, make, options):
    import sympy

    sympy.core.cache.clear_cache()
    system, params = make()
    if "numeric" in options:
        numeric = tuple(k for k in options["numeric"] if k in params)
        options = {**options, "numeric": numeric}
    t0 = time.perf_counter()
    try:
        eq = lx.symbolic.equations(system, params, **options)
    except lx.symbolic.ExpressionSizeError as err:
        seconds = time.perf_counter() - t0
        return f"| {name} | {system.n_dof} | {seconds:.1f} (raised) | {str(err)[:90]}… | |"
    seconds = time.perf_counter() - t0
    raw = lx.symbolic.tree_size(
        lx.symbolic.interpret(system.kinetic, eq.q, eq.qd, _symbols(eq, params))
    )
    return f"| {name} | {eq.n} | {seconds:.2f} | {raw:,} | {eq.size:,} |"


def _symbols(eq, params):
    """`params` with the equations' symbols in place of the symbolic entries."""
    import numpy as np

    out = dict(params)
    for key in {k for k, _ in eq.parameter_keys}:
        arr = np.empty(np.shape(params[key]), dtype=object)
        for s, (k, index) in zip(eq.parameters, eq.parameter_keys, strict=True):
            if k == key:
                arr[index] = s
        out[key] = arr if arr.ndim else arr[()]
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--more", action="store_true", help="also the larger systems")
    parser.add_argument(
        "--max-size", type=int, default=MAX_SIZE, help="expression budget (nodes) per system"
    )
    parser.add_argument(
        "--timeout", type=float, default=TIMEOUT, help="time budget (seconds) per system"
    )
    args = parser.parse_args(argv)
    budget = {"max_size": args.max_size, "timeout": args.timeout}
    system, params = lx.models.planar_2r()
    lx.symbolic.equations(system, params)  # warm-up: imports, first traces
    print("| system | n | time (s) | T as interpreted (nodes) | M, C q̇, G simplified (nodes) |")
    print("|---|---|---|---|---|")
    cases = {**CASES, **(MORE if args.more else {})}
    for name, (make, options) in cases.items():
        print(measure(name, make, {**options, **budget}), flush=True)


if __name__ == "__main__":
    main()
