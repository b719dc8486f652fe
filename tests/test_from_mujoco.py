"""``lagrax.chains.from_mujoco``: a MuJoCo model as MuJoCo runs it, in one call.

- gymnasium's ant loads with its ground contact, its eight joint limits enforced and its
  eight motors driven by the scene's input (``tau=`` is MuJoCo's ``ctrl``), with nothing
  left out (MuJoCo's ant has nothing
  lagrax does not simulate): no warning;
- a model with what lagrax does not simulate (a height field, torsional and rolling
  friction, contact between bodies, a filtered actuator, an equality beside contact) is
  loaded, with each named in one warning and on ``scene.unsupported``;
- the actuators' generalized force at a ``ctrl`` is MuJoCo's ``qfrc_actuator`` (a
  filtered servo's at MuJoCo's activation ``act = ctrl``), and the ant's accelerations
  with ``tau=ctrl`` (one control beyond its range, clamped) are MuJoCo's ``qacc``;
- with ``tau=ctrl`` a solve's energy balance holds with the actuators' work in it, and
  a sweep's members end where ``simulate`` does; a
  ``ctrl`` of the wrong length (a constant or a function's) is a ``ShapeError`` naming
  ``tau`` and both lengths;
- a model MuJoCo cannot compile is an ``MJCFError`` (a ``LagraxError``) with MuJoCo's
  message;
- with ``LAGRAX_ALL_ROBOTS=1``: the ant started from MuJoCo's initial state with
  ``ctrl = 0`` comes to rest with its torso within 25 mm of MuJoCo's at ``timestep =
  5e-4``.
"""

import importlib.util
import os
import warnings

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax import LagraxError, MJCFError

mujoco = pytest.importorskip("mujoco")
ALL_ROBOTS = os.environ.get("LAGRAX_ALL_ROBOTS", "") not in ("", "0")


def ant_xml() -> str:
    spec = importlib.util.find_spec("gymnasium")
    if spec is None or not spec.submodule_search_locations:
        pytest.skip("gymnasium is not installed")
    return os.path.join(spec.submodule_search_locations[0], "envs", "mujoco", "assets", "ant.xml")


ROVER = """
<mujoco>
  <asset><hfield name="bumps" nrow="3" ncol="3" size="1 1 0.05 0.1"/></asset>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <geom name="bumps" type="hfield" hfield="bumps" pos="3 0 0"/>
    <body name="cart" pos="0 0 0.1">
      <freejoint/>
      <geom name="chassis" type="box" size="0.2 0.1 0.05" mass="2"/>
      <body name="arm" pos="0.2 0 0">
        <joint name="shoulder" type="hinge" axis="0 1 0" limited="true" range="-60 60"/>
        <geom name="arm" type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" mass="0.3"
              condim="6" friction="1 0.02 0.001"/>
      </body>
      <body name="flap" pos="-0.2 0 0">
        <joint name="flap" type="hinge" axis="0 1 0"/>
        <geom name="flap" type="sphere" pos="-0.1 0 0" size="0.03" mass="0.1"/>
      </body>
    </body>
  </worldbody>
  <equality><joint joint1="flap" joint2="shoulder"/></equality>
  <actuator>
    <motor name="drive" joint="shoulder" gear="2" ctrlrange="-1 1"/>
    <position name="servo" joint="flap" kp="5" timeconst="0.1"/>
  </actuator>
</mujoco>
"""


@pytest.fixture(scope="module")
def rover():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene, params = lx.chains.from_mujoco(ROVER)
    return scene, params, [w for w in caught if issubclass(w.category, UserWarning)]


def test_the_ant_loads_with_everything_on_and_nothing_left_out():
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing left out: no warning
        scene, params = lx.chains.from_mujoco(ant_xml())
    assert scene.unsupported == ()
    assert len(scene.spheres) == 25  # the torso's sphere and the legs' capsules
    names = [lim.name for lim in scene.limits]
    assert names == [f"{part}_{k}" for k in (1, 2, 3, 4) for part in ("hip", "ankle")]
    assert all(lim.angular for lim in scene.limits)
    model = mujoco.MjModel.from_xml_path(ant_xml())
    # each stop at MuJoCo's range, on the joint's own coordinate (7 + i) and rate (6 + i)
    for lim in scene.limits:
        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, lim.name)
        assert (lim.lower, lim.upper) == pytest.approx(tuple(model.jnt_range[j]))
        assert (lim.index, lim.rate) == (model.jnt_qposadr[j], model.jnt_dofadr[j])
    assert scene.n_input == model.nu == 8 and scene.n_dof == 14  # tau= is MuJoCo's ctrl
    assert "ctrl" not in params


def test_what_is_not_simulated_is_named_in_one_warning(rover):
    scene, _, caught = rover
    assert len(caught) == 1
    text = str(caught[0].message)
    for what in (
        "height field",
        "torsional friction",
        "rolling friction",
        "contact between bodies",
        "actuator 'servo'",
        "time constant 0.1",
        "equality constraint",
    ):
        assert what in text, what
    assert len(scene.unsupported) == 6
    assert all(item in text for item in scene.unsupported)
    # what is simulated: the ground, the limited shoulder, the free flap unlimited
    assert [lim.name for lim in scene.limits] == ["shoulder"]


def test_the_actuators_force_is_mujocos(rover):
    scene, params, _ = rover
    model = mujoco.MjModel.from_xml_string(ROVER)
    data = mujoco.MjData(model)
    data.qpos[7:] = [0.3, -0.2]
    data.qvel[6:] = [0.5, 1.5]
    ctrl = np.array([1.7, 0.4])  # the motor's beyond its range: clamped, as MuJoCo does
    data.ctrl[:] = ctrl
    data.act[:] = ctrl[1:]  # the filtered servo, its activation arrived at its control
    mujoco.mj_forward(model, data)
    q, v = lx.chains.from_mujoco_state(data.qpos, data.qvel, scene)
    force = scene.generalized_input(q, v, ctrl)
    # (the base at rest and upright: its generalized force is MuJoCo's as it is)
    np.testing.assert_allclose(force, data.qfrc_actuator, rtol=1e-12, atol=1e-12)
    assert float(force[6]) == pytest.approx(2.0 * 1.0)  # gear 2 on ctrl clamped to 1


def test_the_ants_accelerations_under_ctrl_are_mujocos():
    """In the air (no contact) with every joint inside its range (no limit acting),
    the ant's forward dynamics with ``tau=ctrl`` is MuJoCo's: motors of gear 150, a
    control beyond ``ctrlrange = [-1, 1]`` clamped as MuJoCo clamps it."""
    scene, params = lx.chains.from_mujoco(ant_xml())
    model = mujoco.MjModel.from_xml_path(ant_xml())
    data = mujoco.MjData(model)
    data.qpos[2] = 2.0
    rng = np.random.default_rng(3)
    low, high = model.jnt_range[1:, 0], model.jnt_range[1:, 1]
    data.qpos[7:] = low + (high - low) * rng.uniform(0.2, 0.8, 8)
    data.qvel[:] = rng.normal(0.0, 0.5, model.nv)
    ctrl = np.array([0.3, -0.7, 1.6, -2.0, 0.0, 0.5, -0.1, 0.9])  # two beyond ±1
    data.ctrl[:] = ctrl
    mujoco.mj_forward(model, data)
    assert data.ncon == 0 and data.nefc == 0  # nothing but the actuators and gravity
    q, v = lx.chains.from_mujoco_state(data.qpos, data.qvel, scene)
    np.testing.assert_allclose(
        scene.generalized_input(q, v, ctrl), data.qfrc_actuator, rtol=1e-12, atol=1e-9
    )
    a = scene.forward_dynamics(q, v, params, tau=ctrl)
    qacc = lx.chains.to_mujoco_acceleration(q, v, a, scene.system)
    np.testing.assert_allclose(qacc, data.qacc, rtol=1e-8, atol=1e-8)
    # with no tau, ctrl = 0: the motors have no bias, so no actuator force
    free = scene.forward_dynamics(q, v, params)
    data.ctrl[:] = 0.0
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(
        lx.chains.to_mujoco_acceleration(q, v, free, scene.system), data.qacc, rtol=1e-8, atol=1e-8
    )


def test_ctrl_drives_a_solve_and_its_work_is_in_the_energy_balance(rover):
    """The rover in the air, its shoulder motor (gear 2) driven by ``ctrl(t)`` and its
    flap's servo (kp 5) by a constant through ``tau=``: the energy balance holds with
    the actuators' work, which it could not if the input were left out of it."""
    scene, params, _ = rover
    q0 = np.zeros(scene.n_configuration)
    q0[2], q0[6] = 1.0, 1.0  # 1 m up, upright
    v0 = np.zeros(scene.n_dof)

    def ctrl(t, q, v):
        return jnp.array([0.8, 0.0]) * jnp.cos(jnp.pi * t) + jnp.array([0.0, 0.3])

    sol = lx.simulate(scene, q0, v0, params, t1=0.2, tau=ctrl, solver="tsit5", n_save=21)
    assert bool(sol.ok)
    assert float(np.max(np.abs(sol.work))) > 1e-2  # the actuators did work
    assert float(np.max(np.abs(sol.energy_error))) < 1e-7
    idle = lx.simulate(scene, q0, v0, params, t1=0.2, solver="tsit5", n_save=21)
    assert float(np.max(np.abs(sol.q[-1, 7:] - idle.q[-1, 7:]))) > 1e-3  # ctrl acts


def test_a_sweep_takes_ctrl_as_simulate_does(rover):
    """Two members (their friction differs; in the air it does not act), one ``ctrl``
    for both: each member's final state is ``simulate``'s with the same ``tau=ctrl``."""
    scene, params, _ = rover
    q0 = np.zeros(scene.n_configuration)
    q0[2], q0[6] = 1.0, 1.0
    v0 = np.zeros(scene.n_dof)
    ctrl = np.array([0.8, 0.3])
    friction = np.stack([params["contact_friction"], 0.5 * params["contact_friction"]])
    batch = {**params, "contact_friction": friction}
    batch = {k: (v if k == "contact_friction" else np.stack([v, v])) for k, v in batch.items()}
    run = dict(t1=0.1, tau=ctrl, solver="tsit5")
    ds = lx.sweep(scene, np.stack([q0, q0]), np.stack([v0, v0]), batch, **run)
    for i in range(2):
        member = {k: v[i] for k, v in batch.items()}
        sol = lx.simulate(scene, q0, v0, member, **run)
        np.testing.assert_allclose(ds.q.values[i], sol.q[-1], rtol=1e-9, atol=1e-12)


def test_a_ctrl_of_the_wrong_length_names_tau_and_both_lengths(rover):
    scene, params, _ = rover
    q0 = np.zeros(scene.n_configuration)
    q0[2], q0[6] = 1.0, 1.0
    v0 = np.zeros(scene.n_dof)
    with pytest.raises(lx.ShapeError, match=r"tau has length 8 but .* has 2 inputs") as info:
        lx.simulate(scene, q0, v0, params, t1=0.1, tau=np.zeros(8))
    assert isinstance(info.value, LagraxError)
    with pytest.raises(lx.ShapeError, match=r"tau has length 3 but .* has 2 actuators"):
        scene.forward_dynamics(q0, v0, params, tau=np.zeros(3))
    with pytest.raises(
        lx.ShapeError, match=r"tau\(t, q, qd\) returned shape \(8,\); expected \(2,\)"
    ):
        lx.simulate(scene, q0, v0, params, t1=0.1, tau=lambda t, q, v: np.zeros(8))


def test_a_model_mujoco_cannot_compile_is_an_mjcf_error_with_its_message():
    bad = "<mujoco><worldbody><body><joint type='bogus'/></body></worldbody></mujoco>"
    with pytest.raises(MJCFError, match="MuJoCo cannot compile") as info:
        lx.chains.from_mujoco(bad)
    assert isinstance(info.value, LagraxError)
    assert "bogus" in str(info.value)  # MuJoCo's own words
    with pytest.raises(lx.MissingFileError):
        lx.chains.from_mujoco("no/such/model.xml")


@pytest.mark.skipif(not ALL_ROBOTS, reason="a 2 s drop of the ant: LAGRAX_ALL_ROBOTS=1")
def test_the_ant_comes_to_rest_where_mujocos_does():
    """MuJoCo's ant starts with its ankles at 0, outside their limits (30° to 70°):
    MuJoCo's soft limit kicks them in at 9.6 rad/s, into the opposite limit, and the
    ant lands on steep legs that friction then holds (0.541 m at 2 s, still sinking
    7 mm/s). lagrax starts a joint past its limit at the limit. From that start, the
    ankles on their limits, both rest at the same height, MuJoCo's contact margins
    included (the ant stands 20 mm above its floor in both)."""
    scene, params = lx.chains.from_mujoco(ant_xml())
    model = mujoco.MjModel.from_xml_path(ant_xml())
    data = mujoco.MjData(model)
    data.qpos[7:] = np.clip(data.qpos[7:], model.jnt_range[1:, 0], model.jnt_range[1:, 1])
    q0, v0 = lx.chains.from_mujoco_state(data.qpos, data.qvel, scene)
    model.opt.timestep = 5e-4  # MuJoCo's converged answer
    for _ in range(4000):
        mujoco.mj_step(model, data)
    assert np.max(np.abs(data.qvel)) < 1e-6  # MuJoCo's ant is at rest
    sol = lx.simulate(scene, q0, v0, params, t1=2.0, n_save=21)  # the default: rodas4
    assert bool(sol.ok)
    assert np.max(np.abs(np.asarray(sol.qd[-1]))) < 1e-6  # at rest
    assert abs(float(sol.q[-1, 2]) - float(data.qpos[2])) < 0.025  # measured 0.1 mm
    # ...and started from MuJoCo's own initial state, lagrax rests there too
    qpos0 = mujoco.MjData(model).qpos
    q1, v1 = lx.chains.from_mujoco_state(qpos0, np.zeros(model.nv), scene)
    again = lx.simulate(scene, q1, v1, params, t1=2.0, n_save=21)
    assert abs(float(again.q[-1, 2]) - float(sol.q[-1, 2])) < 1e-6


PLANAR = """
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1"/>
    <body name="torso" pos="0 0 0.5">
      <joint name="rootx" type="slide" axis="1 0 0"/>
      <joint name="rootz" type="slide" axis="0 0 1"/>
      <joint name="rooty" type="hinge" axis="0 1 0"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.05" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""


def test_a_planar_roots_state_is_mujocos_as_it_is():
    """A planar root (two slides and a hinge, as in hopper.xml and walker.xml) has no free
    joint: the state converts unchanged, both ways, given the scene (this raised an
    `AttributeError` once)."""
    scene, _ = lx.chains.from_mujoco(PLANAR)
    qpos, qvel = np.array([0.1, -0.2, 0.3]), np.array([1.0, 2.0, -3.0])
    q, v = lx.chains.from_mujoco_state(qpos, qvel, scene)
    np.testing.assert_array_equal(np.asarray(q), qpos)
    np.testing.assert_array_equal(np.asarray(v), qvel)
    back = lx.chains.to_mujoco_state(q, v, scene)
    np.testing.assert_array_equal(np.asarray(back[0]), qpos)
    np.testing.assert_array_equal(np.asarray(back[1]), qvel)


def test_two_free_bodies_on_the_ground_are_refused_for_what_they_are():
    """dm_control's quadruped with its ball: two free bodies, no equality constraint; the
    refusal names the parts and nothing else (it named equality constraints once)."""
    two = """
    <mujoco><worldbody><geom type="plane" size="5 5 0.1"/>
      <body pos="0 0 1"><freejoint/><geom type="sphere" size="0.1" mass="1"/></body>
      <body pos="1 0 1"><freejoint/><geom type="sphere" size="0.1" mass="1"/></body>
    </worldbody></mujoco>"""
    with pytest.raises(MJCFError, match=r"2 part\(s\)") as info:
        lx.chains.from_mujoco(two)
    assert "equality" not in str(info.value).split("this one has")[1]


def test_a_robot_that_bears_no_weight_on_its_ground_is_refused_at_load():
    """The contact's defaults are scaled from the weight the ground bears at `qpos0`: a
    pendulum hanging from the world bears none, and the load says so (the scaling runs
    as one compiled program there, not op by op)."""
    hanging = """
    <mujoco><worldbody><geom type="plane" size="5 5 0.1"/>
      <body pos="0 0 1"><joint type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.05" mass="1"/></body>
    </worldbody></mujoco>"""
    with pytest.raises(MJCFError, match="bears no weight on its ground"):
        lx.chains.from_mujoco(hanging)
