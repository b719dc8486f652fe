"""Velocity (non-holonomic) constraints ``A(q) q̇ = 0``: the knife edge and the vertical
rolling disk against their closed-form motions, multipliers against the constraint forces
of those closed forms, a mixed holonomic + velocity system, drift under Baumgarte
stabilization, the projection of initial velocities, and the errors for bad input."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import lagrax as lx

TIGHT = {"rtol": 1e-12, "atol": 1e-12}


# --------------------------------------------------------------------------- knife edge
# q = (x, y, θ): a blade at (x, y) pointing along θ, mass m, moment of inertia I about
# the vertical; no velocity across the blade: −sin θ ẋ + cos θ ẏ = 0. A thrust F along the
# blade and no torque.
KNIFE = {"m": 1.3, "I": 0.2, "F": 0.7}
TH0, OMEGA, V0 = 0.3, 0.9, 1.1  # initial heading, turn rate, speed along the blade
X0, Y0 = 0.5, -0.2


def _knife_T(q, qd, p):
    return 0.5 * p["m"] * (qd[0] ** 2 + qd[1] ** 2) + 0.5 * p["I"] * qd[2] ** 2


def _flat(q, p):
    return 0.0 * q[0]


def _thrust(t, q, qd, p):  # F along the blade, no torque
    return p["F"] * jnp.stack([jnp.cos(q[2]), jnp.sin(q[2]), 0.0 * q[2]])


def _blade(q, p):
    return jnp.stack([-jnp.sin(q[2]), jnp.cos(q[2]), 0.0 * q[2]])[None]


def knife_exact(t, a):
    """The closed form: no torque and no work by the lateral force keep θ̇ = ω; the speed
    along the blade obeys m v̇ = F, v = v₀ + a t (a = F/m); (ẋ, ẏ) = v (cos θ, sin θ)
    integrate to Fresnel-free expressions (∫ s cos(θ₀ + ω s) ds by parts). The lateral
    (constraint) force is the centripetal one, μ = m v ω."""
    th = TH0 + OMEGA * t
    v = V0 + a * t
    x = X0 + V0 * (np.sin(th) - np.sin(TH0)) / OMEGA
    x = x + a * (t * np.sin(th) / OMEGA + (np.cos(th) - np.cos(TH0)) / OMEGA**2)
    y = Y0 + V0 * (np.cos(TH0) - np.cos(th)) / OMEGA
    y = y + a * (-t * np.cos(th) / OMEGA + (np.sin(th) - np.sin(TH0)) / OMEGA**2)
    return x, y, th, v


@pytest.fixture(scope="module")
def knife():
    free = lx.LagrangianSystem(_knife_T, _flat, force=_thrust, n_dof=3, name="skate")
    return lx.ConstrainedSystem(free, None, velocity_constraints=_blade)


def _knife_start():
    q0 = np.array([X0, Y0, TH0])
    qd0 = np.array([V0 * np.cos(TH0), V0 * np.sin(TH0), OMEGA])
    return q0, qd0


# one save grid shape for every knife-edge solve (the drift test's too), so that the
# solves share one compiled program
KNIFE_TS = np.linspace(0.0, 10.0, 801)


@pytest.mark.parametrize("thrust", [KNIFE["F"], 0.0])
def test_knife_edge_closed_form(knife, thrust):
    """With thrust: the spiral of the closed form; without: a circle of radius v₀/ω."""
    p = {**KNIFE, "F": thrust}
    sol = lx.simulate(knife, *_knife_start(), p, t1=10.0, ts=KNIFE_TS, **TIGHT)
    assert bool(sol.ok)
    x, y, th, v = knife_exact(KNIFE_TS, thrust / KNIFE["m"])
    q = np.asarray(sol.q)
    # measured: 6e-13 (x, y), 1e-13 (θ)
    np.testing.assert_allclose(q[:, 0], x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(q[:, 1], y, rtol=0, atol=1e-9)
    np.testing.assert_allclose(q[:, 2], th, rtol=0, atol=1e-9)
    # the lateral force on the blade is the centripetal force m v ω (measured 1.7e-11)
    assert sol.multipliers.shape == (KNIFE_TS.size, 1)
    np.testing.assert_allclose(sol.multipliers[:, 0], KNIFE["m"] * v * OMEGA, rtol=0, atol=1e-8)
    assert sol.constraint_violation is None  # no holonomic constraints
    assert sol.velocity_constraint_violation.shape == (KNIFE_TS.size, 1)
    assert float(np.max(np.abs(sol.velocity_constraint_violation))) < 1e-10
    if thrust == 0.0:
        cx, cy = X0 - V0 * np.sin(TH0) / OMEGA, Y0 + V0 * np.cos(TH0) / OMEGA
        np.testing.assert_allclose(np.hypot(q[:, 0] - cx, q[:, 1] - cy), V0 / OMEGA, atol=1e-9)
        # the blade's force does no work: h = T is conserved
        assert float(np.max(np.abs(sol.energy_error))) < 1e-10
    else:  # the thrust's work F Δs is the whole change of h (see test_energy_measures)
        s = V0 * KNIFE_TS + 0.5 * thrust / KNIFE["m"] * KNIFE_TS**2
        np.testing.assert_allclose(sol.energy_change, thrust * s, rtol=0, atol=1e-9)


def test_knife_edge_at_a_state(knife):
    """q̈, μ and the constraint force at one state against the closed form, eager, under
    jit and vmap, and with gradients (forward and reverse)."""
    th, v, w = 1.1, -0.6, 2.3
    q = jnp.asarray([0.2, 0.4, th])
    qd = jnp.asarray([v * np.cos(th), v * np.sin(th), w])
    e_t, e_n = np.array([np.cos(th), np.sin(th)]), np.array([-np.sin(th), np.cos(th)])
    a = KNIFE["F"] / KNIFE["m"]
    qdd = np.concatenate([a * e_t + v * w * e_n, [0.0]])
    np.testing.assert_allclose(knife.forward_dynamics(q, qd, KNIFE), qdd, atol=1e-13)
    mu = KNIFE["m"] * v * w
    np.testing.assert_allclose(knife.multipliers(q, qd, KNIFE), [mu], atol=1e-13)
    np.testing.assert_allclose(
        knife.constraint_forces(q, qd, KNIFE), np.concatenate([mu * e_n, [0.0]]), atol=1e-13
    )
    np.testing.assert_allclose(knife.constraint_matrix(q, KNIFE), [[*e_n, 0.0]], atol=1e-15)
    assert knife.violation(q, KNIFE).shape == (0,)
    np.testing.assert_allclose(knife.velocity_violation(q, qd, KNIFE), [0.0], atol=1e-15)
    # under jit (also vmap, gradients, float32: jitted, as op-by-op dispatch is slow)
    fd = jax.jit(lambda a, b, p: knife.forward_dynamics(a, b, p))
    np.testing.assert_allclose(fd(q, qd, KNIFE), qdd, atol=1e-13)
    batch = jax.jit(jax.vmap(lambda b: knife.forward_dynamics(q, b, KNIFE)))(jnp.stack([qd, -qd]))
    np.testing.assert_allclose(batch[0], qdd, atol=1e-13)
    check_grads(lambda a, b: fd(a, b, KNIFE), (q, qd), order=1, modes=("fwd", "rev"))
    # float32 stays float32
    p32 = {k: jnp.float32(v) for k, v in KNIFE.items()}
    out32 = fd(q.astype(jnp.float32), qd.astype(jnp.float32), p32)
    assert out32.dtype == jnp.float32
    np.testing.assert_allclose(out32, qdd, atol=1e-5)


def test_drift_is_bounded_by_baumgarte(knife):
    """Loose tolerances over a long horizon (about 57 turns): with the velocity-level
    Baumgarte term the violation |A q̇| stays at the integrator's error (measured 2.0e-6
    in both halves); without it, it grows (3.6e-5, then 7.3e-5) and h drifts."""
    ts = 40.0 * KNIFE_TS
    p = {**KNIFE, "F": 0.0}
    out = {}
    for beta in (10.0, 0.0):
        system = knife
        if beta != knife.beta:
            system = lx.ConstrainedSystem(
                knife.system, None, velocity_constraints=_blade, beta=beta
            )
        sol = lx.simulate(system, *_knife_start(), p, t1=400.0, ts=ts, rtol=1e-6, atol=1e-6)
        assert bool(sol.ok)
        v = np.abs(np.asarray(sol.velocity_constraint_violation[:, 0]))
        out[beta] = (v[:400].max(), v[400:].max(), np.abs(np.asarray(sol.energy_error)).max())
    first, second, energy = out[10.0]
    assert second < 1e-5 and second < 1.5 * first  # bounded, not growing
    assert energy < 1e-5
    first0, second0, energy0 = out[0.0]
    assert second0 > 1.5 * first0 and second0 > 10 * second  # the drift it prevents
    assert energy0 > 100 * energy


# --------------------------------------------------------------------- vertical rolling disk
# q = (x, y, θ, φ): contact point (x, y), heading θ, spin angle φ of a disk of radius R
# held vertical, rolling without slipping: ẋ = R φ̇ cos θ, ẏ = R φ̇ sin θ.
DISK = {"m": 2.0, "R": 0.35}
I_SPIN = 0.5 * DISK["m"] * DISK["R"] ** 2  # about the axle
I_TURN = 0.25 * DISK["m"] * DISK["R"] ** 2  # about a vertical diameter


def _disk_T(q, qd, p):
    i_spin, i_turn = 0.5 * p["m"] * p["R"] ** 2, 0.25 * p["m"] * p["R"] ** 2
    trans = 0.5 * p["m"] * (qd[0] ** 2 + qd[1] ** 2)
    return trans + 0.5 * i_turn * qd[2] ** 2 + 0.5 * i_spin * qd[3] ** 2


def _rolling(q, p):
    zero, one = 0.0 * q[0], 1.0 + 0.0 * q[0]
    c, s = jnp.cos(q[2]), jnp.sin(q[2])
    return jnp.stack(
        [jnp.stack([one, zero, zero, -p["R"] * c]), jnp.stack([zero, one, zero, -p["R"] * s])]
    )


@pytest.fixture(scope="module")
def disk():
    free = lx.LagrangianSystem(_disk_T, _flat, n_dof=4, name="disk")
    return lx.ConstrainedSystem(free, velocity_constraints=_rolling, name="rolling disk")


def test_rolling_disk_circle_and_projection(disk):
    """Start with a velocity that slips; the projection gives the admissible velocity of
    least kinetic-energy change (angular momentum about the contact line conserved by the
    impulsive constraint): θ̇ unchanged, spin Ω = (m R e·v + I_s φ̇)/(m R² + I_s). Then
    the motion is the closed form: constant turn rate ω and spin Ω, the centre on a circle
    of radius R Ω/ω, the friction force m R Ω ω toward its centre."""
    m, R = DISK["m"], DISK["R"]
    th0, w, spin0 = -0.4, 1.7, 6.0
    v_slip = np.array([0.8, -1.5])  # not along the heading
    q0 = np.array([0.1, 0.3, th0, 0.2])
    qd0 = np.array([*v_slip, w, spin0])
    e0 = np.array([np.cos(th0), np.sin(th0)])
    spin = (m * R * e0 @ v_slip + I_SPIN * spin0) / (m * R**2 + I_SPIN)
    q1, qd1 = disk.project(q0, qd0, DISK)
    np.testing.assert_allclose(q1, q0, atol=0)  # no holonomic constraint: q stays
    np.testing.assert_allclose(qd1, [*(R * spin * e0), w, spin], atol=1e-14)

    ts = np.linspace(0.0, 6.0, 61)
    # (a zero tau: the same compiled solve as the driven test's)
    sol = lx.simulate(disk, q0, qd0, DISK, t1=6.0, ts=ts, tau=jnp.zeros(4), **TIGHT)
    assert bool(sol.ok)
    th, phi = th0 + w * ts, 0.2 + spin * ts
    radius = R * spin / w
    cx, cy = 0.1 - radius * np.sin(th0), 0.3 + radius * np.cos(th0)
    q = np.asarray(sol.q)
    np.testing.assert_allclose(q[:, 0], cx + radius * np.sin(th), rtol=0, atol=1e-9)
    np.testing.assert_allclose(q[:, 1], cy - radius * np.cos(th), rtol=0, atol=1e-9)
    np.testing.assert_allclose(q[:, 2], th, rtol=0, atol=1e-9)
    np.testing.assert_allclose(q[:, 3], phi, rtol=0, atol=1e-9)
    # multipliers: the friction force (μ₁, μ₂) = m R Ω ω (−sin θ, cos θ)
    f = m * R * spin * w
    np.testing.assert_allclose(
        sol.multipliers, f * np.stack([-np.sin(th), np.cos(th)], 1), atol=1e-8
    )
    assert sol.velocity_constraint_violation.shape == (ts.size, 2)
    assert float(np.max(np.abs(sol.velocity_constraint_violation))) < 1e-10
    # h = ½(m R² + I_s) Ω² + ½ I_t ω², conserved
    h = 0.5 * (m * R**2 + I_SPIN) * spin**2 + 0.5 * I_TURN * w**2
    np.testing.assert_allclose(sol.energy, h, rtol=1e-11)


def test_rolling_disk_driven_spin(disk):
    """A torque τ on the axle: (m R² + I_s) φ̈ = τ, the heading still turns at ω, so the
    contact point follows the knife edge's spiral with a = R τ/(m R² + I_s)."""
    m, R, tau = DISK["m"], DISK["R"], 0.3
    acc = tau / (m * R**2 + I_SPIN)
    q0 = np.array([X0, Y0, TH0, 0.0])
    qd0 = np.array([V0 * np.cos(TH0), V0 * np.sin(TH0), OMEGA, V0 / R])
    ts = np.linspace(0.0, 4.0, 61)
    sol = lx.simulate(
        disk, q0, qd0, DISK, t1=4.0, ts=ts, tau=jnp.asarray([0.0, 0.0, 0.0, tau]), **TIGHT
    )
    x, y, th, v = knife_exact(ts, R * acc)
    np.testing.assert_allclose(sol.q[:, 0], x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.q[:, 1], y, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.q[:, 2], th, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sol.qd[:, 3], v / R, rtol=0, atol=1e-9)
    # the friction force: lateral m v ω, and along the heading m a (it accelerates the
    # centre): (μ₁, μ₂) = m (a e_t + v ω e_n)
    mu = m * (R * acc * np.stack([np.cos(th), np.sin(th)], 1))
    mu = mu + m * (v * OMEGA)[:, None] * np.stack([-np.sin(th), np.cos(th)], 1)
    np.testing.assert_allclose(sol.multipliers, mu, rtol=0, atol=1e-8)


# ------------------------------------------------------------------- holonomic + velocity
# The knife edge with its heading as a unit vector: q = (x, y, c, s), c² + s² = 1
# (holonomic) and −s ẋ + c ẏ = 0 (velocity). T = ½ m (ẋ² + ẏ²) + ½ I (ċ² + ṡ²) is the
# knife edge's T on the circle (θ̇² = ċ² + ṡ²).
def _mixed_T(q, qd, p):
    return 0.5 * p["m"] * (qd[0] ** 2 + qd[1] ** 2) + 0.5 * p["I"] * (qd[2] ** 2 + qd[3] ** 2)


def _mixed_thrust(t, q, qd, p):
    return p["F"] * jnp.stack([q[2], q[3], 0.0 * q[0], 0.0 * q[0]])


def test_mixed_holonomic_and_velocity_constraints():
    free = lx.LagrangianSystem(_mixed_T, _flat, force=_mixed_thrust, n_dof=4)
    system = lx.ConstrainedSystem(
        free,
        lambda q, p: jnp.stack([q[2] ** 2 + q[3] ** 2 - 1.0]),
        velocity_constraints=lambda q, p: jnp.stack([-q[3], q[2], 0.0 * q[0], 0.0 * q[0]]),
    )
    c0, s0 = np.cos(TH0), np.sin(TH0)
    # off the circle and with an inadmissible velocity: the projection fixes both
    q0 = np.array([X0, Y0, 1.02 * c0, 1.02 * s0])
    qd0 = np.array([V0 * c0, V0 * s0, -OMEGA * s0, OMEGA * c0])
    ts = np.linspace(0.0, 6.0, 61)
    sol = lx.simulate(system, q0, qd0, KNIFE, t1=6.0, ts=ts, **TIGHT)
    assert bool(sol.ok)
    x, y, th, v = knife_exact(ts, KNIFE["F"] / KNIFE["m"])
    q = np.asarray(sol.q)
    np.testing.assert_allclose(q[:, 0], x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(q[:, 1], y, rtol=0, atol=1e-9)
    np.testing.assert_allclose(q[:, 2], np.cos(th), rtol=0, atol=1e-9)
    np.testing.assert_allclose(q[:, 3], np.sin(th), rtol=0, atol=1e-9)
    # multipliers in order (λ holonomic, μ velocity): I (c̈, s̈) = 2λ (c, s) with
    # (c̈, s̈) = −ω² (c, s), so λ = −I ω²/2; μ = m v ω as for the knife edge
    assert sol.multipliers.shape == (ts.size, 2)
    np.testing.assert_allclose(sol.multipliers[:, 0], -KNIFE["I"] * OMEGA**2 / 2, atol=1e-8)
    np.testing.assert_allclose(sol.multipliers[:, 1], KNIFE["m"] * v * OMEGA, atol=1e-8)
    assert sol.constraint_violation.shape == (ts.size, 1)
    assert float(np.max(np.abs(sol.constraint_violation))) < 1e-10
    assert sol.velocity_constraint_violation.shape == (ts.size, 1)
    assert float(np.max(np.abs(sol.velocity_constraint_violation))) < 1e-10
    kq = system.velocity_violation(sol.q[-1], sol.qd[-1], KNIFE)
    assert kq.shape == (2,) and float(jnp.max(jnp.abs(kq))) < 1e-10


# --------------------------------------------------------------------------- bad input
def test_velocity_constraint_errors(knife):
    free = knife.system
    q, qd = _knife_start()
    with pytest.raises(lx.ConfigurationError, match="neither"):
        lx.ConstrainedSystem(free)
    with pytest.raises(lx.ArgumentTypeError, match="velocity_constraints must be a function"):
        lx.ConstrainedSystem(free, velocity_constraints=np.eye(3))
    wrong_n = lx.ConstrainedSystem(free, velocity_constraints=lambda q, p: jnp.ones((1, 2)))
    with pytest.raises(lx.ShapeError, match=r"shape \(1, 2\) for q of shape \(3,\)"):
        wrong_n.forward_dynamics(q, qd, KNIFE)
    cube = lx.ConstrainedSystem(free, velocity_constraints=lambda q, p: jnp.ones((1, 1, 3)))
    with pytest.raises(lx.ShapeError, match=r"\(m, 3\)"):
        lx.simulate(cube, q, qd, KNIFE, t1=1.0)
    # the same row twice: K M⁻¹ Kᵀ is singular
    twice = lx.ConstrainedSystem(
        free, velocity_constraints=lambda q, p: jnp.concatenate([_blade(q, p)] * 2)
    )
    with pytest.raises(lx.ConstraintError, match="velocity constraint matrix A.*rank-deficient"):
        twice.forward_dynamics(q, qd, KNIFE)  # (simulate checks the start the same way)
    with pytest.raises(Exception, match="rank-deficient"):  # under jit: error_if, not NaN
        jax.jit(twice.forward_dynamics)(jnp.asarray(q), jnp.asarray(qd), KNIFE)
    # a velocity row that repeats a holonomic row's gradient
    mixed = lx.ConstrainedSystem(
        free, lambda q, p: q[2] - TH0, velocity_constraints=lambda q, p: jnp.array([0.0, 0.0, 1.0])
    )
    with pytest.raises(lx.ConstraintError, match=r"\[J; A\].*1 holonomic and 1 velocity"):
        mixed.multipliers(q, qd, KNIFE)
    # more rows than coordinates
    many = lx.ConstrainedSystem(free, velocity_constraints=lambda q, p: jnp.eye(4, 3))
    with pytest.raises(lx.ConstraintError, match=r"more constraints \(m=4\) than coordinates"):
        many.check_state(q, qd, KNIFE, project=False)
    nan_rows = lx.ConstrainedSystem(free, velocity_constraints=lambda q, p: jnp.nan * _blade(q, p))
    with pytest.raises(lx.NonFiniteError, match="velocity constraint matrix"):
        nan_rows.check_state(q, qd, KNIFE)


def test_sweep_over_the_thrust(knife):
    """A sweep of the knife edge: final states against the closed form, max |A q̇| at the
    end reported, and the energy balance closing (the thrust's work accounted for)."""
    thrusts = np.array([0.0, 0.7, 1.5])
    grid = lx.grid({k: jnp.asarray(v) for k, v in KNIFE.items()}, F=thrusts)
    ds = lx.sweep(knife, *_knife_start(), grid, t1=5.0, rtol=1e-11, atol=1e-11, progress=False)
    assert bool(ds.ok.all())
    for i, f in enumerate(thrusts):
        x, y, th, v = knife_exact(np.array(5.0), f / KNIFE["m"])
        np.testing.assert_allclose(ds.q.values[i], [x, y, th], rtol=0, atol=1e-8)
    assert ds.velocity_constraint_violation.dims == ("F",)
    assert float(ds.velocity_constraint_violation.max()) < 1e-10
    assert "constraint_violation" not in ds.data_vars
    assert float(np.abs(ds.energy_error).max()) < 1e-8
    s = V0 * 5.0 + 0.5 * thrusts / KNIFE["m"] * 25.0  # the thrust's work F s
    np.testing.assert_allclose(ds.energy_change.values, thrusts * s, rtol=0, atol=1e-8)
