"""Identification through ``simulate``: fit ``m2, r2`` of the 2R arm from a trajectory.

The small, fast version of notebook 06: Levenberg–Marquardt (optimistix) on the residuals
``q_model(t_k; m2, r2) − q_data(t_k)``, with the Jacobian by reverse-mode autodiff through
the ODE solve. Noise-free data must give back the true values to 1e-6; noisy data must
land within four standard errors (from the Gauss–Newton covariance ``σ² (JᵀJ)⁻¹``).
"""

import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

import lagrax as lx

TRUE = jnp.array([1.3, 0.42])  # m2 [kg], r2 [m]
GUESS = jnp.array([0.8, 0.6])
SIGMA = 0.01  # rad, the noise on the measured angles
TS = jnp.linspace(0.0, 1.5, 31)
Q0, QD0 = jnp.array([0.4, 0.9]), jnp.zeros(2)


@pytest.fixture(scope="module")
def problem():
    system, params = lx.models.planar_2r()

    def trajectory(y):
        p = {**params, "m2": y[0], "r2": y[1]}
        sol = lx.simulate(system, Q0, QD0, p, t1=1.5, ts=TS, rtol=1e-10, atol=1e-10)
        return sol.q

    def residuals(y, q_obs):
        return (trajectory(y) - q_obs).ravel()

    def fit(q_obs):
        solver = optx.LevenbergMarquardt(rtol=1e-10, atol=1e-10)
        out = optx.least_squares(
            residuals, solver, GUESS, args=q_obs, options={"jac": "bwd"}, max_steps=100
        )
        return out.value, int(out.stats["num_steps"])

    return trajectory, residuals, fit


@pytest.mark.slow
def test_noise_free_recovers_parameters(problem):
    trajectory, _, fit = problem
    value, steps = fit(trajectory(TRUE))
    np.testing.assert_allclose(value, TRUE, rtol=1e-6)
    assert steps < 50


def test_noisy_fit_within_its_standard_errors(problem):
    trajectory, _, fit = problem
    q_clean = trajectory(TRUE)
    noise = SIGMA * np.random.default_rng(0).standard_normal(q_clean.shape)
    q_obs = q_clean + noise
    value, _ = fit(q_obs)
    # standard errors from J = ∂q/∂(m2, r2) at the fit, by central differences (the
    # forward solve is compiled already; a reverse-mode Jacobian would compile again)
    h = 1e-6
    jac = np.stack(
        [
            (np.asarray(trajectory(value + h * e)) - np.asarray(trajectory(value - h * e))).ravel()
            / (2 * h)
            for e in np.eye(2)
        ],
        axis=1,
    )
    std = SIGMA * np.sqrt(np.diag(np.linalg.inv(jac.T @ jac)))
    z = np.abs(np.asarray(value - TRUE)) / std
    assert np.all(z < 4.0), (value, std)
    assert np.all(np.abs(np.asarray(value / TRUE - 1)) < 0.02)  # and within 2 %
