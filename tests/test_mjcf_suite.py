"""The DeepMind Control Suite's MJCF files (``dm_control/suite/*.xml``, as ``pip install
dm-control`` ships them), read with ``from_mjcf``'s default options and held to MuJoCo.

- The files that load (``LOADS``): ``M`` against ``mj_fullM`` (armature included) and
  ``q̈`` against ``mj_forward``'s ``qacc`` at a random state with a random generalized
  force (``qfrc_applied``), MuJoCo's contacts, constraints (limits, friction loss,
  equality) and actuators disabled, to 1e-10 relative (lagrax's friction loss taken out
  too); a floating model through ``from_mujoco_state`` (``M`` congruent by the base's
  rotation), a model with several free bodies (the dog and its ball, the quadruped and
  its ball: a ``Forest``) through ``from_mujoco_state(..., robot)``; a model with
  equality constraints (manipulator, stacker, quadruped: a ``ConstrainedRobot``) by its
  unconstrained robot, and its constraints ``φ(q)`` against MuJoCo's equality residuals
  ``efc_pos``. The finger's friction loss: ``−f sign(q̇)`` away from rest.
- ``lqr.xml``, a template without bodies, is refused; the model its task builds loads.
- The files that do not (``REFUSED``): an ``MJCFError`` naming the construct.
- The fish (refused for its fluid forces) with MuJoCo's fluid model switched off in the
  compiled model: a free body with joint springs and a fixed tendon's spring, held to
  MuJoCo the same way.
- Other real MJCF files we did not write, MJX's test models (the ``mujoco-mjx`` package):
  Barkour (a free base with armature), a tendon model and ``convex.xml`` (four free
  bodies) load and match MuJoCo the same way; a tendon with armature, springs on ball
  joints and friction loss are refused by name.
"""

import os
import re
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import every_robot, lqr_model, mjx_test_data, rel_error
from lagrax.chains import from_mjcf, from_mujoco_state, to_mujoco_acceleration

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is the reference for MJCF dynamics")
dm_control = pytest.importorskip("dm_control", reason="dm_control ships the suite's MJCF files")

SUITE = Path(os.path.dirname(dm_control.__file__)) / "suite"
RTOL = 1e-10

LOADS = [
    "acrobot",
    "ball_in_cup",
    "cartpole",
    "cheetah",
    "dog",
    "finger",
    "hopper",
    "humanoid",
    "humanoid_CMU",
    "manipulator",
    "pendulum",
    "point_mass",
    "quadruped",
    "reacher",
    "stacker",
    "walker",
]
REFUSED = {
    "fish": ["fluid forces", "density=5000"],
    "swimmer": ["fluid forces", "density=3000"],
    "lqr": ["no hinge or slide joint", "lqr.xml"],
}


def test_the_lists_cover_the_suite():
    assert sorted(LOADS + list(REFUSED)) == sorted(p.stem for p in SUITE.glob("*.xml"))


def _compiled(name: str):
    """MuJoCo's model of a suite file with contacts, constraints and actuators off."""
    model = mujoco.MjModel.from_xml_path(str(SUITE / f"{name}.xml"))
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_CONSTRAINT | off.mjDSBL_ACTUATION
    return model


def _random_qpos(model, rng) -> np.ndarray:
    """`qpos0` moved at random: each free joint to a random pose, the others by up to
    ±0.5."""
    qpos = np.array(model.qpos0) + rng.uniform(-0.5, 0.5, model.nq)
    for j in np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE):
        a = int(model.jnt_qposadr[j])
        quat = rng.normal(size=4)
        qpos[a : a + 3] = model.qpos0[a : a + 3] + rng.normal(size=3)
        qpos[a + 3 : a + 7] = quat / np.linalg.norm(quat)
    return qpos


def _against_mujoco(robot, params, model, seed: int) -> tuple[float, float]:
    """`(M error, q̈ error)`, relative, at one random state and force (see the module
    docstring)."""
    rng = np.random.default_rng(seed)
    if isinstance(robot, lx.chains.Forest):
        return _forest_against_mujoco(robot, params, model, rng)
    floating = isinstance(robot, lx.chains.FloatingTree)
    qpos = _random_qpos(model, rng)
    qvel, force, data, m_mj = _mujoco_at(model, qpos, rng)
    system = robot.system()
    forward = jax.jit(lambda q, v, f: system.forward_dynamics(q, v, params, f))
    mass = jax.jit(lambda q: system.mass_matrix(q, params))
    if not floating:
        qacc = forward(jnp.asarray(qpos), jnp.asarray(qvel), jnp.asarray(force))
        m_lx = mass(jnp.asarray(qpos))
        return rel_error(m_lx, m_mj), rel_error(qacc, data.qacc)
    q, v = from_mujoco_state(qpos, qvel)
    rot = data.xmat[model.jnt_bodyid[0]].reshape(3, 3)
    tau = np.concatenate([rot.T @ force[:3], force[3:]])  # a force converts like v
    qacc = to_mujoco_acceleration(q, v, forward(q, v, jnp.asarray(tau)))
    t = np.eye(model.nv)
    t[:3, :3] = rot
    return rel_error(mass(q), t.T @ m_mj @ t), rel_error(qacc, data.qacc)


def _mujoco_at(model, qpos, rng):
    """`(qvel, force, data, M)`: a random velocity and generalized force, and MuJoCo's
    `mj_forward` and `mj_fullM` at them and `qpos`."""
    qvel, force = (rng.uniform(-1.0, 1.0, model.nv) for _ in range(2))
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:], data.qfrc_applied[:] = qpos, qvel, force
    mujoco.mj_forward(model, data)
    m_mj = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, m_mj)
    return qvel, force, data, m_mj


def _forest_against_mujoco(forest, params, model, rng) -> tuple[float, float]:
    """`_against_mujoco` of a `Forest`: every free joint converted where it is; `M`
    congruent by the bases' rotations."""
    qpos = _random_qpos(model, rng)
    qvel, force, data, m_mj = _mujoco_at(model, qpos, rng)
    system = forest.system()
    q, v = from_mujoco_state(qpos, qvel, forest)
    _, tau = from_mujoco_state(qpos, force, forest)
    a = jax.jit(lambda q, v, f: system.forward_dynamics(q, v, params, f))(q, v, tau)
    qacc, t = to_mujoco_acceleration(q, v, a, forest), np.eye(model.nv)
    for j in np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE):
        va = int(model.jnt_dofadr[j])
        t[va : va + 3, va : va + 3] = data.xmat[model.jnt_bodyid[j]].reshape(3, 3)
    mass = jax.jit(lambda q: system.mass_matrix(q, params))(q)
    return rel_error(mass, t.T @ m_mj @ t), rel_error(qacc, data.qacc)


def _size(robot) -> int:
    """The size of `q` of a loaded robot."""
    if isinstance(robot, lx.chains.Forest):
        return robot.system().n_configuration
    return 7 + robot.n if isinstance(robot, lx.chains.FloatingTree) else robot.n


FRICTION = ("frictionloss", "friction_velocity")


def _without_friction(params):
    """`params` (a dict, or a forest's tuple of them) without friction loss."""
    if isinstance(params, tuple):
        return tuple(_without_friction(p) for p in params)
    return {k: v for k, v in params.items() if k not in FRICTION}


# the dog (85 velocities, two free bodies) and the stacker (an equality on a fixed robot)
# compile for long: the quadruped (two free bodies, equalities) and the manipulator (an
# equality on a fixed robot) hold the same constructs to MuJoCo in the suite; the dog and
# the stacker run with LAGRAX_ALL_ROBOTS=1
SLOW = {"dog", "stacker"}


@pytest.mark.parametrize(
    "name",
    [
        pytest.param(n, marks=every_robot("the quadruped and the manipulator hold them"))
        if n in SLOW
        else n
        for n in LOADS
    ],
)
def test_suite_file_matches_mujoco(name):
    robot, params = from_mjcf(SUITE / f"{name}.xml")
    # MuJoCo's friction loss is a constraint, off here: lagrax's is taken out too
    params = _without_friction(params)
    model = _compiled(name)
    if isinstance(robot, lx.chains.ConstrainedRobot):
        _constraints_against_mujoco(robot, params, name)
        robot = robot.robot  # the unconstrained robot against MuJoCo without equality
    assert _size(robot) == model.nq
    err_m, err_a = _against_mujoco(robot, params, model, seed=len(name))
    print(f"{name}: M {err_m:.1e}, qacc {err_a:.1e} relative to MuJoCo")
    assert err_m < RTOL and err_a < RTOL, (err_m, err_a)


def _constraints_against_mujoco(robot, params, name: str) -> None:
    """`φ(q)` at a random configuration equals MuJoCo's equality residuals (`efc_pos`
    with limits and contacts off: the equality rows alone)."""
    model = mujoco.MjModel.from_xml_path(str(SUITE / f"{name}.xml"))
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_LIMIT | off.mjDSBL_FRICTIONLOSS
    qpos = _random_qpos(model, np.random.default_rng(7))
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_forward(model, data)
    q, _ = from_mujoco_state(qpos, np.zeros(model.nv), robot)
    phi = np.asarray(robot.constraints(q, params))
    assert phi.shape == (data.nefc,) and rel_error(phi, data.efc_pos[: data.nefc]) < RTOL


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_suite_file_refused_names_the_construct(name):
    with pytest.raises(lx.MJCFError) as info:
        from_mjcf(SUITE / f"{name}.xml")
    for word in REFUSED[name]:
        assert word in str(info.value), str(info.value)


def test_lqr_as_the_task_builds_it_matches_mujoco():
    """``lqr.xml`` is a template: the task's ``lqr_6_2`` model (six slides with springs)
    loads and matches MuJoCo."""
    model = lqr_model(6, 2)
    robot, params = from_mjcf(model)
    assert robot.n == model.nq == 6 and params["stiffness"].shape == (6,)
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_CONSTRAINT | off.mjDSBL_ACTUATION
    err_m, err_a = _against_mujoco(robot, params, model, seed=5)
    assert err_m < RTOL and err_a < RTOL, (err_m, err_a)


def test_finger_friction_loss_is_coulomb_away_from_rest():
    """The finger's friction loss (0.1 on its ``hinge``): with it, ``M (q̈ − qacc) =
    −f sign(q̇)`` against MuJoCo's constraint-free ``qacc`` and ``mj_fullM`` at a state
    sliding faster than the stiction velocity."""
    robot, params = from_mjcf(SUITE / "finger.xml")
    model = _compiled("finger")
    f = np.asarray(model.dof_frictionloss)
    assert np.array_equal(np.asarray(params["frictionloss"]), f) and f[2] == 0.1
    data = mujoco.MjData(model)
    rng = np.random.default_rng(2)
    data.qpos[:] = model.qpos0 + rng.uniform(-0.5, 0.5, model.nq)
    data.qvel[:] = [0.3, -0.8, -0.5]
    data.qfrc_applied[:] = rng.uniform(-1.0, 1.0, model.nv)
    mujoco.mj_forward(model, data)
    m_mj = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, m_mj)
    qdd = robot.system().forward_dynamics(
        jnp.asarray(data.qpos), jnp.asarray(data.qvel), params, jnp.asarray(data.qfrc_applied)
    )
    force = m_mj @ (np.asarray(qdd) - data.qacc)
    assert np.max(np.abs(force + f * np.sign(data.qvel))) < 1e-12, force


def test_fish_without_fluid_matches_mujoco():
    """The fish with `opt.density = 0`: a free body, joint springs and the fixed tendons'
    springs (one of stiffness 1e-4), gravity disabled by the file."""
    model = _compiled("fish")
    model.opt.density = 0.0
    robot, params = from_mjcf(model)
    assert isinstance(robot, lx.chains.FloatingTree)
    assert params["tendon"].shape == (1, robot.n)  # the tendon with stiffness; the other none
    err_m, err_a = _against_mujoco(robot, params, model, seed=3)
    assert err_m < RTOL and err_a < RTOL, (err_m, err_a)


# Other real MJCF files we did not write: MJX's test models (the mujoco-mjx package)
WHEEL_LOADS = ["barkour_v0/assets/barkour_v0_mjx.xml", "tendon/tendon.xml", "convex.xml"]
WHEEL_REFUSED = {
    "tendon/armature.xml": "armature (inertia added to M along the tendon) 123 on tendon",
    "pendula.xml": "stiffness 0.1 on the ball joint 'joint1'",
    "quadratic_frictionloss.xml": "friction loss",
}


@pytest.mark.parametrize("path", WHEEL_LOADS)
def test_wheel_model_matches_mujoco(path):
    """Barkour (a free base with armature), MJX's tendon test model (tendons with
    limits and actuators only) and its four free bodies (``convex.xml``)."""
    robot, params = from_mjcf(mjx_test_data(path))
    model = mujoco.MjModel.from_xml_path(str(mjx_test_data(path)))
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_CONSTRAINT | off.mjDSBL_ACTUATION
    err_m, err_a = _against_mujoco(robot, params, model, seed=11)
    assert err_m < RTOL and err_a < RTOL, (err_m, err_a)


@pytest.mark.parametrize("path", sorted(WHEEL_REFUSED))
def test_wheel_model_refused_names_the_construct(path):
    with pytest.raises(lx.MJCFError, match=re.escape(WHEEL_REFUSED[path])):
        from_mjcf(mjx_test_data(path))
