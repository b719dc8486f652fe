"""`to_mujoco_acceleration` / `from_mujoco_acceleration` against MuJoCo's own `qacc`.

At random states (unit quaternions, contacts and limits off) lagrax's `v̇` converted by
`to_mujoco_acceleration` equals `mj_forward`'s `qacc`, and MuJoCo's `qacc` converted by
`from_mujoco_acceleration` equals lagrax's `v̇`, both to 1e-12 relative, on a floating
robot (`tests/mjcf/floating.xml`), a `Forest` (two free bodies, one with a joint below
it, and a robot fixed to the world between them), a tree of ball joints and ball joints
under a free joint (`test_ball_joints`' models). The two are inverse to each other, one
state or a batch; a free joint's linear part is not the plain rotation of `v̇` (the
base frame turns), so a conversion that dropped `ω × v` fails here.
"""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import rel_error
from lagrax.chains import (
    from_mujoco_acceleration,
    from_mujoco_state,
    to_mujoco_acceleration,
    to_mujoco_state,
)

mujoco = pytest.importorskip("mujoco", reason="MuJoCo's qacc is the reference")

from test_ball_joints import CHAIN, FREE  # noqa: E402  (after the skip: they need mujoco)

RTOL = 1e-12
N_STATES = 3

FOREST = """
<mujoco>
  <option><flag contact="disable" constraint="disable"/></option>
  <worldbody>
    <body name="a" pos="0.1 0 1" quat="0.9 0.1 -0.3 0.2"><freejoint name="fa"/>
      <geom type="box" size="0.2 0.1 0.05" pos="0.02 0.01 0" mass="2"/>
      <body name="a1" pos="0.2 0 0"><joint name="ja" axis="0.2 1 0.1" pos="0.01 0 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 -0.2" size="0.03" mass="0.4"/></body></body>
    <body name="arm" pos="0 1 0"><joint name="fixed_arm" axis="1 0 0"/>
      <geom type="capsule" fromto="0 0 0 0 0.3 0" size="0.04" mass="0.7"/></body>
    <body name="b" pos="0.5 0 1"><freejoint name="fb"/>
      <geom type="ellipsoid" size="0.05 0.08 0.12" pos="0.01 0 0.02" mass="0.5"/></body>
  </worldbody>
</mujoco>
"""

MODELS = {
    "floating": (Path(__file__).parent / "mjcf" / "floating.xml").read_text(),
    "forest": FOREST,
    "balls": CHAIN,
    "balls_on_a_free_joint": FREE,
}
KINDS = {
    "floating": lx.chains.FloatingTree,
    "forest": lx.chains.Forest,
    "balls": lx.chains.Tree,
    "balls_on_a_free_joint": lx.chains.FloatingTree,
}


def _random_states(model, rng, size):
    """`size` random MuJoCo `(qpos, qvel, qfrc_applied)`, every quaternion a unit one."""
    qpos = np.array(model.qpos0) + rng.uniform(-0.5, 0.5, (size, model.nq))
    for j in range(model.njnt):
        kind = model.jnt_type[j]
        if kind in (mujoco.mjtJoint.mjJNT_BALL, mujoco.mjtJoint.mjJNT_FREE):
            a = model.jnt_qposadr[j] + (3 if kind == mujoco.mjtJoint.mjJNT_FREE else 0)
            quat = rng.normal(size=(size, 4))
            qpos[:, a : a + 4] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    return qpos, rng.uniform(-2.0, 2.0, (size, model.nv)), rng.uniform(-1, 1, (size, model.nv))


@pytest.fixture(scope="module", params=list(MODELS))
def case(request):
    """`(name, robot, params, model, states, forward)`: the loaded robot, MuJoCo's model
    (contacts and limits off) and `N_STATES` states, and lagrax's `v̇` (jitted)."""
    name, xml = request.param, MODELS[request.param]
    robot, params = lx.chains.from_mjcf(xml)
    assert isinstance(robot, KINDS[name])
    model = mujoco.MjModel.from_xml_string(xml)
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_CONSTRAINT
    system = robot.system()
    forward = jax.jit(lambda q, v, tau: system.forward_dynamics(q, v, params, tau))
    states = _random_states(model, np.random.default_rng(7), N_STATES)
    return name, robot, params, model, states, forward


def test_the_conversions_match_mujocos_qacc(case):
    name, robot, _, model, (qposs, qvels, forces), forward = case
    data = mujoco.MjData(model)
    n_free = int(np.sum(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE))
    worst = {"to": 0.0, "from": 0.0, "plain rotation": np.inf}
    for qpos, qvel, force in zip(qposs, qvels, forces, strict=True):
        data.qpos[:], data.qvel[:], data.qfrc_applied[:] = qpos, qvel, force
        mujoco.mj_forward(model, data)
        q, v = from_mujoco_state(qpos, qvel, robot)
        _, tau = from_mujoco_state(qpos, force, robot)  # a force converts like v
        a = np.asarray(forward(q, v, tau))
        qacc = to_mujoco_acceleration(q, v, a, robot)
        back = from_mujoco_acceleration(qpos, qvel, data.qacc, robot)
        assert qacc.shape == a.shape and back.shape == a.shape
        worst["to"] = max(worst["to"], rel_error(qacc, data.qacc))
        worst["from"] = max(worst["from"], rel_error(back, a))
        # the velocity's conversion (R v̇ for the linear part) is not the acceleration's
        worst["plain rotation"] = min(
            worst["plain rotation"], rel_error(to_mujoco_state(q, a, robot)[1], data.qacc)
        )
    assert worst["to"] < RTOL and worst["from"] < RTOL, (name, worst)
    if n_free:
        assert worst["plain rotation"] > 1e-3, (name, worst)
    else:  # balls and joints only: the accelerations are the same in both
        assert rel_error(to_mujoco_acceleration(q, v, a, robot), a) == 0.0


def test_the_conversions_are_inverse_one_state_or_a_batch(case):
    _, robot, _, model, (qposs, qvels, _), _ = case
    rng = np.random.default_rng(8)
    q, v = from_mujoco_state(qposs, qvels, robot)  # a batch of N_STATES
    a = jnp.asarray(rng.normal(size=v.shape))
    qacc = to_mujoco_acceleration(q, v, a, robot)
    assert rel_error(from_mujoco_acceleration(qposs, qvels, qacc, robot), a) < 1e-14
    assert (
        rel_error(
            to_mujoco_acceleration(
                q, v, from_mujoco_acceleration(qposs, qvels, qacc, robot), robot
            ),
            qacc,
        )
        < 1e-14
    )
    for i in range(N_STATES):  # the batch converts as its states one by one
        one = to_mujoco_acceleration(q[i], v[i], a[i], robot)
        np.testing.assert_allclose(qacc[i], one, rtol=0, atol=1e-15 * float(jnp.abs(a).max()))


def test_bad_input_is_named():
    robot, _ = lx.chains.from_mjcf(MODELS["floating"])
    q, v = jnp.zeros(7 + robot.n).at[6].set(1.0), jnp.zeros(6 + robot.n)
    with pytest.raises(lx.ShapeError, match=r"a has shape \(3,\) but v has shape"):
        to_mujoco_acceleration(q, v, jnp.zeros(3), robot)
    with pytest.raises(lx.ShapeError, match=r"qacc has shape \(2, \d+\) but qvel has shape"):
        from_mujoco_acceleration(q, v, jnp.zeros((2, 6 + robot.n)), robot)
    with pytest.raises(lx.ShapeError, match="q must have 7 \\+ n entries"):
        to_mujoco_acceleration(q[:5], v[:5], v[:5], robot)
    with pytest.raises(lx.ArgumentTypeError, match="a must be an array of real numbers"):
        to_mujoco_acceleration(q, v, {"not": "an array"}, robot)
