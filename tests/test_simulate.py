"""``lagrax.simulate`` against analytic solutions, conservation laws and finite differences."""

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import simpson

import lagrax
from lagrax.models import _planar_2r as arm_model

TIGHT = {"rtol": 1e-10, "atol": 1e-10}
ARM_P = {k: float(v) for k, v in arm_model.default_params().items()}


# --------------------------------------------------------------------------- helpers
def arm_energy(q, qd, p=ARM_P):
    """Closed-form T + V of the 2R arm, vectorized over the leading axis (NumPy)."""
    q, qd = np.asarray(q, float), np.asarray(qd, float)
    c2 = np.cos(q[..., 1])
    m11 = (
        p["I1"]
        + p["I2"]
        + p["m1"] * p["r1"] ** 2
        + p["m2"] * (p["l1"] ** 2 + p["r2"] ** 2 + 2 * p["l1"] * p["r2"] * c2)
    )
    m12 = p["I2"] + p["m2"] * (p["r2"] ** 2 + p["l1"] * p["r2"] * c2)
    m22 = p["I2"] + p["m2"] * p["r2"] ** 2
    a, b = qd[..., 0], qd[..., 1]
    kin = 0.5 * (m11 * a**2 + 2 * m12 * a * b + m22 * b**2)
    s1, s12 = np.sin(q[..., 0]), np.sin(q[..., 0] + q[..., 1])
    pot = p["g"] * (p["m1"] * p["r1"] * s1 + p["m2"] * (p["l1"] * s1 + p["r2"] * s12))
    return kin + pot


def arm_gravity(q, p=ARM_P):
    """Closed-form G(q) of the 2R arm (jnp, usable inside a controller)."""
    c1, c12 = jnp.cos(q[0]), jnp.cos(q[0] + q[1])
    return jnp.stack(
        [
            p["m1"] * p["g"] * p["r1"] * c1 + p["m2"] * p["g"] * (p["l1"] * c1 + p["r2"] * c12),
            p["m2"] * p["g"] * p["r2"] * c12,
        ]
    )


def msd_exact(t, x0, v0, m, k, c=0.0, f0=0.0, omega=1.0):
    """Exact x(t), v(t) of m x'' + c x' + k x = f0 cos(omega t), underdamped (c² < 4km)."""
    t = np.asarray(t, float)
    det = (k - m * omega**2) ** 2 + (c * omega) ** 2
    a = f0 * (k - m * omega**2) / det  # particular solution a cos(ωt) + b sin(ωt)
    b = f0 * c * omega / det
    xh0, vh0 = x0 - a, v0 - b * omega  # homogeneous part fitted to the initial state
    wn = np.sqrt(k / m)
    zeta = c / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta**2)
    sigma = zeta * wn
    cos, sin, env = np.cos(wd * t), np.sin(wd * t), np.exp(-sigma * t)
    beta = (vh0 + sigma * xh0) / wd
    xh = env * (xh0 * cos + beta * sin)
    vh = env * (-sigma * (xh0 * cos + beta * sin) + (-xh0 * wd * sin + beta * wd * cos))
    xp = a * np.cos(omega * t) + b * np.sin(omega * t)
    vp = omega * (-a * np.sin(omega * t) + b * np.cos(omega * t))
    return xh + xp, vh + vp


# --------------------------------------------------------------------------- (a) MSD
MSD_TS = np.linspace(0.0, 12.0, 241)


@pytest.mark.parametrize(
    "params",
    [
        pytest.param({"m": 1.0, "k": 4.0}, id="free-undamped"),
        pytest.param({"m": 2.0, "k": 8.0, "c": 0.8}, id="free-underdamped"),
        pytest.param({"m": 1.5, "k": 6.0, "c": 0.9, "f0": 2.5, "omega": 1.3}, id="forced-damped"),
        pytest.param({"m": 1.0, "k": 4.0, "c": 0.0, "f0": 1.0, "omega": 3.0}, id="forced-undamped"),
    ],
)
def test_mass_spring_damper_analytic(params):
    system, p = lagrax.models.mass_spring_damper(**params)
    x0, v0 = 0.7, -0.3
    sol = lagrax.simulate(system, [x0], [v0], p, t1=MSD_TS[-1], ts=MSD_TS, **TIGHT)
    x, v = msd_exact(MSD_TS, x0, v0, **params)
    assert sol.q.shape == (MSD_TS.size, 1)
    np.testing.assert_allclose(sol.ts, MSD_TS, rtol=0, atol=1e-14)
    np.testing.assert_allclose(sol.q[:, 0], x, rtol=0, atol=1e-7)
    np.testing.assert_allclose(sol.qd[:, 0], v, rtol=0, atol=1e-7)
    if params.get("c", 0.0) == 0.0 and params.get("f0", 0.0) == 0.0:
        w = np.sqrt(params["k"] / params["m"])  # the textbook form, once more
        np.testing.assert_allclose(
            sol.q[:, 0], x0 * np.cos(w * MSD_TS) + v0 / w * np.sin(w * MSD_TS), atol=1e-7
        )


def test_mass_spring_damper_nonuniform_ts_and_t0():
    params = {"m": 1.5, "k": 6.0, "c": 0.9, "f0": 2.5, "omega": 1.3}
    system, p = lagrax.models.mass_spring_damper(**params)
    t0 = 1.0
    ts = np.array([1.0, 1.05, 1.4, 2.0, 3.7, 4.0, 6.25])
    sol = lagrax.simulate(system, [0.2], [0.5], p, t0=t0, t1=ts[-1], ts=ts, **TIGHT)
    np.testing.assert_array_equal(np.asarray(sol.ts), ts)
    # the load is f0 cos(ω t) in absolute time, i.e. f0 cos(ω s + ω t0) in s = t − t0
    x_ref, v_ref = _msd_exact_phase(ts - t0, 0.2, 0.5, params, phase=params["omega"] * t0)
    np.testing.assert_allclose(sol.q[:, 0], x_ref, atol=1e-7)
    np.testing.assert_allclose(sol.qd[:, 0], v_ref, atol=1e-7)
    x_unforced, _ = msd_exact(ts - t0, 0.2, 0.5, m=params["m"], k=params["k"], c=params["c"])
    x_no_phase, _ = msd_exact(ts - t0, 0.2, 0.5, **params)
    assert np.max(np.abs(x_ref - x_unforced)) > 1e-2  # the forcing matters here
    assert np.max(np.abs(x_ref - x_no_phase)) > 1e-2  # and so does its phase at t0


def _msd_exact_phase(s, x0, v0, params, phase):
    """Exact response to f0 cos(ω s + φ) via a cos/sin superposition of ``msd_exact``."""
    m, k, c, f0, w = (params[n] for n in ("m", "k", "c", "f0", "omega"))
    # particular solution of m x'' + c x' + k x = f0 cos(ω s + φ): a cos(ωs+φ) + b sin(ωs+φ)
    det = (k - m * w**2) ** 2 + (c * w) ** 2
    a, b = f0 * (k - m * w**2) / det, f0 * c * w / det
    xp = a * np.cos(w * s + phase) + b * np.sin(w * s + phase)
    vp = w * (-a * np.sin(w * s + phase) + b * np.cos(w * s + phase))
    xp0 = a * np.cos(phase) + b * np.sin(phase)
    vp0 = w * (-a * np.sin(phase) + b * np.cos(phase))
    xh, vh = msd_exact(s, x0 - xp0, v0 - vp0, m=m, k=k, c=c)
    return xh + xp, vh + vp


# --------------------------------------------------------------------------- (b) energy
def test_energy_conservation_torque_free_arm(arm):
    system, params = arm
    q0, qd0 = np.array([0.5, 0.8]), np.array([1.0, -2.0])
    sol = lagrax.simulate(system, q0, qd0, params, t1=10.0, rtol=1e-11, atol=1e-11)
    assert bool(sol.ok)
    e_exact = arm_energy(sol.q, sol.qd)
    e0 = arm_energy(q0, qd0)
    # the stored energy is T + V of the saved states
    np.testing.assert_allclose(sol.energy, e_exact, rtol=1e-13, atol=1e-13 * abs(e0))
    drift = np.max(np.abs(e_exact - e0)) / abs(e0)
    # measured 3.4e-10 for this scene (Tsit5, rtol = atol = 1e-11); at rtol = atol = 1e-8
    # the drift is 2.6e-7, so the bound also checks that the tolerances are honoured
    assert drift < 3e-9, drift
    # energy_error: the change over max(|h0|, max (|T| + |V|)) along the saves
    e_saved = np.asarray(sol.energy)
    t_sv = jax.vmap(lambda a, b: system.kinetic_energy(a, b, params))(sol.q, sol.qd)
    v_sv = jax.vmap(lambda a: system.potential_energy(a, params))(sol.q)
    scale = max(abs(e_saved[0]), float(jnp.max(jnp.abs(t_sv) + jnp.abs(v_sv))))
    np.testing.assert_allclose(
        sol.energy_error, (e_saved - e_saved[0]) / scale, rtol=1e-12, atol=1e-16
    )
    # the motion is not trivial: the arm swings through a large range
    assert np.ptp(np.asarray(sol.q[:, 1])) > 1.0


# --------------------------------------------------------------------------- (c) power
def _damping(q, qd, p):
    return 0.5 * p["c"] * jnp.sum(qd**2)


DAMPED = lagrax.LagrangianSystem(
    arm_model.kinetic, arm_model.potential, dissipation=_damping, n_dof=2, name="damped arm"
)


def _drive(t, q, qd):
    return jnp.stack([1.5 * jnp.sin(2.0 * t), -0.8 * jnp.cos(3.0 * t)])


def test_energy_balance_with_input_and_damping():
    c = 0.4
    params = {**ARM_P, "c": c}
    q0, qd0 = np.array([0.2, -0.4]), np.array([0.5, 1.0])
    t1, n = 4.0, 4001
    sol = lagrax.simulate(
        DAMPED, q0, qd0, params, t1=t1, n_save=n, tau=_drive, rtol=1e-12, atol=1e-12
    )
    ts, qd = np.asarray(sol.ts), np.asarray(sol.qd)
    tau = np.stack([1.5 * np.sin(2.0 * ts), -0.8 * np.cos(3.0 * ts)], axis=1)
    power_in = np.sum(qd * tau, axis=1)
    power_loss = c * np.sum(qd**2, axis=1)  # q̇ · ∂D/∂q̇
    work_in, loss = simpson(power_in, x=ts), simpson(power_loss, x=ts)
    e = arm_energy(sol.q, qd)
    scale = simpson(np.abs(power_in), x=ts) + loss
    assert loss > 0.1 and abs(work_in) > 0.1  # both terms matter
    # measured residual 5e-14 of the scale (Simpson on 4001 points, rtol = atol = 1e-12)
    assert abs((e[-1] - e[0]) - (work_in - loss)) < 1e-9 * scale
    # and along the way, not only at the end
    mid = n // 2
    work_mid = simpson(power_in[: mid + 1] - power_loss[: mid + 1], x=ts[: mid + 1])
    assert abs((e[mid] - e[0]) - work_mid) < 1e-9 * scale


# --------------------------------------------------------------------------- (d) vmap
def test_vmap_simulate_over_params_matches_loop(arm):
    system, params = arm
    batch = {**params, "m2": jnp.array([0.5, 1.0, 2.0]), "l1": jnp.array([0.8, 1.0, 1.3])}
    axes = {k: 0 if k in ("m2", "l1") else None for k in batch}
    q0, qd0 = jnp.array([0.4, 0.3]), jnp.array([0.0, 0.5])

    def run(p):
        return lagrax.simulate(system, q0, qd0, p, t1=2.0, n_save=21, throw=False)

    sols = jax.vmap(run, in_axes=(axes,))(batch)
    assert sols.q.shape == (3, 21, 2)
    assert np.all(np.asarray(sols.ok))
    for i in range(3):
        pi = {**params, "m2": batch["m2"][i], "l1": batch["l1"][i]}
        ref = run(pi)
        np.testing.assert_allclose(sols.q[i], ref.q, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(sols.qd[i], ref.qd, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(sols.energy[i], ref.energy, rtol=1e-10, atol=1e-10)
    # the members differ, so the comparison is not vacuous
    assert np.max(np.abs(np.asarray(sols.q[0, -1] - sols.q[2, -1]))) > 1e-2


def test_vmap_simulate_bad_member_does_not_kill_batch(arm):
    system, params = arm
    batch = {**params, "m2": jnp.array([1.0, 0.0]), "I2": jnp.array([1 / 12, 0.0])}
    axes = {k: 0 if k in ("m2", "I2") else None for k in batch}
    sols = jax.vmap(
        lambda p: lagrax.simulate(
            system,
            jnp.array([0.4, 0.3]),
            jnp.zeros(2),
            p,
            t1=1.0,
            n_save=21,
            max_steps=200,
            throw=False,
        ),
        in_axes=(axes,),
    )(batch)
    ok = np.asarray(sols.ok)
    assert ok[0] and not ok[1]
    assert np.all(np.isfinite(np.asarray(sols.q[0])))
    ref = lagrax.simulate(system, [0.4, 0.3], [0.0, 0.0], params, t1=1.0, n_save=21)
    np.testing.assert_allclose(sols.q[0], ref.q, rtol=1e-10, atol=1e-10)


# --------------------------------------------------------------------------- (e) gradients
def test_grad_of_final_state_matches_finite_differences(arm):
    system, params = arm
    qd0 = jnp.array([0.2, -0.1])
    weights = jnp.array([1.0, -0.5])
    opts = {"t1": 1.5, "n_save": 2, "rtol": 1e-12, "atol": 1e-12, "throw": False}

    def final(m2, q0):
        sol = lagrax.simulate(system, q0, qd0, {**params, "m2": m2}, **opts)
        return jnp.dot(weights, sol.q[-1]) + 0.3 * sol.qd[-1, 1]

    # one compiled function gives both the gradient and the values for the differences
    value_and_grad = jax.jit(jax.value_and_grad(final, argnums=(0, 1)))
    m2, q0 = jnp.asarray(1.2), jnp.array([0.6, 0.4])
    _, (g_m2, g_q0) = value_and_grad(m2, q0)

    def f(m2, q0):
        return float(value_and_grad(m2, q0)[0])

    h = 1e-4
    fd_m2 = (f(m2 + h, q0) - f(m2 - h, q0)) / (2 * h)
    fd_q0 = np.array(
        [(f(m2, q0.at[i].add(h)) - f(m2, q0.at[i].add(-h))) / (2 * h) for i in range(2)]
    )
    assert abs(fd_m2) > 1e-2
    np.testing.assert_allclose(g_m2, fd_m2, rtol=1e-5)
    np.testing.assert_allclose(g_q0, fd_q0, rtol=1e-5)


# --------------------------------------------------------------------------- (f) options
def test_n_save_and_default_save_grid(arm):
    system, params = arm
    sol = lagrax.simulate(system, [0.4, 0.3], [0.0, 0.0], params, t1=1.0, n_save=21)
    np.testing.assert_allclose(sol.ts, np.linspace(0.0, 1.0, 21), rtol=0, atol=1e-15)
    assert sol.q.shape == sol.qd.shape == (21, 2) and sol.energy.shape == (21,)
    np.testing.assert_allclose(sol.q[0], [0.4, 0.3])
    sol = lagrax.simulate(system, [0.4, 0.3], [0.0, 0.0], params, t0=0.5, t1=1.0)
    assert sol.ts.shape == (501,) and sol.q.shape == (501, 2)
    np.testing.assert_allclose(np.asarray(sol.ts)[[0, -1]], [0.5, 1.0], rtol=0, atol=1e-15)


def test_custom_saveat_and_solver(msd):
    system, p = msd  # unit oscillator: x = cos t from (1, 0)
    sol = lagrax.simulate(
        system,
        [1.0],
        [0.0],
        p,
        t1=2.0,
        saveat=dfx.SaveAt(t1=True),
        solver=dfx.Dopri8(),
        **TIGHT,
    )
    assert sol.q.shape == (1, 1)
    np.testing.assert_allclose(sol.q[0, 0], np.cos(2.0), atol=1e-8)


def test_constant_tau_holds_arm_in_static_equilibrium(arm):
    system, params = arm
    q_star = np.array([0.8, -0.5])
    hold = np.asarray(arm_gravity(q_star))
    sol = lagrax.simulate(system, q_star, [0.0, 0.0], params, t1=2.0, n_save=21, tau=hold)
    np.testing.assert_allclose(sol.q, np.broadcast_to(q_star, sol.q.shape), atol=1e-9)
    np.testing.assert_allclose(sol.qd, 0.0, atol=1e-9)
    # without the holding torque (or with the wrong one) the arm falls
    sol = lagrax.simulate(system, q_star, [0.0, 0.0], params, t1=2.0, n_save=21, tau=0.9 * hold)
    assert np.max(np.abs(np.asarray(sol.q[-1]) - q_star)) > 0.1


def test_tau_callable_pd_controller_reaches_target(arm):
    system, params = arm
    q_star = jnp.array([0.8, -0.5])
    kp, kd = 100.0, 20.0

    def controller(t, q, qd):
        return arm_gravity(q) + kp * (q_star - q) - kd * qd

    sol = lagrax.simulate(system, [0.0, 0.0], [0.0, 0.0], params, t1=8.0, n_save=81, tau=controller)
    np.testing.assert_allclose(sol.q[-1], q_star, atol=1e-6)
    np.testing.assert_allclose(sol.qd[-1], 0.0, atol=1e-6)
    assert np.max(np.abs(np.asarray(sol.q[1]) - np.asarray(q_star))) > 0.1  # it moved there


def test_changing_tolerances_params_state_does_not_retrace():
    traces = []

    def kinetic(q, qd, p):
        if isinstance(jax.lax.stop_gradient(q), jax.core.Tracer):
            traces.append(1)  # abstract: we are being traced, not evaluated
        return arm_model.kinetic(q, qd, p)

    system = lagrax.LagrangianSystem(kinetic, arm_model.potential, n_dof=2, name="counted")
    params = arm_model.default_params()
    opts = {"n_save": 11}
    sol1 = lagrax.simulate(system, [0.4, 0.3], [0.0, 0.0], params, t1=1.0, rtol=1e-6, **opts)
    first = len(traces)
    assert first > 0  # the counter does see tracing
    params2 = {**params, "m2": jnp.asarray(1.7), "g": jnp.asarray(3.0)}
    sol2 = lagrax.simulate(
        system, [0.1, -0.2], [0.3, 0.1], params2, t1=1.5, rtol=1e-9, atol=1e-10, **opts
    )
    sol3 = lagrax.simulate(system, [0.4, 0.3], [0.0, 0.0], params, t1=1.0, rtol=1e-6, **opts)
    assert len(traces) == first
    # the second call really used its own values
    assert not np.allclose(sol1.q[-1], sol2.q[-1])
    np.testing.assert_array_equal(sol3.q, sol1.q)
    np.testing.assert_allclose(sol2.ts[-1], 1.5)


def test_each_system_gets_its_own_compiled_solve():
    """`simulate` keeps compiled solves by the identity of the system and settings (a
    front cache) and, on a miss, by value. Systems made one after another (the old one
    dropped, so its id may be reused by Python) each get their own dynamics: a harmonic
    oscillator of stiffness k_i matches cos(√k_i t), whatever ran before it."""

    def oscillator(k):
        return lagrax.LagrangianSystem(
            lambda q, qd, p: 0.5 * qd[0] ** 2, lambda q, p: 0.5 * k * q[0] ** 2, n_dof=1
        )

    for k in (1.0, 4.0, 9.0, 4.0):
        system = oscillator(k)
        sol = lagrax.simulate(system, [1.0], [0.0], {}, t1=1.0, n_save=3, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(sol.q[:, 0], np.cos(np.sqrt(k) * sol.ts), atol=1e-8)
        # the same object again, with another save grid and step: its own program too
        sol = lagrax.simulate(system, [1.0], [0.0], {}, t1=1.0, n_save=5, dt=1e-3, solver="rk4")
        np.testing.assert_allclose(sol.q[:, 0], np.cos(np.sqrt(k) * sol.ts), atol=1e-8)
        del system


def test_one_system_with_inputs_of_other_structures(arm):
    """One system and settings, called with inputs of other structures in turn (a
    constant `tau` adds the work to the solution, weakly typed parameters trace anew):
    each call gets the solution of its own structure back, also when an earlier trace is
    reused."""
    system, params = arm
    weak = {k: jnp.asarray(float(v)) for k, v in params.items()}  # weakly typed scalars
    q0, qd0 = [0.3, 0.2], [0.0, 0.0]
    plain = lagrax.simulate(system, q0, qd0, params, t1=0.5, n_save=7)
    driven = lagrax.simulate(system, q0, qd0, params, t1=0.5, n_save=7, tau=[0.1, 0.0])
    again = lagrax.simulate(system, q0, qd0, weak, t1=0.5, n_save=7)
    twice = lagrax.simulate(system, q0, qd0, params, t1=0.5, n_save=7)
    assert plain.work is None and twice.work is None and again.work is None
    assert driven.work is not None and driven.work.shape == (7,)
    np.testing.assert_array_equal(twice.q, plain.q)
    np.testing.assert_allclose(again.q, plain.q, rtol=1e-12)


# --------------------------------------------------------------------------- (g) float32
def test_float32_simulation(arm):
    system, _ = arm
    p32 = arm_model.default_params(jnp.float32)
    q0 = np.array([0.5, 0.8], np.float32)
    qd0 = np.zeros(2, np.float32)
    sol = lagrax.simulate(system, q0, qd0, p32, t1=1.0, n_save=11, rtol=1e-5, atol=1e-5)
    for arr in (sol.ts, sol.q, sol.qd, sol.energy):
        assert arr.dtype == jnp.float32
    ref = lagrax.simulate(
        system, q0.astype(float), qd0.astype(float), ARM_P, t1=1.0, n_save=11, **TIGHT
    )
    assert ref.q.dtype == jnp.float64
    np.testing.assert_allclose(sol.q, ref.q, rtol=0, atol=2e-4)
    np.testing.assert_allclose(sol.qd, ref.qd, rtol=0, atol=1e-3)


# --------------------------------------------------------------------------- regressions
def test_python_float_params_do_not_retrace():
    traces = []

    def kinetic(q, qd, p):
        if isinstance(jax.lax.stop_gradient(q), jax.core.Tracer):
            traces.append(1)
        return arm_model.kinetic(q, qd, p)

    system = lagrax.LagrangianSystem(kinetic, arm_model.potential, n_dof=2, name="counted")
    lagrax.simulate(system, [0.4, 0.3], [0.0, 0.0], ARM_P, t1=1.0, n_save=11)
    first = len(traces)
    lagrax.simulate(system, [0.4, 0.3], [0.0, 0.0], {**ARM_P, "m2": 1.7}, t1=1.0, n_save=11)
    assert len(traces) == first
