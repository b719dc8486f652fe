"""Events (``lagrax.Event``): crossing times against closed forms, impacts with
restitution against the geometric series of bounce times, Zeno cascades reported,
terminal stops at the root, direction filtering; under ``jit``, ``vmap``, ``throw=False``
and in a sweep; bad input refused with a ``LagraxError``."""

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.special import ellipk

import lagrax as lx

G = 9.81
H = 1.0


def _ball():
    """A ball in 1-D gravity: ``q`` is its height."""
    return lx.LagrangianSystem(
        kinetic=lambda q, qd, p: 0.5 * qd[0] ** 2, potential=lambda q, p: p["g"] * q[0]
    )


BALL = _ball()
PENDULUM = lx.LagrangianSystem(
    kinetic=lambda q, qd, p: 0.5 * p["m"] * p["l"] ** 2 * qd[0] ** 2,
    potential=lambda q, p: -p["m"] * p["g"] * p["l"] * jnp.cos(q[0]),
)
PEND_PARAMS = {"m": 1.3, "l": 0.7, "g": G}

# module-level events: the same objects, so every test reuses the compiled solves
FLOOR = lx.Event(
    lambda t, q, qd, p: q[0], direction=-1, reset=lambda t, q, qd, p: (q, -p["e"] * qd)
)
FLOOR_SHORT = lx.Event(
    lambda t, q, qd, p: q[0],
    direction=-1,
    reset=lambda t, q, qd, p: (q, -p["e"] * qd),
    max_events=30,
)
GROUND = lx.Event(lambda t, q, qd, p: q[0], terminal=True)


def _height(t, q, qd, p):
    return q[0]


def bounce_times(h, g, e, k):
    """The first ``k`` impact times of a ball dropped from rest at height ``h`` onto a
    floor with restitution ``e``: ``t_1 = sqrt(2h/g)``, then flights of ``2 e^j v_1 / g``."""
    t1, v1 = np.sqrt(2 * h / g), np.sqrt(2 * g * h)
    flights = 2 * v1 / g * e ** np.arange(1, k)
    return t1 + np.concatenate([[0.0], np.cumsum(flights)])


def zeno_time(h, g, e):
    """Where the bounce times accumulate: ``t_1 + 2 v_1 e / (g (1 − e))``."""
    return np.sqrt(2 * h / g) + 2 * np.sqrt(2 * g * h) / g * e / (1 - e)


# ------------------------------------------------------------------ crossing times


@pytest.fixture(scope="module")
def pendulum_crossings():
    theta0 = 2.5  # large amplitude: the period is far from 2π sqrt(l/g)
    l, g = PEND_PARAMS["l"], PEND_PARAMS["g"]
    period = 4 * np.sqrt(l / g) * ellipk(np.sin(theta0 / 2) ** 2)  # K(m), m = k²
    either = lx.Event(lambda t, q, qd, p: q[0])
    up = lx.Event(lambda t, q, qd, p: q[0], direction=1)
    down = lx.Event(lambda t, q, qd, p: q[0], direction=-1)
    sol = lx.simulate(
        PENDULUM,
        [theta0],
        [0.0],
        PEND_PARAMS,
        t1=3.2 * period,
        events=[either, up, down],
        solver="dopri8",
        rtol=1e-12,
        atol=1e-12,
        n_save=2,
    )
    return sol, period


def test_pendulum_period_from_crossings(pendulum_crossings):
    sol, period = pendulum_crossings
    rec = sol.events[0]
    k = int(rec.count)
    assert k == 6  # crossings at T/4 + j T/2 before 3.2 T
    times = np.asarray(rec.times[:k])
    np.testing.assert_allclose(times, period / 4 + np.arange(k) * period / 2, rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.diff(times[::2]), period, rtol=0, atol=1e-10)
    # the recorded states lie on the crossing: θ = 0, |θ̇| from energy conservation
    np.testing.assert_allclose(np.asarray(rec.q[:k, 0]), 0.0, atol=1e-10)
    l, g = PEND_PARAMS["l"], PEND_PARAMS["g"]
    speed = np.sqrt(2 * g / l * (1 - np.cos(2.5)))
    np.testing.assert_allclose(np.abs(np.asarray(rec.qd[:k, 0])), speed, rtol=1e-10)
    assert np.all(np.isinf(np.asarray(rec.times[k:])))  # padding
    assert bool(sol.ok) and sol.result == lx.RESULTS.successful
    assert float(sol.t_end) == pytest.approx(3.2 * period)


def test_direction_filtering(pendulum_crossings):
    sol, period = pendulum_crossings
    _, up, down = sol.events
    # released at θ0 > 0: it crosses downwards first (at T/4), upwards at 3T/4
    k_up, k_down = int(up.count), int(down.count)
    assert (k_up, k_down) == (3, 3)
    np.testing.assert_allclose(
        np.asarray(up.times[:k_up]), 3 * period / 4 + np.arange(k_up) * period, atol=1e-10
    )
    np.testing.assert_allclose(
        np.asarray(down.times[:k_down]), period / 4 + np.arange(k_down) * period, atol=1e-10
    )
    assert np.all(np.asarray(up.qd[:k_up, 0]) > 0)
    assert np.all(np.asarray(down.qd[:k_down, 0]) < 0)


# ------------------------------------------------------------------ impacts


def test_bouncing_ball_against_analytic_bounce_times():
    e = 0.8
    t1 = 0.9 * zeno_time(H, G, e)
    sol = lx.simulate(BALL, [H], [0.0], {"g": G, "e": e}, t1=t1, events=FLOOR, n_save=201)
    rec = sol.events[0]
    k = int(rec.count)
    expected = bounce_times(H, G, e, 40)
    expected = expected[expected < t1]
    assert k == len(expected) and k >= 5
    np.testing.assert_allclose(np.asarray(rec.times[:k]), expected, rtol=0, atol=1e-10)
    # the recorded state is the one before the impact: speed v_1 e^j, falling
    v1 = np.sqrt(2 * G * H)
    np.testing.assert_allclose(np.asarray(rec.qd[:k, 0]), -v1 * e ** np.arange(k), rtol=1e-10)
    # between impacts the saves follow the parabola of the current flight
    ts, q = np.asarray(sol.ts), np.asarray(sol.q[:, 0])
    j = np.searchsorted(expected, ts, side="right")  # impacts before each save
    t_last = np.where(j > 0, expected[np.maximum(j - 1, 0)], 0.0)
    v_up = np.where(j > 0, v1 * e**j, 0.0)
    h0 = np.where(j > 0, 0.0, H)
    tau = ts - t_last
    np.testing.assert_allclose(q, h0 + v_up * tau - 0.5 * G * tau**2, atol=1e-10)
    assert bool(sol.ok)


def test_zeno_cascade_is_detected_and_reported():
    e = 0.5
    params = {"g": G, "e": e}
    t_zeno = zeno_time(H, G, e)
    sol = lx.simulate(BALL, [H], [0.0], params, t1=2 * t_zeno, events=FLOOR_SHORT, throw=False)
    assert sol.result == lx.RESULTS.event_cascade
    assert not bool(sol.ok)
    rec = sol.events[0]
    assert int(rec.count) == 30  # max_events recorded, the next one ended the solve
    np.testing.assert_allclose(np.asarray(rec.times), bounce_times(H, G, e, 30), rtol=0, atol=1e-10)
    # stopped at the 31st bounce, just before the accumulation point
    assert float(rec.times[-1]) < float(sol.t_end) <= t_zeno + 1e-9
    assert t_zeno - float(sol.t_end) < 1e-8
    with pytest.raises(lx.SimulationError, match=r"event cascade at t=.*30 of max_events=30"):
        lx.simulate(BALL, [H], [0.0], params, t1=2 * t_zeno, events=FLOOR_SHORT)


def test_resting_contact_cascade_is_reported_not_looped():
    # e = 0: the ball sticks to the floor; the floor keeps being crossed at one time
    params = {"g": G, "e": 0.0}
    sol = lx.simulate(BALL, [H], [0.0], params, t1=3.0, events=FLOOR_SHORT, throw=False)
    assert sol.result == lx.RESULTS.event_cascade
    assert float(sol.t_end) == pytest.approx(np.sqrt(2 * H / G), abs=1e-10)
    assert int(sol.stats["num_steps"]) < 100


# ------------------------------------------------------------------ terminal events


def test_terminal_event_stops_at_the_root():
    params = {"g": G}
    sol = lx.simulate(BALL, [H], [0.0], params, t1=2.0, events=GROUND, n_save=41)
    t_hit = np.sqrt(2 * H / G)
    assert sol.result == lx.RESULTS.event_occurred
    assert bool(sol.ok)
    assert float(sol.t_end) == pytest.approx(t_hit, abs=1e-12)
    assert float(sol.q_end[0]) == pytest.approx(0.0, abs=1e-12)
    assert float(sol.qd_end[0]) == pytest.approx(-np.sqrt(2 * G * H), rel=1e-12)
    assert float(sol.events[0].times[0]) == float(sol.t_end)
    ts, q = np.asarray(sol.ts), np.asarray(sol.q[:, 0])
    before = np.linspace(0.0, 2.0, 41) <= t_hit
    np.testing.assert_allclose(q[before], H - 0.5 * G * ts[before] ** 2, atol=1e-12)
    assert np.all(np.isinf(ts[~before])) and np.all(np.isinf(q[~before]))
    assert np.all(np.isinf(np.asarray(sol.energy)[~before]))


def test_gradient_of_the_event_time():
    # t_hit = sqrt(2h/g): d t_hit / dh = 1 / sqrt(2 g h), through the implicit root
    def hit(h):
        sol = lx.simulate(
            BALL, h[None], jnp.zeros(1), {"g": G}, t1=2.0, events=GROUND, solver="rk4",
            dt=0.05, n_save=2,
        )  # fmt: skip
        return sol.t_end

    grad = jax.grad(hit)(jnp.asarray(H))
    assert float(grad) == pytest.approx(1 / np.sqrt(2 * G * H), rel=1e-10)


def test_terminal_event_with_fixed_step_rk4():
    sol = lx.simulate(BALL, [H], [0.0], {"g": G}, t1=2.0, events=GROUND, solver="rk4", dt=0.05)
    # the cubic Hermite output of RK4 is exact on a parabola
    assert float(sol.t_end) == pytest.approx(np.sqrt(2 * H / G), abs=1e-12)


def test_terminal_event_in_float32():
    q0 = np.asarray([H], np.float32)
    sol = lx.simulate(BALL, q0, np.zeros(1, np.float32), {"g": G}, t1=2.0, events=GROUND)
    assert sol.t_end.dtype == np.float32 and sol.events[0].times.dtype == np.float32
    assert float(sol.t_end) == pytest.approx(np.sqrt(2 * H / G), rel=1e-5)


# ------------------------------------------------------------------ jit, vmap, sweep


def test_under_jit_and_vmap():
    @jax.jit
    def hit_time(h):
        sol = lx.simulate(BALL, h[None], jnp.zeros(1), {"g": G}, t1=2.0, events=GROUND)
        return sol.t_end, sol.ok

    heights = jnp.asarray([0.5, 1.0, 2.0])
    t_end, ok = jax.vmap(hit_time)(heights)
    np.testing.assert_allclose(np.asarray(t_end), np.sqrt(2 * np.asarray(heights) / G), atol=1e-12)
    assert np.all(np.asarray(ok))


def test_vmap_throw_false_reports_the_cascading_member():
    restitution = jnp.asarray([0.8, 0.5])
    t1 = 1.2 * zeno_time(H, G, 0.5)  # past 0.5's accumulation point, not 0.8's

    def run(e):
        sol = lx.simulate(
            BALL, jnp.asarray([H]), jnp.zeros(1), {"g": G, "e": e}, t1=t1,
            events=FLOOR_SHORT, throw=False, n_save=5,
        )  # fmt: skip
        return sol.ok, sol.events[0].count, sol.events[0].first

    ok, count, first = jax.jit(jax.vmap(run))(restitution)
    assert np.asarray(ok).tolist() == [True, False]
    expected = bounce_times(H, G, 0.8, 30)
    assert int(count[0]) == int(np.sum(expected < t1))
    assert int(count[1]) == 30
    np.testing.assert_allclose(np.asarray(first), np.sqrt(2 * H / G), atol=1e-12)


def test_jit_throw_raises_on_a_cascade():
    @jax.jit
    def run(e):
        return lx.simulate(
            BALL, jnp.asarray([H]), jnp.zeros(1), {"g": G, "e": e}, t1=5.0,
            events=FLOOR_SHORT, n_save=5,
        ).t_end  # fmt: skip

    with pytest.raises(Exception, match="event cascade"):
        jax.block_until_ready(run(jnp.asarray(0.5)))


def test_sweep_reports_event_count_and_first_time():
    heights = np.asarray([0.5, 1.0, 2.0])
    ds = lx.sweep(
        BALL, heights[:, None], np.zeros((3, 1)), {"g": np.full(3, G)}, t1=0.6,
        events=GROUND, progress=False,
    )  # fmt: skip
    t_hit = np.sqrt(2 * heights / G)  # 0.32, 0.45, 0.64: the last is not reached
    reached = t_hit < 0.6
    assert ds.event_count.dims == ("member", "event")
    np.testing.assert_array_equal(ds.event_count.values[:, 0], reached.astype(int))
    first = ds.first_event_time.values[:, 0]
    np.testing.assert_allclose(first[reached], t_hit[reached], atol=1e-12)
    assert np.all(np.isinf(first[~reached]))
    assert bool(ds.ok.all())
    np.testing.assert_allclose(ds.t_end.values, np.where(reached, t_hit, 0.6), atol=1e-12)


# ------------------------------------------------------------------ bad input


def test_bad_events_are_refused():
    params = {"g": G, "e": 0.5}
    with pytest.raises(lx.ArgumentTypeError, match="condition"):
        lx.Event(0.0)  # type: ignore[arg-type]
    with pytest.raises(lx.ArgumentTypeError, match="reset"):
        lx.Event(_height, reset=1.0)  # type: ignore[arg-type]
    with pytest.raises(lx.ConfigurationError, match="direction=2"):
        lx.Event(_height, direction=2)
    with pytest.raises(lx.ConfigurationError, match="terminal"):
        lx.Event(_height, terminal=True, reset=lambda t, q, qd, p: (q, qd))
    with pytest.raises(lx.ConfigurationError, match="max_events=0"):
        lx.Event(_height, max_events=0)
    with pytest.raises(lx.ArgumentTypeError, match=r"events\[0\]: condition.*four"):
        lx.simulate(BALL, [H], [0.0], params, t1=1.0, events=lx.Event(lambda q: q[0]))
    with pytest.raises(lx.ArgumentTypeError, match="lagrax.Event"):
        lx.simulate(BALL, [H], [0.0], params, t1=1.0, events=[_height])  # type: ignore[list-item]
    vector = lx.Event(lambda t, q, qd, p: q)
    with pytest.raises(lx.ShapeError, match=r"events\[0\].*real scalar, got shape \(1,\)"):
        lx.simulate(BALL, [H], [0.0], params, t1=1.0, events=vector)
    wrong = lx.Event(_height, reset=lambda t, q, qd, p: (q, jnp.zeros(2)))
    with pytest.raises(lx.ShapeError, match=r"events\[1\].*reset.*\(1,\)"):
        lx.simulate(BALL, [H], [0.0], params, t1=1.0, events=[GROUND, wrong])
    with pytest.raises(lx.ConfigurationError, match="variational"):
        lx.simulate(BALL, [H], [0.0], params, t1=1.0, events=GROUND, solver="variational", dt=0.01)
    with pytest.raises(lx.ConfigurationError, match="adjoint"):  # (ForwardMode runs: lean loop)
        lx.simulate(BALL, [H], [0.0], params, t1=1.0, events=GROUND, adjoint=dfx.BacksolveAdjoint())
    with pytest.raises(lx.ShapeError, match="real scalar"):
        lx.sweep(BALL, [H], [0.0], {"g": np.full(2, G)}, t1=1.0, events=vector, progress=False)
