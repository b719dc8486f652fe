"""Periodic orbits (`lagrax.periodic_orbit`, `lagrax.continue_orbits`) against independent
implementations written here in NumPy/SciPy:

- the compass-gait walker (Goswami, Thuilot & Espiau 1998: legs of m = 5 kg, a hip of
  M = 10 kg, a = b = 0.5 m): lagrax's model from its energies, with the heel-strike
  impact from the impulse equations of the walker with a free stance foot; SciPy's from
  the explicit equations of motion and the impact by conservation of angular momentum
  (about the new stance foot, and of the trailing leg about the hip), with
  `solve_ivp` events and `scipy.optimize.root`. Fixed point, step period, the
  multipliers against central differences of SciPy's return map, and the
  period-doubling slope;
- a forced, damped pendulum against SciPy shooting;
- `vmap` against a loop, failures reported, bad input refused.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, root

import lagrax as lx

GOSWAMI = {"m": 5.0, "M": 10.0, "a": 0.5, "b": 0.5, "g": 9.81}
TIGHT = {"rtol": 1e-12, "atol": 1e-12}

# ----------------------------------------------------------------- the lagrax walker
# q = (θ_ns, θ_s): the swing and stance legs' angles from the upward vertical (foot to
# hip), positive towards +x, the walking direction down the slope.


def _points(q, p, foot=(0.0, 0.0)):
    """Stance-leg mass, hip, swing-leg mass, swing foot."""
    ns, s = q[0], q[1]
    a, b = p["a"], p["b"]
    e_s = jnp.stack([jnp.sin(s), jnp.cos(s)])
    e_ns = jnp.stack([jnp.sin(ns), jnp.cos(ns)])
    hip = jnp.stack([foot[0], foot[1]]) + (a + b) * e_s
    return hip - b * e_s, hip, hip - b * e_ns, hip - (a + b) * e_ns


def _kinetic(points):
    def T(q, qd, p):
        vel = jax.jvp(lambda x: points(x, p)[:3], (q,), (qd,))[1]
        masses = (p["m"], p["M"], p["m"])
        return 0.5 * sum(mi * jnp.sum(v**2) for mi, v in zip(masses, vel, strict=True))

    return T


def _potential(q, p):
    heights = [r[1] for r in _points(q, p)[:3]]
    return p["g"] * sum(mi * h for mi, h in zip((p["m"], p["M"], p["m"]), heights, strict=True))


WALKER = lx.LagrangianSystem(_kinetic(_points), _potential, n_dof=2, name="compass gait")
# the walker with its stance foot free, qe = (x, y, θ_ns, θ_s): for the impact
FREE = lx.LagrangianSystem(
    _kinetic(lambda z, p: _points(z[2:], p, (z[0], z[1]))), lambda z, p: 0.0 * z[0], n_dof=4
)


def _heel_strike(t, q, qd, p):
    """The impact: an impulse at the swing foot brings it to rest (`J q̇e⁺ = 0`,
    `M_e (q̇e⁺ − q̇e⁻) = Jᵀ Λ`), then the legs swap roles."""
    qe = jnp.concatenate([jnp.zeros(2), q])
    qde = jnp.concatenate([jnp.zeros(2), qd])
    me = FREE.mass_matrix(qe, p)
    jac = jax.jacfwd(lambda z: _points(z[2:], p, (z[0], z[1]))[3])(qe)
    kkt = jnp.block([[me, -jac.T], [jac, jnp.zeros((2, 2))]])
    after = jnp.linalg.solve(kkt, jnp.concatenate([me @ qde, jnp.zeros(2)]))[2:4]
    return q[::-1], after[::-1]


HEEL_STRIKE = lx.Event(
    lambda t, q, qd, p: q[0] + q[1] - 2 * p["slope"], direction=1, reset=_heel_strike
)
GUESS = (np.array([0.3234, -0.2187]), np.array([0.3772, 1.0918]))  # near the 3° gait

# ----------------------------------------------------------- the SciPy walker (NumPy)


def _np_rhs(t, x, m, M, a, b, g):
    ns, s, dns, ds = x
    ll = a + b
    c, sn = np.cos(s - ns), np.sin(s - ns)
    mass = np.array([[m * b * b, -m * ll * b * c], [-m * ll * b * c, (M + m) * ll**2 + m * a * a]])
    coriolis = np.array([m * ll * b * sn * ds**2, -m * ll * b * sn * dns**2])
    gravity = np.array([m * b * g * np.sin(ns), -(M * ll + m * a + m * ll) * g * np.sin(s)])
    return [dns, ds, *np.linalg.solve(mass, -coriolis - gravity)]


def _np_impact(x, m, M, a, b):
    """Angular momentum of the whole walker about the new stance foot, and of the
    trailing leg about the hip, are conserved; then the legs swap."""
    ns, s, dns, ds = x
    ll = a + b
    u_s, u_ns = np.array([np.sin(s), np.cos(s)]), np.array([np.sin(ns), np.cos(ns)])
    d_s, d_ns = np.array([np.cos(s), -np.sin(s)]), np.array([np.cos(ns), -np.sin(ns)])
    hip = ll * u_s
    r_st, r_sw, foot = a * u_s, hip - b * u_ns, hip - ll * u_ns

    def cross(r, v):
        return r[0] * v[1] - r[1] * v[0]

    def moments(v_st, v_hip, v_sw):  # v_st, v_sw: the old stance and swing legs' masses
        whole = m * cross(r_st - foot, v_st) + M * cross(hip - foot, v_hip)
        whole += m * cross(r_sw - foot, v_sw)
        return np.array([whole, m * cross(r_st - hip, v_st)])

    before = moments(a * ds * d_s, ll * ds * d_s, ll * ds * d_s - b * dns * d_ns)
    lhs = np.zeros((2, 2))
    for j, (dns_new, ds_new) in enumerate(np.eye(2)):  # new stance: the old swing leg
        v_hip = ll * ds_new * d_ns
        lhs[:, j] = moments(v_hip - b * dns_new * d_s, v_hip, a * ds_new * d_ns)
    dns_new, ds_new = np.linalg.solve(lhs, before)
    return np.array([s, ns, dns_new, ds_new])


def _np_return(x, slope, p=GOSWAMI):
    """SciPy's return map: heel strike (solve_ivp event), then the impact; and the time."""

    def strike(t, y, *args):  # swing foot on the slope, the stance leg past the vertical
        return y[0] + y[1] - 2 * slope if y[1] > 0 else 1.0

    strike.terminal, strike.direction = True, 1
    args = (p["m"], p["M"], p["a"], p["b"], p["g"])
    sol = solve_ivp(
        _np_rhs, (0.0, 5.0), x, "DOP853", args=args, rtol=1e-12, atol=1e-12, events=strike
    )
    assert sol.status == 1, sol.message
    return _np_impact(sol.y_events[0][0], *args[:4]), sol.t_events[0][0]


def _central(fn, x, h):
    return np.stack([(fn(x + h * e) - fn(x - h * e)) / (2 * h) for e in np.eye(x.size)], -1)


def _np_fixed_point(x, slope):
    """`scipy.optimize.root`, then Newton steps with a central-difference Jacobian (the
    hybrid method stalls a little above the return map's round-off)."""

    def residual(y):
        return _np_return(y, slope)[0] - y

    x = root(residual, x, method="hybr", tol=1e-13).x
    for _ in range(3):
        jac = _central(residual, x, 1e-6)
        x = x - np.linalg.solve(jac, residual(x))
    return x


@pytest.fixture(scope="module")
def gait():
    """lagrax's and SciPy's 3° gaits."""
    slope = np.deg2rad(3.0)
    params = {**GOSWAMI, "slope": slope}
    orbit = lx.periodic_orbit(WALKER, *GUESS, params, section=HEEL_STRIKE, **TIGHT, tol=1e-12)
    reference = _np_fixed_point(np.concatenate(GUESS), slope)
    return orbit, reference, slope


def test_compass_gait_against_scipy(gait):
    orbit, reference, slope = gait
    assert bool(orbit.ok), lx.RESULTS[orbit.result]
    assert np.max(np.abs(np.asarray(orbit.state) - reference)) <= 1e-9
    period = _np_return(reference, slope)[1]
    assert abs(float(orbit.period) - period) <= 1e-9
    assert float(orbit.residual) <= 1e-11 and 0 < int(orbit.iterations) <= 10
    assert 0.73 < period < 0.74  # Goswami et al.'s 3° gait: a step of about 0.73 s


def test_compass_gait_multipliers_against_finite_differences(gait):
    orbit, reference, slope = gait
    jac_fd = _central(lambda y: _np_return(y, slope)[0], reference, 1e-5)
    assert np.max(np.abs(np.asarray(orbit.jacobian) - jac_fd)) <= 1e-6
    mu_fd = np.linalg.eigvals(jac_fd)
    mu_fd = mu_fd[np.argsort(-np.abs(mu_fd))][:-1]  # the trivial 0 dropped
    mu = np.asarray(orbit.multipliers)
    assert mu.shape == (3,)
    key = np.lexsort
    order, order_fd = key((mu.imag, np.abs(mu))), key((mu_fd.imag, np.abs(mu_fd)))
    assert np.max(np.abs(mu[order] - mu_fd[order_fd])) <= 1e-6
    assert bool(orbit.stable) and np.max(np.abs(mu)) < 0.6  # a stable gait at 3°


def test_compass_gait_under_jit(gait):
    orbit, _, slope = gait
    solve = jax.jit(
        lambda q, qd, s: lx.periodic_orbit(
            WALKER, q, qd, {**GOSWAMI, "slope": s}, section=HEEL_STRIKE, **TIGHT, tol=1e-12
        )
    )
    again = solve(jnp.asarray(GUESS[0]), jnp.asarray(GUESS[1]), slope)
    assert bool(again.ok)
    assert np.max(np.abs(np.asarray(again.state) - np.asarray(orbit.state))) <= 1e-12


def test_period_doubling_slope_against_scipy(gait):
    orbit, _, _ = gait
    slopes = np.deg2rad(np.linspace(3.0, 4.8, 10))
    branch = lx.continue_orbits(
        WALKER, orbit.q, orbit.qd, {**GOSWAMI, "slope": slopes[0]}, "slope", slopes,
        section=HEEL_STRIKE, **TIGHT, tol=1e-12,
    )  # fmt: skip
    assert np.all(np.asarray(branch.ok))
    flips = [b for b in branch.bifurcations if b.kind == "period_doubling"]
    assert len(flips) == 1 and flips[0].refined
    assert [b.kind for b in branch.bifurcations] == ["period_doubling"]
    k = flips[0].index
    stable = np.asarray(branch.stable)
    assert stable[: k + 1].all() and not stable[k + 1 :].any()

    # SciPy: det(DP + I) of central differences of its return map, root in the slope
    state = {"x": np.asarray(branch.orbits.state[k])}

    def flip_test(slope):
        state["x"] = x = _np_fixed_point(state["x"], slope)
        jac = _central(lambda y: _np_return(y, slope)[0], x, 1e-5)
        return np.linalg.det(jac + np.eye(4))

    reference = brentq(flip_test, slopes[k], slopes[k + 1], xtol=1e-8)
    assert abs(flips[0].value - reference) <= 1e-4
    assert abs(flips[0].value - reference) <= 1e-6  # (measured: far inside the target)


# ----------------------------------------------------------- a forced, damped pendulum

FORCED = lx.LagrangianSystem(
    lambda q, qd, p: 0.5 * qd[0] ** 2,
    lambda q, p: -jnp.cos(q[0]),
    dissipation=lambda q, qd, p: 0.5 * p["c"] * qd[0] ** 2,
    force=lambda t, q, qd, p: jnp.stack([p["A"] * jnp.cos(p["w"] * t)]),
    n_dof=1,
    name="forced pendulum",
)
FORCING = {"c": 0.5, "A": 0.9, "w": 2.0 / 3.0}


def _np_pendulum_orbit(x, p):
    def rhs(t, y):
        return [y[1], -p["c"] * y[1] - np.sin(y[0]) + p["A"] * np.cos(p["w"] * t)]

    period = 2 * np.pi / p["w"]

    def residual(y):
        sol = solve_ivp(rhs, (0.0, period), y, "DOP853", rtol=1e-13, atol=1e-13)
        return sol.y[:, -1] - y

    x = root(residual, x, method="hybr", tol=1e-13).x
    for _ in range(2):
        x = x - np.linalg.solve(_central(residual, x, 1e-6), residual(x))
    return x, residual


@pytest.fixture(scope="module")
def pendulum_solve():
    return jax.jit(
        lambda x, amplitude: lx.periodic_orbit(
            FORCED, x[:1], x[1:], {**FORCING, "A": amplitude}, period=2 * jnp.pi / FORCING["w"],
            **TIGHT, tol=1e-12,
        )
    )  # fmt: skip


def test_forced_pendulum_against_scipy_shooting(pendulum_solve):
    guess = np.array([-0.6, 1.9])
    orbit = pendulum_solve(jnp.asarray(guess), FORCING["A"])
    assert bool(orbit.ok), lx.RESULTS[orbit.result]
    reference, residual = _np_pendulum_orbit(guess, FORCING)
    assert np.max(np.abs(residual(reference))) <= 1e-11
    assert np.max(np.abs(np.asarray(orbit.state) - reference)) <= 1e-9
    assert abs(float(orbit.period) - 2 * np.pi / FORCING["w"]) <= 1e-15
    mu = np.asarray(orbit.multipliers)
    assert mu.shape == (2,)
    # Liouville: det DP = exp(−c T) for a damping c, whatever the forcing
    assert abs(np.prod(mu).real - np.exp(-FORCING["c"] * 2 * np.pi / FORCING["w"])) <= 1e-9
    jac_fd = _central(lambda y: residual(y) + y, reference, 1e-5)
    assert np.max(np.abs(np.asarray(orbit.jacobian) - jac_fd)) <= 1e-6


def test_vmap_equals_a_loop(pendulum_solve):
    guesses = jnp.array([[-0.6, 1.9], [-0.5, 1.8], [-0.4, 1.6]])
    amplitudes = jnp.array([0.9, 0.85, 0.8])
    batch = jax.vmap(pendulum_solve)(guesses, amplitudes)
    for k in range(3):
        one = pendulum_solve(guesses[k], amplitudes[k])
        assert bool(one.ok)
        for field in ("state", "period", "multipliers", "jacobian"):
            a, b = np.asarray(getattr(batch, field)[k]), np.asarray(getattr(one, field))
            assert np.max(np.abs(a - b)) <= 1e-12, field
        assert int(batch.iterations[k]) == int(one.iterations)


def test_orbit_map_of_a_grid_equals_individual_calls():
    amplitudes, frequencies = np.array([0.85, 0.9]), np.array([0.64, 2 / 3, 0.69])
    walks = lx.grid(FORCING, A=amplitudes, w=frequencies, units={"w": "rad/s"})
    guess = ([-0.6], [1.9])
    ds = lx.orbit_map(
        FORCED, *guess, walks, period=lambda p: 2 * jnp.pi / p["w"], **TIGHT, tol=1e-12
    )
    assert ds.q.dims == ("A", "w", "dof") and ds.multipliers.dims == ("A", "w", "multiplier")
    assert np.array_equal(ds.A.values, amplitudes) and np.array_equal(ds.w.values, frequencies)
    assert ds.w.attrs["units"] == "rad/s" and ds.period.attrs["units"] == "s"
    assert ds.attrs["n_members"] == 6 and ds.attrs["n_failed"] == 0
    for i, amplitude in enumerate(amplitudes):
        for j, w in enumerate(frequencies):
            one = lx.periodic_orbit(
                FORCED, *guess, {**FORCING, "A": amplitude, "w": w}, period=2 * np.pi / w,
                **TIGHT, tol=1e-12,
            )  # fmt: skip
            assert bool(one.ok) and bool(ds.ok[i, j]) and ds.status[i, j] == "ok"
            member = ds.isel(A=i, w=j)
            assert np.max(np.abs(member.q.values - np.asarray(one.q))) <= 1e-12
            assert np.max(np.abs(member.qd.values - np.asarray(one.qd))) <= 1e-12
            assert abs(float(member.period) - float(one.period)) <= 1e-12
            mu = np.asarray(one.multipliers)
            assert np.max(np.abs(member.multipliers.values - mu)) <= 1e-10
            assert abs(float(member.max_multiplier) - np.max(np.abs(mu))) <= 1e-10
            assert bool(member.stable) == bool(one.stable)
            assert int(member.iterations) == int(one.iterations)
    # four members at a time under vmap (then the last two): the same orbits
    batched = lx.orbit_map(
        FORCED, *guess, walks, period=lambda p: 2 * jnp.pi / p["w"], batch_size=4, **TIGHT,
        tol=1e-12,
    )  # fmt: skip
    assert np.max(np.abs(batched.q.values - ds.q.values)) <= 1e-12
    assert np.max(np.abs(batched.multipliers.values - ds.multipliers.values)) <= 1e-10


def test_orbit_map_of_samples_reports_failures():
    # one Newton step is not enough from this guess: every member fails, none raises
    draws = lx.samples(FORCING, A=[0.9, 0.88], qd0_0=[1.9, 1.8])
    ds = lx.orbit_map(FORCED, [[-0.6], [-0.6]], [1.9], draws, period=3 * np.pi, max_iter=1, **TIGHT)
    assert ds.q.dims == ("member", "dof") and list(ds.member.values) == [0, 1]
    assert not ds.ok.any() and ds.attrs["n_failed"] == 2
    assert np.isnan(ds.q.values).all() and np.isnan(ds.period.values).all()
    assert np.array_equal(ds.A.values, [0.9, 0.88]) and ds.qd0_0.dims == ("member",)
    assert all("converge" in str(s) for s in ds.status.values), ds.status.values
    with pytest.raises(lx.ConfigurationError, match="unknown options"):
        lx.orbit_map(FORCED, [-0.6], [1.9], draws, period=3 * np.pi, maxiter=3)
    with pytest.raises(lx.ConfigurationError, match="batch_size must be a positive integer"):
        lx.orbit_map(FORCED, [-0.6], [1.9], draws, period=3 * np.pi, batch_size=0)


# ------------------------------------------------------------ failures and bad input


def test_no_orbit_near_the_guess_is_reported():
    # on level ground the walker loses energy at every step: no gait exists
    orbit = lx.periodic_orbit(
        WALKER, *GUESS, {**GOSWAMI, "slope": 0.0}, section=HEEL_STRIKE, t_max=5.0, max_iter=15
    )
    assert not bool(orbit.ok) and not bool(orbit.stable)
    assert orbit.result != lx.RESULTS.successful


def test_a_section_never_crossed_is_a_clear_error():
    # the energy reaching 100 upwards: damped, the pendulum only loses energy
    never = lx.Event(lambda t, q, qd, p: 0.5 * qd[0] ** 2 - jnp.cos(q[0]) - 100.0, direction=1)
    with pytest.raises(lx.PeriodicOrbitError, match="never crosses the section upwards"):
        lx.periodic_orbit(FORCED, [0.1], [0.0], {**FORCING, "A": 0.0}, section=never, t_max=5.0)
    solve = jax.jit(
        lambda q: lx.periodic_orbit(
            FORCED, q, jnp.zeros(1), {**FORCING, "A": 0.0}, section=never, t_max=5.0
        )
    )
    orbit = solve(jnp.array([0.1]))
    assert orbit.result == lx.RESULTS.orbit_no_return and not bool(orbit.ok)


def test_bad_input_is_refused():
    bad = lx.Event(lambda t, q, qd, p: q[0], direction=1, reset=lambda q, qd: (q, -qd))
    with pytest.raises(lx.ArgumentTypeError, match="reset must take the four arguments"):
        lx.periodic_orbit(FORCED, [0.1], [0.0], FORCING, section=bad)
    wrong = lx.Event(lambda t, q, qd, p: q[0], direction=1, reset=lambda t, q, qd, p: q)
    with pytest.raises(lx.ShapeError, match="reset"):
        lx.periodic_orbit(FORCED, [0.1], [0.0], FORCING, section=wrong)
    with pytest.raises(lx.ConfigurationError, match="exactly one of section= .* and period="):
        lx.periodic_orbit(FORCED, [0.1], [0.0], FORCING)
    with pytest.raises(lx.ConfigurationError, match="period must be positive"):
        lx.periodic_orbit(FORCED, [0.1], [0.0], FORCING, period=-1.0)
    with pytest.raises(lx.ArgumentTypeError, match="section must be a lagrax.Event"):
        lx.periodic_orbit(FORCED, [0.1], [0.0], FORCING, section=lambda t, q, qd, p: q[0])


# ------------------------------------- the heel strike as users write it for simulate


def _guarded(t, q, qd, p):
    """The swing foot's height above the slope, counted once the swing leg is 0.05 rad
    ahead of the stance leg (no scuffing at mid-stance); `1` before."""
    ns, s, slope = q[0], q[1], p["slope"]
    height = (p["a"] + p["b"]) * (jnp.cos(s - slope) - jnp.cos(ns - slope))
    return jnp.where(s - ns > 0.05, height, 1.0)


GUARDED = lx.Event(_guarded, direction=-1, reset=_heel_strike)


def _off(orbit):
    """A guess 0.01 rad and 0.04 rad/s off the fixed point."""
    return orbit.q + jnp.array([0.01, -0.01]), orbit.qd + jnp.array([0.04, -0.04])


def test_guarded_heel_strike_against_the_smooth_section(gait):
    # the same Event as simulate's: the condition is 1 (∇g = 0) just after the strike,
    # where the fixed point of x⁺ ↦ R(flow to the next crossing) lies
    smooth, reference, slope = gait
    params = {**GOSWAMI, "slope": slope}
    q0, qd0 = _off(smooth)
    assert float(_guarded(0.0, q0, qd0, params)) == 1.0
    orbit = lx.periodic_orbit(WALKER, q0, qd0, params, section=GUARDED, **TIGHT, tol=1e-12)
    assert bool(orbit.ok), lx.RESULTS[orbit.result]
    assert np.max(np.abs(np.asarray(orbit.state) - np.asarray(smooth.state))) <= 1e-10
    assert np.max(np.abs(np.asarray(orbit.state) - reference)) <= 1e-9  # and SciPy's
    assert abs(float(orbit.period) - float(smooth.period)) <= 1e-10
    mu, mu_smooth = np.asarray(orbit.multipliers), np.asarray(smooth.multipliers)
    order, order_smooth = (
        np.lexsort((mu.imag, np.abs(mu))),
        np.lexsort((mu_smooth.imag, np.abs(mu_smooth))),
    )
    assert np.max(np.abs(mu[order] - mu_smooth[order_smooth])) <= 1e-10
    # the walker really is there just after the strike: simulate with the same Event
    sol = lx.simulate(WALKER, orbit.q, orbit.qd, params, t1=1.0, events=GUARDED, **TIGHT)
    record = sol.events[0]
    assert int(record.count) == 1 and abs(float(record.times[0] - orbit.period)) <= 1e-10
    after = _heel_strike(0.0, record.q[0], record.qd[0], params)
    assert np.max(np.abs(np.concatenate(after) - np.asarray(orbit.state))) <= 1e-10


def test_a_constant_condition_without_reset_is_diagnosed(gait):
    smooth, _, slope = gait
    params = {**GOSWAMI, "slope": slope}
    no_reset = lx.Event(_guarded, direction=-1)
    with pytest.raises(lx.PeriodicOrbitError) as info:
        lx.periodic_orbit(WALKER, *_off(smooth), params, section=no_reset)
    message = str(info.value)
    assert "section _guarded" in message and "value 1" in message and "∇g = 0" in message
    assert "give the impact as the section's reset" in message
    assert "max_steps" not in message
    solve = jax.jit(
        lambda q, qd: lx.periodic_orbit(WALKER, q, qd, params, section=no_reset, max_iter=1)
    )
    orbit = solve(*_off(smooth))
    assert orbit.result == lx.RESULTS.orbit_bad_section and not bool(orbit.ok)


def test_a_guess_on_the_section_with_the_reset_off_it_is_diagnosed(gait):
    smooth, _, slope = gait
    params = {**GOSWAMI, "slope": slope}
    sol = lx.simulate(WALKER, smooth.q, smooth.qd, params, t1=1.0, events=GUARDED, **TIGHT)
    before = (sol.events[0].q[0], sol.events[0].qd[0])  # the state at the strike
    assert abs(float(_guarded(0.0, *before, params))) <= 1e-9
    with pytest.raises(lx.PeriodicOrbitError) as info:
        lx.periodic_orbit(WALKER, *before, params, section=GUARDED)
    message = str(info.value)
    assert "section _guarded" in message and "reset _heel_strike" in message
    assert "the reset's image is not (the condition is 1 there, ∇g = 0)" in message
    assert "q0, qd0 = section.reset(t0, q0, qd0, params)" in message
    # that advice works: from the post-reset state the orbit is found
    after = _heel_strike(0.0, *before, params)
    orbit = lx.periodic_orbit(WALKER, *after, params, section=GUARDED, **TIGHT, tol=1e-12)
    assert np.max(np.abs(np.asarray(orbit.state) - np.asarray(smooth.state))) <= 1e-10


def test_a_first_crossing_the_other_way_is_diagnosed(gait):
    # direction=+1 by mistake: the heel strike (downwards) is not counted, the walker falls
    smooth, _, slope = gait
    params = {**GOSWAMI, "slope": slope}
    upwards = lx.Event(_guarded, direction=1, reset=_heel_strike)
    with pytest.raises(lx.PeriodicOrbitError) as info:
        lx.periodic_orbit(WALKER, *_off(smooth), params, section=upwards, t_max=2.0)
    message = str(info.value)
    assert "section _guarded (crossing upwards, direction=+1" in message
    assert "first crosses the section downwards, at t = " in message
    assert "the condition's rate is ġ = -" in message and "give direction=-1" in message
    assert "max_steps" not in message


def test_a_section_crossed_only_the_other_way_is_diagnosed():
    # the damped pendulum's energy falls through -0.5 once: downwards, never upwards
    level = lx.Event(lambda t, q, qd, p: 0.5 * qd[0] ** 2 - jnp.cos(q[0]) + 0.5, direction=1)
    with pytest.raises(lx.PeriodicOrbitError) as info:
        lx.periodic_orbit(FORCED, [0.1], [2.0], {**FORCING, "A": 0.0}, section=level, t_max=5.0)
    message = str(info.value)
    assert "never crosses the section " in message and "<lambda> (crossing upwards" in message
    assert "It crosses the section downwards instead, at t = " in message
    assert "give direction=-1" in message
