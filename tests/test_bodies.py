"""Bodies, springs, dampers and inertia tools (``lagrax.bodies``) against independent sources.

- inertia of shapes: textbook formulas and a midpoint-rule volume integral in NumPy;
- parallel axis, rotation: textbook results (rod about its end ``m L²/3``) and invariants;
- scenes: hand-written energies and closed-form equations of motion (pendulums, a
  mass–spring–damper's frequency and decay, spring and damper forces), body-frame angular
  velocity against the Euler-angle rate formula, and the energy balance with dampers.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import random_rotation
from lagrax import bodies as B
from lagrax.bodies import Param


# ------------------------------------------------------------------------ inertia tools
def grid_inertia(inside, half, n=80):
    """``I = ∫ −[r]² ρ dV`` of a unit-density solid by the midpoint rule on a cube grid,
    and its mass (independent of the closed forms)."""
    h = 2 * half / n
    x = -half + h * (np.arange(n) + 0.5)
    xs, ys, zs = np.meshgrid(x, x, x, indexing="ij")
    w = inside(xs, ys, zs).astype(float) * h**3
    mass = w.sum()
    r = np.stack([xs, ys, zs]).reshape(3, -1)
    w = w.reshape(-1)
    inertia = np.sum(w * np.sum(r**2, axis=0)) * np.eye(3) - (w * r) @ r.T
    return mass, inertia


def test_shape_inertias_textbook_values():
    m, length, radius, height = 2.0, 1.5, 0.3, 0.8
    np.testing.assert_allclose(
        B.rod_inertia(m, length), np.diag([0, m * length**2 / 12, m * length**2 / 12])
    )
    np.testing.assert_allclose(
        B.rod_inertia(m, length, axis="z"), np.diag([m * length**2 / 12] * 2 + [0.0])
    )
    np.testing.assert_allclose(B.sphere_inertia(m, radius), np.eye(3) * 0.4 * m * radius**2)
    across = m * (3 * radius**2 + height**2) / 12
    np.testing.assert_allclose(
        B.cylinder_inertia(m, radius, height), np.diag([across, across, 0.5 * m * radius**2])
    )
    a, b, c = 0.4, 0.6, 1.0
    np.testing.assert_allclose(
        B.box_inertia(m, jnp.array([a, b, c])),
        m / 12 * np.diag([b**2 + c**2, a**2 + c**2, a**2 + b**2]),
    )


@pytest.mark.parametrize(
    "shape",
    [
        ("box", lambda x, y, z: (abs(x) < 0.2) & (abs(y) < 0.3) & (abs(z) < 0.5)),
        ("cylinder", lambda x, y, z: (x**2 + y**2 < 0.3**2) & (abs(z) < 0.4)),
        ("sphere", lambda x, y, z: x**2 + y**2 + z**2 < 0.45**2),
    ],
    ids=lambda s: s[0],
)
def test_shape_inertias_match_volume_integral(shape):
    name, inside = shape
    mass, numeric = grid_inertia(inside, half=0.5)
    closed = {
        "box": lambda: B.box_inertia(mass, jnp.array([0.4, 0.6, 1.0])),
        "cylinder": lambda: B.cylinder_inertia(mass, 0.3, 0.8),
        "sphere": lambda: B.sphere_inertia(mass, 0.45),
    }[name]()
    # midpoint rule on a voxelized boundary: ~1 % for curved shapes at 80³
    tol = 1e-3 if name == "box" else 2e-2
    np.testing.assert_allclose(closed, numeric, rtol=tol, atol=tol * np.max(numeric))


def test_parallel_axis():
    m, length = 3.0, 2.0
    about_end = B.parallel_axis(B.rod_inertia(m, length), m, jnp.array([length / 2, 0, 0]))
    np.testing.assert_allclose(about_end, np.diag([0, m * length**2 / 3, m * length**2 / 3]))
    # planar (scalar) inertia: the lecture's I1 + m1 r1²
    np.testing.assert_allclose(B.parallel_axis(0.5, 2.0, jnp.array([0.3, 0.4])), 0.5 + 2 * 0.25)
    # sphere about a point on its surface: 2/5 + 1 = 7/5 m R² about tangent axes
    r = 0.5
    surf = B.parallel_axis(B.sphere_inertia(m, r), m, jnp.array([0.0, 0.0, r]))
    np.testing.assert_allclose(np.diag(surf), [1.4 * m * r**2, 1.4 * m * r**2, 0.4 * m * r**2])
    # a general offset: off-diagonal −m d_i d_j
    d = jnp.array([0.1, -0.2, 0.3])
    shifted = B.parallel_axis(jnp.zeros((3, 3)), 1.0, d)
    np.testing.assert_allclose(shifted[0, 1], 0.1 * 0.2)  # −m d_x d_y = +0.02
    with pytest.raises(lx.ShapeError):
        B.parallel_axis(jnp.eye(3), 1.0, jnp.zeros(2))


def test_rotation_invariants_and_principal_axes():
    rng = np.random.default_rng(0)
    body = B.box_inertia(2.0, jnp.array([0.3, 0.7, 1.1]))
    rot = random_rotation(rng)
    world = B.rotate_inertia(body, rot)
    np.testing.assert_allclose(world, rot @ np.asarray(body) @ rot.T)
    np.testing.assert_allclose(np.trace(world), np.trace(body))
    np.testing.assert_allclose(np.linalg.det(world), np.linalg.det(body))
    moments, axes = B.principal_axes(world)
    np.testing.assert_allclose(moments, np.sort(np.diag(body)))
    np.testing.assert_allclose(axes @ np.diag(moments) @ axes.T, world, atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(axes), 1.0)
    # the principal axes are the box's edges (up to sign)
    edges = rot[:, np.argsort(np.diag(body))]
    np.testing.assert_allclose(np.abs(np.sum(axes * edges, axis=0)), 1.0)
    # the world inertia is a valid inertia; the box's off-diagonal terms are non-zero there
    B.check_inertia(world)
    assert np.max(np.abs(world - np.diag(np.diag(world)))) > 1e-3


def test_check_inertia_errors():
    B.check_inertia(B.cylinder_inertia(1.0, 0.1, 2.0))
    B.check_inertia(jnp.stack([jnp.eye(3), 2 * jnp.eye(3)]))
    B.check_inertia(jnp.array([0.1, 0.2]))
    B.check_inertia(B.rod_inertia(1.0, 1.0), semidefinite=True)
    B.check_inertia(jnp.zeros((3, 3)), semidefinite=True)  # a point mass
    with pytest.raises(lx.ParameterError, match=r"triangle inequality.*1 \+ 1 = 2 < I3 = 3"):
        B.check_inertia(jnp.diag(jnp.array([1.0, 1.0, 3.0])))
    with pytest.raises(lx.ParameterError, match="not symmetric.*0.5"):
        B.check_inertia(jnp.array([[1.0, 0.5, 0], [0, 1, 0], [0, 0, 1]]))
    with pytest.raises(lx.ParameterError, match=r"not positive-definite.*smallest -1"):
        B.check_inertia(jnp.diag(jnp.array([1.0, -1.0, 1.0])))
    with pytest.raises(lx.ParameterError, match="semidefinite=True"):
        B.check_inertia(B.rod_inertia(1.0, 1.0))
    with pytest.raises(lx.ParameterError, match=r"link\[1\]"):
        B.check_inertia(jnp.stack([jnp.eye(3), jnp.diag(jnp.array([1.0, 2, 4]))]), name="link")
    with pytest.raises(lx.ParameterError, match=r"\[1\] = -0.2"):
        B.check_inertia(jnp.array([0.1, -0.2]))
    with pytest.raises(lx.ShapeError):
        B.check_inertia(jnp.eye(2))
    with pytest.raises(Exception, match="not a physical inertia"):
        jax.jit(B.check_inertia)(jnp.diag(jnp.array([1.0, 1.0, 3.0]))).block_until_ready()
    np.testing.assert_allclose(jax.jit(B.check_inertia)(jnp.eye(3)), jnp.eye(3))


# ------------------------------------------------------------------------------ bodies
def _terms(system, q, qd, p):
    return (
        system.mass_matrix(q, p),
        system.coriolis(q, qd, p),
        system.gravity(q, p),
        system.forward_dynamics(q, qd, p),
        system.energy(q, qd, p),
    )


terms = jax.jit(_terms, static_argnums=0)


def test_point_mass_pendulum_equals_hand_written():
    """A spherical-coordinates pendulum in 3-D: θ from the downward vertical, ψ azimuth."""

    def bob(q, p):
        th, ps = q
        return p["l"] * jnp.stack(
            [jnp.sin(th) * jnp.cos(ps), jnp.sin(th) * jnp.sin(ps), -jnp.cos(th)]
        )

    def kinetic(q, qd, p):
        return 0.5 * p["m"] * p["l"] ** 2 * (qd[0] ** 2 + jnp.sin(q[0]) ** 2 * qd[1] ** 2)

    def potential(q, p):
        return -p["m"] * p["g"] * p["l"] * jnp.cos(q[0])

    scene = B.Scene([B.PointMass(Param("m"), bob)], gravity=Param("g"), n_dof=2)
    by_hand = lx.LagrangianSystem(kinetic, potential, n_dof=2)
    p = {"m": 1.3, "l": 0.7, "g": 9.81}
    rng = np.random.default_rng(1)
    for _ in range(3):
        q, qd = rng.uniform(0.2, 2.5, 2), rng.uniform(-2, 2, 2)
        for got, want in zip(
            terms(scene.system(), q, qd, p), terms(by_hand, q, qd, p), strict=True
        ):
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_planar_body_physical_pendulum_closed_form():
    """A rod pivoting about one end: ``θ̈ = −m g r sin θ / (I_c + m r²)``."""
    rod = B.PlanarBody(
        mass=Param("m"),
        inertia=lambda p: p["m"] * p["l"] ** 2 / 12,
        position=lambda q, p: 0.5 * p["l"] * jnp.stack([jnp.sin(q[0]), -jnp.cos(q[0])]),
        angle=lambda q, p: q[0],
    )
    system = B.Scene([rod], gravity=Param("g"), n_dof=1).system()
    p = {"m": 2.0, "l": 1.2, "g": 9.81}
    q, qd = jnp.array([0.9]), jnp.array([0.4])
    mass, _, _, qdd, energy = terms(system, q, qd, p)
    i_pivot = p["m"] * p["l"] ** 2 / 3
    np.testing.assert_allclose(mass, [[i_pivot]], rtol=1e-14)
    np.testing.assert_allclose(qdd, [-p["m"] * 9.81 * 0.6 * np.sin(0.9) / i_pivot], rtol=1e-13)
    np.testing.assert_allclose(
        energy, 0.5 * i_pivot * 0.16 - p["m"] * 9.81 * 0.6 * np.cos(0.9), rtol=1e-13
    )


def _rot_zyx(q):
    """``R = Rz(ψ) Ry(θ) Rx(φ)`` for ``q = (ψ, θ, φ)`` (yaw, pitch, roll)."""
    ps, th, ph = q[0], q[1], q[2]
    cz, sz, cy, sy, cx, sx = (f(a) for a in (ps, th, ph) for f in (jnp.cos, jnp.sin))
    rz = jnp.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1.0]])
    ry = jnp.array([[cy, 0, sy], [0, 1.0, 0], [-sy, 0, cy]])
    rx = jnp.array([[1.0, 0, 0], [0, cx, -sx], [0, sx, cx]])
    return rz @ ry @ rx


def _rot_z(a):
    c, s = jnp.cos(a), jnp.sin(a)
    return jnp.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _rot_x(a):
    c, s = jnp.cos(a), jnp.sin(a)
    return jnp.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def test_spatial_body_angular_velocity_from_rotation_jvp():
    """``T`` of a spinning, translating body against ``½ m v² + ½ ωᵀ I ω`` with the body
    rates of ZYX Euler angles written out: ``p = φ̇ − ψ̇ sθ``, ``q = θ̇ cφ + ψ̇ cθ sφ``,
    ``r = −θ̇ sφ + ψ̇ cθ cφ``."""
    rng = np.random.default_rng(2)
    rot = random_rotation(rng)
    inertia = rot @ np.diag([0.3, 0.5, 0.7]) @ rot.T
    body = B.SpatialBody(
        mass=2.5,
        inertia=inertia,
        position=lambda q, p: jnp.stack([q[3], q[4] * jnp.cos(q[0]), q[4] * jnp.sin(q[0])]),
        rotation=lambda q, p: _rot_zyx(q),
    )
    q, qd = rng.uniform(-1, 1, 5), rng.uniform(-2, 2, 5)
    kinetic = jax.jit(lambda a, b: body.kinetic_energy(a, b, {}))(q, qd)
    ps, th, ph = q[:3]
    dps, dth, dph = qd[:3]
    omega = np.array(
        [
            dph - dps * np.sin(th),
            dth * np.cos(ph) + dps * np.cos(th) * np.sin(ph),
            -dth * np.sin(ph) + dps * np.cos(th) * np.cos(ph),
        ]
    )
    v = np.array(
        [
            qd[3],
            qd[4] * np.cos(ps) - q[4] * np.sin(ps) * dps,
            qd[4] * np.sin(ps) + q[4] * np.cos(ps) * dps,
        ]
    )
    np.testing.assert_allclose(
        kinetic, 0.5 * 2.5 * v @ v + 0.5 * omega @ inertia @ omega, rtol=1e-13
    )
    # default gravity along −z: V = m g z_c
    np.testing.assert_allclose(
        body.potential_energy(q, {}, 9.81), 2.5 * 9.81 * q[4] * np.sin(ps), rtol=1e-14
    )


def test_batched_bodies_list_array_and_separate_agree():
    """``k`` bodies in one: a list of poses, a stacked array, and ``k`` separate bodies."""
    rng = np.random.default_rng(4)
    masses, inertias = jnp.array([1.0, 2.0, 0.5]), jnp.array([0.1, 0.3, 0.2])
    spatial_inertia = jnp.stack([jnp.diag(jnp.array([0.2, 0.3, 0.4])) * (i + 1) for i in range(3)])

    def planar_pose(q, p):  # three links of a chain-like mechanism
        angles = [q[0], q[0] + q[1], q[1] - 0.5 * q[0]]
        points = [
            jnp.stack([jnp.cos(a) + 0.3 * i, jnp.sin(a) * q[1]]) for i, a in enumerate(angles)
        ]
        return points, angles

    def spatial_pose(q, p):
        points, angles = planar_pose(q, p)
        rots = [_rot_z(a) @ _rot_x(0.5 * q[1]) for a in angles]
        return [jnp.stack([x[0], x[1], q[0] * x[1]]) for x in points], rots

    def stacked(pose):
        return lambda q, p: tuple(jnp.stack(v) for v in pose(q, p))

    def single(pose, i):
        return lambda q, p: tuple(v[i] for v in pose(q, p))

    scenes = {
        "planar": [
            [B.PlanarBody(masses, inertias, planar_pose, None)],
            [B.PlanarBody(masses, inertias, stacked(planar_pose), None)],
            [B.PlanarBody(masses[i], inertias[i], single(planar_pose, i), None) for i in range(3)],
        ],
        "spatial": [
            [B.SpatialBody(masses, spatial_inertia, spatial_pose, None)],
            [B.SpatialBody(masses, spatial_inertia, stacked(spatial_pose), None)],
            [
                B.SpatialBody(masses[i], spatial_inertia[i], single(spatial_pose, i), None)
                for i in range(3)
            ],
        ],
        "points": [
            [B.PointMass(masses, lambda q, p: planar_pose(q, p)[0])],
            [B.PointMass(masses, lambda q, p: jnp.stack(planar_pose(q, p)[0]))],
            [B.PointMass(masses[i], lambda q, p, i=i: planar_pose(q, p)[0][i]) for i in range(3)],
        ],
    }
    q = rng.uniform(-1, 1, 2)

    def mcv(bodies):  # T is quadratic in q̇: M(q) determines it
        system = B.Scene(bodies, n_dof=2).system()
        fn = jax.jit(lambda q: (system.mass_matrix(q, {}), system.potential_energy(q, {})))
        return fn(q)

    for kind, variants in scenes.items():
        results = [mcv(bodies) for bodies in variants]
        for res in results[1:]:
            for got, want in zip(res, results[0], strict=True):
                np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12, err_msg=kind)
    assert B.Scene(scenes["spatial"][0]).system().scalar_derivatives is False
    assert B.Scene(scenes["planar"][0]).system().scalar_derivatives is None


# ---------------------------------------------------------------- springs and dampers
def test_mass_spring_damper_closed_form():
    """A 1-D mass on a spring and damper to the origin: same equations as the hand-written
    ``models.mass_spring_damper``; simulated, ``x(t) = e^{−ζω t}(x0 cos ω_d t + …)``."""
    point = B.PointMass(Param("m"), lambda q, p: q)
    scene = B.Scene(
        [point],
        springs=[B.LinearSpring(Param("k"), lambda q, p: q)],
        dampers=[B.LinearDamper(Param("c"), lambda q, p: q, jnp.zeros(1))],
        gravity=None,
        n_dof=1,
    )
    system = scene.system()
    p = {"m": 2.0, "k": 50.0, "c": 1.5}
    reference, ref_p = lx.models.mass_spring_damper(m=2.0, k=50.0, c=1.5)
    for x, v in [(0.3, -1.0), (-1.2, 2.0)]:
        q, qd = jnp.array([x]), jnp.array([v])
        np.testing.assert_allclose(
            system.forward_dynamics(q, qd, p), [-(50.0 * x + 1.5 * v) / 2.0], rtol=1e-14
        )
        np.testing.assert_allclose(
            system.forward_dynamics(q, qd, p), reference.forward_dynamics(q, qd, ref_p)
        )
    w0 = np.sqrt(p["k"] / p["m"])
    zeta = p["c"] / (2 * np.sqrt(p["k"] * p["m"]))
    wd = w0 * np.sqrt(1 - zeta**2)
    ts = np.linspace(0.0, 3.0, 31)
    x0, v0 = 0.4, 0.0
    exact = np.exp(-zeta * w0 * ts) * (
        x0 * np.cos(wd * ts) + (v0 + zeta * w0 * x0) / wd * np.sin(wd * ts)
    )
    sol = lx.simulate(system, jnp.array([x0]), jnp.array([v0]), p, t1=3.0, ts=ts)
    np.testing.assert_allclose(sol.q[:, 0], exact, rtol=0, atol=1e-6)


def test_spring_and_damper_forces_closed_form():
    """A free point in the plane (q = its coordinates) tied to an anchor ``c``:
    spring force ``−k (L − L0) d̂``, axial dashpot ``−c L̇ d̂``, drag ``−c_v v``."""
    anchor = jnp.array([0.2, -0.1])
    p = {"k": 30.0, "L0": 0.5, "c": 4.0, "cv": 0.7}
    point = B.PointMass(1.0, lambda q, p: q)
    system = B.Scene(
        [point],
        springs=[B.LinearSpring(Param("k"), lambda q, p: q, anchor, rest_length=Param("L0"))],
        dampers=[
            B.LinearDamper(Param("c"), lambda q, p: q, anchor, axial=True),
            B.LinearDamper(Param("cv"), lambda q, p: q),
        ],
        gravity=None,
        n_dof=2,
    ).system()
    q, qd = np.array([1.1, 0.7]), np.array([0.3, -0.8])
    d = q - np.asarray(anchor)
    length = np.linalg.norm(d)
    unit = d / length
    np.testing.assert_allclose(system.gravity(q, p), 30.0 * (length - 0.5) * unit, rtol=1e-13)
    length_rate = unit @ qd
    np.testing.assert_allclose(
        system.damping(q, qd, p), 4.0 * length_rate * unit + 0.7 * qd, rtol=1e-13
    )


def test_torsional_spring_and_damper():
    """On a coordinate and on a relative angle ``q1 − q0``."""
    p = {"k": 3.0, "c": 0.4}
    system = B.Scene(
        kinetic=lambda q, qd, p: 0.5 * jnp.sum(qd**2),
        springs=[
            B.TorsionalSpring(Param("k"), 0, rest_angle=0.2),
            B.TorsionalSpring(5.0, lambda q, p: q[1] - q[0]),
        ],
        dampers=[B.TorsionalDamper(Param("c"), lambda q, p: q[1] - q[0])],
        n_dof=2,
    ).system()
    q, qd = np.array([0.5, -0.3]), np.array([1.0, 2.5])
    rel, rel_rate = q[1] - q[0], qd[1] - qd[0]
    np.testing.assert_allclose(
        system.gravity(q, p), [3.0 * (0.5 - 0.2) - 5.0 * rel, 5.0 * rel], rtol=1e-14
    )
    np.testing.assert_allclose(system.damping(q, qd, p), [-0.4 * rel_rate, 0.4 * rel_rate])


def test_energy_balance_with_dampers():
    """``dE/dt = −q̇·∂D/∂q̇ = −2 D`` for quadratic ``D``, at random states of a scene with
    bodies, gravity, springs and dampers (``dE/dt`` by a JVP of ``E`` along ``(q̇, q̈)``)."""

    def bob1(q, p):
        return jnp.stack([jnp.sin(q[0]), -jnp.cos(q[0])])

    def bob2(q, p):
        return bob1(q, p) + q[2] * jnp.stack([jnp.sin(q[1]), -jnp.cos(q[1])])

    rod = B.PlanarBody(1.0, 0.1, lambda q, p: 0.5 * bob1(q, p), lambda q, p: q[0])
    scene = B.Scene(
        [rod, B.PointMass(Param("m"), bob2)],
        springs=[B.LinearSpring(20.0, bob2, bob1, rest_length=0.8)],
        dampers=[
            B.LinearDamper(Param("c"), bob2, bob1, axial=True),
            B.TorsionalDamper(0.3, 0),
        ],
        gravity=Param("g"),
        n_dof=3,
    )
    system = scene.system()
    p = {"m": 0.7, "c": 1.1, "g": 9.81}

    @jax.jit
    def balance(q, qd):
        qdd = system.forward_dynamics(q, qd, p)
        e_dot = jax.jvp(lambda a, b: system.energy(a, b, p), (q, qd), (qd, qdd))[1]
        return e_dot, scene.dissipation_function(q, qd, p)

    rng = np.random.default_rng(5)
    for _ in range(3):
        q = np.array([*rng.uniform(-1, 1, 2), rng.uniform(0.5, 1.5)])
        e_dot, diss = balance(q, rng.uniform(-2, 2, 3))
        assert diss > 0
        np.testing.assert_allclose(e_dot, -2 * diss, rtol=1e-11)


# --------------------------------------------------------------- scene API and errors
def test_gravity_options_and_float32():
    point = B.PointMass(2.0, lambda q, p: q)
    q, qd = jnp.zeros(3), jnp.zeros(3)
    np.testing.assert_allclose(
        B.Scene([point], n_dof=3).system().forward_dynamics(q, qd, {}), [0, 0, -9.81]
    )
    tilted = B.Scene([point], gravity=jnp.array([1.0, 0.0, -2.0]), n_dof=3).system()
    np.testing.assert_allclose(tilted.forward_dynamics(q, qd, {}), [1.0, 0, -2.0])
    free = B.Scene([point], gravity=None, n_dof=3).system()
    assert free.potential is None and free.dissipation is None
    with pytest.raises(lx.ShapeError, match="gravity vector"):
        B.Scene([point], gravity=jnp.ones(2)).system().gravity(q, {})
    # float32 in, float32 out (constants stay weakly typed)
    q32 = jnp.array([0.1, 0.2, 0.3], jnp.float32)
    out = (
        B.Scene([point], gravity=Param("g"))
        .system()
        .forward_dynamics(q32, q32, {"g": jnp.float32(9.81)})
    )
    assert out.dtype == jnp.float32


def test_scene_errors():
    with pytest.raises(TypeError, match=r"Scene.springs\[0\] is a TorsionalDamper"):
        B.Scene([B.PointMass(1.0, lambda q, p: q)], springs=[B.TorsionalDamper(1.0, 0)])
    with pytest.raises(ValueError, match="at least one body"):
        B.Scene()
    bad = B.PlanarBody(1.0, 1.0, lambda q, p: jnp.stack([q[0], q[0], q[0]]), lambda q, p: q[0])
    with pytest.raises(lx.ShapeError, match=r"PlanarBody: position must give shape \(2,\)"):
        B.Scene([bad], n_dof=1).system().mass_matrix(jnp.zeros(1), {})
    pendulum = B.Scene([B.PointMass(Param("m"), lambda q, p: q)], n_dof=1).system()
    with pytest.raises(lx.ParameterError, match="'m'"):
        pendulum.mass_matrix(jnp.zeros(1), {"M": 1.0})
    # Param on a NamedTuple / object reads attributes
    from collections import namedtuple

    P = namedtuple("P", "m")
    np.testing.assert_allclose(pendulum.mass_matrix(jnp.zeros(1), P(m=2.0)), [[2.0]])
    assert Param("m") == Param("m")
