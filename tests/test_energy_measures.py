"""Honest energy measures: ``Solution.energy_error`` is the balance residual
``h − h₀ − W`` (``W`` the work of inputs, dissipation and explicit time dependence) over a
scale that cannot vanish on a moving system; ``sweep`` reports the same balance."""

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx

PEND = {"m": 1.3, "l": 0.8, "g": 9.81}


def _pend_T(q, qd, p):
    return 0.5 * p["m"] * p["l"] ** 2 * qd[0] ** 2


def _pend_V(q, p):
    return -p["m"] * p["g"] * p["l"] * jnp.cos(q[0])


def test_pendulum_released_from_horizontal_has_a_finite_error():
    """h(0) = 0 up to round-off (cos(π/2) ≈ 6e-17): the old |h0|-relative measure reads
    8e8 here; the residual over max(|h0|, max(|T| + |V|)) reads the integrator's
    error."""
    system = lx.LagrangianSystem(_pend_T, _pend_V, n_dof=1)
    sol = lx.simulate(system, [np.pi / 2], [0.0], PEND, t1=4.0, n_save=201)
    h = np.asarray(sol.energy)
    assert abs(h[0]) < 1e-14
    # the scale from the saved states, computed independently: T + |V| is largest at
    # the bottom, 2 m g l there (the saves come close)
    theta, thetad = np.asarray(sol.q[:, 0]), np.asarray(sol.qd[:, 0])
    mag = 0.5 * PEND["m"] * PEND["l"] ** 2 * thetad**2
    mag = mag + np.abs(PEND["m"] * PEND["g"] * PEND["l"] * np.cos(theta))
    np.testing.assert_allclose(sol.energy_scale, mag.max(), rtol=1e-12)
    bottom = 2 * PEND["m"] * PEND["g"] * PEND["l"]
    assert 0.99 * bottom < float(sol.energy_scale) <= bottom * (1 + 1e-9)
    np.testing.assert_allclose(sol.energy_error, (h - h[0]) / mag.max(), rtol=1e-12, atol=0)
    np.testing.assert_allclose(sol.energy_balance, h - h[0], atol=0)
    err = np.abs(np.asarray(sol.energy_error))
    assert np.all(np.isfinite(err)) and err.max() < 1e-7  # measured 2.3e-8 at rtol 1e-8
    assert err.max() > 1e-12  # a real (integrator) error, not a zero by construction
    old = np.abs(h - h[0]).max() / abs(h[0])  # what the |h0|-relative measure reads
    assert old > 1e3


def _damped_driven(t, x0, v0, p):
    """m ẍ + c ẋ + k x = f0 cos ω t, underdamped: the steady response (A cos + B sin) plus
    the decaying homogeneous one matched to (x0, v0)."""
    m, k, c, f0, w = (p[key] for key in ("m", "k", "c", "f0", "omega"))
    det = (k - m * w**2) ** 2 + (c * w) ** 2
    a, b = f0 * (k - m * w**2) / det, f0 * c * w / det
    gam, wd = c / (2 * m), np.sqrt(k / m - (c / (2 * m)) ** 2)
    c1 = x0 - a
    c2 = (v0 + gam * c1 - b * w) / wd
    env = np.exp(-gam * t)
    x = env * (c1 * np.cos(wd * t) + c2 * np.sin(wd * t)) + a * np.cos(w * t) + b * np.sin(w * t)
    v = env * ((-gam * c1 + wd * c2) * np.cos(wd * t) + (-gam * c2 - wd * c1) * np.sin(wd * t))
    v = v - a * w * np.sin(w * t) + b * w * np.cos(w * t)
    return x, v


@pytest.fixture(scope="module")
def msd():
    system, params = lx.models.mass_spring_damper()
    return system, {**params, "k": jnp.asarray(4.0), "c": jnp.asarray(0.3)}


@pytest.mark.parametrize("f0", [0.0, 0.8])
def test_damped_and_driven_work_closes_the_balance(msd, f0):
    """The work of the damper and the load, integrated along the saves, equals the change
    of h = ½ m v² + ½ k x² of the closed-form motion; the change is O(1), the residual
    (energy_error) the integrator's."""
    system, params = msd
    params = {**params, "f0": jnp.asarray(f0), "omega": jnp.asarray(1.7)}
    ts = np.linspace(0.0, 12.0, 241)
    sol = lx.simulate(system, [1.0], [0.5], params, t1=12.0, ts=ts, rtol=1e-11, atol=1e-11)
    p = {k: float(v) for k, v in params.items()}
    x, v = _damped_driven(ts, 1.0, 0.5, p)
    h = 0.5 * p["m"] * v**2 + 0.5 * p["k"] * x**2
    assert sol.work is not None
    # measured 1.0e-10 (damped) and 1.2e-10 (driven); energy_error 5e-11, 6e-11
    np.testing.assert_allclose(sol.work, h - h[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.energy_change, h - h[0], rtol=0, atol=1e-9)
    assert np.abs(h - h[0]).max() > 0.5  # the change is physics, and large
    assert float(np.max(np.abs(sol.energy_error))) < 1e-9
    # without the dissipation's work the residual would be the whole change
    np.testing.assert_allclose(sol.energy_balance, sol.energy_change - sol.work, atol=0)


def test_conservative_system_has_no_work(msd):
    system, params = msd
    sol = lx.simulate(system, [1.0], [0.0], {**params, "c": jnp.asarray(0.0)}, t1=1.0, n_save=11)
    # the model has a force function (f0 = 0 here) and a dissipation (c = 0): both are
    # in the balance, contributing zero work
    np.testing.assert_allclose(sol.work, 0.0, atol=1e-15)
    free = lx.LagrangianSystem(_pend_T, _pend_V, n_dof=1)
    assert lx.simulate(free, [0.3], [0.0], PEND, t1=1.0, n_save=11).work is None


# a spring whose stiffness is modulated in time: V = ½ k0 (1 + ε sin ν t) x²
def _timed_T(t, q, qd, p):
    return 0.5 * p["m"] * qd[0] ** 2


def _timed_V(t, q, p):
    return 0.5 * p["k"] * (1.0 + p["eps"] * jnp.sin(p["nu"] * t)) * q[0] ** 2


TIMED = {"m": 1.0, "k": 3.0, "eps": 0.4, "nu": 2.5}


def test_sweep_reports_the_same_balance_as_simulate(msd):
    """A time-dependent system and a damped, driven one in sweep(keep="final"): the
    energy_error is the balance residual at t1, as simulate's (it was NaN for the
    time-dependent one and the relative change of h for the damped one)."""
    timed = lx.LagrangianSystem(_timed_T, _timed_V, n_dof=1, time_dependent=True)
    ks = np.array([2.0, 3.0, 5.0])
    grid = lx.grid({k: jnp.asarray(v) for k, v in TIMED.items()}, k=ks)
    kw = dict(t1=6.0, rtol=1e-10, atol=1e-10)
    ds = lx.sweep(timed, [1.0], [0.0], grid, progress=False, **kw)
    err = ds.energy_error.values
    change = ds.energy_change.values
    assert np.all(np.isfinite(err)) and np.abs(err).max() < 1e-8
    assert np.abs(change).min() > 0.05  # the modulation pumps energy: not conserved
    ref = lx.simulate(timed, [1.0], [0.0], {**TIMED, "k": 5.0}, n_save=101, **kw)
    np.testing.assert_allclose(change[-1], ref.energy_change[-1], rtol=1e-8)
    # the work integrated with the state on the same steps: measured equal (−3.04e-10
    # both; −1.04e-9 when a Hermite rule over the saves formed it)
    np.testing.assert_allclose(err[-1], ref.energy_error[-1], rtol=0, atol=1e-12)
    assert abs(float(ref.energy_error[-1])) < 1e-8

    system, params = msd
    params = {**params, "f0": jnp.asarray(0.8), "omega": jnp.asarray(1.7)}
    ds = lx.sweep(system, [1.0], [0.5], lx.grid(params, c=[0.1, 0.3]), progress=False, **kw)
    x, v = _damped_driven(6.0, 1.0, 0.5, {**{k: float(a) for k, a in params.items()}, "c": 0.3})
    h0, h1 = 0.5 * 4.0 * 1.0 + 0.5 * 0.5**2, 0.5 * v**2 + 0.5 * 4.0 * x**2
    np.testing.assert_allclose(ds.energy_change.values[1], h1 - h0, rtol=0, atol=1e-8)
    assert np.abs(ds.energy_error.values).max() < 1e-8
