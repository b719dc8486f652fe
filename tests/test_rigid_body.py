"""A free rigid body: Euler's equations on quaternions against the Jacobi elliptic
solution, against the Lagrangian in Euler angles, the intermediate-axis instability, and
gimbal lock reported as a singular configuration."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.special import ellipj, ellipk, ellipkinc

import lagrax as lx

rb = lx.rigid_body
INERTIA = np.array([1.0, 2.0, 2.5])  # distinct principal moments, I1 < I2 < I3
TS = np.linspace(0.0, 30.0, 601)


def elliptic_omega(omega0, t, inertia=INERTIA):
    """Body angular velocity of the torque-free body for ``L² > 2 E I2`` (Landau &
    Lifshitz, Mechanics, §37): ``ω = (A1 cn u, A2 sn u, A3 dn u)``, ``u = λ t + u0``.

    Returns ``(ω(t), time of the first downward zero crossing of ω2)``.
    """
    i1, i2, i3 = inertia
    e2 = np.sum(inertia * omega0**2)  # 2E
    l2 = np.sum((inertia * omega0) ** 2)  # L²
    assert l2 > e2 * i2 and omega0[2] > 0
    a1 = np.sqrt((e2 * i3 - l2) / (i1 * (i3 - i1)))
    a2 = np.sqrt((e2 * i3 - l2) / (i2 * (i3 - i2)))
    a3 = np.sqrt((l2 - e2 * i1) / (i3 * (i3 - i1)))
    lam = np.sqrt((i3 - i2) * (l2 - e2 * i1) / (i1 * i2 * i3))
    m = (i2 - i1) * (e2 * i3 - l2) / ((i3 - i2) * (l2 - e2 * i1))
    u0 = ellipkinc(np.arctan2(omega0[1] / a2, omega0[0] / a1), m)  # amplitude at t = 0
    sn, cn, dn, _ = ellipj(lam * np.asarray(t) + u0, m)
    return np.stack([a1 * cn, a2 * sn, a3 * dn], axis=-1), (2 * ellipk(m) - u0) / lam


def _first_sign_change(ts, x):
    k = np.nonzero(np.sign(x[1:]) != np.sign(x[:-1]))[0]
    return (
        None
        if k.size == 0
        else ts[k[0]] - x[k[0]] * (ts[k[0] + 1] - ts[k[0]]) / (x[k[0] + 1] - x[k[0]])
    )


@pytest.fixture(scope="module")
def euler_model():
    return lx.models.free_rigid_body_euler_angles(*INERTIA)


# --------------------------------------------------------------------------- attitude
def test_attitude_maps_are_consistent():
    key = jax.random.PRNGKey(0)
    for i in range(5):
        angles, rates = jax.random.normal(jax.random.fold_in(key, i), (2, 3))
        rot = rb.euler_angles_to_matrix(angles)
        np.testing.assert_allclose(rot @ rot.T, np.eye(3), atol=1e-15)
        assert abs(np.linalg.det(rot) - 1) < 1e-14
        # quaternion route (products of half-angle quaternions) == matrix product route
        quat = rb.euler_angles_to_quaternion(angles)
        np.testing.assert_allclose(rb.quaternion_to_matrix(quat), rot, atol=1e-15)
        # ω from the closed form == vee(Rᵀ Ṙ) with Ṙ by a JVP
        rot_dot = jax.jvp(rb.euler_angles_to_matrix, (angles,), (rates,))[1]
        omega = rb.body_angular_velocity(angles, rates)
        np.testing.assert_allclose(rot.T @ rot_dot, rb.hat(omega), atol=1e-14)
        np.testing.assert_allclose(rb.euler_angle_rates(angles, omega), rates, rtol=1e-12)
    # conventions: yaw turns x towards y; rotations compose body → space
    np.testing.assert_allclose(
        rb.euler_angles_to_matrix(jnp.array([0.5, 0.0, 0.0]))[:, 0],
        [np.cos(0.5), np.sin(0.5), 0.0],
        atol=1e-16,
    )
    p, q = jnp.array([0.3, 0.1, -0.5, 0.8]), jnp.array([-0.2, 0.9, 0.4, 0.1])
    np.testing.assert_allclose(
        rb.quaternion_to_matrix(rb.quaternion_product(p, q)),
        rb.quaternion_to_matrix(p) @ rb.quaternion_to_matrix(q),
        atol=1e-15,
    )


# --------------------------------------------------------------------------- (a) Euler
def test_euler_equations_match_the_elliptic_solution():
    omega0 = np.array([0.8, 0.0, 1.5])
    sol = rb.simulate_euler(INERTIA, omega0, t1=30.0, ts=TS)
    exact, _ = elliptic_omega(omega0, TS)
    # measured: 2.5e-10 over 30 s (about 8 periods) at rtol = atol = 1e-10
    assert np.max(np.abs(np.asarray(sol.omega) - exact)) < 1e-8
    # invariants: energy, |I ω|, the space-frame angular momentum, the quaternion norm
    assert np.max(np.abs(sol.energy / sol.energy[0] - 1)) < 1e-9
    body_l = np.linalg.norm(np.asarray(sol.body_angular_momentum), axis=1)
    assert np.max(np.abs(body_l / body_l[0] - 1)) < 1e-9
    np.testing.assert_allclose(
        sol.angular_momentum, np.tile(INERTIA * omega0, (TS.size, 1)), atol=1e-8
    )
    assert np.max(np.abs(np.linalg.norm(np.asarray(sol.quat), axis=1) - 1)) < 1e-9


def test_euler_equations_general_inertia_and_torque():
    """A 3×3 inertia (the principal one rotated) gives the rotated motion; a constant
    torque about a principal axis from rest spins it up as I ω̇ = M."""
    rot = np.asarray(rb.euler_angles_to_matrix(jnp.array([0.3, -0.2, 0.7])))
    full = rot @ np.diag(INERTIA) @ rot.T
    omega0 = np.array([0.8, 0.0, 1.5])
    w_principal = rb.euler_equations(omega0, INERTIA)
    np.testing.assert_allclose(
        rb.euler_equations(rot @ omega0, full), rot @ w_principal, atol=1e-14
    )
    expected = np.array([0.0, 0.0, 0.5]) / INERTIA[2]
    np.testing.assert_allclose(
        rb.euler_equations(np.zeros(3), INERTIA, [0.0, 0.0, 0.5]), expected, atol=1e-16
    )


@pytest.mark.parametrize(
    ("axis", "flips"), [(0, False), (1, True), (2, False)], ids=["minor", "intermediate", "major"]
)
def test_intermediate_axis_instability(axis, flips):
    eps = 1e-3
    omega0 = np.full(3, eps)
    omega0[axis] = 1.0
    sol = rb.simulate_euler(INERTIA, omega0, t1=30.0, ts=TS)
    w = np.asarray(sol.omega)
    t_flip = _first_sign_change(TS, w[:, axis])
    if flips:
        # the spin about axis 2 reverses; its time from the elliptic solution: 22.87 s
        assert np.min(w[:, 1]) < -0.99
        _, t_exact = elliptic_omega(omega0, TS)
        assert t_flip is not None and abs(t_flip - t_exact) < 0.01
        exact, _ = elliptic_omega(omega0, TS)
        assert np.max(np.abs(w - exact)) < 1e-6  # measured 1e-9 near the separatrix
    else:
        # about the minor or major axis the spin keeps its sign, the wobble stays O(ε)
        assert t_flip is None
        others = np.delete(w, axis, axis=1)
        assert np.max(np.abs(others)) < 3 * eps  # measured 1.7e-3
        assert np.max(np.abs(w[:, axis] - 1.0)) < 10 * eps**2


# --------------------------------------------------------------------------- (b) angles
@pytest.fixture(scope="module")
def angle_run(euler_model):
    system, params = euler_model
    q0 = jnp.array([0.1, 0.2, 0.3])
    omega0 = jnp.array([0.3, 0.2, 2.0])  # mostly about the major axis: pitch stays small
    qd0 = rb.euler_angle_rates(q0, omega0)
    sol_b = lx.simulate(system, q0, qd0, params, t1=10.0, ts=TS / 3, rtol=1e-11, atol=1e-11)
    sol_a = rb.simulate_euler(
        INERTIA,
        omega0,
        quat0=rb.euler_angles_to_quaternion(q0),
        t1=10.0,
        ts=TS / 3,
        rtol=1e-11,
        atol=1e-11,
    )
    return sol_a, sol_b


def test_euler_angle_lagrangian_agrees_with_euler_equations(angle_run):
    sol_a, sol_b = angle_run
    assert bool(sol_b.ok) and bool(sol_a.ok)
    assert np.max(np.abs(np.asarray(sol_b.q[:, 1]))) < 1.0  # away from gimbal lock
    omega_b = jax.vmap(rb.body_angular_velocity)(sol_b.q, sol_b.qd)
    # measured: 3e-11 (ω) and 6e-11 (attitude) over 10 s
    assert np.max(np.abs(np.asarray(omega_b - sol_a.omega))) < 1e-8
    rot_b = jax.vmap(rb.euler_angles_to_matrix)(sol_b.q)
    assert np.max(np.abs(np.asarray(rot_b - sol_a.rotation))) < 1e-8
    # (b) conserves energy and |I ω| too
    assert np.max(np.abs(np.asarray(sol_b.energy_error))) < 1e-9
    body_l = np.linalg.norm(np.asarray(omega_b) * INERTIA, axis=1)
    assert np.max(np.abs(body_l / body_l[0] - 1)) < 1e-9
    np.testing.assert_allclose(sol_b.energy, sol_a.energy, rtol=1e-9)


def test_gimbal_lock_is_a_clear_error(euler_model):
    system, params = euler_model
    lock = jnp.array([0.2, np.pi / 2, -0.4])
    with pytest.raises(lx.MassMatrixError) as info:
        system.check_state(lock, jnp.zeros(3), params)
    msg = str(info.value)
    assert "q=[ 0.2" in msg and "1.5707963" in msg  # names the configuration
    assert "gimbal lock" in msg and "change coordinates" in msg  # and suggests others
    # a start within 1e-9 rad of it is refused before solving
    with pytest.raises(lx.MassMatrixError, match="singular"):
        lx.simulate(system, lock - jnp.array([0.0, 1e-9, 0.0]), jnp.zeros(3), params, t1=1.0)
    # a motion that runs into it: spin about the body y axis (pitch) with a tiny wobble
    omega0 = jnp.array([1e-8, 1.0, 1e-8])
    qd0 = rb.euler_angle_rates(jnp.zeros(3), omega0)
    with pytest.raises(lx.SimulationError) as info:
        lx.simulate(system, jnp.zeros(3), qd0, params, t1=10.0, ts=TS / 3, rtol=1e-11, atol=1e-11)
    msg = str(info.value)
    assert "singular" in msg and "Use coordinates without this singularity" in msg
    t_stop = float(msg.split("stopped at t=")[1].split()[0])
    assert abs(t_stop - np.pi / 2) < 1e-3  # pitch reaches π/2 at t = π/2 for ω2 = 1
    # ... which Euler's equations on the quaternion integrate without trouble
    sol = rb.simulate_euler(INERTIA, omega0, t1=10.0, ts=TS / 3, rtol=1e-11, atol=1e-11)
    assert bool(sol.ok) and int(sol.stats["num_steps"]) < 1000


def test_simulate_euler_input_checks_and_float32():
    with pytest.raises(lx.ShapeError, match="principal"):
        rb.simulate_euler(np.ones(4), np.ones(3), t1=1.0)
    with pytest.raises(lx.MassMatrixError, match="positive-definite"):
        rb.simulate_euler(np.array([1.0, -2.0, 3.0]), np.ones(3), t1=1.0)
    sol = rb.simulate_euler(
        INERTIA.astype(np.float32),
        np.array([0.8, 0.0, 1.5], np.float32),
        t1=5.0,
        n_save=11,
        rtol=1e-6,
        atol=1e-6,
    )
    assert sol.omega.dtype == jnp.float32 and sol.quat.dtype == jnp.float32
    assert float(np.max(np.abs(sol.energy / sol.energy[0] - 1))) < 1e-4
