"""lagrax.plot.show3d: the saved page plays offline in headless Chromium (the `viz` extra and
a chromium binary; skipped without them), and bad input is refused."""

import base64
import io
import shutil
import sys
from pathlib import Path
from types import SimpleNamespace

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import every_robot
from lagrax import ArgumentTypeError, ConfigurationError, ShapeError

pytest.importorskip("meshcat", reason="the 3D viewer needs the viz extra (meshcat)")


@pytest.fixture(scope="module")
def arm7():
    tree, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"))
    q0 = jnp.array([0.3, 0.8, 0.0, -1.0, 0.2, 0.5, 0.0])
    sol = lx.simulate(tree.system(), q0, jnp.zeros(7), params, t1=1.0)
    return tree, params, sol


@pytest.fixture(scope="module")
def planar():
    system, params = lx.models.planar_2r()
    sol = lx.simulate(system, jnp.array([0.0, 0.0]), jnp.zeros(2), params, t1=1.0)
    return params, sol


def test_tree_poses_are_the_trees_frames(arm7):
    tree, params, sol = arm7
    view = lx.plot.show3d(sol, tree, params=params, fps=20.0)
    p = view.poses
    assert p.times.size == 21 and p.origins.shape == (21, 8, 3)
    assert len(p.links) == 7 and p.links[0] == (0, 1)
    origins, rots = tree.frames(jnp.asarray(sol.q[-1]), params)
    np.testing.assert_allclose(p.origins[-1, 1:], origins, atol=1e-9)
    np.testing.assert_allclose(p.rotations[-1, 1:], rots, atol=1e-9)


def test_floating_tree_poses_follow_the_base():
    robot, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"), floating_base=True)
    n = robot.n
    angle = 0.7
    q = np.zeros((2, 7 + n))
    q[:, :3] = [1.0, 2.0, 3.0]
    q[:, 3:7] = [np.sin(angle / 2), 0.0, 0.0, np.cos(angle / 2)]  # a turn about x
    sol = SimpleNamespace(ts=np.array([0.0, 1.0]), q=q)  # the two fields show3d reads
    p = lx.plot.show3d(sol, robot, params=params, fps=1.0).poses
    origins = np.asarray(robot.tree.frames(jnp.zeros(n), params)[0])
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    np.testing.assert_allclose(p.origins[0, 0], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(p.origins[0, 1:], [1.0, 2.0, 3.0] + origins @ turn.T, atol=1e-12)
    np.testing.assert_allclose(p.rotations[0, 0], turn, atol=1e-12)


def test_planar_chain_is_drawn_upright_in_xz(planar):
    params, sol = planar
    p = lx.plot.show3d(sol, params=params).poses
    assert p.planar and np.all(p.origins[..., 1] == 0.0)
    np.testing.assert_allclose(p.origins[0, 2], [float(params["l1"] + params["l2"]), 0.0, 0.0])


def test_bad_input_is_refused(arm7, planar):
    tree, params, sol = arm7
    _, sol2 = planar
    with pytest.raises(ShapeError, match="2 coordinates per state but the Tree has 7"):
        lx.plot.show3d(sol2, tree, params=params)
    with pytest.raises(ConfigurationError, match="needs its parameters"):
        lx.plot.show3d(sol, tree)
    with pytest.raises(ConfigurationError, match="fps must be a positive"):
        lx.plot.show3d(sol, tree, params=params, fps=0.0)
    with pytest.raises(ArgumentTypeError, match="cannot draw a str"):
        lx.plot.show3d(sol, "arm7")


def test_a_batch_draws_its_members_and_a_missing_extra_is_named(arm7, monkeypatch):
    tree, params, sol = arm7
    batch = SimpleNamespace(ts=np.stack([sol.ts, sol.ts]), q=np.stack([sol.q, sol.q]))
    view = lx.plot.show3d(batch, tree, params=params)
    assert len(view.members) == 2 and view.ghost and not np.any(view.offsets)
    monkeypatch.setitem(sys.modules, "meshcat", None)  # as if the viz extra were missing
    with pytest.raises(ImportError, match=r"pip install 'lagrax\[viz\]'"):
        lx.plot.show3d(sol, tree, params=params)


def test_page_is_standalone(arm7, tmp_path):
    tree, params, sol = arm7
    view = lx.plot.show3d(sol, tree, params=params)
    path = view.save(tmp_path / "run.html")
    text = path.read_text()
    assert "MeshCat.Viewer" in text and "lagraxCommands" in text
    assert "http://" not in text.split("<script>")[0] and 'src="http' not in text
    assert view._repr_html_().startswith("<div") and "srcdoc=" in view._repr_html_()
    assert "8 bodies, 7 rods" in repr(view)


# -- the robot's own shapes ----------------------------------------------------------------

SOLO12 = "solo_description/robots/solo12.urdf"


def _robots():
    from _helpers import example_robot_data

    share = example_robot_data()
    if share is None:
        pytest.skip("example-robot-data is not installed (pip install example-robot-data)")
    return share / "robots"


@pytest.fixture(scope="module")
def solo12():
    path = _robots() / SOLO12
    robot, params = lx.chains.from_urdf(path, floating_base=True)
    ts = np.linspace(0.0, 2.0, 121)
    q = np.zeros((ts.size, 7 + robot.n))
    q[:, 2], q[:, 6] = 0.35, 1.0
    q[:, 7:] = 0.5 * np.sin(2 * np.pi * ts)[:, None]
    return path, robot, params, SimpleNamespace(ts=ts, q=q)


def test_urdf_meshes_ride_on_their_bodies(solo12):
    pin = pytest.importorskip("pinocchio")
    path, robot, params, sol = solo12
    p = lx.plot.show3d(sol, robot, params=params, geometry=path, fps=10.0).poses
    meshes = [s for s in p.shapes if s.kind == "mesh"]
    assert len(meshes) == 17 and all(len(s.faces) > 100 for s in meshes)  # base + 4 × 4 links
    names = tuple(robot.tree.body_names)
    assert "FL_FOOT" not in names  # fixed to FL_LOWER_LEG: its mesh rides on that body
    lower = names.index("FL_LOWER_LEG") + 1
    leg, foot = [s for s in meshes if s.body == lower]
    np.testing.assert_allclose(foot.transform[:3, 3], [0.0, 0.008, -0.16])  # FL_ANKLE's origin
    # the foot's mesh frame in the world, against Pinocchio's frame of the link
    model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    data = model.createData()
    f = 7
    pin.framesForwardKinematics(model, data, _state_at(sol, p.times[f]))
    world = np.eye(4)
    world[:3, :3], world[:3, 3] = p.rotations[f, lower], p.origins[f, lower]
    expected = data.oMf[model.getFrameId("FL_FOOT")]
    np.testing.assert_allclose((world @ foot.transform)[:3, 3], expected.translation, atol=1e-9)
    np.testing.assert_allclose((world @ foot.transform)[:3, :3], expected.rotation, atol=1e-9)
    np.testing.assert_allclose(p.origins[0, 0], [0.0, 0.0, 0.35])


def _state_at(sol, t):
    """`sol.q` linearly interpolated at `t`."""
    return np.array([np.interp(t, sol.ts, sol.q[:, i]) for i in range(sol.q.shape[1])])


def test_solo12_recording_is_one_small_page(solo12, tmp_path):
    path, robot, params, sol = solo12
    view = lx.plot.show3d(sol, robot, params=params, geometry=path, fps=60.0)
    assert view.poses.times.size == 121
    page = view.save(tmp_path / "solo12.html")
    assert page.stat().st_size < 10e6, page.stat().st_size  # 1.9 MB when measured


def test_a_missing_or_unreadable_mesh_is_named_and_drawn_as_a_box(arm7, tmp_path):
    tree, params, sol = arm7
    # arm7.urdf names meshes that lagrax does not ship: every link a box
    with pytest.warns(lx.URDFWarning) as record:
        view = lx.plot.show3d(sol, tree, params=params, geometry=lx.models.urdf_path("arm7"))
    assert len(record) == 8  # one per link, once for the recording
    assert "meshes/link3.stl' of link 'link3' cannot be drawn (no such file)" in str(
        record[3].message
    )
    assert [s.kind for s in view.poses.shapes] == ["box"] * 8
    (tmp_path / "bad.stl").write_text("not a mesh")
    urdf = """<robot name="r">
      <material name="blue"><color rgba="0 0 1 1"/></material>
      <link name="base"><visual><geometry><mesh filename="bad.stl"/></geometry></visual></link>
      <link name="arm"><inertial><mass value="1"/><origin xyz="0 0 0.2"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
        <visual><origin xyz="0 0 0.2"/><geometry><cylinder radius="0.02" length="0.4"/></geometry>
          <material name="blue"/></visual>
        <visual><geometry><sphere radius="0.05"/></geometry></visual>
        <visual><geometry><mesh filename="package://nowhere/gone.obj"/></geometry></visual>
      </link>
      <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
        <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
    </robot>"""
    (tmp_path / "r.urdf").write_text(urdf)
    robot, p1 = lx.chains.from_urdf(tmp_path / "r.urdf")
    one = SimpleNamespace(ts=np.array([0.0, 1.0]), q=np.array([[0.0], [1.0]]))
    with pytest.warns(lx.URDFWarning) as record:
        view = lx.plot.show3d(one, robot, params=p1, geometry=tmp_path / "r.urdf", fps=2.0)
    messages = " ".join(str(w.message) for w in record)
    assert "'bad.stl' of link 'base'" in messages and "gone.obj' of link 'arm'" in messages
    kinds = [(s.kind, s.body) for s in view.poses.shapes]
    assert kinds == [("box", 0), ("cylinder", 1), ("sphere", 1), ("box", 1)]
    cylinder = view.poses.shapes[1]
    assert cylinder.size == (0.02, 0.4) and cylinder.colour == 0x0000FF
    np.testing.assert_allclose(cylinder.transform[:3, 3], [0.0, 0.0, 0.2])
    sides = np.array(view.poses.shapes[3].size)
    assert sides[2] >= 0.2 - 1e-12  # the arm's box spans its origin and its centre of mass


def test_a_dense_mesh_is_simplified_within_its_outline(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=0.1)  # 81,920 triangles
    sphere.export(tmp_path / "ball.stl")
    urdf = """<robot name="r"><link name="base"/>
      <link name="ball"><inertial><mass value="1"/>
        <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
        <visual><geometry><mesh filename="ball.stl" scale="2 2 2"/></geometry></visual></link>
      <joint name="j" type="continuous"><parent link="base"/><child link="ball"/>
        <axis xyz="0 0 1"/></joint></robot>"""
    (tmp_path / "r.urdf").write_text(urdf)
    robot, params = lx.chains.from_urdf(tmp_path / "r.urdf")
    one = SimpleNamespace(ts=np.array([0.0]), q=np.array([[0.0]]))
    (mesh,) = lx.plot.show3d(one, robot, params=params, geometry=tmp_path / "r.urdf").poses.shapes
    assert 2000 < len(mesh.faces) <= 10_000 and mesh.faces.max() < len(mesh.vertices)
    radii = np.linalg.norm(mesh.vertices, axis=1)  # scaled by 2: a sphere of 0.2 m
    assert np.all(radii < 0.2 * (1 + 1e-6)) and np.all(radii > 0.2 * 0.97)  # STL: float32


MJCF = """<mujoco><asset><mesh name="tet" vertex="0 0 0 .2 0 0 0 .2 0 0 0 .2"/></asset>
<worldbody><geom type="plane" size="0 0 1" rgba=".8 .8 .7 1"/>
<body name="a" pos="0 0 1"><joint name="j1" type="hinge" axis="0 1 0"/>
 <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.05" rgba="0.8 0.3 0.1 1"/>
 <body name="b" pos="0 0 -0.5" euler="0 0 30"><joint name="j2" type="hinge" axis="0 1 0"/>
  <geom type="box" size=".05 .05 .2" pos="0 0 -.2" euler="10 0 0" rgba="0.1 0.3 0.8 1"/>
  <geom type="sphere" size=".08" pos="0 0 -.45"/>
  <geom type="cylinder" size=".03 .1" pos=".1 0 -.3"/>
  <geom type="ellipsoid" size=".05 .08 .03" pos="-.1 0 -.3"/>
  <geom type="mesh" mesh="tet" pos="0 .1 -.3"/>
  <geom type="sphere" size=".5" group="3"/>
 </body></body></worldbody></mujoco>"""


def test_mjcf_geoms_are_posed_as_mujoco_poses_them():
    mujoco = pytest.importorskip("mujoco")
    tree, params = lx.chains.from_mjcf(MJCF)
    q = np.array([[0.0, 0.0], [0.7, -1.2]])
    sol = SimpleNamespace(ts=np.array([0.0, 1.0]), q=q)
    p = lx.plot.show3d(sol, tree, params=params, geometry=MJCF, fps=1.0).poses
    kinds = [s.kind for s in p.shapes]
    assert kinds == ["box", "mesh", "box", "sphere", "cylinder", "ellipsoid", "mesh"]  # no group 3
    model = mujoco.MjModel.from_xml_string(MJCF)
    data = mujoco.MjData(model)
    data.qpos[:] = q[1]
    mujoco.mj_forward(model, data)
    for g, shape in zip(range(model.ngeom), p.shapes, strict=False):
        world = np.eye(4)
        world[:3, :3], world[:3, 3] = p.rotations[1, shape.body], p.origins[1, shape.body]
        placed = world @ shape.transform
        if shape.kind != "box" or g > 0:  # the plane's slab sits just below it
            np.testing.assert_allclose(placed[:3, 3], data.geom_xpos[g], atol=1e-12)
            np.testing.assert_allclose(placed[:3, :3], data.geom_xmat[g].reshape(3, 3), atol=1e-12)
    box = p.shapes[2]
    assert box.size == pytest.approx((0.1, 0.1, 0.4)) and box.colour == 0x1A4DCC
    assert p.shapes[4].size == pytest.approx((0.03, 0.2))
    with pytest.raises(ShapeError, match="3 coordinates per state but the Tree has 2"):
        lx.plot.show3d(SimpleNamespace(ts=np.zeros(1), q=np.zeros((1, 3))), tree, geometry=MJCF)


def test_contact_scene_draws_spheres_ground_and_forces():
    from lagrax.contact import ContactSystem, Plane, Sphere

    ball = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * p["m"] * qd @ qd, lambda q, p: p["m"] * 9.81 * q[2], n_dof=3
    )
    scene = ContactSystem(ball, Sphere(0.1, lambda q, p: q), Plane([0.0, 0.0, 1.0]), friction=0.3)
    q0, qd0 = jnp.array([0.0, 0.0, 0.3]), jnp.array([1.0, 0.0, 0.0])
    sol = lx.simulate(scene, q0, qd0, {"m": 1.0}, t1=0.6)
    p = lx.plot.show3d(sol, scene, params={"m": 1.0}, fps=50.0).poses
    assert [s.kind for s in p.shapes] == ["sphere", "box"] and p.shapes[1].body == -1
    arrows = p.arrows
    assert arrows is not None and arrows.shape == (p.times.size, 1, 2, 3)
    feet, vectors = arrows[:, 0, 0], arrows[:, 0, 1]
    np.testing.assert_allclose(feet[:, 2], p.origins[:, 0, 2] - 0.1, atol=1e-12)
    touching = np.linalg.norm(vectors, axis=-1) > 0
    assert touching.any() and not touching[0]  # dropped from 0.2 m above the ground
    assert np.all(vectors[touching, 2] > 0)  # the ground pushes up
    with pytest.raises(ShapeError, match="2 coordinates per state but the ContactSystem has 3"):
        lx.plot.show3d(SimpleNamespace(ts=np.zeros(1), q=np.zeros((1, 2))), scene, params={})


def test_contact_spheres_beside_a_robot(arm7):
    from lagrax.contact import ContactSystem, Plane, body_sphere

    tree, params, sol = arm7
    hand = body_sphere(tree, "link7", 0.05, (0.0, 0.0, 0.1))
    scene = ContactSystem(tree.system(), hand, Plane([0.0, 0.0, 1.0], -1.0))
    p = lx.plot.show3d(sol, tree, params=params, contact=scene, fps=5.0).poses
    assert p.skeleton and p.arrows is None  # the robot's spheres and rods, no forces kept
    assert p.origins.shape[1] == 8 + 1 and [s.kind for s in p.shapes] == ["sphere", "box"]
    link7 = tree.body_names.index("link7") + 1
    tip = p.origins[:, link7] + p.rotations[:, link7] @ np.array([0.0, 0.0, 0.1])
    np.testing.assert_allclose(p.origins[:, 8], tip, atol=1e-12)
    ground = p.shapes[1].transform[:3, 3]
    assert ground[2] == pytest.approx(-1.0 - 0.5 * p.shapes[1].size[2])  # its top at z = −1


def test_sweep_members_overlaid_or_side_by_side(arm7):
    import xarray as xr

    tree, params, sol = arm7
    # a sweep's dataset as lagrax.sweep(..., keep="trajectory") lays it out: the grid's
    # dimension, then time and dof (made from one solution, shifted, to stay cheap)
    shift = np.array([0.0, 0.5, -0.5])
    q = np.asarray(sol.q)[None] + shift[:, None, None]
    ds = xr.Dataset(
        {"q": (("q0_1", "time", "dof"), q)},
        coords={"q0_1": shift, "time": np.asarray(sol.ts), "dof": np.arange(7)},
    )
    over = lx.plot.show3d(ds, tree, params=params, fps=10.0)
    assert len(over.members) == 3 and over.ghost and not np.any(over.offsets)
    assert over.labels == ["q0_1 = 0", "q0_1 = 0.5", "q0_1 = -0.5"]
    frames = tree.frames(jnp.asarray(q[1, -1]), params)[0]
    np.testing.assert_allclose(over.members[1].origins[-1, 1:], frames, atol=1e-12)
    side = lx.plot.show3d(ds, tree, params=params, fps=10.0, layout="side", members=[0, 2])
    assert not side.ghost and side.labels == ["q0_1 = 0", "q0_1 = -0.5"]
    assert side.offsets[0, 1] == 0.0 and side.offsets[1, 1] > 0.5
    with pytest.raises(ShapeError, match="one per drawn member"):
        lx.plot.show3d(ds, tree, params=[params], fps=10.0)
    with pytest.raises(ConfigurationError, match="layout"):
        lx.plot.show3d(ds, tree, params=params, layout="grid")
    with pytest.raises(ShapeError, match='keep="trajectory"'):
        lx.plot.show3d(ds.isel(time=-1), tree, params=params)


# -- a user's own bodies -------------------------------------------------------------------


@pytest.fixture(scope="module")
def bicycle():
    """The benchmark bicycle (four `SpatialBody`s, gravity along +z) along a made-up motion:
    riding on, leaning and steering, its wheels rolling."""
    system, params = lx.models.benchmark_bicycle()
    ts = np.linspace(0.0, 1.0, 11)
    q = np.zeros((ts.size, 8))
    q[:, 0], q[:, 2], q[:, 3] = 2.0 * ts, 0.3 * ts, 0.2 * np.sin(3.0 * ts)
    q[:, 5], q[:, 6], q[:, 7] = 0.4 * ts, -2.0 * ts / 0.3, -2.0 * ts / 0.35
    return system, params, SimpleNamespace(ts=ts, q=q)


def test_bodies_are_drawn_on_their_pose_maps_with_their_inertia(bicycle):
    system, params, sol = bicycle
    p = lx.plot.show3d(sol, system, params=params, fps=10.0).poses
    (body,) = system.system.kinetic.__self__.bodies  # the scene's four bodies, in one
    assert p.origins.shape == (11, 4, 3) and not p.planar and p.links == ()
    flip = np.diag([1.0, -1.0, -1.0])  # the paper's z points down: turned so gravity does
    for f in (0, 7):
        x, rot = body.pose(jnp.asarray(sol.q[f]), params)
        np.testing.assert_allclose(p.origins[f], np.stack(x) @ flip.T, atol=1e-12)
        np.testing.assert_allclose(p.rotations[f], flip @ np.stack(rot), atol=1e-12)
    assert p.origins[0, 0, 2] == pytest.approx(0.3)  # the rear wheel's centre, rR up
    # each shape is the uniform solid of the body's mass with the body's inertia
    masses, inertias = np.asarray(body.mass(params)), np.asarray(body.inertia(params))
    assert [s.kind for s in p.shapes] == ["cylinder", "box", "cylinder", "cylinder"]
    for shape, m, inertia in zip(p.shapes, masses, inertias, strict=True):
        if shape.kind == "box":
            own = lx.bodies.box_inertia(m, jnp.asarray(shape.size))
        else:
            own = lx.bodies.cylinder_inertia(m, *shape.size)
        axes = shape.transform[:3, :3]
        np.testing.assert_allclose(axes @ np.asarray(own) @ axes.T, inertia, atol=1e-12)
    assert p.shapes[0].size[0] == pytest.approx(np.sqrt(2 * 0.12 / 2.0))  # m r²/2 = IRyy


def test_planar_bodies_lie_in_the_xz_plane():
    from lagrax.bodies import Param, PlanarBody, PointMass, Scene

    def link(q, p):  # a rod pivoted at the origin, its centre half way
        return [0.5 * jnp.stack([jnp.cos(q[0]), jnp.sin(q[0])])], [q[0]]

    def tip(q, p):
        return jnp.stack([jnp.cos(q[0]), jnp.sin(q[0])])

    rod = PlanarBody(Param("m"), Param("I"), link, None)
    scene = Scene([rod, PointMass(1.0, tip)], gravity=9.81, n_dof=1)
    params = {"m": 2.0, "I": 2.0 / 12.0}
    ts = np.linspace(0.0, 1.0, 6)
    sol = SimpleNamespace(ts=ts, q=np.linspace(0.2, -1.1, 6)[:, None])
    p = lx.plot.show3d(sol, scene.system(), params=params, fps=5.0).poses
    assert p.planar and [s.kind for s in p.shapes] == ["box", "sphere"]
    theta = sol.q[3, 0]
    np.testing.assert_allclose(p.origins[3, 0], [0.5 * np.cos(theta), 0.0, 0.5 * np.sin(theta)])
    np.testing.assert_allclose(p.origins[3, 1], [np.cos(theta), 0.0, np.sin(theta)])
    np.testing.assert_allclose(p.rotations[3, 0][:, 0], [np.cos(theta), 0.0, np.sin(theta)])
    length = p.shapes[0].size[0]  # the uniform rod of its moment: m L²/12 = I
    assert float(lx.bodies.rod_inertia(2.0, length)[1, 1]) == pytest.approx(params["I"])
    with pytest.raises(ShapeError, match="2 coordinates per state but the Scene has 1"):
        lx.plot.show3d(SimpleNamespace(ts=ts, q=np.zeros((6, 2))), scene, params=params)


# -- in a real browser ---------------------------------------------------------------------


def _chromium() -> tuple[str, str]:
    """The chromium and chromedriver binaries, or skip."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if browser is None or driver is None:
        pytest.skip("no chromium/chromedriver binary (apt-get install chromium chromium-driver)")
    return browser, driver


@pytest.fixture(scope="module")
def browser():
    try:
        from selenium import webdriver
    except ImportError:
        pytest.skip("the browser test needs selenium (the dev extra)")
    binary, driver_path = _chromium()
    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for flag in (
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--window-size=800,600",
    ):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    service = webdriver.ChromeService(executable_path=driver_path)
    driver = webdriver.Chrome(options=options, service=service)
    driver.execute_cdp_cmd("Network.enable", {})
    driver.execute_cdp_cmd(
        "Network.emulateNetworkConditions",
        {"offline": True, "latency": 0, "downloadThroughput": 0, "uploadThroughput": 0},
    )
    yield driver
    driver.quit()


def _image(driver, script: str) -> np.ndarray:
    """RGB pixels of the viewer's canvas after running `script` (rendered at once)."""
    from PIL import Image

    url = driver.execute_script(script + "; return viewer.capture_image();")
    data = base64.b64decode(url.split(",", 1)[1])
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), dtype=float)


def test_saved_page_plays_offline_in_chromium(arm7, browser, tmp_path):
    tree, params, sol = arm7
    path = lx.plot.show3d(sol, tree, params=params, play=False).save(tmp_path / "arm7.html")
    browser.get(path.as_uri())
    assert browser.execute_script("return window.lagraxReady === true")
    duration = browser.execute_script("return window.lagraxDuration")
    assert duration == pytest.approx(1.0)
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == [], errors
    # the controls: play, pause, reset, the time slider and the speed
    labels = browser.execute_script(
        "return Array.from(document.querySelectorAll('.dg .property-name'))"
        ".map((e) => e.textContent)"
    )
    assert {"play", "pause", "reset", "time", "timeScale"} <= set(labels)

    hidden = "viewer.animator.seek(0); viewer.scene_tree.find(['lagrax']).object.visible = false"
    shown = "viewer.scene_tree.find(['lagrax']).object.visible = true; viewer.animator.seek(0)"
    background, start = _image(browser, hidden), _image(browser, shown)
    robot = np.abs(start - background).sum(axis=-1) > 30
    h, w = robot.shape
    assert robot.sum() > 500, "the robot covers almost no pixels"
    rows, cols = np.nonzero(robot)
    assert h / 4 < rows.mean() < 3 * h / 4 and w / 4 < cols.mean() < 3 * w / 4
    end = _image(browser, f"viewer.animator.seek({duration})")
    moved = np.abs(end - start).sum(axis=-1) > 30
    assert moved.sum() > 200, "the first and last frames look the same"
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == [], errors


def test_floating_base_page_turns_in_chromium(browser, tmp_path):
    robot, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"), floating_base=True)
    q = np.zeros((2, 7 + robot.n))
    q[:, 6] = 1.0
    q[1, :7] = [0.3, 0.0, 0.2, np.sin(0.6), 0.0, 0.0, np.cos(0.6)]  # moved, turned about x
    q[1, 8] = 0.8
    sol = SimpleNamespace(ts=np.array([0.0, 1.0]), q=q)
    path = lx.plot.show3d(sol, robot, params=params, fps=10.0, play=False).save(tmp_path / "f.html")
    browser.get(path.as_uri())
    assert browser.execute_script("return window.lagraxReady === true")
    start = _image(browser, "viewer.animator.seek(0)")
    end = _image(browser, "viewer.animator.seek(1.0)")
    assert (np.abs(end - start).sum(axis=-1) > 30).sum() > 200
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == [], errors


def _robot_in_view(driver, root: str = "lagrax", at: float = 0.0) -> np.ndarray:
    """Pixels that change when the scene's `root` is hidden (at time `at`)."""
    hidden = (
        f"viewer.animator.seek({at}); viewer.scene_tree.find(['{root}']).object.visible = false"
    )
    shown = f"viewer.scene_tree.find(['{root}']).object.visible = true; viewer.animator.seek({at})"
    background, start = _image(driver, hidden), _image(driver, shown)
    return np.abs(start - background).sum(axis=-1) > 30


def test_solo12_with_its_meshes_plays_in_chromium(solo12, browser, tmp_path):
    path, robot, params, sol = solo12
    view = lx.plot.show3d(sol, robot, params=params, geometry=path, fps=60.0, play=False)
    page = view.save(tmp_path / "solo12.html")
    browser.get(page.as_uri())
    assert browser.execute_script("return window.lagraxReady === true")
    assert browser.execute_script("return window.lagraxDuration") == pytest.approx(2.0)
    assert _robot_in_view(browser).sum() > 2000, "solo12's meshes cover almost no pixels"
    start = _image(browser, "viewer.animator.seek(0)")
    later = _image(browser, "viewer.animator.seek(0.25)")  # the legs swung by 0.5 rad
    assert (np.abs(later - start).sum(axis=-1) > 30).sum() > 200
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == [], errors


DOCS = Path(__file__).resolve().parent.parent / "docs"


def _gallery():
    """The docs' hook that writes the site's recordings (tools/docs_gallery.py)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "gallery", DOCS.parent / "tools" / "docs_gallery.py"
    )
    assert spec is not None and spec.loader is not None
    gallery = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gallery)
    return gallery


def _plays(driver, page: Path, pixels: int, later: float) -> None:
    """The page loads offline with no console error, shows its model (`pixels` at least)
    and moves by `later` seconds."""
    driver.get(page.as_uri())
    assert driver.execute_script("return window.lagraxReady === true")
    assert _robot_in_view(driver).sum() > pixels, f"{page.name}: no model in view"
    start = _image(driver, "viewer.animator.seek(0)")
    moved = _image(driver, f"viewer.animator.seek({later})")
    assert (np.abs(moved - start).sum(axis=-1) > 30).sum() > 100, f"{page.name} stands still"
    errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == [], (page.name, errors)


def test_the_sites_gallery_pages_play_in_chromium(browser, tmp_path):
    _robots()
    docs = DOCS
    gallery = _gallery()
    pages = gallery.write_gallery(tmp_path)
    embedded = (docs / "viewer.md").read_text()
    assert len(pages) == len(gallery.GALLERY) >= 2
    for page in pages:
        assert f'src="../recordings/{page.name}"' in embedded  # the page embeds each one
        assert page.stat().st_size < 4e6, (page.name, page.stat().st_size)
        browser.get(page.as_uri())
        assert browser.execute_script("return window.lagraxReady === true")
        assert _robot_in_view(browser).sum() > 1000, f"{page.name}: no robot in view"
        errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
        assert errors == [], (page.name, errors)


def test_the_sites_simulated_recordings_play_in_chromium(bicycle, browser, tmp_path):
    """The contact page's solo12 drop and the bicycle's run, drawn by the hook's own
    functions along made-up motions: simulating them compiles for about a minute and a
    half (the docs build does it; `LAGRAX_ALL_ROBOTS=1` runs the next test)."""
    robots = _robots()
    gallery = _gallery()
    for name, where in gallery.SIMULATED.items():  # each page embeds its recording
        assert f'src="../recordings/{name}.html"' in (DOCS / where).read_text()
    page = gallery.bicycle_view(bicycle[2], fps=10.0).save(tmp_path / "bicycle.html")
    _plays(browser, page, 500, 1.0)
    ts = np.linspace(0.0, 6.0, 13)  # riding 30 m, 17 times its size: the view follows it
    q = np.zeros((ts.size, 8))
    q[:, 0], q[:, 6], q[:, 7] = 5.0 * ts, -5.0 * ts / 0.3, -5.0 * ts / 0.35
    page = gallery.bicycle_view(SimpleNamespace(ts=ts, q=q), fps=2.0).save(tmp_path / "ride.html")
    browser.get(page.as_uri())
    start = _robot_in_view(browser).sum()
    end = _robot_in_view(browser, at=6.0).sum()
    assert start > 500 and end == pytest.approx(start, rel=0.1)  # as large, at the end too
    ts = np.linspace(0.0, 1.0, 31)
    q = np.zeros((ts.size, 19))
    q[:, 2], q[:, 6], q[:, 7:] = 0.3 - 0.1 * ts, 1.0, gallery.STANCE  # falling 10 cm
    force = np.zeros((ts.size, 4, 3))
    force[15:, :, 2] = 6.0  # the feet pushed up in the second half
    drop = SimpleNamespace(ts=ts, q=q, contact_force=force)
    view = gallery.solo12_drop_view(drop, robots)
    assert view.poses.arrows is not None and view.poses.arrows.shape[:2] == (31, 4)
    page = view.save(tmp_path / "solo12_drop.html")
    assert page.stat().st_size < 10e6
    _plays(browser, page, 1000, 1.0)


@every_robot("the test above draws the same pages along made-up motions")
def test_the_sites_simulated_recordings_from_their_simulations(browser, tmp_path):
    """The hook's simulations themselves: solo12 stands on its feet at the end of its
    drop, the bicycle rights itself, and both pages play."""
    gallery = _gallery()
    robots = _robots()
    drop = gallery.solo12_drop(robots)
    assert bool(drop.ok) and float(np.min(drop.contact_gap)) >= -2e-3
    assert 0.15 < float(drop.q[-1, 2]) < 0.3
    run = gallery.bicycle_run()
    assert bool(run.ok) and abs(float(run.q[-1, 3])) < 0.01  # upright again after 6 s
    _plays(browser, gallery.bicycle_view(run).save(tmp_path / "bicycle.html"), 500, 1.0)
    view = gallery.solo12_drop_view(drop, robots)
    _plays(browser, view.save(tmp_path / "solo12_drop.html"), 1000, 0.5)
