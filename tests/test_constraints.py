"""Holonomic constraints: ``ConstrainedSystem`` against minimal coordinates, closed forms
and invariants; projection, Baumgarte stabilization and singular-KKT errors."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads
from scipy.special import ellipj, ellipk

import lagrax as lx
from lagrax.models import _four_bar as four_bar_model

P = {"m": 1.3, "l": 0.8, "g": 9.81}  # not unit values, so a missing factor shows
THETA0 = 1.2  # rad from the downward vertical: far from the small-angle regime
TS = np.linspace(0.0, 8.0, 401)  # about four periods (period 2.0 s at this amplitude)
TIGHT = {"rtol": 1e-11, "atol": 1e-11}


def _params(**kw):
    return {k: jnp.asarray(v) for k, v in {**P, **kw}.items()}


def _bob(theta, p=P):
    return np.stack([p["l"] * np.sin(theta), -p["l"] * np.cos(theta)], axis=-1)


def exact_theta(t, theta0=THETA0, p=P):
    """Pendulum released from rest at ``theta0``: ``sin(θ/2) = k sn(K − ω t | k²)``,
    ``k = sin(θ0/2)``, ``ω = √(g/l)`` (Jacobi elliptic functions, SciPy)."""
    m = np.sin(theta0 / 2) ** 2
    sn = ellipj(ellipk(m) - np.sqrt(p["g"] / p["l"]) * np.asarray(t), m)[0]
    return 2.0 * np.arcsin(np.sqrt(m) * sn)


def _min_T(q, qd, p):
    return 0.5 * p["m"] * p["l"] ** 2 * qd[0] ** 2


def _min_V(q, p):
    return -p["m"] * p["g"] * p["l"] * jnp.cos(q[0])


@pytest.fixture(scope="module")
def pendulum():
    return lx.models.cartesian_pendulum(m=P["m"], l=P["l"])


@pytest.fixture(scope="module")
def cartesian_sol(pendulum):
    system, params = pendulum
    return lx.simulate(system, _bob(THETA0), [0.0, 0.0], params, t1=8.0, ts=TS, **TIGHT)


@pytest.fixture(scope="module")
def minimal_sol():
    system = lx.LagrangianSystem(_min_T, _min_V, n_dof=1, name="pendulum (θ)")
    return lx.simulate(system, [THETA0], [0.0], _params(), t1=8.0, ts=TS, **TIGHT)


# --------------------------------------------------------------------------- pendulum
def test_cartesian_pendulum_equals_minimal_pendulum(cartesian_sol, minimal_sol):
    assert bool(cartesian_sol.ok)
    x, y = np.asarray(cartesian_sol.q).T
    theta_cart = np.arctan2(x, -y)
    theta_min = np.asarray(minimal_sol.q[:, 0])
    theta_exact = exact_theta(TS)
    # measured: 1.0e-10 (Cartesian vs minimal), 4e-11 and 1.3e-10 (each vs elliptic)
    assert np.max(np.abs(theta_cart - theta_min)) < 1e-8
    assert np.max(np.abs(theta_cart - theta_exact)) < 1e-8
    assert np.max(np.abs(theta_min - theta_exact)) < 1e-8
    # angular rate θ̇ = (x ẏ − y ẋ)/l² against the minimal model
    xd, yd = np.asarray(cartesian_sol.qd).T
    np.testing.assert_allclose((x * yd - y * xd) / P["l"] ** 2, minimal_sol.qd[:, 0], atol=1e-7)
    # constraint held and energy conserved
    assert cartesian_sol.constraint_violation.shape == (TS.size, 1)
    assert float(np.max(np.abs(cartesian_sol.constraint_violation))) < 1e-9
    assert float(np.max(np.abs(cartesian_sol.energy_error))) < 1e-9


def test_multipliers_are_the_rod_tension(cartesian_sol, minimal_sol):
    theta, thetad = np.asarray(minimal_sol.q[:, 0]), np.asarray(minimal_sol.qd[:, 0])
    tension = P["m"] * (P["l"] * thetad**2 + P["g"] * np.cos(theta))  # minimal model
    # closed form from energy conservation: T = m g (3 cos θ − 2 cos θ0)
    np.testing.assert_allclose(
        tension, P["m"] * P["g"] * (3 * np.cos(theta) - 2 * np.cos(THETA0)), atol=1e-7
    )
    lam = np.asarray(cartesian_sol.multipliers[:, 0])
    # J^T λ = 2λ (x, y) must be the rod's pull −T (x, y)/l  =>  λ = −T/(2l)
    # measured: 1.9e-9 N (tension between 1.2 and 21 N)
    np.testing.assert_allclose(-2.0 * P["l"] * lam, tension, rtol=0, atol=1e-7)
    assert np.all(tension > 0) and np.ptp(tension) > 10.0  # a real test: T varies a lot


def test_constrained_accelerations_and_forces_at_a_state(pendulum):
    """Closed form: r̈ = l θ̈ e_θ − l θ̇² e_r with θ̈ = −(g/l) sin θ; the rod force is
    −T e_r with T = m (l θ̇² + g cos θ)."""
    system, params = pendulum
    theta, thetad = 0.7, -1.9
    e_r = np.array([np.sin(theta), -np.cos(theta)])
    e_t = np.array([np.cos(theta), np.sin(theta)])
    q, qd = P["l"] * e_r, P["l"] * thetad * e_t
    qdd_exact = P["l"] * (-P["g"] / P["l"] * np.sin(theta)) * e_t - P["l"] * thetad**2 * e_r
    tension = P["m"] * (P["l"] * thetad**2 + P["g"] * np.cos(theta))
    np.testing.assert_allclose(system.forward_dynamics(q, qd, params), qdd_exact, atol=1e-12)
    np.testing.assert_allclose(system.constraint_forces(q, qd, params), -tension * e_r, atol=1e-12)
    np.testing.assert_allclose(system.multipliers(q, qd, params), [-tension / (2 * P["l"])])
    # jit and vmap give the same; a tau along the rod changes λ, not q̈
    jitted = jax.jit(system.forward_dynamics)(jnp.asarray(q), jnp.asarray(qd), params)
    np.testing.assert_allclose(jitted, qdd_exact, atol=1e-12)
    qs = jnp.stack([jnp.asarray(q), -jnp.asarray(q)])
    qds = jnp.stack([jnp.asarray(qd), -jnp.asarray(qd)])
    batch = jax.vmap(lambda a, b: system.forward_dynamics(a, b, params))(qs, qds)
    np.testing.assert_allclose(batch[0], qdd_exact, atol=1e-12)
    pull = 5.0 * e_r
    np.testing.assert_allclose(
        system.forward_dynamics(q, qd, params, tau=pull), qdd_exact, atol=1e-12
    )
    np.testing.assert_allclose(
        system.constraint_forces(q, qd, params, tau=pull), -(tension + 5.0) * e_r, atol=1e-12
    )
    check_grads(
        lambda a, b: system.forward_dynamics(a, b, params),
        (jnp.asarray(q), jnp.asarray(qd)),
        order=1,
        modes=("fwd", "rev"),
    )


def test_initial_state_is_projected(pendulum):
    """With M = m·1 the M-metric projection is the Euclidean one: radial for positions,
    the tangential part for velocities."""
    system, params = pendulum
    q0, qd0 = np.array([0.9, -0.5]), np.array([0.4, 1.0])
    q_star = P["l"] * q0 / np.linalg.norm(q0)
    e_r = q_star / P["l"]
    qd_star = qd0 - (qd0 @ e_r) * e_r
    q1, qd1 = system.project(q0, qd0, params)
    np.testing.assert_allclose(q1, q_star, atol=1e-14)
    np.testing.assert_allclose(qd1, qd_star, atol=1e-14)
    sol = lx.simulate(system, q0, qd0, params, t1=0.5, ts=TS / 16, **TIGHT)  # compiled once
    np.testing.assert_allclose(sol.q[0], q_star, atol=1e-14)
    np.testing.assert_allclose(sol.qd[0], qd_star, atol=1e-14)
    assert float(np.max(np.abs(sol.constraint_violation))) < 1e-10


def test_baumgarte_controls_drift(pendulum):
    """Loose tolerances: without stabilization the violation drifts; with it, it decays."""
    _, params = pendulum
    q0, qd0 = _bob(THETA0), np.zeros(2)
    runs = {}
    for gain in (0.0, 10.0):
        system, _ = lx.models.cartesian_pendulum(alpha=gain, beta=gain)
        sol = lx.simulate(system, q0, qd0, params, t1=20.0, ts=TS * 2.5, rtol=1e-6, atol=1e-6)
        runs[gain] = np.max(np.abs(np.asarray(sol.constraint_violation)))
    # measured over 20 s: 1.2e-3 without, 3.8e-7 with (alpha = beta = 10)
    assert runs[10.0] < 1e-6
    assert runs[0.0] > 10 * runs[10.0]


# --------------------------------------------------------------------------- four-bar
def _closure_distance(q, p):
    """|A − B'|, from the crank and rocker angles only: must equal the coupler length."""
    a = p["l1"] * np.stack([np.cos(q[:, 0]), np.sin(q[:, 0])], axis=-1)
    b = np.array([p["d"], 0.0]) + p["l3"] * np.stack([np.cos(q[:, 2]), np.sin(q[:, 2])], -1)
    return np.linalg.norm(a - b, axis=-1)


@pytest.fixture(scope="module")
def four_bar():
    return lx.models.four_bar()


@pytest.fixture(scope="module")
def four_bar_run(four_bar):
    system, params = four_bar
    # crank up, coupler and rocker roughly assembled (projected by simulate)
    return lx.simulate(
        system,
        [1.57, 0.35, 1.9],
        [2.0, 0.0, 0.0],
        params,
        t1=100.0,
        n_save=1001,
        rtol=1e-10,
        atol=1e-10,
    )


def test_four_bar_long_run_keeps_constraint_and_energy(four_bar, four_bar_run):
    _, params = four_bar
    p = {k: float(v) for k, v in params.items()}
    sol = four_bar_run
    assert bool(sol.ok)
    violation = np.max(np.abs(np.asarray(sol.constraint_violation)))
    # measured over 100 s at rtol = atol = 1e-10: violation 3e-11 m, |ΔE/E| 4e-10
    assert violation < 1e-9
    assert float(np.max(np.abs(sol.energy_error))) < 1e-8
    q = np.asarray(sol.q)
    assert np.max(np.abs(_closure_distance(q, p) - p["l2"])) < 1e-9
    # the crank really turns (a long, non-trivial run), the multipliers stay finite
    assert np.ptp(q[:, 0]) > 2 * np.pi
    assert np.all(np.isfinite(np.asarray(sol.multipliers)))
    # the projected start is assembled and its velocity admissible
    assert np.max(np.abs(np.asarray(four_bar_model.loop_closure(sol.q[0], params)))) < 1e-13


# --------------------------------------------------------------------------- errors
def _redundant(q, p):
    rod = q[0] ** 2 + q[1] ** 2 - p["l"] ** 2
    return jnp.stack([rod, 2.0 * rod])


def test_redundant_constraints_raise_a_clear_error(pendulum):
    free = pendulum[0].system
    system = lx.ConstrainedSystem(free, _redundant, name="doubled rod")
    params = _params()
    q, qd = jnp.asarray(_bob(0.5)), jnp.array([0.3, 0.2])
    for method in (system.forward_dynamics, system.multipliers, system.constraint_forces):
        with pytest.raises(lx.ConstraintError, match="rank-deficient") as info:
            method(q, qd, params)
        assert "redundant" in str(info.value) and "doubled rod" in str(info.value)
    with pytest.raises(lx.ConstraintError, match="KKT"):
        system.check_state(q, qd, params)
    with pytest.raises(lx.ConstraintError, match="rank-deficient"):
        lx.simulate(system, q, qd, params, t1=1.0)
    with pytest.raises(Exception, match="rank-deficient"):  # under jit: error_if, not NaN
        jax.block_until_ready(jax.jit(system.forward_dynamics)(q, qd, params))


def test_singular_configuration_raises(four_bar):
    """A four-bar with l1 + l2 = d + l3 can lie flat: all links along x, J of rank 1."""
    system, params = four_bar
    flat = {**params, "l3": jnp.asarray(0.5)}
    q, qd = jnp.zeros(3), jnp.zeros(3)
    assert np.max(np.abs(np.asarray(four_bar_model.loop_closure(q, flat)))) < 1e-15
    with pytest.raises(lx.ConstraintError, match="singular configuration") as info:
        system.forward_dynamics(q, qd, flat)
    assert "q=[0. 0. 0.]" in str(info.value) and "singular values" in str(info.value)


def test_unreachable_constraints_cannot_be_projected(four_bar):
    system, params = four_bar
    apart = {**params, "d": jnp.asarray(10.0)}  # l1 + l2 + l3 = 4 < d: cannot close
    with pytest.raises(lx.ConstraintError, match="could not project"):
        system.project([1.57, 0.35, 1.9], [0.0, 0.0, 0.0], apart)
    with pytest.raises(lx.ConstraintError, match="could not project"):
        lx.simulate(system, [1.57, 0.35, 1.9], [0.0, 0.0, 0.0], apart, t1=1.0)


def test_projection_failure_is_reported_per_member_under_vmap(pendulum):
    """Under vmap (a sweep) a member whose constraints cannot be met is flagged, not raised."""
    free = pendulum[0].system

    def rod_and_wall(q, p):  # on the circle and at x = c: impossible for |c| > l
        return jnp.stack([q[0] ** 2 + q[1] ** 2 - p["l"] ** 2, q[0] - p["c"]])

    system = lx.ConstrainedSystem(free, rod_and_wall)

    def run(c):
        return lx.simulate(
            system, _bob(0.3), [0.0, 0.0], {**_params(), "c": c}, t1=0.5, n_save=5, throw=False
        )

    sols = jax.vmap(run)(jnp.array([0.2, 3.0]))
    assert bool(sols.ok[0]) and not bool(sols.ok[1])
    assert bool((sols.result == lx.RESULTS.constraint_projection_failed)[1])
    np.testing.assert_allclose(sols.q[0, :, 0], 0.2, atol=1e-12)  # pinned at x = c


def test_constrained_system_input_checks(pendulum):
    system, params = pendulum
    with pytest.raises(ValueError, match="variational"):
        lx.simulate(system, _bob(0.3), [0.0, 0.0], params, t1=1.0, solver="variational", dt=0.01)
    with pytest.raises(ValueError, match="non-negative"):
        lx.ConstrainedSystem(system.system, _redundant, alpha=-1.0)
    with pytest.raises(TypeError, match="LagrangianSystem"):
        lx.ConstrainedSystem(system, _redundant)
    bad = lx.ConstrainedSystem(system.system, lambda q, p: jnp.ones((2, 2)))
    with pytest.raises(lx.ShapeError, match="1-D"):
        bad.violation(jnp.ones(2), params)


def test_float32_works(pendulum):
    system, _ = pendulum
    params32 = {k: jnp.asarray(v, jnp.float32) for k, v in P.items()}
    q = jnp.asarray(_bob(0.7), jnp.float32)
    qd = jnp.zeros(2, jnp.float32)
    qdd = system.forward_dynamics(q, qd, params32)
    assert qdd.dtype == jnp.float32
    sol = lx.simulate(system, q, qd, params32, t1=1.0, n_save=11, rtol=1e-5, atol=1e-5)
    assert sol.q.dtype == jnp.float32 and bool(sol.ok)
    assert float(np.max(np.abs(np.asarray(sol.constraint_violation)))) < 1e-4
