"""Time-dependent (rheonomic) energies and Lagrangians with terms linear in q̇.

References, none of which goes through lagrax's derivatives:

- SymPy's ``LagrangesMethod`` with explicit ``t`` (a pendulum whose length is reeled in
  and out, a bead on a hoop spun at a prescribed ``ω(t)``), lambdified to NumPy, and
  integrated by SciPy's ``solve_ivp`` (DOP853) at tight tolerance;
- the Kapitza pendulum (vertically driven support) reduced by hand to an autonomous
  pendulum with a time-dependent applied force;
- closed forms: ``M(t) = m l(t)²``; the Larmor circle of a charge in a uniform magnetic
  field; the Jacobi integral of a hoop spun at constant ``ω``.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp
from sympy.physics.mechanics import LagrangesMethod, dynamicsymbols

import lagrax as lx


def _lambdified(lagrangian, coords, t, params):
    """``q̈(t, q, q̇, *params)`` and ``M(t, q, *params)`` of a SymPy Lagrangian."""
    lm = LagrangesMethod(lagrangian, coords)
    lm.form_lagranges_equations()
    speeds = [sp.diff(c, t) for c in coords]
    qs = sp.symbols(f"q0:{len(coords)}")
    us = sp.symbols(f"u0:{len(coords)}")
    subs = {**dict(zip(speeds, us, strict=True)), **dict(zip(coords, qs, strict=True))}
    mass = sp.Matrix(lm.mass_matrix).subs(subs)
    rhs = sp.Matrix(lm.mass_matrix).LUsolve(sp.Matrix(lm.forcing)).subs(subs)
    args = (t, qs, us, *params)
    return sp.lambdify(args, list(rhs), "numpy"), sp.lambdify(args, mass, "numpy")


# --------------------------------------------------------------------------- reeled pendulum
#   l(t) = l0 + b sin(ν t): time enters the mass matrix M(t) = m l(t)²
REEL = {"m": 0.7, "g": 9.81, "l0": 1.0, "b": 0.3, "nu": 2.0}


def _reel_position(t, q, p):
    length = p["l0"] + p["b"] * jnp.sin(p["nu"] * t)
    return jnp.stack([length * jnp.sin(q[0]), -length * jnp.cos(q[0])])


def _reel_kinetic(t, q, qd, p):
    v = jax.jvp(lambda s, a: _reel_position(s, a, p), (t, q), (jnp.ones_like(t), qd))[1]
    return 0.5 * p["m"] * v @ v


def _reel_potential(t, q, p):
    return p["m"] * p["g"] * _reel_position(t, q, p)[1]


@pytest.fixture(scope="module")
def reel():
    system = lx.LagrangianSystem(_reel_kinetic, _reel_potential, n_dof=1, time_dependent=True)
    t = dynamicsymbols._t
    th = dynamicsymbols("theta")
    m, g, l0, b, nu = sp.symbols("m g l0 b nu")
    length = l0 + b * sp.sin(nu * t)
    x, y = length * sp.sin(th), -length * sp.cos(th)
    lag = m / 2 * (sp.diff(x, t) ** 2 + sp.diff(y, t) ** 2) - m * g * y
    qdd, mass = _lambdified(lag, [th], t, (m, g, l0, b, nu))
    fd = jax.jit(lambda q, qd, t: system.forward_dynamics(q, qd, REEL, t=t))
    return system, fd, qdd, mass


def test_reeled_pendulum_equations_match_sympy(reel):
    system, fd, qdd_ref, mass_ref = reel
    rng = np.random.default_rng(0)
    pv = tuple(REEL[k] for k in ("m", "g", "l0", "b", "nu"))
    worst = 0.0
    for _ in range(20):
        t, q, qd = rng.uniform(0, 5), rng.uniform(-2, 2, 1), rng.uniform(-3, 3, 1)
        ref = np.asarray(qdd_ref(t, q, qd, *pv), float)
        worst = max(worst, float(np.max(np.abs(fd(q, qd, t) - ref))))
        # closed form M(t) = m l(t)², against SymPy too
        length = REEL["l0"] + REEL["b"] * np.sin(REEL["nu"] * t)
        mass = np.asarray(system.mass_matrix(q, REEL, t=t))
        np.testing.assert_allclose(mass, [[REEL["m"] * length**2]], rtol=1e-14)
        np.testing.assert_allclose(mass, np.asarray(mass_ref(t, q, qd, *pv), float), rtol=1e-14)
    assert worst < 1e-12


def test_reeled_pendulum_inverse_dynamics_and_vector_path(reel):
    system, fd, _, _ = reel
    vector = lx.LagrangianSystem(
        _reel_kinetic, _reel_potential, n_dof=1, time_dependent=True, scalar_derivatives=False
    )
    q, qd, t = jnp.array([0.4]), jnp.array([-1.1]), 1.3
    qdd = fd(q, qd, t)
    np.testing.assert_allclose(vector.forward_dynamics(q, qd, REEL, t=t), qdd, rtol=1e-13)
    tau = system.inverse_dynamics(q, qd, qdd, REEL, t=t)
    assert float(jnp.max(jnp.abs(tau))) < 1e-13
    # at another time the same state accelerates differently (t is really read)
    assert abs(float(fd(q, qd, t + 0.5)[0] - qdd[0])) > 1e-2


def test_reeled_pendulum_simulation_matches_scipy(reel):
    system, _, qdd_ref, _ = reel
    pv = tuple(REEL[k] for k in ("m", "g", "l0", "b", "nu"))
    ts = np.linspace(0.0, 5.0, 201)
    sol = lx.simulate(
        system, [0.5], [0.0], REEL, t1=5.0, ts=ts, solver="dopri8", rtol=1e-12, atol=1e-12
    )

    def rhs(t, y):
        return [y[1], float(qdd_ref(t, y[:1], y[1:], *pv)[0])]

    ref = solve_ivp(rhs, (0.0, 5.0), [0.5, 0.0], method="DOP853", t_eval=ts, rtol=1e-13, atol=1e-13)
    assert np.max(np.abs(np.asarray(sol.q[:, 0]) - ref.y[0])) < 1e-9
    assert np.max(np.abs(np.asarray(sol.qd[:, 0]) - ref.y[1])) < 1e-9
    # the reel does work: h changes by O(1), and the balance h − h0 − W closes (W by a
    # sixth-order quadrature over the saves: 5e-11 with these 201)
    assert float(jnp.max(jnp.abs(sol.energy_change))) > 0.1
    assert float(jnp.max(jnp.abs(sol.energy_error))) < 1e-9


# --------------------------------------------------------------------------- Kapitza
#   support at height a cos(Ω t): explicit t in T and V, against the pendulum in the
#   support's (accelerating) frame, where the support motion is a force
KAPITZA = {"m": 1.0, "g": 9.81, "l": 1.0, "a": 0.1, "Om": 60.0}


def _kapitza_position(t, q, p):
    support = p["a"] * jnp.cos(p["Om"] * t)
    return jnp.stack([p["l"] * jnp.sin(q[0]), support - p["l"] * jnp.cos(q[0])])


def _kapitza_kinetic(t, q, qd, p):
    v = jax.jvp(lambda s, a: _kapitza_position(s, a, p), (t, q), (jnp.ones_like(t), qd))[1]
    return 0.5 * p["m"] * v @ v


def _kapitza_potential(t, q, p):
    return p["m"] * p["g"] * _kapitza_position(t, q, p)[1]


def _reduced_force(t, q, qd, p):
    # −m l ÿ_s sin θ with ÿ_s = −a Ω² cos Ω t
    return jnp.stack(
        [p["m"] * p["l"] * p["a"] * p["Om"] ** 2 * jnp.cos(p["Om"] * t) * jnp.sin(q[0])]
    )


@pytest.fixture(scope="module")
def kapitza():
    timed = lx.LagrangianSystem(
        _kapitza_kinetic, _kapitza_potential, n_dof=1, time_dependent=True, name="kapitza"
    )
    reduced = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * p["m"] * p["l"] ** 2 * qd[0] ** 2,
        lambda q, p: -p["m"] * p["g"] * p["l"] * jnp.cos(q[0]),
        force=_reduced_force,
        n_dof=1,
    )
    return timed, reduced


def test_kapitza_equations_match_hand_reduction(kapitza):
    timed, reduced = kapitza
    rng = np.random.default_rng(1)
    for _ in range(10):
        t, q, qd = rng.uniform(0, 2), rng.uniform(-4, 4, 1), rng.uniform(-5, 5, 1)
        a = timed.forward_dynamics(q, qd, KAPITZA, t=t)
        b = reduced.forward_dynamics(q, qd, KAPITZA, t=t)
        assert float(jnp.max(jnp.abs(a - b))) < 1e-12 * max(1.0, float(jnp.max(jnp.abs(b))))


def test_kapitza_inverted_pendulum_is_stabilized(kapitza):
    timed, reduced = kapitza
    kw = dict(t1=2.0, n_save=2001, rtol=1e-11, atol=1e-11)
    sol = lx.simulate(timed, [np.pi - 0.1], [0.0], KAPITZA, **kw)
    ref = lx.simulate(reduced, [np.pi - 0.1], [0.0], KAPITZA, **kw)
    assert float(jnp.max(jnp.abs(sol.q - ref.q))) < 1e-8
    # a^2 Ω^2 = 36 > 2 g l: the upside-down pendulum stays up
    assert float(jnp.max(jnp.abs(sol.q[:, 0] - np.pi))) < 0.25
    # the support pumps energy in and out (O(10)); the balance closes to the tolerance
    assert float(jnp.max(jnp.abs(sol.energy_change))) > 1.0
    assert float(jnp.max(jnp.abs(sol.energy_error))) < 1e-8
    # the hand reduction's inertial force F does work too: its balance closes as well
    assert sol.work is not None and ref.work is not None
    assert float(jnp.max(jnp.abs(ref.energy_error))) < 1e-8


# --------------------------------------------------------------------------- spun hoop
#   a bead on a hoop of radius R spun about the vertical axis by φ(t)
HOOP = {"m": 0.3, "g": 9.81, "R": 0.5, "w0": 4.0, "alpha": 0.0}


def _hoop_position(t, q, p):
    phi = p["w0"] * t + 0.5 * p["alpha"] * t**2
    s = jnp.sin(q[0])
    return p["R"] * jnp.stack([s * jnp.cos(phi), s * jnp.sin(phi), -jnp.cos(q[0])])


def _hoop_kinetic(t, q, qd, p):
    v = jax.jvp(lambda s, a: _hoop_position(s, a, p), (t, q), (jnp.ones_like(t), qd))[1]
    return 0.5 * p["m"] * v @ v


def _hoop_potential(t, q, p):
    return p["m"] * p["g"] * _hoop_position(t, q, p)[2]


@pytest.fixture(scope="module")
def hoop():
    return lx.LagrangianSystem(_hoop_kinetic, _hoop_potential, n_dof=1, time_dependent=True)


def test_spun_hoop_equations_match_sympy(hoop):
    t = dynamicsymbols._t
    th = dynamicsymbols("theta")
    m, g, r, w0, alpha = sp.symbols("m g R w0 alpha")
    phi = w0 * t + alpha * t**2 / 2
    pos = [r * sp.sin(th) * sp.cos(phi), r * sp.sin(th) * sp.sin(phi), -r * sp.cos(th)]
    lag = m / 2 * sum(sp.diff(c, t) ** 2 for c in pos) - m * g * pos[2]
    qdd_ref, _ = _lambdified(lag, [th], t, (m, g, r, w0, alpha))
    p = dict(HOOP, alpha=1.5)  # ω(t) = w0 + α t: ∂L/∂t ≠ 0
    rng = np.random.default_rng(2)
    for _ in range(10):
        s, q, qd = rng.uniform(0, 3), rng.uniform(-3, 3, 1), rng.uniform(-4, 4, 1)
        ref = np.asarray(qdd_ref(s, q, qd, *(p[k] for k in ("m", "g", "R", "w0", "alpha"))))
        got = hoop.forward_dynamics(q, qd, p, t=s)
        assert abs(float(got[0]) - float(ref[0])) < 1e-12 * max(1.0, abs(float(ref[0])))


def test_spun_hoop_jacobi_integral(hoop):
    p = HOOP  # constant ω: ∂L/∂t = 0, h conserved, T + V not
    sol = lx.simulate(hoop, [0.3], [0.0], p, t1=5.0, rtol=1e-10, atol=1e-10)
    q, qd = np.asarray(sol.q[:, 0]), np.asarray(sol.qd[:, 0])
    m, g, r, w = p["m"], p["g"], p["R"], p["w0"]
    h_ref = 0.5 * m * r**2 * (qd**2 - w**2 * np.sin(q) ** 2) - m * g * r * np.cos(q)
    np.testing.assert_allclose(np.asarray(sol.energy), h_ref, rtol=1e-13, atol=1e-14)
    assert float(jnp.max(jnp.abs(sol.work))) < 1e-12
    assert float(jnp.max(jnp.abs(sol.energy_error))) < 1e-8
    e_total = [float(hoop.energy(sol.q[i], sol.qd[i], p, t=sol.ts[i])) for i in (0, 100)]
    assert abs(e_total[1] - e_total[0]) > 1e-3  # T + V is not conserved
    # spun up (α > 0) the motor does work on the bead: the balance still closes
    spun = lx.simulate(hoop, [0.3], [0.0], dict(p, alpha=0.5), t1=5.0, rtol=1e-10, atol=1e-10)
    assert float(jnp.max(jnp.abs(spun.energy_change))) > 0.1
    assert float(jnp.max(jnp.abs(spun.energy_error))) < 1e-8
    # C q̇ is the velocity-product part of coriolis: coriolis(q, 0) = −∂T₀/∂q is not
    q0, qd0 = jnp.array([0.7]), jnp.array([1.3])
    c_mat = hoop.coriolis_matrix(q0, qd0, p, t=0.4)
    lhs = c_mat @ qd0
    rhs = hoop.coriolis(q0, qd0, p, t=0.4) - hoop.coriolis(q0, jnp.zeros(1), p, t=0.4)
    np.testing.assert_allclose(lhs, rhs, atol=1e-13)


# --------------------------------------------------------------------------- charge in B
#   T = ½ m |v|² + e A·v with A = (B/2)(−y, x): a uniform field B along z
CHARGE = {"m": 2.0, "e": 1.5, "B": 0.8}


@pytest.fixture(scope="module")
def charge():
    def kinetic(q, qd, p):
        a = 0.5 * p["B"] * jnp.stack([-q[1], q[0]])
        return 0.5 * p["m"] * qd @ qd + p["e"] * a @ qd

    return lx.LagrangianSystem(kinetic, n_dof=2, name="charge")


def test_charge_larmor_circle_and_jacobi_integral(charge):
    p = CHARGE
    omega = p["e"] * p["B"] / p["m"]
    v0 = 1.2
    t1 = 5 * 2 * np.pi / omega  # five cyclotron periods
    sol = lx.simulate(charge, [0.0, 0.0], [v0, 0.0], p, t1=t1, rtol=1e-11, atol=1e-11)
    ts = np.asarray(sol.ts)
    x = v0 / omega * np.sin(omega * ts)
    y = v0 / omega * (np.cos(omega * ts) - 1.0)
    assert np.max(np.abs(np.asarray(sol.q) - np.stack([x, y], 1))) < 1e-8
    # h = ½ m v² is conserved; T + V (with the e A·v term) is not
    np.testing.assert_allclose(np.asarray(sol.energy), 0.5 * p["m"] * v0**2, rtol=1e-9)
    assert float(jnp.max(jnp.abs(sol.energy_error))) < 1e-8
    assert sol.work is None
    e_total = np.array([float(charge.energy(sol.q[i], sol.qd[i], p)) for i in range(0, 500, 50)])
    assert np.ptp(e_total) > 0.1


def test_charge_coriolis_matrix_is_the_lorentz_force(charge):
    p = CHARGE
    q, qd = jnp.array([0.3, -0.7]), jnp.array([1.1, 0.4])
    c_mat = charge.coriolis_matrix(q, qd, p)
    lorentz = p["e"] * p["B"] * jnp.array([qd[1], -qd[0]])  # e v × B; C q̇ is its negative
    np.testing.assert_allclose(charge.coriolis(q, qd, p), -lorentz, rtol=1e-14)
    np.testing.assert_allclose(c_mat @ qd, charge.coriolis(q, qd, p), rtol=1e-14)
    np.testing.assert_allclose(c_mat, -c_mat.T, atol=1e-15)  # M constant: C is skew
    np.testing.assert_allclose(
        charge.jacobi_integral(0.0, q, qd, p), 0.5 * p["m"] * qd @ qd, rtol=1e-15
    )


# --------------------------------------------------------------------------- bad input
def test_time_dependent_system_refuses_autonomous_energies():
    with pytest.raises(lx.ArgumentTypeError, match=r"time_dependent=True.*T\(t, q, qd, params\)"):
        lx.LagrangianSystem(lambda q, qd, p: qd @ qd, time_dependent=True)
    with pytest.raises(lx.ArgumentTypeError, match=r"V\(t, q, params\)"):
        lx.LagrangianSystem(lambda t, q, qd, p: qd @ qd, lambda q, p: q[0], time_dependent=True)
    with pytest.raises(lx.ArgumentTypeError, match="time_dependent must be True or False"):
        lx.LagrangianSystem(lambda t, q, qd, p: qd @ qd, time_dependent=1)  # type: ignore[arg-type]


def test_autonomous_system_given_a_timed_energy_says_so():
    system = lx.LagrangianSystem(_reel_kinetic, n_dof=1)
    with pytest.raises(lx.ArgumentTypeError, match=r"one more: the time\?.*time_dependent=True"):
        system.forward_dynamics(jnp.array([0.1]), jnp.array([0.2]), REEL)
    # ... also at trace time under jit
    with pytest.raises(lx.ArgumentTypeError, match="time_dependent=True"):
        jax.jit(lambda q: system.mass_matrix(q, REEL))(jnp.array([0.1]))


def test_time_dependent_system_refuses_chain_equations():
    chain, _ = lx.chains.planar_chain(4)  # 4 links and up: Featherstone's recursions
    assert chain.equations is not None
    with pytest.raises(lx.ConfigurationError, match="equations=None"):
        lx.LagrangianSystem(
            lambda t, q, qd, p: qd @ qd, equations=chain.equations, time_dependent=True
        )
