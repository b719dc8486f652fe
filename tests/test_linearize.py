"""``LagrangianSystem.linearize``: analytic pendulum, finite differences, ``B = (0, M⁻¹)``."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx


def _pendulum(damping: bool = False):
    """A point mass ``m`` on a massless rod ``l``; ``θ`` from hanging straight down."""

    def T(q, qd, p):
        return 0.5 * p["m"] * p["l"] ** 2 * qd[0] ** 2

    def V(q, p):
        return -p["m"] * p["g"] * p["l"] * jnp.cos(q[0])

    def D(q, qd, p):
        return 0.5 * p["c"] * qd[0] ** 2

    system = lx.LagrangianSystem(T, V, dissipation=D if damping else None, n_dof=1)
    params = {
        "m": jnp.asarray(0.7),
        "l": jnp.asarray(1.3),
        "g": jnp.asarray(9.81),
        "c": jnp.asarray(0.2),
    }
    return system, params


@pytest.mark.parametrize("theta, sign", [(0.0, -1.0), (np.pi, 1.0)])
def test_small_angle_pendulum(theta, sign):
    """Hanging: ``A = [[0, 1], [−g/l, 0]]``; upright: ``+g/l``; ``B = [[0], [1/(m l²)]]``."""
    system, p = _pendulum()
    A, B = system.linearize(jnp.array([theta]), jnp.array([0.0]), p)
    g_over_l = float(p["g"] / p["l"])
    np.testing.assert_allclose(A, [[0.0, 1.0], [sign * g_over_l, 0.0]], rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(B, [[0.0], [1.0 / float(p["m"] * p["l"] ** 2)]], rtol=1e-14)
    assert A.shape == (2, 2) and B.shape == (2, 1)


def test_damped_pendulum_damping_entry():
    """``∂q̈/∂q̇ = −c/(m l²)`` from the Rayleigh function."""
    system, p = _pendulum(damping=True)
    A, _ = system.linearize(jnp.array([0.0]), jnp.array([0.0]), p)
    np.testing.assert_allclose(A[1, 1], -float(p["c"] / (p["m"] * p["l"] ** 2)), rtol=1e-14)


def _central_jacobian(f, x, h):
    cols = []
    for i in range(x.shape[0]):
        e = np.zeros_like(x)
        e[i] = h
        cols.append((np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h))
    return np.stack(cols, axis=-1)


def test_arm_matches_central_differences(arm_system, arm_params):
    """At a random state and torque, ``A`` and ``B`` equal central differences of
    ``forward_dynamics`` to ~1e-6 relative, and ``B``'s lower block is ``M(q)⁻¹``."""
    rng = np.random.default_rng(6)
    q, qd, tau = rng.uniform(-2, 2, 2), rng.uniform(-1, 1, 2), rng.uniform(-3, 3, 2)
    A, B = arm_system.linearize(q, qd, arm_params, tau)
    assert A.shape == (4, 4) and B.shape == (4, 2)

    fd = jax.jit(lambda a, b, u: arm_system.forward_dynamics(a, b, arm_params, u))

    def field(x):
        return np.concatenate([x[2:], np.asarray(fd(x[:2], x[2:], tau))])

    A_fd = _central_jacobian(field, np.concatenate([q, qd]), 1e-5)
    B_fd = _central_jacobian(lambda u: fd(q, qd, u), tau, 1e-5)
    scale = np.max(np.abs(A_fd))
    np.testing.assert_allclose(A, A_fd, rtol=1e-6, atol=1e-6 * scale)
    np.testing.assert_allclose(B[2:], B_fd, rtol=1e-6, atol=1e-6 * np.max(np.abs(B_fd)))
    # B = [[0], [M⁻¹]] exactly (up to round-off), and the top of A is [0 I]
    m_inv = np.linalg.inv(np.asarray(arm_system.mass_matrix(q, arm_params)))
    np.testing.assert_allclose(B[:2], 0.0, atol=0)
    np.testing.assert_allclose(B[2:], m_inv, rtol=1e-12)
    np.testing.assert_allclose(A[:2], np.hstack([np.zeros((2, 2)), np.eye(2)]), atol=0)


def test_upright_arm_under_jit_and_vmap(arm_system, arm_params):
    """Jit and vmap agree with the eager call; the upright arm has unstable eigenvalues."""
    q_up, zero = jnp.array([np.pi / 2, 0.0]), jnp.zeros(2)
    A, B = arm_system.linearize(q_up, zero, arm_params)
    A_j, B_j = jax.jit(arm_system.linearize)(q_up, zero, arm_params)
    np.testing.assert_allclose(A_j, A, rtol=1e-14)
    np.testing.assert_allclose(B_j, B, rtol=1e-14)
    qs = jnp.stack([q_up, jnp.array([-np.pi / 2, 0.0])])
    As, _ = jax.vmap(lambda a: arm_system.linearize(a, zero, arm_params))(qs)
    np.testing.assert_allclose(As[0], A, rtol=1e-14)
    assert np.max(np.linalg.eigvals(np.asarray(A)).real) > 1.0  # upright: unstable
    assert np.max(np.linalg.eigvals(np.asarray(As[1])).real) < 1e-9  # hanging: marginal


def test_bad_input_is_refused(arm_system, arm_params):
    with pytest.raises(lx.ShapeError):
        arm_system.linearize(jnp.zeros(3), jnp.zeros(3), arm_params)
    with pytest.raises(lx.NonFiniteError):
        arm_system.linearize(jnp.array([np.nan, 0.0]), jnp.zeros(2), arm_params)
    with pytest.raises(lx.MassMatrixError):
        massless = {**arm_params, "m1": 0.0, "m2": 0.0, "I1": 0.0, "I2": 0.0}
        arm_system.linearize(jnp.zeros(2), jnp.zeros(2), massless)
