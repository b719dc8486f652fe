"""MuJoCo's actuators as ``lagrax.chains.mjcf_actuation``: ``ctrl`` to ``τ``.

- Every DeepMind Control Suite file with actuators (and the model the lqr task builds):
  ``τ`` and the actuators' forces for a random ``ctrl`` (half again beyond
  ``ctrlrange`` on each side, so the clamp acts) at a random state against MuJoCo's
  ``qfrc_actuator`` and ``actuator_force``, to round-off; a floating model through
  ``from_mujoco_state``. Motors, position servos (the fish), fixed tendons (point_mass,
  manipulator, stacker, fish). The dog and the quadruped (activation filters) are refused
  by name.
- A model written for this test: position and velocity servos, a general actuator with
  an affine gain, ``forcerange``, a joint's ``actuatorfrcrange`` and a geared fixed
  tendon, against MuJoCo the same way.
- A control sequence drives lagrax as it drives MuJoCo: the cartpole under a
  piecewise-constant ``ctrl`` (changed every 0.1 s) against MuJoCo's RK4 at a 1 ms step,
  contacts and constraints off.
"""

import os
import re
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import lqr_model
from lagrax.chains import from_mjcf, from_mujoco_state, mjcf_actuation

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is the reference for MJCF actuators")
dm_control = pytest.importorskip("dm_control", reason="dm_control ships the suite's MJCF files")

SUITE = Path(os.path.dirname(dm_control.__file__)) / "suite"
ACTUATED = [
    "acrobot",
    "ball_in_cup",
    "cartpole",
    "cheetah",
    "finger",
    "fish",
    "hopper",
    "humanoid",
    "humanoid_CMU",
    "manipulator",
    "pendulum",
    "point_mass",
    "reacher",
    "stacker",
    "walker",
]
REFUSED = {"dog": "'lumbar_extend' has activation dynamics", "quadruped": "activation dynamics"}


def test_the_lists_cover_the_suite_files_with_actuators():
    have = [p.stem for p in SUITE.glob("*.xml") if "<actuator>" in p.read_text()]
    assert sorted(have) == sorted(ACTUATED + list(REFUSED))


@jax.jit
def _evaluate(actuation, ctrl, q, v):
    return actuation(ctrl, q, v), actuation.force(ctrl, q, v)


def _against_mujoco(model, seed: int) -> tuple[float, float]:
    """`(τ error, force error)`, absolute, at a random state and `ctrl`."""
    actuation = mjcf_actuation(model)
    rng = np.random.default_rng(seed)
    data = mujoco.MjData(model)
    free = model.njnt and int(model.jnt_type[0]) == 0
    data.qpos[:] = model.qpos0
    data.qpos[7 if free else 0 :] += rng.uniform(-0.5, 0.5, model.nq - (7 if free else 0))
    data.qvel[:] = rng.uniform(-1.0, 1.0, model.nv)
    low, high = np.where(model.actuator_ctrllimited[:, None], model.actuator_ctrlrange, [-1, 1]).T
    data.ctrl[:] = rng.uniform(low - 0.5 * (high - low), high + 0.5 * (high - low))
    mujoco.mj_forward(model, data)
    if free:
        q, v = from_mujoco_state(data.qpos, data.qvel)
    else:
        q, v = jnp.asarray(data.qpos), jnp.asarray(data.qvel)
    tau, force = (np.asarray(x) for x in _evaluate(actuation, data.ctrl, q, v))
    scale = max(1.0, float(np.max(np.abs(data.qfrc_actuator))))
    return (
        float(np.max(np.abs(tau - data.qfrc_actuator))) / scale,
        float(np.max(np.abs(force - data.actuator_force))) / scale,
    )


@pytest.mark.parametrize("name", ACTUATED)
def test_suite_actuators_match_mujoco(name):
    model = mujoco.MjModel.from_xml_path(str(SUITE / f"{name}.xml"))
    err_tau, err_force = _against_mujoco(model, seed=len(name))
    assert err_tau < 1e-13 and err_force < 1e-13, (err_tau, err_force)


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_activation_dynamics_are_refused_by_name(name):
    with pytest.raises(lx.MJCFError, match=re.escape(REFUSED[name])):
        mjcf_actuation(SUITE / f"{name}.xml")


def test_lqr_motors_match_mujoco():
    assert max(_against_mujoco(lqr_model(6, 2), seed=4)) < 1e-13


SERVOS = """<mujoco><worldbody><body>
  <joint name="a" axis="0 1 0" actuatorfrcrange="-0.7 0.9"/>
  <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
  <body pos="0.3 0 0"><joint name="b" type="slide" axis="1 0 0"/>
    <geom size="0.05"/>
    <body><joint name="c" axis="0 0 1"/><geom type="box" size="0.1 0.05 0.02"/></body>
  </body>
</body></worldbody>
<tendon><fixed name="t"><joint joint="a" coef="0.5"/><joint joint="c" coef="-2"/></fixed></tendon>
<actuator>
  <position joint="a" kp="3" gear="2" ctrlrange="-1 1"/>
  <velocity joint="b" kv="0.8" forcerange="-0.3 0.4"/>
  <motor tendon="t" gear="1.5" ctrlrange="-2 2"/>
  <general joint="c" gaintype="affine" gainprm="0.5 0.2 -0.1" biastype="affine"
           biasprm="0.1 -0.4 -0.2" gear="0.7"/>
</actuator></mujoco>"""


def test_servos_ranges_and_a_tendon_match_mujoco():
    model = mujoco.MjModel.from_xml_string(SERVOS)
    for seed in range(3):
        assert max(_against_mujoco(model, seed)) < 1e-13


def test_a_control_sequence_drives_lagrax_as_mujoco():
    path = SUITE / "cartpole.xml"
    tree, params = from_mjcf(path)
    actuation = mjcf_actuation(path)
    ctrl = np.array([0.8, -1.0, 0.3, 1.5, -0.4])  # the last beyond ctrlrange: clamped

    def policy(t):
        return jnp.asarray(ctrl)[jnp.clip(jnp.floor(t / 0.1).astype(int), 0, 4)][None]

    q0, qd0 = np.array([0.1, 0.2]), np.array([0.0, -0.3])
    sol = lx.simulate(
        tree.system(), q0, qd0, params, t1=0.5, ts=[0.5], tau=actuation.tau(policy),
        rtol=1e-11, atol=1e-11,
    )  # fmt: skip
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    model.opt.integrator, model.opt.timestep = mujoco.mjtIntegrator.mjINT_RK4, 1e-3
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:] = q0, qd0
    for k in range(500):
        data.ctrl[:] = ctrl[k // 100]
        mujoco.mj_step(model, data)
    assert bool(sol.ok)
    assert np.max(np.abs(np.asarray(sol.q[-1]) - data.qpos)) < 1e-8, (sol.q[-1], data.qpos)
    assert np.max(np.abs(np.asarray(sol.qd[-1]) - data.qvel)) < 1e-8
