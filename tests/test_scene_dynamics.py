"""Scenes' equations from their bodies' pose maps against the definition.

``Scene(equations="poses")`` forms ``M = Σ m J_vᵀJ_v + J_ωᵀ I J_ω`` and ``C q̇`` from
Newton's and Euler's equations of each body, projected on the coordinates. They must
equal the autodiff Euler–Lagrange equations of the same energies (``"energies"``) and,
for chains of bodies, the independent Newton–Euler oracle ``lagrax.newton_euler.rnea``;
for every way a body can give its pose (one item, a list of ``k``, an array of ``k``),
in the plane and in space, with springs, dampers and applied forces.
"""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import lagrax as lx
from _helpers import check_grad_against_central_difference, close
from lagrax._multibody.energies.scene_equations import SceneEquations
from lagrax._systems.derivatives import mass_and_force
from lagrax.bodies import (
    LinearDamper,
    Param,
    PlanarBody,
    PointMass,
    Scene,
    SpatialBody,
    TorsionalSpring,
)
from lagrax.chains import PlanarChain, SpatialChain
from lagrax.newton_euler import rnea


def _rodrigues(w):
    """``exp(ŵ)`` by Rodrigues' formula (a smooth rotation of three coordinates)."""
    th2 = jnp.sum(w**2)
    th = jnp.sqrt(th2)
    k = jnp.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    return jnp.eye(3) + jnp.sin(th) / th * k + (1 - jnp.cos(th)) / th2 * (k @ k)


def _quantities(system, params, q, qd, qdd):
    """``M`` and ``M q̈ + C q̇ + G`` (which determine all the rest), compiled once."""
    fn = jax.jit(
        lambda q, qd, qdd: (
            system.mass_matrix(q, params),
            system.inverse_dynamics(q, qd, qdd, params),
        )
    )
    return [jnp.stack(x) for x in zip(*map(fn, q, qd, qdd), strict=True)]


def _rotz(a):
    c, s = jnp.cos(a), jnp.sin(a)
    return jnp.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _check(scene, params, n, seed):
    """Pose-map equations == autodiff of the energies, at random states; the pose-map
    system's forward dynamics, ``mass_and_force`` and inverse dynamics agree."""
    poses = dataclasses.replace(scene, equations="poses").system()
    # forward-over-reverse autodiff: compiles faster than scalar derivatives
    energies = dataclasses.replace(scene, equations="energies", scalar_derivatives=False)
    energies = energies.system()
    assert isinstance(poses.equations, SceneEquations) and energies.equations is None
    rng = np.random.default_rng(seed)
    q, qd, qdd = (jnp.asarray(rng.normal(size=(2, n))) for _ in range(3))
    got = _quantities(poses, params, q, qd, qdd)
    for a, b in zip(got, _quantities(energies, params, q, qd, qdd), strict=True):
        close(a, b)
    for i, mass in enumerate(got[0]):
        close(mass, mass.T)
        assert np.linalg.eigvalsh(np.asarray(mass))[0] > 0
        tau = got[1][i]
        close(poses.forward_dynamics(q[i], qd[i], params, tau), qdd[i], rtol=1e-10)
        m_f, f = mass_and_force(poses, None, 0.0, q[i], qd[i], params, tau)
        close(m_f, mass)
        close(f, mass @ qdd[i])
    return poses


def _arm_positions(q, p):
    """Three point masses at the joints of a planar 3-link arm, as a ``(3, 2)`` array."""
    ang = jnp.cumsum(q)
    return jnp.stack([jnp.cumsum(jnp.sin(ang)), -jnp.cumsum(jnp.cos(ang))], axis=1) * p["l"]


def test_point_masses_as_array_and_single():
    scene = Scene(
        [
            PointMass(Param("m"), _arm_positions),  # (3,) masses, (3, 2) positions
            PointMass(2.0, lambda q, p: jnp.array([q[0], q[1] ** 2, jnp.sin(q[2])])),  # 3-D
            PointMass(0.5, lambda q, p: q[1:2] * q[0]),  # 1-D
        ],
        springs=[TorsionalSpring(3.0, 1)],
        dampers=[LinearDamper(0.4, lambda q, p: _arm_positions(q, p)[2], (0.0, 0.0))],
        gravity=jnp.array([0.0, -9.81]),
        n_dof=3,
    )
    with pytest.raises(Exception, match="gravity vector"):  # a 3-D body under 2-D gravity
        _check(scene, {"m": jnp.array([1.0, 2.0, 3.0]), "l": 0.7}, 3, 0)
    scene = dataclasses.replace(scene, gravity=9.81)
    _check(scene, {"m": jnp.array([1.0, 2.0, 3.0]), "l": 0.7}, 3, 0)


def test_planar_bodies_as_array_list_and_single():
    arr = PlanarBody(
        jnp.array([1.0, 2.0, 3.0]),
        jnp.array([0.1, 0.2, 0.3]),
        _arm_positions,
        lambda q, p: jnp.cumsum(q),
    )
    lst = PlanarBody(
        1.5,  # shared by the list's items
        jnp.array([0.05, 0.3]),
        lambda q, p: [jnp.array([q[0], q[1]]), jnp.array([q[1] * q[2], q[0]])],
        lambda q, p: [q[2], q[0] * q[1]],
    )
    one = PlanarBody(0.7, 0.02, lambda q, p: (jnp.array([jnp.cos(q[2]), q[0]]), q[1] + q[2]), None)
    _check(Scene([arr, lst, one], n_dof=3), {"l": 0.9}, 3, 1)


def test_spatial_bodies_as_array_and_single():
    d = np.array([[0.2, 0.3, 0.4], [0.5, 0.2, 0.6]])
    frame = Rotation.random(random_state=3).as_matrix()
    inertia = jnp.stack(
        [frame @ np.diag([di[1] + di[2], di[0] + di[2], di[0] + di[1]]) @ frame.T for di in d]
    )

    def rotations(q, p):
        r1 = _rodrigues(q[:3])
        return jnp.stack([r1, r1 @ _rotz(q[3])])

    def positions(q, p):
        return jnp.stack([0.3 * q[:3], rotations(q, p)[0] @ jnp.array([1.0, 0, 0]) + q[3]])

    pair = SpatialBody(jnp.array([1.0, 2.0]), inertia, positions, rotations)
    one = SpatialBody(
        1.5, inertia[0], lambda q, p: positions(q, p)[1], lambda q, p: rotations(q, p)[1]
    )
    _check(Scene([pair, one], n_dof=4), {}, 4, 2)


@pytest.mark.parametrize("types", ["RPR", "RRPRRR"])
def test_spatial_chain_of_bodies_equals_rnea(types):
    """A chain's scene (a list of spatial bodies) by its pose maps, against the
    Newton–Euler oracle (and the autodiff energies, whose compilation is slow, for the
    short chain)."""
    rng = np.random.default_rng(len(types))
    n = len(types)
    chain = SpatialChain(types, axes=[tuple(rng.normal(size=3)) for _ in range(n)])
    params = chain.params(m=rng.uniform(0.5, 2, n), com=rng.normal(size=(n, 3)) * 0.3)
    scene = chain.scene()
    system = scene.system()
    assert isinstance(system.equations, SceneEquations)  # spatial bodies: poses by default
    if n <= 3:
        _check(scene, params, n, 4)
    q, qd, tau = (jnp.asarray(rng.normal(size=n)) for _ in range(3))
    qdd = system.forward_dynamics(q, qd, params, tau)
    close(rnea(chain, q, qd, qdd, params), tau)


def test_planar_chain_of_bodies_equals_rnea():
    chain = PlanarChain(5)
    rng = np.random.default_rng(6)
    params = chain.params(m=rng.uniform(0.5, 2, 5), l=rng.uniform(0.3, 1.2, 5))
    system = _check(chain.scene(bodies="planar"), params, 5, 5)
    assert isinstance(chain.scene(bodies="planar").system().equations, SceneEquations)
    q, qd, tau = (jnp.asarray(rng.normal(size=5)) for _ in range(3))
    qdd = system.forward_dynamics(q, qd, params, tau)
    close(rnea(chain, q, qd, qdd, params), tau)


def test_choice_of_equations():
    bob = PointMass(1.0, lambda q, p: jnp.array([jnp.sin(q[0]), -jnp.cos(q[0])]))
    assert Scene([bob], n_dof=1).system().equations is None  # small planar: autodiff
    assert Scene([bob], n_dof=1, equations="poses").system().equations is not None
    four = Scene([bob], n_dof=4)
    assert isinstance(four.system().equations, SceneEquations)
    assert Scene([bob]).system().equations is None  # n unknown: autodiff
    extra = Scene([bob], n_dof=4, kinetic=lambda q, qd, p: 0.5 * qd[1] ** 2)
    assert extra.system().equations is None  # a hand-written T: autodiff
    with pytest.raises(ValueError, match="hand-written kinetic"):
        dataclasses.replace(extra, equations="poses").system()
    with pytest.raises(ValueError, match="equations must be one of"):
        Scene([bob], equations="fast")


def test_bad_rotation_shape_is_named():
    body = SpatialBody(1.0, jnp.eye(3), lambda q, p: q[:3], lambda q, p: jnp.eye(2))
    system = Scene([body], n_dof=3).system()
    with pytest.raises(lx.ShapeError, match="rotation"):
        system.forward_dynamics(jnp.zeros(3), jnp.zeros(3), {}, None)


def test_simulate_gradient_and_vmap_through_poses():
    """A spatial double pendulum of bodies (pose-map equations): gradients through a
    solve match finite differences, and vmap over parameters equals a loop."""
    chain = SpatialChain("RR", axes=[(0, 0, 1), (0, 1, 0)])
    system = chain.scene().system()
    assert isinstance(system.equations, SceneEquations)
    q0, qd0 = jnp.array([0.3, -0.4]), jnp.array([0.5, 0.0])

    def final_angle(m0):
        params = chain.params(m=jnp.stack([m0, 1.0]))
        sol = lx.simulate(system, q0, qd0, params, t1=0.5, rtol=1e-10, atol=1e-10)
        return sol.q_end[1]

    check_grad_against_central_difference(final_angle, 1.0)
    masses = jnp.array([0.5, 1.0, 2.0])
    batched = jax.vmap(final_angle)(masses)
    close(batched, jnp.stack([final_angle(m) for m in masses]), rtol=1e-12)
