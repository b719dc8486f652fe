"""Equations of motion: lagrax's autodiff Lagrangian against independent derivations.

Oracles used here, none of which goes through ``LagrangianSystem``:

- the lecture's closed-form 2R torques, mass matrix, Coriolis and gravity terms (written
  out below in NumPy);
- the free-body Newton–Euler derivation in ``lagrax.newton_euler`` (no Lagrangian);
- for a hand-written 3-link pendulum and 7/9-DOF chains: a mass matrix assembled from
  link Jacobians (or given explicitly), Coriolis terms from Christoffel symbols of that
  matrix, and ``jnp.linalg.solve``.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from jax.test_util import check_grads

import lagrax
from lagrax.models import _planar_2r as arm_model

ARM, ARM_PARAMS = lagrax.models.planar_2r()
PARAM_NAMES = ("m1", "m2", "l1", "l2", "r1", "r2", "I1", "I2", "g")

# Compiled once for the whole module; params travel as a dict of floats, so new values
# do not retrace.
_inverse = jax.jit(lambda q, qd, qdd, p: ARM.inverse_dynamics(q, qd, qdd, p))
_newton_euler = jax.jit(lagrax.newton_euler.planar_2r)
_forward = jax.jit(lambda q, qd, p, tau: ARM.forward_dynamics(q, qd, p, tau))
_mass = jax.jit(lambda q, p: ARM.mass_matrix(q, p))
_coriolis = jax.jit(lambda q, qd, p: ARM.coriolis(q, qd, p))
_coriolis_matrix = jax.jit(lambda q, qd, p: ARM.coriolis_matrix(q, qd, p))
_mass_dot = jax.jit(lambda q, qd, p: jax.jvp(lambda a: ARM.mass_matrix(a, p), (q,), (qd,))[1])
_gravity = jax.jit(lambda q, p: ARM.gravity(q, p))
_grad_potential = jax.jit(jax.grad(lambda q, p: ARM.potential_energy(q, p)))


# --------------------------------------------------------------------------- closed form
def closed_form_terms(q, qd, p):
    """The lecture's 2R arm: ``M(q)``, ``C(q, q̇) q̇``, Christoffel ``C`` and ``G(q)``."""
    c1, c2, s2, c12 = np.cos(q[0]), np.cos(q[1]), np.sin(q[1]), np.cos(q[0] + q[1])
    m1, m2, l1, r1, r2, i1, i2, g = (p[k] for k in ("m1", "m2", "l1", "r1", "r2", "I1", "I2", "g"))
    m11 = i1 + i2 + m1 * r1**2 + m2 * (l1**2 + r2**2 + 2 * l1 * r2 * c2)
    m12 = i2 + m2 * (r2**2 + l1 * r2 * c2)
    m22 = i2 + m2 * r2**2
    mass = np.array([[m11, m12], [m12, m22]])
    h = m2 * l1 * r2 * s2
    cor = np.array([-h * (2 * qd[0] + qd[1]) * qd[1], h * qd[0] ** 2])
    cmat = np.array([[-h * qd[1], -h * (qd[0] + qd[1])], [h * qd[0], 0.0]])
    grav = np.array([m1 * g * r1 * c1 + m2 * g * (l1 * c1 + r2 * c12), m2 * g * r2 * c12])
    return mass, cor, cmat, grav


def closed_form_tau(q, qd, qdd, p):
    """τ of the lecture and the size of its largest terms (the scale of rounding errors)."""
    c1, c2, s2, c12 = np.cos(q[0]), np.cos(q[1]), np.sin(q[1]), np.cos(q[0] + q[1])
    m1, m2, l1, r1, r2, i1, i2, g = (p[k] for k in ("m1", "m2", "l1", "r1", "r2", "I1", "I2", "g"))
    terms1 = [
        (i1 + i2 + m1 * r1**2 + m2 * (l1**2 + r2**2 + 2 * l1 * r2 * c2)) * qdd[0],
        (i2 + m2 * (r2**2 + l1 * r2 * c2)) * qdd[1],
        -m2 * l1 * r2 * s2 * (2 * qd[0] + qd[1]) * qd[1],
        m1 * g * r1 * c1,
        m2 * g * (l1 * c1 + r2 * c12),
    ]
    terms2 = [
        (i2 + m2 * (r2**2 + l1 * r2 * c2)) * qdd[0],
        (i2 + m2 * r2**2) * qdd[1],
        m2 * l1 * r2 * s2 * qd[0] ** 2,
        m2 * g * r2 * c12,
    ]
    tau = np.array([sum(terms1), sum(terms2)])
    scale = max(sum(map(abs, terms1)), sum(map(abs, terms2)), 1.0)
    return tau, scale


def closed_form_energy(q, qd, p):
    mass, _, _, _ = closed_form_terms(q, qd, p)
    s1, s12 = np.sin(q[0]), np.sin(q[0] + q[1])
    kin = 0.5 * qd @ mass @ qd
    pot = p["g"] * (p["m1"] * p["r1"] * s1 + p["m2"] * (p["l1"] * s1 + p["r2"] * s12))
    return kin, pot


def closed_form_qdd(q, qd, p, tau):
    mass, cor, _, grav = closed_form_terms(q, qd, p)
    return np.linalg.solve(mass, tau - cor - grav)


# --------------------------------------------------------------------------- strategies
def _f(lo, hi):
    return st.floats(lo, hi, allow_nan=False, allow_infinity=False)


@st.composite
def arm_params(draw):
    l1, l2 = draw(_f(0.1, 3.0)), draw(_f(0.1, 3.0))
    return {
        "m1": draw(_f(0.05, 10.0)),
        "m2": draw(_f(0.05, 10.0)),
        "l1": l1,
        "l2": l2,
        "r1": l1 * draw(_f(0.05, 0.95)),
        "r2": l2 * draw(_f(0.05, 0.95)),
        "I1": draw(_f(0.01, 5.0)),
        "I2": draw(_f(0.01, 5.0)),
        "g": draw(_f(0.0, 20.0)),
    }


def vec(lo, hi, n=2):
    return st.lists(_f(lo, hi), min_size=n, max_size=n).map(np.array)


angles = vec(-2 * np.pi, 2 * np.pi)
rates = vec(-5.0, 5.0)
accels = vec(-20.0, 20.0)


# --------------------------------------------------------------------------- (1) torques
@given(arm_params(), angles, rates, accels)
def test_inverse_dynamics_matches_newton_euler_and_closed_form(p, q, qd, qdd):
    tau_cf, scale = closed_form_tau(q, qd, qdd, p)
    tau_lag = np.asarray(_inverse(q, qd, qdd, p))
    tau_ne = np.asarray(_newton_euler(q, qd, qdd, p))
    atol = 1e-12 * scale
    np.testing.assert_allclose(tau_lag, tau_cf, rtol=0, atol=atol)
    np.testing.assert_allclose(tau_ne, tau_cf, rtol=0, atol=atol)
    np.testing.assert_allclose(tau_lag, tau_ne, rtol=0, atol=atol)


@given(arm_params(), angles, rates, accels)
def test_forward_dynamics_matches_closed_form(p, q, qd, qdd):
    tau, scale = closed_form_tau(q, qd, qdd, p)
    qdd_lag = np.asarray(_forward(q, qd, p, tau))
    expected = closed_form_qdd(q, qd, p, tau)
    np.testing.assert_allclose(qdd_lag, expected, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(qdd_lag, qdd, rtol=1e-9, atol=1e-9)


def test_inverse_dynamics_eager_matches_lecture_example(arm):
    system, params = arm
    p = {k: float(v) for k, v in params.items()}
    q, qd, qdd = np.array([0.3, -1.1]), np.array([0.7, 1.9]), np.array([-2.0, 0.5])
    tau_cf, scale = closed_form_tau(q, qd, qdd, p)
    tau = system.inverse_dynamics(q, qd, qdd, params)
    assert tau.shape == (2,) and tau.dtype == jnp.float64
    np.testing.assert_allclose(tau, tau_cf, rtol=0, atol=1e-13 * scale)


# --------------------------------------------------------------------------- (2) mass matrix
@given(arm_params(), angles)
def test_mass_matrix_spd_and_closed_form(p, q):
    mass = np.asarray(_mass(q, p))
    expected, _, _, _ = closed_form_terms(q, np.zeros(2), p)
    scale = np.max(np.abs(expected))
    assert mass.shape == (2, 2)
    np.testing.assert_allclose(mass, mass.T, rtol=0, atol=1e-14 * scale)
    assert np.all(np.linalg.eigvalsh(mass) > 0)
    np.testing.assert_allclose(mass, expected, rtol=1e-12, atol=1e-13 * scale)


def test_mass_matrix_independent_of_qd(arm):
    system, params = arm
    q = jnp.array([0.4, 1.3])
    m0 = system.mass_matrix(q, params)
    m1 = system.mass_matrix(q, params, qd=jnp.array([3.0, -7.0]))
    np.testing.assert_allclose(m1, m0, rtol=1e-13, atol=1e-13)


# --------------------------------------------------------------------------- (3) Coriolis
@given(arm_params(), angles, rates)
def test_coriolis_matrix_christoffel_and_skew(p, q, qd):
    _, cor_cf, cmat_cf, _ = closed_form_terms(q, qd, p)
    scale = max(np.max(np.abs(cmat_cf)), 1.0) * max(np.max(np.abs(qd)), 1.0)
    cmat = np.asarray(_coriolis_matrix(q, qd, p))
    cor = np.asarray(_coriolis(q, qd, p))
    m_dot = np.asarray(_mass_dot(q, qd, p))
    # Ṁ against the closed form: d/dt M = ∂M/∂θ2 θ̇2
    h = p["m2"] * p["l1"] * p["r2"] * np.sin(q[1])
    np.testing.assert_allclose(
        m_dot, np.array([[-2 * h, -h], [-h, 0.0]]) * qd[1], rtol=0, atol=1e-12 * scale
    )
    skew = m_dot - 2 * cmat
    np.testing.assert_allclose(skew, -skew.T, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(cmat, cmat_cf, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(cmat @ qd, cor, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(cor, cor_cf, rtol=0, atol=1e-12 * scale)


# --------------------------------------------------------------------------- (4) round trip
def _dissipation(q, qd, p):
    return 0.5 * p["c"] * jnp.sum(qd**2) + 0.25 * p["c2"] * qd[0] ** 2 * (1 + jnp.sin(q[1]) ** 2)


def _force(t, q, qd, p):
    return jnp.stack([p["fa"] * jnp.cos(3 * t) - p["fk"] * q[0], p["fa"] * jnp.sin(t) * qd[0]])


DAMPED = lagrax.LagrangianSystem(
    arm_model.kinetic, arm_model.potential, _dissipation, _force, n_dof=2, name="damped arm"
)
_damped_inverse = jax.jit(lambda q, qd, qdd, p, t: DAMPED.inverse_dynamics(q, qd, qdd, p, t))
_damped_forward = jax.jit(lambda q, qd, p, tau, t: DAMPED.forward_dynamics(q, qd, p, tau, t))
_damped_damping = jax.jit(lambda q, qd, p: DAMPED.damping(q, qd, p))


@given(arm_params(), angles, rates, accels, _f(0.0, 3.0), _f(-5.0, 5.0))
def test_forward_inverse_round_trip(p, q, qd, qdd, c, t):
    tau = _inverse(q, qd, qdd, p)
    np.testing.assert_allclose(_forward(q, qd, p, tau), qdd, rtol=1e-9, atol=1e-9)

    pd = {**p, "c": c, "c2": 0.7, "fa": 1.3, "fk": 2.1}
    tau_d = np.asarray(_damped_inverse(q, qd, qdd, pd, t))
    np.testing.assert_allclose(_damped_forward(q, qd, pd, tau_d, t), qdd, rtol=1e-9, atol=1e-9)
    # the extra torque equals ∂D/∂q̇ − F, written out by hand
    d_dqd = np.array([c * qd[0] + 0.5 * 0.7 * qd[0] * (1 + np.sin(q[1]) ** 2), c * qd[1]])
    force = np.array([1.3 * np.cos(3 * t) - 2.1 * q[0], 1.3 * np.sin(t) * qd[0]])
    _, scale = closed_form_tau(q, qd, qdd, p)
    np.testing.assert_allclose(
        tau_d - np.asarray(tau), d_dqd - force, rtol=0, atol=1e-12 * (scale + 10)
    )
    np.testing.assert_allclose(_damped_damping(q, qd, pd), d_dqd, rtol=1e-12, atol=1e-12)
    # forward dynamics of the damped system with no input, against the closed form
    expected = closed_form_qdd(q, qd, p, force - d_dqd)
    np.testing.assert_allclose(
        _damped_forward(q, qd, pd, np.zeros(2), t), expected, rtol=1e-9, atol=1e-9
    )


DISSIPATIVE_ONLY = lagrax.LagrangianSystem(
    arm_model.kinetic, arm_model.potential, dissipation=_dissipation, n_dof=2
)
_dissipative_forward = jax.jit(lambda q, qd, p: DISSIPATIVE_ONLY.forward_dynamics(q, qd, p))


@given(arm_params(), angles, rates, _f(0.1, 3.0))
def test_dissipation_without_input_or_force(p, q, qd, c):
    # damping must act even when neither tau nor a force function is given
    pd = {**p, "c": c, "c2": 0.7}
    d_dqd = np.array([c * qd[0] + 0.5 * 0.7 * qd[0] * (1 + np.sin(q[1]) ** 2), c * qd[1]])
    expected = closed_form_qdd(q, qd, p, -d_dqd)
    np.testing.assert_allclose(_dissipative_forward(q, qd, pd), expected, rtol=1e-9, atol=1e-9)


# --------------------------------------------------------------------------- (5) energies
@given(arm_params(), angles, rates)
def test_gravity_energy_momentum(p, q, qd):
    mass, _, _, grav_cf = closed_form_terms(q, qd, p)
    kin_cf, pot_cf = closed_form_energy(q, qd, p)
    scale = max(abs(kin_cf) + abs(pot_cf), 1.0)
    np.testing.assert_allclose(_gravity(q, p), grav_cf, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(_grad_potential(q, p), grav_cf, rtol=0, atol=1e-12 * scale)

    e, h, lag, t_kin, v_pot, mom = _energies(q, qd, p)
    np.testing.assert_allclose(t_kin, kin_cf, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(v_pot, pot_cf, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(e, kin_cf + pot_cf, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(h, kin_cf + pot_cf, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(lag, kin_cf - pot_cf, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(mom, mass @ qd, rtol=0, atol=1e-12 * np.max(np.abs(mass)) * 5)


@jax.jit
def _energies(q, qd, p):
    return (
        ARM.energy(q, qd, p),
        ARM.hamiltonian(q, qd, p),
        ARM.lagrangian(q, qd, p),
        ARM.kinetic_energy(q, qd, p),
        ARM.potential_energy(q, p),
        ARM.momentum(q, qd, p),
    )


def test_hamiltonian_differs_from_energy_when_t_not_quadratic():
    # T = ½ q̇² + ¼ q̇⁴ : p = q̇ + q̇³, H = p q̇ − T = ½ q̇² + ¾ q̇⁴  ≠  T + V
    system = lagrax.LagrangianSystem(
        lambda q, qd, p: 0.5 * qd[0] ** 2 + 0.25 * qd[0] ** 4,
        lambda q, p: 0.5 * q[0] ** 2,
        n_dof=1,
    )
    q, qd = jnp.array([0.5]), jnp.array([2.0])
    np.testing.assert_allclose(system.hamiltonian(q, qd, {}), 0.5 * 4 + 0.75 * 16 + 0.125)
    np.testing.assert_allclose(system.energy(q, qd, {}), 0.5 * 4 + 0.25 * 16 + 0.125)
    np.testing.assert_allclose(system.momentum(q, qd, {}), [2.0 + 8.0])


def test_system_without_potential_has_zero_gravity():
    system = lagrax.LagrangianSystem(lambda q, qd, p: 0.5 * p["m"] * jnp.sum(qd**2), n_dof=3)
    q = jnp.array([1.0, 2.0, 3.0])
    p = {"m": 2.0}
    np.testing.assert_array_equal(system.gravity(q, p), np.zeros(3))
    assert float(system.potential_energy(q, p)) == 0.0
    np.testing.assert_allclose(
        system.forward_dynamics(q, jnp.ones(3), p, tau=jnp.array([2.0, -4.0, 6.0])),
        [1.0, -2.0, 3.0],
        rtol=1e-14,
    )


# --------------------------------------------------------------------------- (6) vmap, grad
def test_vmap_over_params_matches_loop(arm_params):
    rng = np.random.default_rng(0)
    batch = 6
    base = {k: float(v) for k, v in arm_params.items()}
    batched = {k: v * rng.uniform(0.5, 1.5, batch) for k, v in base.items()}
    q, qd, tau = np.array([0.3, -0.4]), np.array([1.0, 2.0]), np.array([0.5, -0.25])

    out = jax.vmap(_forward, in_axes=(None, None, 0, None))(q, qd, batched, tau)
    assert out.shape == (batch, 2)
    for i in range(batch):
        pi = {k: float(v[i]) for k, v in batched.items()}
        np.testing.assert_allclose(out[i], _forward(q, qd, pi, tau), rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(out[i], closed_form_qdd(q, qd, pi, tau), rtol=1e-10)

    masses = jax.vmap(_mass, in_axes=(None, 0))(q, batched)
    taus = jax.vmap(_inverse, in_axes=(None, None, None, 0))(q, qd, tau, batched)
    for i in range(batch):
        pi = {k: float(v[i]) for k, v in batched.items()}
        np.testing.assert_allclose(masses[i], closed_form_terms(q, qd, pi)[0], rtol=1e-12)
        np.testing.assert_allclose(taus[i], closed_form_tau(q, qd, tau, pi)[0], rtol=1e-12)


def test_vmap_over_states_matches_loop(arm_params):
    rng = np.random.default_rng(1)
    qs, qds, taus = (rng.uniform(-2, 2, (5, 2)) for _ in range(3))
    out = jax.vmap(_forward, in_axes=(0, 0, None, 0))(qs, qds, arm_params, taus)
    p = {k: float(v) for k, v in arm_params.items()}
    for i in range(5):
        np.testing.assert_allclose(out[i], closed_form_qdd(qs[i], qds[i], p, taus[i]), rtol=1e-10)


@pytest.mark.parametrize("name", ["m2", "l1", "r2", "I1", "g"])
def test_grad_forward_dynamics_wrt_param_matches_finite_differences(arm_params, name):
    p = {k: float(v) for k, v in arm_params.items()}
    q, qd, tau = np.array([0.3, 0.9]), np.array([-1.2, 0.8]), np.array([2.0, -1.0])

    def qdd_of(x):
        return _forward(q, qd, {**p, name: x}, tau)

    jac = np.asarray(jax.jacfwd(qdd_of)(p[name]))
    jac_rev = np.asarray(jax.jacrev(qdd_of)(p[name]))
    h = 1e-5 * max(abs(p[name]), 1.0)
    fd = (
        closed_form_qdd(q, qd, {**p, name: p[name] + h}, tau)
        - closed_form_qdd(q, qd, {**p, name: p[name] - h}, tau)
    ) / (2 * h)
    assert np.max(np.abs(fd)) > 1e-3  # the derivative is not trivially zero
    np.testing.assert_allclose(jac, fd, rtol=1e-7, atol=1e-8)
    np.testing.assert_allclose(jac_rev, jac, rtol=1e-12, atol=1e-12)


def test_check_grads_forward_dynamics(arm_params):
    q, qd, tau = jnp.array([0.3, 0.9]), jnp.array([-1.2, 0.8]), jnp.array([2.0, -1.0])

    def f(m2, l1, q, qd):
        return ARM.forward_dynamics(q, qd, {**arm_params, "m2": m2, "l1": l1}, tau)

    check_grads(jax.jit(f), (1.3, 0.9, q, qd), order=1, modes=("fwd", "rev"))


def test_second_derivative_wrt_param_matches_finite_differences(arm_params):
    p = {k: float(v) for k, v in arm_params.items()}
    q, qd, tau = np.array([0.3, 0.9]), np.array([-1.2, 0.8]), np.array([2.0, -1.0])

    def qdd_of(m2):
        return _forward(q, qd, {**p, "m2": m2}, tau)

    d2 = np.asarray(jax.jacfwd(jax.jacfwd(qdd_of))(p["m2"]))
    h = 1e-3
    f = [closed_form_qdd(q, qd, {**p, "m2": p["m2"] + k * h}, tau) for k in (-1, 0, 1)]
    fd2 = (f[2] - 2 * f[1] + f[0]) / h**2
    assert np.max(np.abs(fd2)) > 1e-2
    np.testing.assert_allclose(d2, fd2, rtol=1e-5, atol=1e-6)


# --------------------------------------------------------------------------- (7) n > 2
def _u(phi):
    return jnp.stack([jnp.cos(phi), jnp.sin(phi)])


def _du(phi):
    return jnp.stack([-jnp.sin(phi), jnp.cos(phi)])


def kinetic3(q, qd, p):
    """Planar 3-link pendulum, relative angles, T from the CoM velocities."""
    phi = jnp.cumsum(q)
    w = jnp.cumsum(qd)
    t = 0.0
    joint_v = jnp.zeros(2, q.dtype)
    for i in range(3):
        v_c = joint_v + p["r"][i] * w[i] * _du(phi[i])
        t = t + 0.5 * p["m"][i] * jnp.sum(v_c**2) + 0.5 * p["I"][i] * w[i] ** 2
        joint_v = joint_v + p["l"][i] * w[i] * _du(phi[i])
    return t


def potential3(q, p):
    phi = jnp.cumsum(q)
    y, v = 0.0, 0.0
    for i in range(3):
        v = v + p["m"][i] * p["g"] * (y + p["r"][i] * jnp.sin(phi[i]))
        y = y + p["l"][i] * jnp.sin(phi[i])
    return v


def mass3(q, p):
    """M = Σ m_i J_iᵀ J_i + I_i J_ωiᵀ J_ωi from the link Jacobians (assembled by hand)."""
    phi = jnp.cumsum(q)
    mass = jnp.zeros((3, 3))
    for i in range(3):
        cols = []
        for k in range(3):
            if k > i:
                cols.append(jnp.zeros(2))
                continue
            col = p["r"][i] * _du(phi[i])
            for j in range(k, i):
                col = col + p["l"][j] * _du(phi[j])
            cols.append(col)
        jac = jnp.stack(cols, axis=1)  # (2, 3)
        jw = jnp.array([1.0 if k <= i else 0.0 for k in range(3)])
        mass = mass + p["m"][i] * jac.T @ jac + p["I"][i] * jnp.outer(jw, jw)
    return mass


def gravity3(q, p):
    """G_k = g Σ_i m_i ∂y_ci/∂q_k."""
    phi = jnp.cumsum(q)
    out = []
    for k in range(3):
        gk = 0.0
        for i in range(k, 3):
            dy = p["r"][i] * jnp.cos(phi[i])
            for j in range(k, i):
                dy = dy + p["l"][j] * jnp.cos(phi[j])
            gk = gk + p["g"] * p["m"][i] * dy
        out.append(gk)
    return jnp.stack(out)


def bias_from_mass(mass_fn, q, qd, p):
    """C(q, q̇) q̇ from Christoffel symbols of an explicit M(q); also the matrix C."""
    dm = jax.jacfwd(mass_fn)(q, p)  # dm[i, j, k] = ∂M_ij/∂q_k
    gamma = 0.5 * (dm + jnp.transpose(dm, (0, 2, 1)) - jnp.transpose(dm, (2, 1, 0)))
    cmat = jnp.einsum("ijk,k->ij", gamma, qd)
    return cmat @ qd, cmat


P3 = {
    "m": jnp.array([1.2, 0.8, 0.5]),
    "l": jnp.array([1.0, 0.7, 0.5]),
    "r": jnp.array([0.45, 0.4, 0.2]),
    "I": jnp.array([0.1, 0.05, 0.02]),
    "g": 9.81,
}
THREE = lagrax.LagrangianSystem(kinetic3, potential3, n_dof=3, name="3-link pendulum")


def _chain_params(n, seed=0):
    rng = np.random.default_rng(seed)
    r = rng.normal(size=(n, n))
    return {
        "K": jnp.asarray(r @ r.T / n + 0.5 * np.eye(n)),
        "A": jnp.asarray(rng.normal(size=(n, n)) / np.sqrt(n)),
        "B": jnp.asarray(rng.normal(size=(n, n)) / np.sqrt(n)),
        "k": jnp.asarray(rng.uniform(1.0, 5.0, n)),
        "kappa": 3.0,
    }


def chain_mass(q, p):
    """Explicit SPD M(q) = K + S(q) S(q)ᵀ with every entry depending on q."""
    s = p["A"] * jnp.cos(q)[None, :] + p["B"] * jnp.sin(q)[:, None]
    return p["K"] + s @ s.T


def chain_kinetic(q, qd, p):
    return 0.5 * qd @ chain_mass(q, p) @ qd


def chain_potential(q, p):
    return jnp.sum(p["k"] * (1 - jnp.cos(q))) + 0.5 * p["kappa"] * jnp.sum(jnp.diff(q) ** 2)


def chain_gravity(q, p):
    d = jnp.diff(q)
    zero = jnp.zeros(1, q.dtype)
    return p["k"] * jnp.sin(q) + p["kappa"] * (
        jnp.concatenate([zero, d]) - jnp.concatenate([d, zero])
    )


def _make_chain(n):
    return lagrax.LagrangianSystem(chain_kinetic, chain_potential, n_dof=n, name=f"chain{n}")


CHAINS = {n: (_make_chain(n), _chain_params(n, seed=n)) for n in (7, 9)}


def _reference_qdd(mass_fn, grav_fn, q, qd, p, tau):
    bias, _ = bias_from_mass(mass_fn, q, qd, p)
    return jnp.linalg.solve(mass_fn(q, p), tau - bias - grav_fn(q, p))


@jax.jit
def _three_hand(q, qd):
    return (
        jax.hessian(kinetic3, argnums=1)(q, qd, P3),
        mass3(q, P3),
        jax.grad(potential3)(q, P3),
        gravity3(q, P3),
        kinetic3(q, qd, P3),
        0.5 * qd @ mass3(q, P3) @ qd,
    )


def test_three_link_hand_derivation_consistent():
    # the hand-assembled M and G match plain jax.hessian / jax.grad of the energies
    hess, mass, grad_v, grav, kin, quad = _three_hand(
        jnp.array([0.3, -0.8, 1.1]), jnp.array([0.5, -1.0, 2.0])
    )
    np.testing.assert_allclose(hess, mass, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(grad_v, grav, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(kin, quad, rtol=1e-13)


_three_fwd = jax.jit(lambda q, qd, tau: THREE.forward_dynamics(q, qd, P3, tau))
_three_inv = jax.jit(lambda q, qd, qdd: THREE.inverse_dynamics(q, qd, qdd, P3))
_three_ref = jax.jit(lambda q, qd, tau: _reference_qdd(mass3, gravity3, q, qd, P3, tau))


@given(vec(-np.pi, np.pi, 3), vec(-3.0, 3.0, 3), vec(-10.0, 10.0, 3))
def test_three_link_forward_dynamics_vs_solve(q, qd, tau):
    expected = np.asarray(_three_ref(q, qd, tau))
    got = np.asarray(_three_fwd(q, qd, tau))
    scale = max(np.max(np.abs(expected)), 1.0)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(_three_fwd(q, qd, _three_inv(q, qd, got)), got, atol=1e-9 * scale)


def _quantities(system, mass_fn, p):
    """lagrax's M, C q̇, C, G and Ṁ of ``system`` (jitted), for comparison with ``mass_fn``."""

    @jax.jit
    def f(q, qd):
        m_dot = jax.jvp(lambda a: system.mass_matrix(a, p), (q,), (qd,))[1]
        return (
            system.mass_matrix(q, p),
            system.coriolis(q, qd, p),
            system.coriolis_matrix(q, qd, p),
            system.gravity(q, p),
            m_dot,
        )

    return f


def test_three_link_mass_coriolis_gravity():
    q, qd = jnp.array([0.3, -0.8, 1.1]), jnp.array([0.5, -1.0, 2.0])
    bias, cmat = bias_from_mass(mass3, q, qd, P3)
    mass, cor, cmat_lx, grav, m_dot = _quantities(THREE, mass3, P3)(q, qd)
    np.testing.assert_allclose(mass, mass3(q, P3), rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(cor, bias, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(cmat_lx, cmat, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(grav, gravity3(q, P3), rtol=1e-13, atol=1e-14)
    skew = m_dot - 2 * cmat_lx
    np.testing.assert_allclose(skew, -skew.T, atol=1e-12)
    assert np.max(np.abs(skew)) > 1e-2  # not trivially zero


@pytest.mark.parametrize("n", [7, 9])
def test_chain_forward_dynamics_vs_solve(n):
    system, p = CHAINS[n]
    fwd = jax.jit(lambda q, qd, tau: system.forward_dynamics(q, qd, p, tau))
    inv = jax.jit(lambda q, qd, qdd: system.inverse_dynamics(q, qd, qdd, p))
    ref = jax.jit(lambda q, qd, tau: _reference_qdd(chain_mass, chain_gravity, q, qd, p, tau))
    rng = np.random.default_rng(n)
    for _ in range(5):
        q, qd, tau = rng.uniform(-2, 2, n), rng.uniform(-2, 2, n), rng.uniform(-5, 5, n)
        expected = np.asarray(ref(q, qd, tau))
        got = fwd(q, qd, tau)
        scale = max(np.max(np.abs(expected)), 1.0)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-10 * scale)
        np.testing.assert_allclose(fwd(q, qd, inv(q, qd, got)), got, rtol=0, atol=1e-9 * scale)
    mass, cor, cmat, grav, m_dot = _quantities(system, chain_mass, p)(q, qd)
    bias, cmat_ref = bias_from_mass(chain_mass, q, qd, p)
    np.testing.assert_allclose(mass, chain_mass(q, p), rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(cor, bias, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(cmat, cmat_ref, rtol=1e-11, atol=1e-11)
    np.testing.assert_allclose(grav, chain_gravity(q, p), rtol=1e-13, atol=1e-13)
    skew = m_dot - 2 * cmat
    np.testing.assert_allclose(skew, -skew.T, atol=1e-11)


# --------------------------------------------------------------------------- float32
def _to32(tree):
    return jax.tree_util.tree_map(lambda x: jnp.asarray(x, jnp.float32), tree)


@pytest.mark.parametrize("case", ["arm", "three", "chain9"])
def test_float32_forward_dynamics(case):
    if case == "arm":
        system, p, n = ARM, ARM_PARAMS, 2
    elif case == "three":
        system, p, n = THREE, P3, 3
    else:
        (system, p), n = CHAINS[9], 9
    rng = np.random.default_rng(3)
    q, qd, tau = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    fwd = jax.jit(system.forward_dynamics)
    out64 = fwd(q, qd, p, tau)
    out32 = fwd(*_to32((q, qd)), _to32(p), _to32(tau))
    assert out64.dtype == jnp.float64
    assert out32.dtype == jnp.float32
    scale = max(float(jnp.max(jnp.abs(out64))), 1.0)
    np.testing.assert_allclose(out32, out64, rtol=0, atol=2e-4 * scale)
    if case == "arm":  # the eager path (with its checks) keeps float32 too
        out32_eager = system.forward_dynamics(*_to32((q, qd)), _to32(p), _to32(tau))
        assert out32_eager.dtype == jnp.float32
        np.testing.assert_allclose(out32_eager, out32, rtol=1e-6, atol=1e-6 * scale)
