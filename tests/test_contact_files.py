"""Contact from model files: `from_urdf(..., contact=)` and `from_mjcf(..., contact=)`.

The spheres each loader reads sit where Pinocchio (its collision geometry placements,
`updateGeometryPlacements`) and MuJoCo (`geom_xpos`, `geom_xmat`) put the shapes they
stand for, at random configurations; the friction read from an MJCF file is the one
MuJoCo's own contacts carry (`mjData.contact.friction`).
"""

import glob
import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax.contact import ContactSystem

pin = pytest.importorskip("pinocchio", reason="Pinocchio places the URDF collision shapes")
mujoco = pytest.importorskip("mujoco", reason="MuJoCo places the MJCF geoms")
trimesh = pytest.importorskip("trimesh", reason="trimesh reads the URDF meshes")

HERE = Path(__file__).resolve().parent


def solo12() -> str:
    """solo12's URDF from example-robot-data (its cmeel prefix)."""
    pattern = "lib/python*/site-packages/cmeel.prefix/share/example-robot-data/robots"
    found = glob.glob(f"{sys.prefix}/{pattern}/solo_description/robots/solo12.urdf")
    if not found:
        pytest.skip("example-robot-data is not installed (pip install example-robot-data)")
    return found[0]


def _random_q(model, rng):
    """A random Pinocchio configuration of a free-flyer model (unit quaternion)."""
    quat = rng.normal(size=4)
    joints = rng.uniform(-1.5, 1.5, model.nq - 7)
    return np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat), joints])


# --------------------------------------------------------------------------- URDF
def test_solo12_collision_meshes_are_bounding_spheres_where_pinocchio_places_them():
    path = solo12()
    scene, params = lx.chains.from_urdf(path, floating_base=True, contact=True)
    assert isinstance(scene, ContactSystem)
    assert scene.plane.normal == (0.0, 0.0, 1.0) and scene.plane.offset == 0.0
    model = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer())
    share = path.split(os.sep + "example-robot-data" + os.sep)[0]
    geometry = pin.buildGeomFromUrdf(model, path, pin.GeometryType.COLLISION, package_dirs=[share])
    objects = geometry.geometryObjects
    assert len(scene.spheres) == len(objects) == 17  # one mesh per link
    # each mesh's smallest bounding sphere, in the mesh's frame (trimesh reads the file)
    local = []
    for g in objects:
        vertices = np.asarray(trimesh.load(g.meshPath, force="mesh").vertices) * g.meshScale
        local.append(trimesh.nsphere.minimum_nsphere(vertices))
    data, placed = model.createData(), pin.GeometryData(geometry)
    centres = jax.jit(scene.centres)
    rng = np.random.default_rng(1)
    for _ in range(2):
        q = _random_q(model, rng)
        pin.updateGeometryPlacements(model, data, geometry, placed, q)
        found = centres(q, params)
        for i, (where, (centre, radius)) in enumerate(zip(placed.oMg, local, strict=True)):
            expected = where.translation + where.rotation @ centre
            np.testing.assert_allclose(found[i], expected, atol=1e-12)
            assert abs(scene.spheres[i].radius - radius) < 1e-12
    # friction: Bullet's <contact><lateral_friction> where a link has one, else 1
    links = ET.parse(path).getroot().findall("link")
    bullet = [
        float(link.find("contact/lateral_friction").get("value"))
        if link.find("contact/lateral_friction") is not None
        else 1.0
        for link in links
        if link.find("collision") is not None
    ]
    np.testing.assert_array_equal(params["contact_friction"], bullet)


_SHAPES = """<robot name="shapes">
  <link name="base"><inertial><mass value="2.0"/>
    <inertia ixx="0.02" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0.1 0.0 -0.05" rpy="0.3 0.1 -0.2"/>
      <geometry><box size="0.2 0.1 0.06"/></geometry></collision></link>
  <link name="arm"><inertial><origin xyz="0 0 -0.1"/><mass value="0.3"/>
    <inertia ixx="0.001" iyy="0.001" izz="0.0002" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 -0.1" rpy="0 0.4 0"/>
      <geometry><cylinder radius="0.03" length="0.2"/></geometry></collision></link>
  <link name="hand"><collision><origin xyz="0.01 0 0.02"/>
      <geometry><sphere radius="0.025"/></geometry></collision>
    <contact><lateral_friction value="0.6"/></contact></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="0.1 0.05 0" rpy="0.2 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/></joint>
  <joint name="wrist" type="fixed"><parent link="arm"/><child link="hand"/>
    <origin xyz="0.01 0 -0.2"/></joint>
</robot>"""


def test_urdf_boxes_cylinders_and_spheres_become_their_sphere_sets():
    """A box is its 8 corners, a cylinder 8 points on each rim, a sphere itself (on a
    link merged into its parent by a fixed joint), each where Pinocchio places the
    shape."""
    scene, params = lx.chains.from_urdf(_SHAPES, floating_base=True, contact=True)
    assert len(scene.spheres) == 8 + 16 + 1
    model = pin.buildModelFromXML(_SHAPES, pin.JointModelFreeFlyer())
    geometry = pin.buildGeomFromUrdfString(model, _SHAPES, pin.GeometryType.COLLISION)
    data, placed = model.createData(), pin.GeometryData(geometry)
    signs = np.array([(i, j, k) for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
    angles = 2 * np.pi * np.arange(8) / 8
    rim = np.stack([0.03 * np.cos(angles), 0.03 * np.sin(angles)], axis=1)
    local = [
        signs * np.array([0.1, 0.05, 0.03]),  # the box's corners
        np.concatenate([np.column_stack([rim, np.full(8, z)]) for z in (-0.1, 0.1)]),
        np.zeros((1, 3)),  # the sphere's centre
    ]
    q = _random_q(model, np.random.default_rng(2))
    pin.updateGeometryPlacements(model, data, geometry, placed, q)
    expected = np.concatenate(
        [w.translation + pts @ w.rotation.T for w, pts in zip(placed.oMg, local, strict=True)]
    )
    found = jax.jit(scene.centres)(q, params)
    np.testing.assert_allclose(found, expected, atol=1e-12)
    assert [s.radius for s in scene.spheres] == [0.0] * 24 + [0.025]
    np.testing.assert_array_equal(params["contact_friction"], [1.0] * 24 + [0.6])
    # only the named links, one friction for all
    hand, params = lx.chains.from_urdf(_SHAPES, floating_base=True, contact=["hand"], friction=0.3)
    np.testing.assert_allclose(hand.spheres[0].position(q, params), expected[-1], atol=1e-12)
    assert len(hand.spheres) == 1 and float(params["contact_friction"][0]) == 0.3


def test_bad_contact_options_are_refused_naming_the_value():
    with pytest.raises(lx.ConfigurationError, match="'toe'"):
        lx.chains.from_urdf(_SHAPES, floating_base=True, contact=["toe"])
    with pytest.raises(lx.ConfigurationError, match="meshes='hull'"):
        lx.chains.from_urdf(_SHAPES, floating_base=True, contact=True, meshes="hull")
    with pytest.raises(lx.ConfigurationError, match="friction=-0.5"):
        lx.chains.from_urdf(_SHAPES, floating_base=True, contact=True, friction=-0.5)
    missing = _SHAPES.replace('<sphere radius="0.025"/>', '<mesh filename="package://x/y.stl"/>')
    with pytest.raises(lx.URDFError, match="link 'hand'.*y.stl"):
        lx.chains.from_urdf(missing, floating_base=True, contact=True)
    # without contact= the geometry is not read: a missing mesh is no error
    lx.chains.from_urdf(missing, floating_base=True)


# --------------------------------------------------------------------------- MJCF
def _geom_spheres(model, data, g):
    """A geom's sphere set in the world, from MuJoCo's placement of the geom."""
    pos, rot, size = data.geom_xpos[g], data.geom_xmat[g].reshape(3, 3), model.geom_size[g]
    kind = int(model.geom_type[g])
    if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
        return pos[None], size[0]
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return np.stack([pos - rot[:, 2] * size[1], pos + rot[:, 2] * size[1]]), size[0]
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        signs = np.array([(i, j, k) for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        return pos + (signs * size) @ rot.T, 0.0
    raise AssertionError(kind)


def _colliding(model):
    """The colliding geoms on moving bodies (not welded to the world), in order."""
    moving = [
        g
        for g in range(model.ngeom)
        if (model.geom_contype[g] or model.geom_conaffinity[g])
        and model.body_weldid[model.geom_bodyid[g]] != 0
    ]
    return moving


def test_mjcf_geoms_of_a_floating_robot_sit_where_mujoco_places_them():
    path = HERE / "mjcf" / "floating.xml"
    scene, params = lx.chains.from_mjcf(str(path), contact=True)
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    data.qpos[:] = model.qpos0 + rng.uniform(-0.5, 0.5, model.nq)
    data.qpos[3:7] /= np.linalg.norm(data.qpos[3:7])
    mujoco.mj_kinematics(model, data)
    expected, radii = [], []
    for g in _colliding(model):  # the floor box is welded to the world: not a sphere
        centres, radius = _geom_spheres(model, data, g)
        expected.append(centres)
        radii += [radius] * len(centres)
    q, _ = lx.chains.from_mujoco_state(data.qpos, np.zeros(model.nv))
    found = jax.jit(scene.centres)(q, params)
    np.testing.assert_allclose(found, np.concatenate(expected), atol=1e-12)
    np.testing.assert_allclose([s.radius for s in scene.spheres], radii, rtol=1e-15)


def test_mjcf_friction_is_the_one_mujocos_contacts_carry():
    """The cheetah (dm_control) on its floor: each geom's sphere set carries the
    friction of MuJoCo's contact between that geom and the floor (the larger of the
    two geoms'), and the ground is the floor plane."""
    dm_control = pytest.importorskip("dm_control", reason="dm_control ships cheetah.xml")
    path = os.path.join(os.path.dirname(dm_control.__file__), "suite", "cheetah.xml")
    scene, params = lx.chains.from_mjcf(path, contact=True)
    model = mujoco.MjModel.from_xml_path(path)
    data = mujoco.MjData(model)
    assert scene.plane.normal == (0.0, 0.0, 1.0) and scene.plane.offset == 0.0
    geoms = _colliding(model)
    owner = np.repeat(geoms, [2] * len(geoms))  # a capsule each: two end spheres
    assert len(scene.spheres) == len(owner)
    # sink the cheetah into its floor, so that MuJoCo makes a contact for every geom
    data.qpos[:] = 0.0
    data.qpos[1] = -1.0  # rootz
    mujoco.mj_forward(model, data)
    seen = {}
    for c in data.contact[: data.ncon]:
        if model.geom_bodyid[c.geom1] == 0:  # the floor and a geom of the cheetah
            seen[int(c.geom2)] = float(c.friction[0])
    assert set(seen) == set(geoms)
    np.testing.assert_array_equal(params["contact_friction"], [seen[int(g)] for g in owner])
    # the geoms' own friction is smaller than the floor's here: the larger one wins
    assert np.all(model.geom_friction[geoms, 0] < params["contact_friction"][::2])
    # and the sphere set sits where MuJoCo puts the geom
    data.qpos[:] = np.random.default_rng(4).uniform(-0.5, 0.5, model.nq)
    mujoco.mj_kinematics(model, data)
    expected = np.concatenate([_geom_spheres(model, data, g)[0] for g in geoms])
    found = jax.jit(scene.centres)(jnp.asarray(data.qpos), params)
    np.testing.assert_allclose(found, expected, atol=1e-12)


def test_a_mesh_is_its_bounding_sphere_or_its_hull_vertices(tmp_path):
    """A box written as a mesh file (found relative to the URDF, scaled): its bounding
    sphere is centred on the box with its half-diagonal as radius; its convex hull's
    vertices are its 8 corners, where the same box as a `<box>` puts them."""
    half = np.array([0.1, 0.05, 0.03])
    trimesh.creation.box(extents=[2.0, 2.0, 2.0]).export(tmp_path / "block.stl")
    mesh = f'<mesh filename="block.stl" scale="{half[0]} {half[1]} {half[2]}"/>'
    (tmp_path / "robot.urdf").write_text(_SHAPES.replace('<box size="0.2 0.1 0.06"/>', mesh))
    kw = dict(floating_base=True, contact=["base"])
    sphere, params = lx.chains.from_urdf(str(tmp_path / "robot.urdf"), **kw)
    hull, _ = lx.chains.from_urdf(str(tmp_path / "robot.urdf"), meshes="vertices", **kw)
    box, _ = lx.chains.from_urdf(_SHAPES, **kw)  # the same box as a <box>
    model = pin.buildModelFromXML(_SHAPES, pin.JointModelFreeFlyer())
    q = _random_q(model, np.random.default_rng(5))
    corners = np.asarray(jax.jit(box.centres)(q, params))
    found = np.asarray(jax.jit(hull.centres)(q, params))
    assert len(hull.spheres) == 8 and all(s.radius == 0.0 for s in hull.spheres)
    order = lambda x: x[np.lexsort(np.round(x, 9).T)]  # noqa: E731
    np.testing.assert_allclose(order(found), order(corners), atol=1e-12)
    assert len(sphere.spheres) == 1
    assert abs(sphere.spheres[0].radius - np.linalg.norm(half)) < 1e-12
    centre = np.asarray(jax.jit(sphere.centres)(q, params))[0]
    np.testing.assert_allclose(centre, corners.mean(axis=0), atol=1e-12)
