"""Bad input gets a clear, typed error that names the problem."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax
from lagrax.models import _planar_2r as arm_model

Q = jnp.array([0.3, 0.7])
QD = jnp.array([0.1, -0.2])


# --------------------------------------------------------------------------- shapes
@pytest.mark.parametrize(
    "call",
    [
        pytest.param(lambda s, p: s.forward_dynamics(jnp.zeros(3), jnp.zeros(3), p), id="fwd-q3"),
        pytest.param(
            lambda s, p: s.inverse_dynamics(jnp.zeros(3), jnp.zeros(3), jnp.zeros(3), p),
            id="inv-q3",
        ),
        pytest.param(lambda s, p: s.mass_matrix(jnp.zeros(3), p), id="mass-q3"),
        pytest.param(lambda s, p: s.gravity(jnp.zeros(1), p), id="gravity-q1"),
        pytest.param(lambda s, p: s.energy(jnp.zeros(3), jnp.zeros(3), p), id="energy-q3"),
        pytest.param(lambda s, p: s.check_state(jnp.zeros(3), jnp.zeros(3), p), id="check-q3"),
        pytest.param(
            lambda s, p: lagrax.simulate(s, jnp.zeros(3), jnp.zeros(3), p, t1=1.0), id="sim-q3"
        ),
    ],
)
def test_wrong_number_of_coordinates(arm, call):
    system, params = arm
    with pytest.raises(lagrax.ShapeError, match=r"length (3|1).*2 degrees of freedom"):
        call(system, params)


def test_qd_shape_mismatch(arm):
    system, params = arm
    with pytest.raises(lagrax.ShapeError, match="qd"):
        system.forward_dynamics(Q, jnp.zeros(3), params)
    # without n_dof the check is q against qd
    free = lagrax.LagrangianSystem(arm_model.kinetic, arm_model.potential)
    with pytest.raises(lagrax.ShapeError, match=r"qd has shape \(3,\) but q has shape \(2,\)"):
        free.forward_dynamics(Q, jnp.zeros(3), params)
    with pytest.raises(lagrax.ShapeError, match="qdd"):
        free.inverse_dynamics(Q, QD, jnp.zeros(3), params)


def test_tau_wrong_length(arm):
    system, params = arm
    with pytest.raises(lagrax.ShapeError, match="tau"):
        system.forward_dynamics(Q, QD, params, tau=jnp.zeros(3))
    with pytest.raises(lagrax.ShapeError, match="tau"):
        lagrax.simulate(system, Q, QD, params, t1=1.0, tau=jnp.zeros(3))


def test_tau_function_wrong_shape(arm):
    system, params = arm
    with pytest.raises(lagrax.ShapeError, match=r"tau\(t, q, qd\) returned shape \(3,\)"):
        lagrax.simulate(system, Q, QD, params, t1=1.0, tau=lambda t, q, qd: jnp.zeros(3))


def test_force_function_wrong_shape(arm_params):
    system = lagrax.LagrangianSystem(
        arm_model.kinetic, arm_model.potential, force=lambda t, q, qd, p: jnp.zeros(3), n_dof=2
    )
    with pytest.raises(lagrax.ShapeError, match=r"force function.*returned shape \(3,\)"):
        system.forward_dynamics(Q, QD, arm_params)


@pytest.mark.parametrize("bad", [jnp.zeros((1, 2)), jnp.zeros((2, 2)), jnp.float64(0.3)])
def test_q_not_one_dimensional(arm, bad):
    system, params = arm
    with pytest.raises(lagrax.ShapeError, match="1-D"):
        system.forward_dynamics(bad, QD, params)
    with pytest.raises(lagrax.ShapeError, match="1-D"):
        system.mass_matrix(bad, params)


def test_ts_not_one_dimensional(arm):
    system, params = arm
    with pytest.raises(lagrax.ShapeError, match="ts must be 1-D"):
        lagrax.simulate(system, Q, QD, params, t1=1.0, ts=jnp.zeros((2, 3)))


def test_t1_not_after_t0(arm):
    system, params = arm
    with pytest.raises(ValueError, match="t1 must be greater than t0"):
        lagrax.simulate(system, Q, QD, params, t0=1.0, t1=1.0)


def test_errors_are_lagrax_errors_and_builtin(arm):
    """What lagrax raises is caught both as the builtin error it refines and as a
    `LagraxError` of its own kind (checked on raised errors, not on the declarations)."""
    system, params = arm
    indefinite = lagrax.LagrangianSystem(lambda q, qd, p: -0.5 * jnp.sum(qd**2), n_dof=2)
    no_m2 = {k: v for k, v in params.items() if k != "m2"}
    cases = (
        (
            lambda: system.forward_dynamics(jnp.zeros(3), jnp.zeros(3), params),
            lagrax.ShapeError,
            ValueError,
        ),
        (lambda: system.forward_dynamics(Q, QD, no_m2), lagrax.ParameterError, KeyError),
        (
            lambda: system.forward_dynamics(jnp.array([jnp.nan, 0.0]), QD, params),
            lagrax.NonFiniteError,
            ValueError,
        ),
        (lambda: indefinite.forward_dynamics(Q, QD, {}), lagrax.MassMatrixError, ValueError),
        (
            lambda: lagrax.simulate(system, Q, QD, params, t1=100.0, max_steps=2),
            lagrax.SimulationError,
            RuntimeError,
        ),
    )
    for call, kind, builtin in cases:
        with pytest.raises(builtin) as info:
            call()
        assert type(info.value) is kind, f"{type(info.value).__name__}: {info.value}"
        assert isinstance(info.value, lagrax.LagraxError)


def test_unknown_model_parameter():
    with pytest.raises(TypeError, match="m3"):
        lagrax.models.planar_2r(m3=1.0)
    with pytest.raises(TypeError, match="zeta"):
        lagrax.models.mass_spring_damper(zeta=0.1)


# --------------------------------------------------------------------------- non-finite
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_q_eager(arm, bad):
    system, params = arm
    q = Q.at[1].set(bad)
    with pytest.raises(lagrax.NonFiniteError, match="q contains non-finite"):
        system.forward_dynamics(q, QD, params)
    with pytest.raises(lagrax.NonFiniteError, match="qd contains non-finite"):
        system.forward_dynamics(Q, q, params)
    with pytest.raises(lagrax.NonFiniteError, match="tau contains non-finite"):
        system.forward_dynamics(Q, QD, params, tau=q)


def test_non_finite_in_simulate(arm):
    system, params = arm
    with pytest.raises(lagrax.NonFiniteError, match="q contains non-finite"):
        lagrax.simulate(system, Q.at[0].set(jnp.nan), QD, params, t1=1.0)
    with pytest.raises(lagrax.NonFiniteError, match="qd contains non-finite"):
        lagrax.simulate(system, Q, QD.at[0].set(jnp.inf), params, t1=1.0)
    with pytest.raises(lagrax.NonFiniteError, match="tau"):
        lagrax.simulate(system, Q, QD, params, t1=1.0, tau=jnp.array([0.0, jnp.nan]))
    with pytest.raises(lagrax.NonFiniteError, match=r"params\['g'\]"):
        lagrax.simulate(system, Q, QD, {**params, "g": jnp.nan}, t1=1.0)


def test_non_finite_q_under_jit_raises_at_run_time(arm):
    system, params = arm
    fwd = jax.jit(lambda q: system.forward_dynamics(q, QD, params))
    assert np.all(np.isfinite(fwd(Q)))  # the same compiled function works on good input
    with pytest.raises(Exception, match="non-finite") as info:
        jax.block_until_ready(fwd(Q.at[0].set(jnp.nan)))
    assert "forward_dynamics" in str(info.value)


def test_simulate_under_jit_fails_at_run_time(arm):
    system, params = arm
    run = jax.jit(lambda q0: lagrax.simulate(system, q0, QD, params, t1=1.0, max_steps=10).q)
    with pytest.raises(Exception, match="lagrax.simulate failed"):
        jax.block_until_ready(run(Q))


# --------------------------------------------------------------------------- parameters
def test_missing_parameter_named(arm):
    system, params = arm
    bad = {k: v for k, v in params.items() if k != "m2"}
    with pytest.raises(lagrax.ParameterError, match="'m2'") as info:
        system.forward_dynamics(Q, QD, bad)
    msg = str(info.value)
    assert "kinetic energy" in msg and "m1" in msg  # says where and lists what is there
    with pytest.raises(lagrax.ParameterError, match="'m2'"):
        system.inverse_dynamics(Q, QD, QD, bad)
    with pytest.raises(lagrax.ParameterError, match="'m2'"):
        lagrax.simulate(system, Q, QD, bad, t1=1.0)
    with pytest.raises(lagrax.ParameterError, match="'m2'"):
        jax.jit(lambda q: system.forward_dynamics(q, QD, bad))(Q)


def test_missing_parameter_in_potential_and_force(msd):
    system, params = msd
    no_k = {k: v for k, v in params.items() if k != "k"}
    with pytest.raises(lagrax.ParameterError, match="potential energy.*'k'"):
        system.forward_dynamics(jnp.array([0.1]), jnp.array([0.0]), no_k)
    no_f0 = {k: v for k, v in params.items() if k != "f0"}
    with pytest.raises(lagrax.ParameterError, match="force.*'f0'"):
        system.forward_dynamics(jnp.array([0.1]), jnp.array([0.0]), no_f0)
    no_c = {k: v for k, v in params.items() if k != "c"}
    with pytest.raises(lagrax.ParameterError, match="dissipation.*'c'"):
        system.forward_dynamics(jnp.array([0.1]), jnp.array([0.0]), no_c)


# --------------------------------------------------------------------------- mass matrix
def test_singular_mass_matrix():
    system, params = lagrax.models.planar_2r(m2=0.0, I2=0.0)
    with pytest.raises(lagrax.MassMatrixError, match="singular or not positive-definite"):
        system.forward_dynamics(Q, QD, params)
    with pytest.raises(lagrax.MassMatrixError, match="eigenvalues") as info:
        system.check_state(Q, QD, params)
    assert "planar 2R arm" in str(info.value)
    with pytest.raises(lagrax.MassMatrixError, match="eigenvalues"):
        lagrax.simulate(system, Q, QD, params, t1=1.0)
    with pytest.raises(Exception, match="non-finite accelerations"):
        jax.block_until_ready(jax.jit(lambda q: system.forward_dynamics(q, QD, params))(Q))


def test_negative_kinetic_energy():
    system = lagrax.LagrangianSystem(lambda q, qd, p: -0.5 * qd[0] ** 2, n_dof=1, name="neg")
    q, qd = jnp.array([0.0]), jnp.array([1.0])
    with pytest.raises(lagrax.MassMatrixError, match="neg"):
        system.forward_dynamics(q, qd, {})
    with pytest.raises(lagrax.MassMatrixError, match="eigenvalues"):
        system.check_state(q, qd, {})


def _diag_kinetic(q, qd, p):
    return 0.5 * jnp.sum(p["d"] * qd**2)


@pytest.mark.parametrize(
    ("n", "bad_value"),
    # n = 1, 2, 3..6 (forward-over-forward, unrolled), 7, 8 (unrolled), 9+ (LAPACK); a
    # tiny positive entry is singular relative to the others (not for n = 1, where it is
    # the only entry)
    [(n, v) for n in (1, 2, 3, 7, 9) for v in (0.0, -1.0, 1e-18) if not (n == 1 and v > 0)],
)
def test_non_positive_definite_mass_matrix_every_solve_path(n, bad_value):
    system = lagrax.LagrangianSystem(_diag_kinetic, n_dof=n, name=f"diag{n}")
    d = jnp.ones(n).at[n // 2].set(bad_value)
    q, qd = jnp.zeros(n), jnp.ones(n)
    fwd = jax.jit(lambda q, p: system.forward_dynamics(q, qd, p, jnp.ones(n)))
    good = fwd(q, {"d": 2.0 * jnp.ones(n)})
    np.testing.assert_allclose(good, 0.5 * np.ones(n), rtol=1e-14)
    with pytest.raises(lagrax.MassMatrixError, match="eigenvalues"):
        system.forward_dynamics(q, qd, {"d": d}, tau=jnp.ones(n))
    with pytest.raises(Exception, match="non-finite accelerations"):
        jax.block_until_ready(fwd(q, {"d": d}))


# --------------------------------------------------------------------------- simulate
def test_max_steps_exceeded(arm):
    system, params = arm
    with pytest.raises(lagrax.SimulationError, match="max_steps") as info:
        lagrax.simulate(system, Q, QD, params, t1=10.0, max_steps=10)
    msg = str(info.value)
    assert "max_steps=10" in msg and "throw=False" in msg


def test_max_steps_exceeded_no_throw(arm):
    system, params = arm
    sol = lagrax.simulate(system, Q, QD, params, t1=10.0, max_steps=10, throw=False)
    assert not bool(sol.ok)
    assert int(sol.stats["num_steps"]) == 10
    q = np.asarray(sol.q)
    assert not np.any(np.isnan(q))  # never silently NaN ...
    assert np.all(np.isinf(q[-1])) and np.all(np.isinf(np.asarray(sol.qd)[-1]))  # ... but inf
    assert np.all(np.isfinite(q[0]))
    np.testing.assert_allclose(q[0], Q)


# --------------------------------------------------------------------------- regressions
def test_non_finite_force_is_not_blamed_on_mass_matrix(arm_params):
    system = lagrax.LagrangianSystem(
        arm_model.kinetic,
        arm_model.potential,
        force=lambda t, q, qd, p: jnp.stack([jnp.nan * q[0], 0.0 * q[1]]),
        n_dof=2,
    )
    with pytest.raises(lagrax.LagraxError) as info:
        system.forward_dynamics(Q, QD, arm_params)
    assert not isinstance(info.value, lagrax.MassMatrixError)
    assert "force" in str(info.value)


def test_unrelated_attribute_error_is_not_a_parameter_error():
    system = lagrax.LagrangianSystem(
        lambda q, qd, p: 0.5 * jnp.sum(qd**2) + jnp.sine(q[0]),
        n_dof=1,  # typo: sine
    )
    with pytest.raises(AttributeError, match="sine") as info:
        system.forward_dynamics(jnp.array([0.3]), jnp.array([0.0]), {})
    assert not isinstance(info.value, lagrax.ParameterError)


def test_missing_field_of_namedtuple_params_is_named():
    from typing import NamedTuple

    class P(NamedTuple):
        m: float

    def kinetic(q, qd, p):
        return 0.5 * p.m * qd[0] ** 2

    def potential(q, p):
        return 0.5 * p.k * q[0] ** 2  # k is not a field of P

    system = lagrax.LagrangianSystem(kinetic, potential, n_dof=1)
    with pytest.raises(lagrax.ParameterError, match="'k'") as info:
        system.forward_dynamics(jnp.array([0.1]), jnp.array([0.0]), P(m=1.0))
    assert "fields ['m']" in str(info.value)
