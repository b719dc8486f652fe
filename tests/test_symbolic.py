"""`lagrax.symbolic`: the symbolic equations of motion from the same JAX energies.

References, none of which goes through `lagrax.symbolic`'s own derivatives:

- SymPy's ``LagrangesMethod`` on Lagrangians written again in SymPy (the elastic pendulum,
  the cart with a double pendulum, the spherical pendulum, the heavy symmetric top):
  the mass matrix and the forcing agree symbolically (``sympy.simplify`` of the
  difference is zero);
- the lecture's slide for the 2R arm, derived three ways (Lagrange, Newton–Euler, Kane);
- lagrax's numbers (``mass_matrix``, ``coriolis``, ``coriolis_matrix``, ``gravity``,
  ``inverse_dynamics``), against the lambdified formulas and the compiled C code;
- JAX itself, for the interpreter: each primitive's symbolic value at random numbers.
"""

import ctypes
import shutil
import subprocess
import sys
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp
from sympy.physics.mechanics import LagrangesMethod, dynamicsymbols

import lagrax as lx
from lagrax.bodies import Param, PointMass, Scene, SpatialBody

sym = lx.symbolic


# ----------------------------------------------------------------------------- systems
def _elastic_kinetic(q, qd, p):  # q = (r, θ): a bob on a spring, θ from straight down
    return 0.5 * p["m"] * (qd[0] ** 2 + (q[0] * qd[1]) ** 2)


def _elastic_potential(q, p):
    return -p["m"] * p["g"] * q[0] * jnp.cos(q[1]) + 0.5 * p["k"] * (q[0] - p["L"]) ** 2


ELASTIC = {"m": 1.0, "g": 9.81, "k": 40.0, "L": 1.0}


def elastic_pendulum():
    system = lx.LagrangianSystem(_elastic_kinetic, _elastic_potential, n_dof=2, name="elastic")
    return system, ELASTIC


def _cart_positions(q, p):  # q = (x, θ1, θ2), absolute angles from straight down
    bob1 = jnp.stack([q[0] + p["l1"] * jnp.sin(q[1]), -p["l1"] * jnp.cos(q[1])])
    bob2 = bob1 + p["l2"] * jnp.stack([jnp.sin(q[2]), -jnp.cos(q[2])])
    return jnp.stack([q[0], jnp.zeros_like(q[0])]), bob1, bob2


def cart_double_pendulum():
    bodies = [
        PointMass(Param(name), lambda q, p, i=i: _cart_positions(q, p)[i])
        for i, name in enumerate(("M", "m1", "m2"))
    ]
    system = Scene(bodies, gravity=Param("g"), n_dof=3, name="cart + double pendulum").system()
    return system, {"M": 2.0, "m1": 0.5, "m2": 0.3, "l1": 1.0, "l2": 0.7, "g": 9.81}


def _spherical_bob(q, p):  # q = (θ, φ): θ from straight down, φ the azimuth
    s = jnp.sin(q[0])
    return p["l"] * jnp.stack([s * jnp.cos(q[1]), s * jnp.sin(q[1]), -jnp.cos(q[0])])


def spherical_pendulum():
    scene = Scene([PointMass(Param("m"), _spherical_bob)], gravity=Param("g"), n_dof=2)
    return scene.system(), {"m": 0.8, "l": 1.2, "g": 9.81}


def _rz(a):
    c, s, z, o = jnp.cos(a), jnp.sin(a), jnp.zeros_like(a), jnp.ones_like(a)
    return jnp.stack([jnp.stack([c, -s, z]), jnp.stack([s, c, z]), jnp.stack([z, z, o])])


def _rx(a):
    c, s, z, o = jnp.cos(a), jnp.sin(a), jnp.zeros_like(a), jnp.ones_like(a)
    return jnp.stack([jnp.stack([o, z, z]), jnp.stack([z, c, -s]), jnp.stack([z, s, c])])


def _top_rotation(q, p):  # z-x-z Euler angles (precession φ, nutation θ, spin ψ)
    return _rz(q[0]) @ _rx(q[1]) @ _rz(q[2])


def _top_com(q, p):
    return _top_rotation(q, p) @ jnp.stack([0.0, 0.0, p["h"]])


def heavy_top():
    """A symmetric top on a fixed tip: centre of mass at `h` along its axis, inertia
    `diag(A, A, C)` about the centre of mass."""
    inertia = lambda p: jnp.diag(jnp.stack([p["A"], p["A"], p["C"]]))  # noqa: E731
    body = SpatialBody(Param("m"), inertia, _top_com, _top_rotation)
    system = Scene([body], gravity=Param("g"), n_dof=3, name="heavy top").system()
    return system, {"m": 1.0, "h": 0.3, "A": 0.02, "C": 0.04, "g": 9.81}


# ------------------------------------------------------------- the same, in SymPy
def _sympy_lagrangian(name, eq):
    """The Lagrangian of each test system written again in SymPy, in dynamic symbols,
    with the parameter symbols of `eq` (same names and assumptions)."""
    s = eq.symbols
    t = dynamicsymbols._t
    n = eq.n
    q = dynamicsymbols(f"x0:{n}")
    v = [sp.diff(c, t) for c in q]
    if name == "elastic":
        m, g, k, length = s["m"], s["g"], s["k"], s["L"]
        r, th = q
        lag = m / 2 * (v[0] ** 2 + r**2 * v[1] ** 2) + m * g * r * sp.cos(th)
        lag -= k / 2 * (r - length) ** 2
    elif name == "cart":
        big, m1, m2, l1, l2, g = (s[k] for k in ("M", "m1", "m2", "l1", "l2", "g"))
        x, a, b = q
        x1, y1 = x + l1 * sp.sin(a), -l1 * sp.cos(a)
        x2, y2 = x1 + l2 * sp.sin(b), y1 - l2 * sp.cos(b)
        speed2 = [sp.diff(u, t) ** 2 + sp.diff(w, t) ** 2 for u, w in ((x1, y1), (x2, y2))]
        lag = big / 2 * v[0] ** 2 + m1 / 2 * speed2[0] + m2 / 2 * speed2[1]
        lag -= g * (m1 * y1 + m2 * y2)
    elif name == "spherical":
        m, length, g = s["m"], s["l"], s["g"]
        th, ph = q
        lag = m * length**2 / 2 * (v[0] ** 2 + sp.sin(th) ** 2 * v[1] ** 2)
        lag += m * g * length * sp.cos(th)
    else:  # the heavy symmetric top: Lagrange's top about its fixed tip
        m, h, a_in, c_in, g = (s[k] for k in ("m", "h", "A", "C", "g"))
        ph, th, ps = q
        lag = (a_in + m * h**2) / 2 * (v[1] ** 2 + v[0] ** 2 * sp.sin(th) ** 2)
        lag += c_in / 2 * (v[2] + v[0] * sp.cos(th)) ** 2 - m * g * h * sp.cos(th)
    return lag, q, t


SYSTEMS = {
    "elastic": elastic_pendulum,
    "cart": cart_double_pendulum,
    "spherical": spherical_pendulum,
    "top": heavy_top,
}


@pytest.fixture(scope="module")
def derived():
    """`(system, params, equations)` of each test system, derived once."""
    out = {}
    for name, make in SYSTEMS.items():
        system, params = make()
        out[name] = system, params, sym.equations(system, params)
    return out


@pytest.mark.parametrize("name", list(SYSTEMS))
def test_equations_match_sympy_lagranges_method(derived, name):
    _, _, eq = derived[name]
    lag, q, t = _sympy_lagrangian(name, eq)
    lm = LagrangesMethod(lag, q)
    lm.form_lagranges_equations()
    to_eq = {sp.diff(c, t, 2): a for c, a in zip(q, eq.qdd, strict=True)}
    to_eq.update({sp.diff(c, t): a for c, a in zip(q, eq.qd, strict=True)})
    to_eq.update(dict(zip(q, eq.q, strict=True)))
    mass = sp.Matrix(lm.mass_matrix).subs(to_eq)
    forcing = sp.Matrix(lm.forcing).subs(to_eq)
    # M q̈ = forcing  ⇔  M q̈ + (C q̇ + G) = 0
    for ours, theirs in ((eq.M, mass), (-(eq.coriolis + eq.G), forcing)):
        for a, b in zip(ours, theirs, strict=True):
            assert sp.simplify(a - b) == 0, (name, a, b)


# --------------------------------------------------------------------- the lecture's slide
@pytest.fixture(scope="module")
def three():
    return sym.derivations_2r()


@pytest.mark.parametrize("method", ["lagrange", "newton_euler", "kane"])
def test_the_slide_by_each_derivation(three, method):
    tau, slide = getattr(three, method), three.slide
    assert tau.shape == slide.shape == (2, 1)
    for got, want in zip(tau, slide, strict=True):
        assert sp.simplify(got - want) == 0, (method, got, want)


def test_the_slide_displayed(three):
    eq = three.equations
    th1, th2 = eq.q
    s = eq.symbols
    c2 = sp.cos(th2)
    # M, C q̇ and G as on the slide, entry by entry, as printed (not only equal)
    assert eq.M[0, 1] == s["I2"] + s["m2"] * s["r2"] ** 2 + s["m2"] * s["l1"] * s["r2"] * c2
    assert eq.M[1, 1] == s["I2"] + s["m2"] * s["r2"] ** 2
    w1, w2 = eq.qd
    c_term = -s["m2"] * s["l1"] * s["r2"] * sp.sin(th2) * (2 * w1 + w2) * w2
    assert eq.coriolis[0] == c_term
    assert eq.coriolis[1] == s["m2"] * s["l1"] * s["r2"] * sp.sin(th2) * w1**2
    assert eq.G[1] == s["m2"] * s["g"] * s["r2"] * sp.cos(th1 + th2)
    assert three.agree()
    latex = eq._repr_latex_()
    assert (
        latex.startswith("$$")
        and r"\ddot{\theta}_{1}" in latex
        and r"\cos{\left(\theta_{2}" in latex
    )
    assert sp.latex(eq.M).count(r"\cos{\left(\theta_{2} \right)}") == 3
    assert {"theta1", "thetadot_1", "thetaddot_2", "m1", "I2", "g", "t"} <= set(eq.symbols)
    assert all(eq.symbols[k].is_positive for k in ("m1", "l1", "r2", "I1", "g"))
    assert eq.q[0].is_real and not eq.q[0].is_positive


def test_christoffel_matrix_makes_mdot_minus_2c_skew(three):
    eq = three.equations
    m_dot = sum((eq.M.diff(a) * v for a, v in zip(eq.q, eq.qd, strict=True)), sp.zeros(2, 2))
    skew = m_dot - 2 * eq.C
    assert (skew + skew.T).applyfunc(sym.simplify) == sp.zeros(2, 2)
    assert (eq.C * eq.qd - eq.coriolis).applyfunc(sym.simplify) == sp.zeros(2, 1)


# ------------------------------------------------------------- numbers: lambdify and C
def _cart_pole():  # the README's example
    def kinetic(q, qd, p):
        v_bob_sq = qd[0] ** 2 + 2 * p["l"] * qd[0] * qd[1] * jnp.cos(q[1]) + (p["l"] * qd[1]) ** 2
        return 0.5 * p["M"] * qd[0] ** 2 + 0.5 * p["m"] * v_bob_sq

    def potential(q, p):
        return -p["m"] * p["g"] * p["l"] * jnp.cos(q[1])

    system = lx.LagrangianSystem(kinetic, potential, n_dof=2, name="cart-pole")
    return system, {"M": 1.0, "m": 0.3, "l": 0.5, "g": 9.81}


def _reeled_pendulum():  # time-dependent: l(t) = l0 + b sin(ν t)
    def position(t, q, p):
        length = p["l0"] + p["b"] * jnp.sin(p["nu"] * t)
        return jnp.stack([length * jnp.sin(q[0]), -length * jnp.cos(q[0])])

    def kinetic(t, q, qd, p):
        v = jax.jvp(lambda s, a: position(s, a, p), (t, q), (jnp.ones_like(t), qd))[1]
        return 0.5 * p["m"] * v @ v

    def potential(t, q, p):
        return p["m"] * p["g"] * position(t, q, p)[1]

    system = lx.LagrangianSystem(kinetic, potential, n_dof=1, time_dependent=True)
    return system, {"m": 0.7, "g": 9.81, "l0": 1.0, "b": 0.3, "nu": 2.0}


def _planar_chain():
    chain = lx.chains.PlanarChain(3)
    return chain.system(), chain.params(m=[1.0, 0.8, 0.5], l=[1.0, 0.9, 0.6])


def _spatial_chain():
    chain = lx.chains.SpatialChain("RR", axes=[(0, 0, 1), (0, 1, 0)])
    return chain.system(), chain.params(m=[1.0, 0.7])


NUMERIC = {
    "2R": (lx.models.planar_2r, {}),
    "cart-pole": (_cart_pole, {}),
    "msd": (lambda: lx.models.mass_spring_damper(c=0.3, f0=0.5, omega=2.0), {}),
    "reeled": (_reeled_pendulum, {}),
    "chain3": (_planar_chain, {}),
    "spatial": (_spatial_chain, {"numeric": ("offset", "com", "inertia")}),
    **{name: (make, {}) for name, make in SYSTEMS.items()},
}


@pytest.fixture(scope="module")
def lambdified(derived):
    out = {}
    for name, (make, options) in NUMERIC.items():
        system, params = make()
        eq = derived[name][2] if name in derived else sym.equations(system, params, **options)
        out[name] = system, params, eq, sym.lambdify(eq), sym.lambdify(eq, modules="jax")
    return out


def _all_parts(fns, params):
    """`q, qd, qdd, t -> (M, C q̇, C, G, τ)` of a system or of lambdified equations."""

    def parts(q, qd, qdd, t):
        return (
            fns.mass_matrix(q, params, t=t),
            fns.coriolis(q, qd, params, t=t),
            fns.coriolis_matrix(q, qd, params, t=t),
            fns.gravity(q, params, t=t),
            fns.inverse_dynamics(q, qd, qdd, params, t),
        )

    return parts


@pytest.mark.parametrize("name", list(NUMERIC))
def test_lambdified_equations_match_lagrax_numbers(lambdified, name):
    system, params, eq, np_fns, jax_fns = lambdified[name]
    reference = jax.jit(_all_parts(system, params))
    with_numpy, with_jax = _all_parts(np_fns, params), jax.jit(_all_parts(jax_fns, params))
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(4):
        q, qd, qdd = rng.uniform(-2, 2, (3, eq.n))
        t = float(rng.uniform(0, 3))
        if name == "elastic":
            q[0] = abs(q[0]) + 0.5  # a spring length
        want = reference(q, qd, qdd, t)
        for got in (with_numpy(q, qd, qdd, t), with_jax(q, qd, qdd, t)):
            for a, b in zip(got, want, strict=True):
                assert np.shape(a) == np.shape(b)
                scale = max(1.0, float(np.max(np.abs(b))))
                worst = max(worst, float(np.max(np.abs(np.asarray(a) - b))) / scale)
    assert worst < 1e-13, worst


def test_jax_functions_jit_and_vmap(lambdified):
    system, params, _, _, fns = lambdified["2R"]
    qs = jnp.asarray(np.random.default_rng(3).uniform(-2, 2, (8, 2)))
    got = jax.jit(jax.vmap(lambda q: fns.mass_matrix(q, params)))(qs)
    want = jax.vmap(lambda q: system.mass_matrix(q, params))(qs)
    assert float(jnp.max(jnp.abs(got - want))) < 1e-13


@pytest.mark.skipif(shutil.which("gcc") is None, reason="no C compiler (gcc) on this machine")
@pytest.mark.parametrize("name", ["2R", "reeled"])
def test_generated_c_compiles_and_matches(lambdified, name, tmp_path):
    system, params, eq, _, _ = lambdified[name]
    code = sym.c_code(eq, prefix="eom")
    c_path, _ = code.write(tmp_path)
    lib_path = tmp_path / "libeom.so"
    subprocess.run(
        [
            "gcc",
            "-std=c99",
            "-O2",
            "-Wall",
            "-Werror",
            "-shared",
            "-fPIC",
            "-o",
            str(lib_path),
            str(c_path),
            "-lm",
        ],
        check=True,
        capture_output=True,
    )
    lib = ctypes.CDLL(str(lib_path))
    ptr = ctypes.POINTER(ctypes.c_double)

    def buf(x):
        return np.ascontiguousarray(x, dtype=np.float64)

    timed = eq.tau.has(eq.t)
    p = buf(sym.parameter_vector(eq, params))
    rng = np.random.default_rng(5)
    n = eq.n
    for _ in range(5):
        q, qd, qdd = (buf(x) for x in rng.uniform(-2, 2, (3, n)))
        t = float(rng.uniform(0, 3))
        tau, mass = np.zeros(n), np.zeros((n, n))
        args = [x.ctypes.data_as(ptr) for x in (q, qd, qdd, p)]
        extra = [ctypes.c_double(t)] if timed else []
        lib.eom_inverse_dynamics(*args, *extra, tau.ctypes.data_as(ptr))
        mass_args = [q.ctypes.data_as(ptr), p.ctypes.data_as(ptr)]
        lib.eom_mass_matrix(*mass_args, *extra, mass.ctypes.data_as(ptr))
        want = np.asarray(system.inverse_dynamics(q, qd, qdd, params, t=t))
        np.testing.assert_allclose(tau, want, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(mass, system.mass_matrix(q, params, t=t), rtol=1e-13, atol=1e-13)
    assert code.functions["inverse_dynamics"] == "eom_inverse_dynamics"
    assert code.parameters == tuple(s.name for s in eq.parameters)
    assert "#include <math.h>" in code.source and "eom_gravity" in code.header


# ------------------------------------------------------------------------- the interpreter
def _custom_square(x):
    return x**2


_custom_square = jax.custom_jvp(_custom_square)
_custom_square.defjvp(lambda primals, tangents: (primals[0] ** 2, 2 * primals[0] * tangents[0]))


@jax.custom_vjp
def _custom_cube(x):
    return x**3


_custom_cube.defvjp(lambda x: (x**3, x), lambda x, g: (3 * x**2 * g,))


PROGRAMS = {
    "arithmetic": lambda x: x[0] / (1 + x[1] ** 2) - jnp.sqrt(2 + x[2]) + x[0] ** 3,
    "functions": lambda x: jnp.stack(
        [
            jnp.tan(x[0]),
            jnp.exp(x[1]),
            jnp.log1p(x[2] ** 2),
            jnp.tanh(x[0]),
            jax.lax.rsqrt(3 + x[1]),
            jnp.arctan2(x[0], 2 + x[1]),
            jnp.abs(x[2]),
            jnp.square(x[0]),
            jnp.expm1(x[1]),
            jnp.maximum(x[0], 0.5),
            jnp.power(2 + x[1], x[2]),
        ]
    ),
    "linear algebra": lambda x: jnp.outer(x, x) @ jnp.eye(3)[::-1] @ x + jnp.sum(x) * x,
    "shapes": lambda x: jnp.concatenate([x.reshape(3, 1).T.ravel(), x[1:], jnp.flip(x)]),
    "cumulative": lambda x: jnp.cumsum(x) * jnp.cumprod(x)[::-1] + jnp.prod(x),
    "indexing": lambda x: x[jnp.array([2, 0, 2])] + x[jnp.array(1)] + x.at[1].set(x[0])[:3],
    "branch on numbers": lambda x: jnp.where(jnp.arange(3) > 0, x, -x),
    "norm (jit)": lambda x: jnp.linalg.norm(x) * jnp.ones(1),
    "custom jvp": lambda x: _custom_square(x),
    "scan": lambda x: jax.lax.fori_loop(0, 4, lambda i, c: c * x + i, x),
    "while on numbers": lambda x: jax.lax.while_loop(
        lambda c: c[0] < 3, lambda c: (c[0] + 1, c[1] * x), (0, x)
    )[1],
    "cond on numbers": lambda x: jax.lax.cond(True, lambda y: y + 1, lambda y: y - 1, x),
    "pad": lambda x: jnp.pad(x, (1, 2)) * 2.0,
    "lax.map": lambda x: jax.lax.map(lambda a: a * jnp.cos(a), x),
    "checkpoint": jax.checkpoint(lambda x: jnp.sin(x) * x[0]),
    "custom vjp": lambda x: _custom_cube(x),
    "vmap": lambda x: jax.vmap(lambda a, b: a * b + 1)(x, x[::-1]),
}


@pytest.mark.parametrize("name", list(PROGRAMS))
def test_interpreter_matches_jax(name):
    fn = PROGRAMS[name]
    xs = sp.symbols("x0:3", real=True)
    out = sym.interpret(fn, np.array(xs, dtype=object))
    value = np.array([0.3, -0.7, 0.45])
    out = out if isinstance(out, sp.MatrixBase) else sp.Matrix([out])
    got = np.asarray(out.subs(dict(zip(xs, value, strict=True))).evalf(), float)
    want = np.asarray(fn(jnp.asarray(value)))
    np.testing.assert_allclose(got.reshape(want.shape), want, rtol=1e-13, atol=1e-14)


def test_interpret_takes_pytrees_and_keeps_numbers():
    th, length = sp.symbols("theta l", positive=True)
    out = sym.interpret(
        lambda q, p: {"tip": p["l"] * jnp.stack([jnp.sin(q), -jnp.cos(q)]), "k": p["k"] * q},
        th,
        {"l": length, "k": 0.5},
    )
    assert out["tip"] == sp.Matrix([length * sp.sin(th), -length * sp.cos(th)])
    assert out["k"] == th / 2  # 0.5 is exactly 1/2
    assert sym.interpret(lambda x: x * 0.1 + x * 0.2, th) == 3 * th / 10
    assert sym.simplify(sp.sin(th) ** 2 + sp.cos(th) ** 2) == 1
    assert sym.tree_size(th + 1) == 3
    assert "dot_general" in sym.supported_primitives()


def test_array_parameters_get_one_symbol_per_entry(lambdified):
    eq = lambdified["chain3"][2]
    names = [s.name for s in eq.parameters]
    assert names[:3] == ["m1", "m2", "m3"] and "I3" in names and names[-1] == "g"
    assert [s.name for s in eq.q] == ["q0", "q1", "q2"]
    assert eq.parameter_keys[1] == ("m", (1,))
    spatial = lambdified["spatial"][2]
    assert {s.name for s in spatial.parameters} == {"m1", "m2", "g"}  # the rest numeric


# ------------------------------------------------------------------------------ bad input
def _pendulum(kinetic=None, potential=None, n_dof=1):
    def plain(q, qd, p):
        return 0.5 * p["m"] * qd[0] ** 2

    return lx.LagrangianSystem(kinetic or plain, potential, n_dof=n_dof, name="bad")


def test_unmapped_primitive_is_named():
    def kinetic(q, qd, p):  # an eigenvalue: no closed form that SymPy would be sure of
        a = jnp.stack([jnp.stack([1 + q[0] ** 2, q[0]]), jnp.stack([q[0], 2.0 + 0 * q[0]])])
        return 0.5 * p["m"] * jnp.linalg.eigvalsh(a)[0] * qd[0] ** 2

    with pytest.raises(sym.UnsupportedPrimitiveError, match="primitive 'eigh'") as info:
        sym.equations(_pendulum(kinetic), {"m": 1.0})
    assert "kinetic" in str(info.value)
    assert isinstance(info.value, lx.LagraxError)


def test_stop_gradient_and_symbolic_branches_are_refused():
    def stopped(q, qd, p):
        return 0.5 * p["m"] * jax.lax.stop_gradient(1 + q[0] ** 2) * qd[0] ** 2

    with pytest.raises(sym.UnsupportedPrimitiveError, match="stop_gradient"):
        sym.equations(_pendulum(stopped), {"m": 1.0})

    def branched(q, p):
        return jnp.where(q[0] > 0, p["m"] * q[0], 0.0)

    with pytest.raises(sym.UnsupportedPrimitiveError, match="depends on q"):
        sym.equations(_pendulum(potential=branched), {"m": 1.0})


def test_expression_past_the_size_budget_names_its_size():
    k = jnp.arange(1, 1001)

    def kinetic(q, qd, p):  # a Fourier series of 1000 terms: 6,004 nodes
        return 0.5 * p["m"] * qd[0] ** 2 * (2 + jnp.sum(jnp.cos(k * q[0]) / k**2))

    match = r"kinetic energy T of 'bad' has 6,004 nodes, past the size budget max_size=5,000"
    with pytest.raises(sym.ExpressionSizeError, match=match):
        sym.equations(_pendulum(kinetic), {"m": 1.0}, max_size=5_000)


def test_non_polynomial_energy_past_the_time_budget():
    def kinetic(q, qd, p):
        weight = jnp.sqrt(1 + p["a"] * jnp.sin(q[0]) ** 2 + q[1] ** 2) * jnp.exp(
            jnp.cos(q[0] - q[1])
        )
        return (
            0.5 * p["m"] * (qd[0] ** 2 + qd[1] ** 2 + qd[0] * qd[1]) * weight / (2 + jnp.tanh(q[1]))
        )

    system = _pendulum(kinetic, n_dof=2)
    with pytest.raises(sym.ExpressionSizeError, match=r"timeout=0.5 s\) while working on"):
        sym.equations(system, {"m": 1.0, "a": 0.5}, timeout=0.5)
    # without simplification it is quick, and the expressions are still right
    eq = sym.equations(system, {"m": 1.0, "a": 0.5}, simplify=False)
    fns = sym.lambdify(eq)
    q = np.array([0.3, -0.4])
    np.testing.assert_allclose(
        fns.mass_matrix(q, {"m": 1.0, "a": 0.5}),
        system.mass_matrix(q, {"m": 1.0, "a": 0.5}),
        rtol=1e-13,
    )


def test_time_budget_interrupts_only_sympy():
    # The alarm raises only in SymPy's (or lagrax.symbolic's) code: raised in anything the
    # interpreter runs in between (a garbage-collector callback, a `__del__`), it would be
    # printed and dropped. Past the deadline, code here runs on; the next SymPy call stops.
    import time

    from lagrax._symbolic.simplification import Budget, Deadline

    x = sp.Symbol("x")
    deadline = Deadline(Budget(timeout=0.05))
    with pytest.raises(sym.ExpressionSizeError, match="time budget"):
        with deadline.running():
            end = time.perf_counter() + 0.4
            while time.perf_counter() < end:  # four alarms pass here
                pass
            survived = True
            while True:
                sp.expand((x + 1) ** 30)
    assert survived


class _Params(NamedTuple):
    m: float


@pytest.mark.parametrize(
    "params, match",
    [
        (_Params(1.0), "dict of numbers"),
        ({"m": {"inner": 1.0}}, r"params\['m'\] is dict"),
        ({"m": "heavy"}, r"params\['m'\] is str"),
        ({"m": 1.0 + 2.0j}, r"params\['m'\] is complex"),
    ],
)
def test_params_that_are_not_a_dict_of_numbers(params, match):
    with pytest.raises(lx.ArgumentTypeError, match=match):
        sym.equations(_pendulum(), params)


def test_other_bad_arguments():
    system, params = lx.models.cartesian_pendulum()
    with pytest.raises(lx.ArgumentTypeError, match="is a ConstrainedSystem"):
        sym.equations(system, params)
    with pytest.raises(lx.ArgumentTypeError, match="needs a lagrax.LagrangianSystem"):
        sym.equations(system.system.kinetic, params)
    with pytest.raises(lx.ConfigurationError, match="coordinates"):
        sym.equations(_pendulum(), {"m": 1.0}, coordinates=("x", "y"))
    with pytest.raises(lx.ConfigurationError, match="not keys of params"):
        sym.equations(_pendulum(), {"m": 1.0}, numeric=("mass",))
    with pytest.raises(lx.ConfigurationError, match="two symbols are named 'x'"):
        sym.equations(_pendulum(), {"m": 1.0, "x": 2.0}, coordinates=("x",))
    with pytest.raises(lx.ParameterError, match=r"reads params\['m'\], which params lacks"):
        sym.equations(_pendulum(), {"mass": 1.0})
    vector_energy = lx.LagrangianSystem(lambda q, qd, p: 0.5 * p["m"] * qd**2, n_dof=1)
    with pytest.raises(lx.ShapeError, match=r"kinetic energy T .* returns shape \(1,\)"):
        sym.equations(vector_energy, {"m": 1.0})
    eq = sym.equations(_pendulum(), {"m": 1.0})
    with pytest.raises(lx.ConfigurationError, match="numpy"):
        sym.lambdify(eq, modules="torch")
    with pytest.raises(lx.ConfigurationError, match="C identifier"):
        sym.c_code(eq, prefix="my arm")


def test_import_lagrax_does_not_import_sympy():
    code = "import sys, lagrax; assert 'sympy' not in sys.modules; lagrax.symbolic.equations"
    subprocess.run([sys.executable, "-c", code], check=True)


def test_missing_sympy_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "sympy", None)  # `import sympy` now raises ImportError
    with pytest.raises(sym.SympyMissingError, match=r'pip install "lagrax\[symbolic\]"'):
        sym.equations(_pendulum(), {"m": 1.0})


# ------------------------------------------------- constrained systems: refused, by parts


def _disk_pose(q, p):
    """A thin disk rolling on z = 0: q = (x, y, ψ, θ, φ) the contact point, yaw, lean and
    spin; orientation Rz(ψ) Rx(θ) Ry(φ), centre R above the contact along the lean frame's
    z axis (the model of tests/test_steady_linearization.py)."""

    def rot(axis, a):
        c, s = jnp.cos(a), jnp.sin(a)
        one, zero = 1.0 + 0.0 * a, 0.0 * a
        rows = {
            0: [[one, zero, zero], [zero, c, -s], [zero, s, c]],
            1: [[c, zero, s], [zero, one, zero], [-s, zero, c]],
            2: [[c, -s, zero], [s, c, zero], [zero, zero, one]],
        }[axis]
        return jnp.stack([jnp.stack(r) for r in rows])

    lean = rot(2, q[2]) @ rot(0, q[3])
    return jnp.stack([q[0], q[1], 0.0 * q[0]]) + p["R"] * lean[:, 2], lean @ rot(1, q[4])


def _disk_no_slip(q, p):
    """The contact point's horizontal material velocity `v_C + ω × (r_P − r_C)` as rows
    of `A(q)`: the rotation's derivative by `jax.jacfwd`."""
    centre, rot = _disk_pose(q, p)
    d_centre, d_rot = jax.jacfwd(lambda a: _disk_pose(a, p))(q)
    arm = jnp.stack([q[0], q[1], 0.0 * q[0]]) - centre
    return (d_centre + jnp.einsum("abj,cb,c->aj", d_rot, rot, arm))[:2]


def test_constrained_system_is_refused_and_its_parts_match_sympy():
    """The rolling disk: `equations` refuses it by name; its no-slip constraint `A(q)`,
    interpreted, equals the velocity constraints SymPy's KanesMethod is given for the same
    disk (contact velocity by `v2pt` kinematics) and the hand-derived rows."""
    me = pytest.importorskip("sympy.physics.mechanics")
    inertia = lambda p: p["m"] * p["R"] ** 2 * jnp.diag(jnp.array([0.25, 0.5, 0.25]))  # noqa: E731
    free = Scene([SpatialBody(Param("m"), inertia, _disk_pose, None)], gravity=Param("g"), n_dof=5)
    disk = lx.ConstrainedSystem(free.system(), velocity_constraints=_disk_no_slip, name="disk")
    params = {"m": 2.0, "R": 0.3, "g": 9.81}
    with pytest.raises(sym.ConstrainedSystemError, match=r"disk is a ConstrainedSystem.*interpret"):
        sym.equations(disk, params)
    assert issubclass(sym.ConstrainedSystemError, lx.ArgumentTypeError)

    q = me.dynamicsymbols("x y psi theta phi")
    u = me.dynamicsymbols("u1:6")
    r = sp.Symbol("R", positive=True)
    n = me.ReferenceFrame("N")
    lean = n.orientnew("Y", "Axis", [q[2], n.z])
    lean = lean.orientnew("L", "Axis", [q[3], lean.x])
    wheel = lean.orientnew("D", "Axis", [q[4], lean.y])
    to_u = {a.diff(): b for a, b in zip(q, u, strict=True)}
    wheel.set_ang_vel(n, wheel.ang_vel_in(n).subs(to_u))
    origin = me.Point("O")
    origin.set_vel(n, 0)
    centre = origin.locatenew("C", q[0] * n.x + q[1] * n.y + r * lean.z)
    centre.set_vel(n, centre.pos_from(origin).dt(n).subs(to_u))
    contact = me.Point("P")
    contact.set_pos(centre, -r * lean.z)
    contact.v2pt_theory(centre, n, wheel)
    rows = [contact.vel(n).dot(axis) for axis in (n.x, n.y)]
    expected = sp.Matrix([[sp.diff(row, b) for b in u] for row in rows])

    names = sp.symbols("x y psi theta phi", real=True)
    to_plain = dict(zip(q, names, strict=True))
    got = sp.Matrix(sym.interpret(_disk_no_slip, sp.Matrix(names), {"R": r}))
    zero = sp.zeros(2, 5)
    assert (got - expected.xreplace(to_plain)).applyfunc(sym.simplify) == zero
    # and by hand: the contact moves with the spin only, ẋ = R cos ψ φ̇, ẏ = R sin ψ φ̇
    psi = names[2]
    by_hand = sp.Matrix([[1, 0, 0, 0, -r * sp.cos(psi)], [0, 1, 0, 0, -r * sp.sin(psi)]])
    assert (got - by_hand).applyfunc(sym.simplify) == zero
