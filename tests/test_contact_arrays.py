"""Contact as arrays: the spheres of one tree, placed by one pass of its kinematics, against
the same spheres taken one at a time.

`ContactSystem` places the spheres that share a source (`body_sphere`'s: their tree) as one
batch, takes their velocities by one JVP and `Q = Σ Jᵢᵀ Fᵢ` by one VJP. The oracle here is
the sphere-by-sphere computation from each `Sphere`'s own `position` and `rotation`
functions: each contact point's velocity Jacobian `Jᵢ` (`jax.jacfwd` of that sphere's
contact-point velocity alone) and the sum of `Jᵢᵀ Fᵢ` over the spheres.
"""

import glob
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax.contact import ContactSystem, Plane, Sphere, body_sphere


def _one_by_one(scene, q, v, params):
    """Centres `(S, 3)`, rotations of the turning spheres, and the contact points'
    velocities `(S, 3)` and Jacobians `(S, 3, n)`, each sphere on its own."""
    normal = jnp.asarray(scene.plane.normal)
    rate = scene.system.configuration_rate

    def point_velocity(s, b):
        c_dot = jax.jvp(lambda a: jnp.asarray(s.position(a, params)), (q,), (rate(q, b),))[1]
        if s.rotation is None or s.radius == 0:
            return c_dot
        rot, rot_dot = jax.jvp(lambda a: jnp.asarray(s.rotation(a, params)), (q,), (rate(q, b),))
        x = rot_dot @ rot.T
        w = 0.5 * jnp.stack([x[2, 1] - x[1, 2], x[0, 2] - x[2, 0], x[1, 0] - x[0, 1]])
        return c_dot + jnp.cross(w, -s.radius * normal)

    centres = jnp.stack([jnp.asarray(s.position(q, params)) for s in scene.spheres])
    velocities = jnp.stack([point_velocity(s, v) for s in scene.spheres])
    jacobians = jnp.stack(
        [jax.jacfwd(lambda b, s=s: point_velocity(s, b))(v) for s in scene.spheres]
    )
    return centres, velocities, jacobians


def _check(scene, q, v, params):
    state = scene.contact_state(q, v, params)
    centres, velocities, jacobians = _one_by_one(scene, q, v, params)
    assert bool(jnp.any(state["normal_force"] > 0)), "no sphere touches: nothing is checked"
    np.testing.assert_allclose(scene.centres(q, params), centres, rtol=0, atol=1e-13)
    np.testing.assert_allclose(state["velocity"], velocities, rtol=0, atol=1e-12)
    expected = jnp.einsum("kdn,kd->n", jacobians, state["force"])
    scale = float(jnp.max(jnp.abs(expected)))
    np.testing.assert_allclose(state["generalized"], expected, rtol=0, atol=1e-12 * scale)


def _solo12() -> str:
    pattern = "lib/python*/site-packages/cmeel.prefix/share/example-robot-data/robots"
    found = glob.glob(f"{sys.prefix}/{pattern}/solo_description/robots/solo12.urdf")
    if not found:
        pytest.fail("example-robot-data's solo12 is missing: pip install -e '.[dev]'")
    return found[0]


def _sink(scene, q, params, depth):
    """`q` with the base lowered until the lowest sphere is `depth` deep."""
    gap = float(jnp.min(scene.gaps(q, params)))
    return q.at[2].add(-(gap + depth))


def test_a_floating_robots_spheres_with_its_base_and_a_sphere_of_its_own():
    """solo12's 17 mesh spheres (one tree), a sphere on its base (body −1) and one
    written as plain functions (placed alone): the batch's centres, velocities and
    `Σ Jᵢᵀ Fᵢ` equal the sphere-by-sphere ones to round-off."""
    meshes, params = lx.chains.from_urdf(_solo12(), floating_base=True, contact=True)
    robot = meshes.system.robot
    base = body_sphere(robot, -1, 0.05, (0.1, -0.05, -0.02))
    alone = Sphere(0.03, lambda q, p: q[:3] + jnp.array([0.0, 0.0, -0.1]))
    spheres = (*meshes.spheres[:9], alone, base, *meshes.spheres[9:])
    scene = ContactSystem(meshes.system, spheres, meshes.plane, friction=0.8, stiffness=1e4,
                          dissipation=0.5, stiction_velocity=0.01)  # fmt: skip
    assert scene.groups == (tuple(i for i in range(len(spheres)) if i != 9),)
    rng = np.random.default_rng(3)
    quat = rng.normal(size=4)
    quat = 0.3 * quat / np.linalg.norm(quat) + np.array([0.0, 0.0, 0.0, 1.0])
    joints = rng.uniform(-1.0, 1.0, 12)
    q = jnp.asarray(np.concatenate([[0.1, -0.2, 0.5], quat / np.linalg.norm(quat), joints]))
    v = jnp.asarray(rng.normal(size=18))
    _check(scene, _sink(scene, q, params, 0.02), v, params)


def test_a_fixed_trees_spheres_in_any_order():
    """arm7 (fixed base) with spheres on its links out of body order, two on one link:
    the batch equals the spheres one by one."""
    tree, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"))
    names = tree.body_names
    spheres = [
        body_sphere(tree, names[5], 0.04, (0.0, 0.02, 0.1)),
        body_sphere(tree, names[2], 0.05),
        body_sphere(tree, names[6], 0.03, (0.05, 0.0, 0.0)),
        body_sphere(tree, names[5], 0.02, (0.0, -0.03, 0.0)),
    ]
    rng = np.random.default_rng(4)
    q = jnp.asarray(rng.uniform(-1.2, 1.2, tree.n_configuration))
    v = jnp.asarray(rng.normal(size=tree.n_configuration))
    probe = ContactSystem(tree.system(), spheres, Plane([0.0, 0.0, 1.0]), stiffness=1e4,
                          dissipation=0.5)  # fmt: skip
    offset = float(jnp.median(probe.centres(q, params)[:, 2]))
    scene = ContactSystem(tree.system(), spheres, Plane([0.0, 0.0, 1.0], offset), friction=0.5,
                          stiffness=1e4, dissipation=0.5, stiction_velocity=0.01)  # fmt: skip
    _check(scene, q, v, params)
