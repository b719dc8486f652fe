"""Contact between spheres (`pairs=`), capsules and boxes as sphere sets, the start
deep inside the ground, and the fixed step past the contact's stability limit.

Planar scenes on a floor `y = 0` with gravity along `−y`: two billiard balls (point
masses of radius R in `(x, y)`), a Newton's cradle of three pendulums, a box and a
capsule as their sphere sets. Each is checked against a closed form or an invariant.
"""

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax.contact import Box, Capsule, ContactSystem, Plane, Sphere

G = 9.81
R = 0.05  # a billiard ball's radius
FLOOR = Plane([0.0, 1.0])


def _table_potential(q, p):
    return p["m"] * G * (q[1] + q[3] + q[5])


@pytest.fixture(scope="module")
def table():
    """Three equal balls on a frictionless table (point masses in `(x, y)`, every pair
    touching), elastic (no dissipation), default stiffness; one compiled solve serves
    the tests below."""
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * p["m"] * qd @ qd, _table_potential, n_dof=6)
    balls = [Sphere(R, lambda q, p, i=i: q[2 * i : 2 * i + 2]) for i in range(3)]
    scene = ContactSystem(body, balls, FLOOR, pairs="all", dissipation=0.0)
    k = float(scene.coefficients({"m": 1.0}).stiffness)
    rest = (G / k) ** (1 / 1.5)  # each ball's static penetration into the table
    return scene, R - rest


def _roll(scene, xs, v, **kw):
    """The balls resting on the table at `xs`, the first launched at `v` along `x`."""
    scene, y = scene
    q0 = [c for x in xs for c in (x, y)]
    return lx.simulate(scene, q0, [v] + [0.0] * 5, {"m": 1.0}, t1=0.5, n_save=51, **kw)


def test_head_on_elastic_collision_of_equal_balls_exchanges_their_velocities(table):
    v = 1.0
    sol = _roll(table, [0.0, 0.3, 2.0], v)  # the third ball far away
    assert bool(sol.ok)
    # the closed form of an elastic collision of equal masses: the striker stops, the
    # other leaves at its speed
    assert abs(float(sol.qd[-1, 0])) < 1e-3 * v
    assert abs(float(sol.qd[-1, 2]) / v - 1.0) < 1e-3
    # no external horizontal force: momentum is conserved to round-off
    momentum = np.asarray(sol.qd[:, 0] + sol.qd[:, 2] + sol.qd[:, 4])
    assert np.max(np.abs(momentum - v)) < 1e-12
    assert float(np.max(np.abs(sol.energy_error))) < 1e-6
    assert sol.pair_gap.shape == (51, 3) and sol.pair_force.shape == (51, 3, 2)
    assert sol.contact_gap.shape == (51, 3)
    # the collision happened (the gap closed and reopened), and nothing pulls
    assert float(sol.pair_gap[0, 0]) > 0 and float(sol.pair_gap[-1, 0]) > 0
    assert float(np.min(sol.pair_force[..., 0])) >= 0.0


def test_newtons_cradle_passes_the_striker_speed_to_the_last_ball(table):
    """A Newton's cradle's row: three balls 1 mm apart (the strings only hold them up),
    the first launched at the second, which strikes the third: each collision exchanges
    the velocities, so the third leaves at the striker's speed and the first two stop."""
    v = 1.0
    sol = _roll(table, [0.0, 2 * R + 1e-3, 4 * R + 2e-3], v)
    assert bool(sol.ok)
    final = np.asarray(sol.qd[-1, 0::2])
    assert abs(final[2] / v - 1.0) < 1e-3
    assert np.all(np.abs(final[:2]) < 1e-3 * v)
    assert float(np.min(sol.pair_gap[-1, :])) > 0  # all apart again
    # two impacts at the default tolerances (1e-8): measured 1.0e-6
    assert float(np.max(np.abs(sol.energy_error))) < 1e-5


# --------------------------------------------------------------------------- shapes
def test_a_box_is_its_corners_and_rests_on_them_with_its_weight():
    """A 3-D box (half-extents a, b, c), turned by a rotation about z: its 8 corners,
    and at its static penetration the 4 bottom ones carry m g, each a quarter."""
    half = np.array([0.2, 0.1, 0.05])
    angle = 0.3
    rot = np.array(
        [[np.cos(angle), -np.sin(angle), 0.0], [np.sin(angle), np.cos(angle), 0.0], [0, 0, 1]]
    )
    box = Box(half, lambda q, p: q[:3], rotation=lambda q, p: jnp.asarray(rot))
    centre = np.array([0.3, -0.1, 0.05])
    corners = np.asarray([s.position(centre, {}) for s in box.spheres])
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
    np.testing.assert_allclose(corners, centre + (signs * half) @ rot.T, atol=1e-15)
    assert all(s.radius == 0.0 for s in box.spheres)

    m = 2.0
    body = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * m * qd @ qd, lambda q, p: m * G * q[2], n_dof=3
    )
    scene = ContactSystem(body, box, Plane([0.0, 0.0, 1.0]), friction=0.5)
    k = float(scene.coefficients({}).stiffness)
    sink = (m * G / 4 / k) ** (1 / 1.5)  # each bottom corner's share, m g/4 = k δ^p
    forces = np.asarray(
        scene.normal_forces(jnp.array([0.3, -0.1, half[2] - sink]), jnp.zeros(3), {})
    )
    bottom = signs[:, 2] < 0
    np.testing.assert_allclose(forces[bottom], m * G / 4, rtol=1e-12)
    assert np.all(forces[~bottom] == 0.0)
    assert abs(forces.sum() / (m * G) - 1.0) < 1e-12


def test_a_capsule_is_its_end_spheres_and_lies_on_both():
    """A planar capsule (radius r, half-length h, axis along the body's x) at angle θ:
    its end spheres at `c ± h (cos θ, sin θ)`, turning with the body; lying flat at its
    static penetration each end carries half its weight, tilted only the lower one
    touches."""
    r, h, m = 0.05, 0.2, 1.0
    capsule = Capsule(r, h, lambda q, p: q[:2], angle=lambda q, p: q[2])
    q = np.array([0.1, 0.2, 0.4])
    ends = np.asarray([s.position(q, {}) for s in capsule.spheres])
    axis = np.array([np.cos(q[2]), np.sin(q[2])])
    np.testing.assert_allclose(ends, [q[:2] + h * axis, q[:2] - h * axis], atol=1e-15)
    assert [s.radius for s in capsule.spheres] == [r, r]
    assert all(s.angle is not None for s in capsule.spheres)

    body = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * m * (qd[0] ** 2 + qd[1] ** 2) + 0.5 * 0.01 * qd[2] ** 2,
        lambda q, p: m * G * q[1],
        n_dof=3,
    )
    k = 1e7
    scene = ContactSystem(body, capsule, FLOOR, stiffness=k)
    sink = (m * G / 2 / k) ** (1 / 1.5)
    normal_forces = jax.jit(lambda q: scene.normal_forces(q, jnp.zeros(3), {}))
    flat = np.asarray(normal_forces(jnp.array([0.0, r - sink, 0.0])))
    np.testing.assert_allclose(flat, m * G / 2, rtol=1e-12)
    tilted = jnp.array([0.0, r + h * np.sin(0.1) - sink, 0.1])  # the lower end as deep
    forces = np.asarray(normal_forces(tilted))
    np.testing.assert_allclose(forces, [0.0, m * G / 2], rtol=1e-9)


# --------------------------------------------------------------------------- deep starts
def test_a_ball_starting_deep_inside_the_table_is_an_error_naming_it(table):
    scene, y = table
    deep = y - 0.02 * R  # 2% of its radius inside: past max_penetration = 1%
    with pytest.raises(lx.ContactError, match=r"sphere 1 \(radius 0.05\) starts 0.001"):
        lx.simulate(scene, [0.0, y, 0.3, deep, 2.0, y], [0.0] * 6, {"m": 1.0}, t1=0.5, n_save=51)
    # two balls overlapping by more than 1% of a radius
    with pytest.raises(lx.ContactError, match=r"spheres 0 and 1 \(pair 0\) start overlapping"):
        scene.check_state(jnp.array([0.0, y, 2 * R - 0.002, y, 2.0, y]), jnp.zeros(6), {"m": 1.0})
    # traced (a sweep's member, under jit): the initial state is flagged not admissible
    start = jax.jit(lambda q: scene.initial_state(q, jnp.zeros(6), {"m": 1.0})[2])
    assert not bool(start(jnp.array([0.0, y, 0.3, deep, 2.0, y])))
    assert bool(start(jnp.array([0.0, y, 0.3, y, 2.0, y])))


# --------------------------------------------------------------------------- fixed steps
def test_a_fixed_step_past_the_contact_stability_limit_is_reported():
    """A ball resting on the floor (its height its one coordinate), on an undamped
    spring of `ω = √(p k δ^{p−1}/m) = √(p g/δ)` (`k δ^p = m g`): RK4 at a fixed step just
    below `2/ω` runs, and just past it the solve stops, naming the limit."""
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, lambda q, p: G * q[0], n_dof=1)
    ball = Sphere(R, lambda q, p: jnp.stack([jnp.zeros_like(q[0]), q[0]]))
    scene = ContactSystem(body, ball, FLOOR, dissipation=0.0)
    delta = (G / float(scene.coefficients({}).stiffness)) ** (1 / 1.5)
    omega = np.sqrt(1.5 * G / delta)  # the spring at the static penetration
    q0, v0 = [R - delta], [0.0]
    run = dict(t1=0.05, n_save=11, solver="rk4", throw=False)
    below = lx.simulate(scene, q0, v0, {}, dt=0.95 * 2 / omega, **run)
    assert bool(below.ok)
    np.testing.assert_allclose(below.q[-1], q0, atol=1e-12)  # still at rest
    past = lx.simulate(scene, q0, v0, {}, dt=1.05 * 2 / omega, **run)
    assert not bool(past.ok)
    assert past.result == lx.RESULTS.step_past_stability_limit
    with pytest.raises(lx.SimulationError, match=r"dt <= 2/lambda") as err:
        lx.simulate(scene, q0, v0, {}, dt=1.05 * 2 / omega, **run | {"throw": True})
    found = re.search(r"lambda=([\d.e+]+) 1/s", str(err.value))
    assert found is not None
    assert abs(float(found.group(1)) / omega - 1.0) < 1e-3  # the rate named is the spring's ω


# --------------------------------------------------------------------------- bad input
def test_bad_pairs_and_shapes_are_refused_naming_the_value():
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, n_dof=4)
    two = [Sphere(R, lambda q, p: q[:2]), Sphere(R, lambda q, p: q[2:])]
    with pytest.raises(lx.ConfigurationError, match=r"pair \(0, 2\), but the spheres are"):
        ContactSystem(body, two, FLOOR, pairs=[(0, 2)])
    with pytest.raises(lx.ConfigurationError, match="cannot touch itself"):
        ContactSystem(body, two, FLOOR, pairs=[(1, 1)])
    with pytest.raises(lx.ConfigurationError, match="needs something to touch"):
        ContactSystem(body, two, None)
    with pytest.raises(lx.ConfigurationError, match="max_penetration=-1"):
        ContactSystem(body, two, FLOOR, max_penetration=-1.0)
    with pytest.raises(lx.ConfigurationError, match=r"half_extents=\[0.1, -0.1\]"):
        Box([0.1, -0.1], lambda q, p: q[:2])
    with pytest.raises(lx.ConfigurationError, match="radius=-0.1"):
        Capsule(-0.1, 0.2, lambda q, p: q[:2])


# --------------------------------------------------------------------------- derivatives
def test_gradients_of_a_settling_ball_match_the_static_penetration():
    """A ball released inside its contact, half its static penetration deep, settles
    (the default dissipation damps it critically) at `y = R − (m g/k)^{1/p}`. The final
    height's derivatives with respect to the mass and the stiffness, by `jax.jacfwd`
    through the solve (sliding at the same time), equal central differences and that
    closed form to 1e-6: a smooth case (the contact never opens, so no onset to locate;
    `jax.grad` through contact: tests/test_contact.py)."""
    body = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * p["m"] * qd @ qd, lambda q, p: p["m"] * G * q[1], n_dof=2
    )
    scene = ContactSystem(
        body, Sphere(R, lambda q, p: q), FLOOR, stiffness=lambda p: p["k"], friction=0.3
    )
    m0, k0 = 1.0, 3e8
    y0 = R - 0.5 * (m0 * G / k0) ** (1 / 1.5)
    kw = dict(t1=0.04, n_save=2, rtol=1e-12, atol=1e-12)

    def height(m, k):
        params = {"m": m, "k": k}
        sol = lx.simulate(scene, jnp.array([0.0, y0]), jnp.array([0.5, 0.0]), params, **kw)
        return sol.q[-1, 1]

    grads = [float(g) for g in jax.jacfwd(height, argnums=(0, 1))(m0, k0)]
    fd_m = (float(height(m0 + 1e-4, k0)) - float(height(m0 - 1e-4, k0))) / 2e-4
    fd_k = (float(height(m0, k0 * 1.0001)) - float(height(m0, k0 * 0.9999))) / (2e-4 * k0)
    exact_m = -(2 / 3) * (G / k0) ** (2 / 3) * m0 ** (-1 / 3)
    exact_k = (2 / 3) * (m0 * G) ** (2 / 3) * k0 ** (-5 / 3)
    for g, f, e in ((grads[0], fd_m, exact_m), (grads[1], fd_k, exact_k)):
        assert abs(g / f - 1.0) < 1e-6
        assert abs(g / e - 1.0) < 1e-6


def test_gradient_through_an_elastic_bounce_from_its_onset_matches_the_closed_form():
    """A ball that starts at the onset of its contact (gap 0), falling at `v0`, bounces
    elastically (Hertz, default stiffness, no dissipation) to the apex `R + v0²/(2 g)`:
    `jax.jacfwd` of the apex through the impact is `v0/g` to 1e-6. (Moving the onset
    inside a step, with the drop height, is the case of the contact guide's table.)"""
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, lambda q, p: G * q[1], n_dof=2)
    scene = ContactSystem(body, Sphere(R, lambda q, p: q), FLOOR, dissipation=0.0)
    kw = dict(t1=0.3, n_save=2, rtol=1e-12, atol=1e-12)

    def apex(v0):
        sol = lx.simulate(scene, jnp.array([0.0, R]), jnp.stack([0.0, -v0]), {}, **kw)
        return sol.q[-1, 1] + sol.qd[-1, 1] ** 2 / (2 * G)

    v0 = 2.0
    assert abs(float(apex(v0)) - R - v0**2 / (2 * G)) < 1e-9  # back up to the apex
    assert abs(float(jax.jacfwd(apex)(v0)) / (v0 / G) - 1.0) < 1e-6


def test_billiards_where_the_object_ball_stops_moves_with_the_cue_speed_by_its_derivative():
    """A cue ball sliding on a table with friction (μ = 0.2, point masses) strikes a
    second ball 0.3 m away, which slides and stops. The derivative of where it stops
    with respect to the cue's speed, by `jax.grad` and `jax.jacfwd` with the defaults
    (the default method here, `rodas4`: something can stick), against central differences
    at `1e-12` (two steps agreeing to 1e-8): the pair's onset moves with the speed. The
    implicit method's sensitivities are under the step-size control (the augmented
    system, as for an explicit method); without it `jax.grad` was 6.8e-3 off."""
    body = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * p["m"] * qd @ qd, lambda q, p: p["m"] * G * (q[1] + q[3]), n_dof=4
    )
    balls = [Sphere(R, lambda q, p, i=i: q[2 * i : 2 * i + 2]) for i in range(2)]
    scene = ContactSystem(body, balls, FLOOR, pairs="all", dissipation=0.0, friction=0.2)
    assert scene.default_method == "rodas4"
    k = float(scene.coefficients({"m": 1.0}).stiffness)
    y = R - (G / k) ** (1 / 1.5)

    def stops_at(v, **kw):
        q0, v0 = jnp.array([0.0, y, 0.3, y]), jnp.stack([v, 0.0, 0.0, 0.0])
        sol = lx.simulate(scene, q0, v0, {"m": 1.0}, t1=1.0, n_save=2, **kw)
        return sol.q[-1, 2]

    tight = dict(rtol=1e-12, atol=1e-12)
    fd = [
        (float(stops_at(1.0 + h, **tight)) - float(stops_at(1.0 - h, **tight))) / (2 * h)
        for h in (1e-3, 1e-4)
    ]
    assert abs(fd[0] / fd[1] - 1.0) < 1e-7  # the central differences have converged
    assert abs(float(stops_at(1.0, **tight)) - 0.3547) < 1e-3  # it moved 5 cm and stopped
    for derivative in (jax.grad(stops_at), jax.jacfwd(stops_at)):
        assert abs(float(derivative(1.0)) / fd[1] - 1.0) < 1e-6  # measured 3e-9, 2e-9
