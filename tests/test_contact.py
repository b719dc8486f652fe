"""Contact (`lagrax.contact`) against the textbook's closed forms, the static load,
the energy balance and central differences.

Every solve here uses the default method (`ContactSystem.default_method`, implicit), as
the contact guide writes them.

Planar models throughout (a disk in `(x, y, θ)`, a point mass in `(x, y)`, a box in
`(x, y, θ)` with four corner points), on a flat floor `y = 0`; an incline is gravity
tilted by `θ` (`params["gx"], params["gy"]`), so that one compiled solve serves every
slope and friction coefficient.
"""

import math
import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax.contact import Box, ContactSystem, JointLimit, Plane, Sphere

G = 9.81
R = 0.1  # the disk's and the point mass's radius
FLOOR = Plane([0.0, 1.0])
TS = np.linspace(0.0, 1.0, 201)  # one shape of saves: one compiled solve per scene


def _gravity(angle):
    """Gravity tilted so that the floor is an incline of `angle` descending towards +x."""
    return {"gx": G * np.sin(angle), "gy": -G * np.cos(angle)}


def _potential(q, p):
    return -p["m"] * (p["gx"] * q[0] + p["gy"] * q[1])


# --------------------------------------------------------------------------- scenes
@pytest.fixture(scope="module")
def ball():
    """A uniform sphere (`I = 2/5 m r²`) rolling or sliding in its plane, friction read
    from params; every other contact coefficient the default (scaled from the scene)."""

    def kinetic(q, qd, p):
        return 0.5 * p["m"] * (qd[0] ** 2 + qd[1] ** 2) + 0.2 * p["m"] * R**2 * qd[2] ** 2

    body = lx.LagrangianSystem(kinetic, _potential, n_dof=3)
    sphere = Sphere(R, lambda q, p: q[:2], angle=lambda q, p: q[2])
    scene = ContactSystem(
        body,
        sphere,
        FLOOR,
        friction=lambda p: p["mu"],
        static_friction=lambda p: p["mus"],
    )

    def run(angle, mu, mus, qd0, t1, ts):
        params = {"m": 1.0, "mu": mu, "mus": mus, **_gravity(angle)}
        k = scene.coefficients(params)
        rest = (params["m"] * G * np.cos(angle) / float(k.stiffness)) ** (1 / 1.5)
        q0 = [0.0, R - rest, 0.0]  # resting on the floor
        return lx.simulate(scene, q0, qd0, params, t1=t1, ts=ts)  # the default method

    return run


@pytest.fixture(scope="module")
def point():
    """A point mass with a sphere of radius R; friction and dissipation read from params
    (so that jax.grad and a sweep see them), the stiffness the default."""
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * p["m"] * qd @ qd, _potential, n_dof=2)
    scene = ContactSystem(
        body,
        Sphere(R, lambda q, p: q),
        FLOOR,
        friction=lambda p: p["mu"],
        dissipation=lambda p: p["c"],
    )
    return scene


def _params(mu=0.0, c=0.0):
    return {"m": 1.0, "mu": mu, "c": c, **_gravity(0.0)}


# --------------------------------------------------------------------------- closed forms
def test_sphere_rolls_down_an_incline_at_five_sevenths_g_sin(ball):
    angle = np.deg2rad(15.0)
    sol = ball(angle, 0.5, 1.0, [0.0, 0.0, 0.0], 1.0, TS)
    ts = TS
    assert bool(sol.ok)
    keep = ts > 0.2  # after the start's transient
    accel = 2.0 * np.polyfit(ts[keep], np.asarray(sol.q[keep, 0]), 2)[0]
    expected = 5.0 / 7.0 * G * np.sin(angle)
    assert abs(accel / expected - 1.0) < 1e-3
    # rolling: the contact point does not slip (within the creep bound v_s)
    slip = np.asarray(sol.qd[-1, 0] + R * sol.qd[-1, 2])
    assert abs(slip) < 1e-4 * np.sqrt(G * R)


def test_sphere_slides_and_spins_up_below_the_rolling_friction(ball):
    angle, mu = np.deg2rad(30.0), 0.1  # mu < 2/7 tan(30°): slips throughout
    sol = ball(angle, mu, mu, [0.0, 0.0, 0.0], 0.5, TS * 0.5)
    ts = TS * 0.5
    keep = ts > 0.1
    accel = 2.0 * np.polyfit(ts[keep], np.asarray(sol.q[keep, 0]), 2)[0]
    spin = np.polyfit(ts[keep], np.asarray(sol.qd[keep, 2]), 1)[0]
    assert abs(accel / (G * (np.sin(angle) - mu * np.cos(angle))) - 1.0) < 1e-3
    assert abs(-spin / (2.5 * mu * G * np.cos(angle) / R) - 1.0) < 1e-3


def test_bowling_ball_rolls_from_two_sevenths_at_five_sevenths_v0(ball):
    v0, mu = 2.0, 0.2
    t_star = 2.0 * v0 / (7.0 * mu * G)
    sol = ball(0.0, mu, mu, [v0, 0.0, 0.0], 0.5, TS * 0.5)
    ts = TS * 0.5
    slip = np.asarray(sol.qd[:, 0] + R * sol.qd[:, 2])
    # the slip falls linearly while it slides: its line's zero is t*; after, it rolls
    sliding = slip > 1e-2
    found = -np.divide(*np.polyfit(ts[sliding], slip[sliding], 1)[::-1])
    assert abs(found / t_star - 1.0) < 1e-3
    assert np.all(np.abs(slip[ts > t_star + 0.01]) < 1e-4 * np.sqrt(G * R))
    assert abs(float(sol.qd[-1, 0]) / (5.0 / 7.0 * v0) - 1.0) < 1e-3


def test_ball_dropped_without_dissipation_rebounds_to_its_height(point):
    params = _params()
    sol = lx.simulate(point, [0.0, 1.0 + R], [0.0, 0.0], params, t1=0.7, n_save=141)
    assert bool(sol.ok)
    assert float(sol.qd[-1, 1]) > 0  # bounced: on its way up, in flight
    apex = float(sol.q[-1, 1]) + float(sol.qd[-1, 1]) ** 2 / (2 * G) - R
    assert abs(apex - 1.0) < 1e-4
    assert float(np.max(np.abs(sol.energy_error))) < 1e-6
    assert sol.contact_gap.shape == (141, 1) and sol.contact_force.shape == (141, 1, 2)


def test_dissipation_is_in_the_work_and_the_contact_never_pulls(point):
    params = _params(c=0.05)  # restitution about 0.8 at the impact speed sqrt(2 g)
    # Solution.work is integrated from the saves: they must resolve the ~1 ms impact
    t_hit = np.sqrt(2.0 / G)
    impact = np.linspace(t_hit - 2e-4, t_hit + 2e-3, 101)
    ts = np.concatenate([np.linspace(0.0, t_hit - 3e-4, 20), impact, np.linspace(0.46, 0.7, 20)])
    sol = lx.simulate(point, [0.0, 1.0 + R], [0.0, 0.0], params, t1=0.7, ts=ts)
    work = np.asarray(sol.work)
    # h − h0 − W, W the dissipation: the work's Hermite rule is sixth order where the
    # power is smooth, and the power has a t^(3/2) onset (measured 1.6e-5 here)
    assert float(np.max(np.abs(sol.energy_error))) < 1e-4
    assert np.all(np.diff(work) <= 1e-12) and work[-1] < -0.1  # energy only leaves
    apex = float(sol.q[-1, 1]) + float(sol.qd[-1, 1]) ** 2 / (2 * G) - R
    assert abs(apex - (1.0 + float(work[-1]) / G)) < 1e-4  # the lost energy is the work
    assert float(np.min(sol.contact_force[..., 1])) >= 0.0  # no adhesion


def test_contact_events_locate_the_hertz_impact(point):
    params = _params()
    sol = lx.simulate(
        point, [0.0, 1.0 + R], [0.0, 0.0], params, t1=0.7, n_save=141, events=point.events()
    )
    record = sol.events[0]
    assert int(record.count) == 2  # onset and release
    onset, release = np.asarray(record.times[:2])
    assert abs(onset - np.sqrt(2.0 / G)) < 1e-9
    # Hertz (p = 3/2, no damping): t_c = 2 (δ_max / v) ∫_0^1 (1 − x^(5/2))^(-1/2) dx,
    # δ_max = (5 m v² / (4 k))^(2/5); gravity shortens it by O(g t_c / v) ~ 2e-3
    k = float(point.coefficients(params).stiffness)
    v = np.sqrt(2.0 * G)
    delta_max = (5.0 * v**2 / (4.0 * k)) ** 0.4
    integral = math.gamma(0.4) * math.gamma(0.5) / math.gamma(0.9) / 2.5
    assert abs((release - onset) / (2.0 * delta_max / v * integral) - 1.0) < 5e-3
    assert float(np.max(np.abs(sol.energy_error))) < 1e-6


def test_box_on_a_slope_below_its_friction_angle_stays_put():
    a, b, m = 0.1, 0.05, 1.0
    inertia = m * (4 * a**2 + 4 * b**2) / 12

    def kinetic(q, qd, p):
        return 0.5 * p["m"] * (qd[0] ** 2 + qd[1] ** 2) + 0.5 * inertia * qd[2] ** 2

    body = lx.LagrangianSystem(kinetic, _potential, n_dof=3)
    corners = Box((a, b), lambda q, p: q[:2], angle=lambda q, p: q[2])  # its 4 corners
    box = ContactSystem(body, corners, FLOOR, friction=0.5)
    angle = np.deg2rad(15.0)
    params = {"m": m, **_gravity(angle)}
    sol = lx.simulate(box, [0.0, b, 0.0], [0.0, 0.0, 0.0], params, t1=5.0)  # default method
    assert bool(sol.ok)
    assert abs(float(sol.q[-1, 0] - sol.q[0, 0])) <= 1e-3
    # at rest the contact forces carry the weight: normal m g cos θ, tangential m g sin θ
    total = np.asarray(jnp.sum(sol.contact_force[-1], axis=0))
    assert abs(total[1] / (m * G * np.cos(angle)) - 1.0) < 1e-6
    assert abs(-total[0] / (m * G * np.sin(angle)) - 1.0) < 1e-6


def test_resting_normal_force_is_the_weight(point):
    params = _params()
    k = float(point.coefficients(params).stiffness)
    rest = (G / k) ** (1 / 1.5)
    forces = point.normal_forces(jnp.array([0.0, R - rest]), jnp.zeros(2), params)
    assert abs(float(forces[0]) / G - 1.0) < 1e-12


@pytest.mark.slow
def test_a_free_sphere_on_a_floating_base_rolls_down_a_3d_incline():
    """The spatial path: a floating base (quaternion configuration, body-frame
    velocities) with `rotation=`, on a tilted 3-D plane, gravity along −z."""
    robot = lx.chains.FloatingTree(lx.chains.Tree("", ()))
    params = robot.params(base_m=1.0, base_inertia=0.4 * R**2 * np.eye(3), g=G)

    def rotation(q, p):  # the base quaternion is (x, y, z, w)
        return lx.rigid_body.quaternion_to_matrix(jnp.stack([q[6], q[3], q[4], q[5]]))

    angle = np.deg2rad(15.0)
    normal = np.array([np.sin(angle), 0.0, np.cos(angle)])  # descending towards +x
    sphere = Sphere(R, lambda q, p: q[:3], rotation=rotation)
    scene = ContactSystem(robot.system(), sphere, Plane(normal), friction=0.5, static_friction=1.0)
    rest = (G * np.cos(angle) / float(scene.coefficients(params).stiffness)) ** (1 / 1.5)
    q0 = jnp.array([*((R - rest) * normal), 0.0, 0.0, 0.0, 1.0])
    sol = lx.simulate(scene, q0, jnp.zeros(6), params, t1=1.0, ts=TS, solver="kvaerno5")
    downhill = np.asarray(sol.q[:, :3]) @ np.array([np.cos(angle), 0.0, -np.sin(angle)])
    keep = TS > 0.2
    accel = 2.0 * np.polyfit(TS[keep], downhill[keep], 2)[0]
    assert abs(accel / (5.0 / 7.0 * G * np.sin(angle)) - 1.0) < 1e-3


def test_sweep_over_friction_slides_each_member_its_closed_form_distance(point):
    v0, t1 = 2.0, 0.3
    k = float(point.coefficients(_params()).stiffness)
    y_rest = R - (G / k) ** (1 / 1.5)
    mus = np.array([0.1, 0.3, 0.5])
    ds = lx.sweep(point, [0.0, y_rest], [v0, 0.0], lx.samples(_params(), mu=mus), t1=t1)
    assert ds.attrs["n_failed"] == 0
    x = np.asarray(ds.q.isel(dof=0))
    np.testing.assert_allclose(x, v0 * t1 - 0.5 * mus * G * t1**2, rtol=1e-6)


# --------------------------------------------------------------------------- derivatives
def _central(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


def test_gradient_through_a_slide_matches_central_differences(point):
    t1, v0, mu = 0.3, 2.0, 0.3
    k = float(point.coefficients(_params()).stiffness)
    y_rest = R - (G / k) ** (1 / 1.5)
    kw = dict(t1=t1, n_save=2, rtol=1e-12, atol=1e-12)

    def distance(v, m):
        sol = lx.simulate(point, jnp.stack([0.0, y_rest]), jnp.stack([v, 0.0]), _params(m), **kw)
        return sol.q[-1, 0]

    grads = jax.grad(distance, argnums=(0, 1))(v0, mu)
    fd_v = _central(lambda v: float(distance(v, mu)), v0, 1e-4)
    fd_mu = _central(lambda m: float(distance(v0, m)), mu, 1e-4)
    assert abs(float(grads[0]) / fd_v - 1.0) < 1e-6
    assert abs(float(grads[1]) / fd_mu - 1.0) < 1e-6
    # and the closed form of the slide, x = v0 t − μ g t²/2
    assert abs(float(grads[1]) / (-0.5 * G * t1**2) - 1.0) < 1e-6


def test_gradient_through_a_bounce_matches_central_differences(point):
    """The rebound's dependence on the Hunt–Crossley dissipation. (With respect to the
    drop height the derivative is the small difference of large timing terms, and the
    sensitivities, on the steps the state's error chooses, reach it only to ~1e-2: see
    the contact guide.)"""
    kw = dict(t1=0.7, n_save=2, rtol=1e-12, atol=1e-12)

    def height(c):
        sol = lx.simulate(point, jnp.stack([0.0, 1.0 + R]), jnp.zeros(2), _params(c=c), **kw)
        return sol.q[-1, 1]

    c0 = 0.05  # restitution about 0.8 at the impact speed sqrt(2 g)
    grad = float(jax.grad(height)(c0))
    assert abs(grad / _central(lambda c: float(height(c)), c0, 1e-5) - 1.0) < 1e-6


# --------------------------------------------------------------------------- walking
def test_rimless_wheel_on_compliant_ground_walks_the_rigid_impact_gait():
    """McGeer's rimless wheel (hub `m`, inertia `I`, 8 massless spokes of length `l`) on
    a slope, each spoke's tip a point against the tilted plane, started in the rigid
    gait just after a heel strike: its steps take the rigid gait's period and its hub
    advances at its speed. The rigid gait is closed-form (`ω⁺ = (I + m l² cos 2α)/(I +
    m l²) ω⁻`, and the stance's energy gain), its period a quadrature of the stance."""
    from scipy.integrate import quad

    n, length, m, inertia, gamma = 8, 1.0, 1.0, 0.1, 0.1
    alpha, j = np.pi / n, inertia + m * length**2
    ratio = (inertia + m * length**2 * np.cos(2 * alpha)) / j
    gain = 4 * m * G * length * np.sin(alpha) * np.sin(gamma)  # the stance's, in j ω²
    w_plus = ratio * np.sqrt(gain / (j * (1 - ratio**2)))

    def rate(theta):  # the stance's θ̇ from the energy, from θ = γ − α
        drop = np.cos(gamma - alpha) - np.cos(theta)
        return np.sqrt(w_plus**2 + 2 * m * G * length * drop / j)

    period = quad(lambda th: 1 / rate(th), gamma - alpha, gamma + alpha, epsabs=1e-13)[0]

    def tip(k):
        def position(q, p):
            a = q[2] + 2 * alpha * k
            return q[:2] + length * jnp.stack([jnp.sin(a), -jnp.cos(a)])

        return position

    hub = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * m * (qd[0] ** 2 + qd[1] ** 2) + 0.5 * inertia * qd[2] ** 2,
        lambda q, p: m * G * q[1],
        n_dof=3,
    )
    depth = 5e-4  # static penetration under the weight
    wheel = ContactSystem(
        hub,
        [Sphere(0.0, tip(k)) for k in range(n)],
        Plane([np.sin(gamma), np.cos(gamma)]),
        friction=1.0,
        stiffness=m * G / depth**1.5,
        dissipation=4 / 3 * np.sqrt(1.5 / (G * depth)),
        stiction_velocity=0.01,
    )
    th, w = gamma - alpha, w_plus
    q0 = [length * np.sin(th), length * np.cos(th), -th]
    qd0 = [length * w * np.cos(th), -length * w * np.sin(th), -w]
    sol = lx.simulate(wheel, q0, qd0, {}, t1=2.5, n_save=1251, rtol=1e-6, atol=1e-6)
    assert bool(sol.ok)
    ts, gaps = np.asarray(sol.ts), np.asarray(sol.contact_gap)
    onsets = []  # each foot's onset, on its gap's zero crossing
    for k in range(n):
        for i in np.flatnonzero((gaps[1:, k] < 0) & (gaps[:-1, k] >= 0)):
            onsets.append(ts[i] + (ts[i + 1] - ts[i]) * gaps[i, k] / (gaps[i, k] - gaps[i + 1, k]))
    onsets = np.sort(onsets)
    assert len(onsets) >= 3
    steps = np.diff(onsets)
    downhill = np.asarray(sol.q[:, :2]) @ np.array([np.cos(gamma), -np.sin(gamma)])
    stride = np.diff(np.interp(onsets, ts, downhill))
    # measured: the steps within 7e-4 of the rigid period (the first, from a start at
    # zero penetration; then 3e-4), the hub's speed within 5e-4 of the rigid gait's
    np.testing.assert_allclose(steps, period, rtol=1e-3)
    np.testing.assert_allclose(stride / steps, 2 * length * np.sin(alpha) / period, rtol=1e-3)


# --------------------------------------------------------------------------- bad input
def test_bad_geometry_and_coefficients_are_refused_naming_the_value():
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, n_dof=2)
    point = Sphere(0.0, lambda q, p: q)
    with pytest.raises(lx.ConfigurationError, match="radius=-0.1"):
        Sphere(-0.1, lambda q, p: q)
    with pytest.raises(lx.ConfigurationError, match=r"normal=\[0.0, 0.0\]"):
        Plane([0.0, 0.0])
    with pytest.raises(lx.ConfigurationError, match="friction=-0.2"):
        ContactSystem(body, point, FLOOR, friction=-0.2)
    with pytest.raises(lx.ConfigurationError, match="stiffness=inf"):
        ContactSystem(body, point, FLOOR, stiffness=float("inf"))
    with pytest.raises(lx.ConfigurationError, match="static_friction=0.1 < friction=0.5"):
        ContactSystem(body, point, FLOOR, friction=0.5, static_friction=0.1)
    with pytest.raises(lx.ConfigurationError, match="needs a 3-D plane"):
        ContactSystem(body, Sphere(0.1, lambda q, p: q, angle=None, rotation=jnp.eye), FLOOR)


def test_a_bad_coefficient_read_from_params_is_refused_by_simulate(point):
    with pytest.raises(lx.ConfigurationError, match="friction=-0.5"):
        lx.simulate(point, [0.0, 1.0 + R], [0.0, 0.0], _params(mu=-0.5), t1=0.7, n_save=141)


def test_a_scene_without_weight_needs_its_stiffness():
    free = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, n_dof=2)  # no gravity
    scene = ContactSystem(free, Sphere(0.1, lambda q, p: q), FLOOR)
    with pytest.raises(lx.ConfigurationError, match="no gravity towards the plane"):
        scene.check_state(jnp.array([0.0, 1.0]), jnp.zeros(2), {})


# --------------------------------------------------------------------------- trees
_LEG = """<robot name="leg">
  <link name="base"><inertial><mass value="2.0"/>
    <inertia ixx="0.02" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="thigh"><inertial><origin xyz="0 0 -0.1"/><mass value="0.3"/>
    <inertia ixx="0.001" iyy="0.001" izz="0.0002" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="shank"><inertial><origin xyz="0 0 -0.1"/><mass value="0.2"/>
    <inertia ixx="0.001" iyy="0.001" izz="0.0002" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="foot"/>
  <joint name="hip" type="revolute"><parent link="base"/><child link="thigh"/>
    <origin xyz="0.1 0.05 0" rpy="0.2 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/></joint>
  <joint name="knee" type="revolute"><parent link="thigh"/><child link="shank"/>
    <origin xyz="0 0 -0.2"/><axis xyz="1 0 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/></joint>
  <joint name="ankle" type="fixed"><parent link="shank"/><child link="foot"/>
    <origin xyz="0.01 0 -0.2"/></joint>
</robot>"""


def test_body_sphere_sits_where_pinocchio_places_the_frame():
    pin = pytest.importorskip("pinocchio", reason="Pinocchio is the kinematics reference")
    robot, params = lx.chains.from_urdf(_LEG, floating_base=True)
    foot = lx.contact.body_sphere(robot, "shank", 0.02, offset=(0.01, 0.0, -0.2))
    base = lx.contact.body_sphere(robot, robot.base_name, 0.0, offset=(0.0, 0.0, 0.1))
    model = pin.buildModelFromXML(_LEG, pin.JointModelFreeFlyer())
    data = model.createData()
    rng = np.random.default_rng(0)
    for _ in range(3):
        quat = rng.normal(size=4)
        q = np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat), rng.normal(size=2)])
        pin.framesForwardKinematics(model, data, q)  # same (x, y, z, w) convention
        placed = data.oMf[model.getFrameId("foot")]
        np.testing.assert_allclose(foot.position(q, params), placed.translation, atol=1e-12)
        np.testing.assert_allclose(foot.rotation(q, params), placed.rotation, atol=1e-12)
        root = data.oMf[model.getFrameId("root_joint")]
        expected = root.translation + root.rotation @ np.array([0.0, 0.0, 0.1])
        np.testing.assert_allclose(base.position(q, params), expected, atol=1e-12)
    with pytest.raises(lx.ConfigurationError, match="no body named 'toe'"):
        lx.contact.body_sphere(robot, "toe", 0.02)


def test_a_contact_scene_defaults_to_an_implicit_method(ball):
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, lambda q, p: 0.0, n_dof=2)
    assert body.default_method == "tsit5"
    ball = Sphere(R, lambda q, p: q)
    # implicit where a contact can stick (friction) or limits are enforced
    assert ContactSystem(body, ball, FLOOR, friction=0.3).default_method == "rodas4"
    assert ContactSystem(body, ball, FLOOR, friction=lambda p: 0.0).default_method == "rodas4"
    stop = [JointLimit(0, -1.0, 1.0)]
    assert ContactSystem(body, ball, FLOOR, limits=stop).default_method == "rodas4"
    # a frictionless scene: its impacts are the explicit method's
    assert ContactSystem(body, ball, FLOOR).default_method == "tsit5"


@pytest.fixture(scope="module")
def held():
    """The rolling sphere of the first test (its friction holds its contact point),
    solved with an explicit method and a small step budget: it runs out of steps."""

    def kinetic(q, qd, p):
        return 0.5 * (qd[0] ** 2 + qd[1] ** 2) + 0.2 * R**2 * qd[2] ** 2

    body = lx.LagrangianSystem(kinetic, lambda q, p: _potential(q, {**p, "m": 1.0}), n_dof=3)
    sphere = Sphere(R, lambda q, p: q[:2], angle=lambda q, p: q[2])
    scene = ContactSystem(body, sphere, FLOOR, friction=0.5, static_friction=1.0)
    params = _gravity(np.deg2rad(15.0))
    k = float(scene.coefficients(params).stiffness)
    rest = (G * np.cos(np.deg2rad(15.0)) / k) ** (1 / 1.5)
    return scene, [0.0, R - rest, 0.0], params


def test_a_contact_that_sticks_and_runs_out_of_steps_is_named_with_what_to_do(held):
    scene, q0, params = held
    with pytest.raises(lx.SimulationError) as info:
        lx.simulate(scene, q0, [0.0] * 3, params, t1=1.0, solver="tsit5", max_steps=2000)
    text = str(info.value)
    v_s = float(scene.coefficients(params).stiction_velocity)
    # which contact, which part of it, its coefficient, its rate against the step reached
    assert "sphere 0's contact with the plane, its friction holding it" in text
    assert f"stiction_velocity={v_s:.4g}" in text
    found = re.search(r"lambda=([0-9.e+]+) 1/s, against a mean step of ([0-9.e+-]+) s", text)
    assert found is not None
    lam, h = float(found.group(1)), float(found.group(2))
    # the stuck contact's rate: μ_s f_n/(v_s m_t), f_n = m g cos θ, m_t = (2/7) m
    expected = 1.0 * G * np.cos(np.deg2rad(15.0)) / (v_s * 2.0 / 7.0)
    assert 0.5 < lam / expected < 2.0
    assert 1.0 < h * lam < 4.0  # an explicit method held at its stability limit
    # what to do: the implicit method, the coefficients, the budget
    for advice in ("solver='rodas4'", "stiction_velocity=", "stiffness=", "max_steps"):
        assert advice in text, advice
