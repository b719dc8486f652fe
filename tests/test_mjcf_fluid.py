"""MuJoCo's inertia-box fluid model as ``lagrax.chains.mjcf_fluid``'s applied force.

- The swimmer as its task builds it (6 links on a planar base of two slides and a
  hinge) and the fish (a free body with 7 hinges), with the files' density and a
  viscosity and wind added (every term of the model acts): the generalized force
  against MuJoCo's ``qfrc_fluid`` at a random state, to round-off; the fish through
  ``from_mujoco_state`` (the base's force rotated as its velocity is).
- Dissipative: without wind the force's power ``q̇·τ`` is negative.
- ``fluid.derivatives``: the analytic ``∂τ/∂q̇`` against ``jax.jacfwd`` of the force, and
  ``∂τ/∂q``, ``∂τ/∂q̇`` against central differences of MuJoCo's ``qfrc_fluid``.
- The shipped files are refused by ``from_mjcf``, naming the fluid and ``mjcf_fluid``,
  and load through it; MuJoCo's ellipsoid model is refused by name.
"""

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import rel_error
from lagrax.chains import from_mjcf, from_mujoco_state, mjcf_fluid

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is the reference for its fluid model")
with warnings.catch_warnings():
    warnings.simplefilter("ignore")  # dm_control's renderer looks for a display
    suite = pytest.importorskip("dm_control.suite", reason="dm_control ships the models")
    fish = pytest.importorskip("dm_control.suite.fish")
    swimmer = pytest.importorskip("dm_control.suite.swimmer")


def _model(name: str, viscosity: float = 0.3, wind=(0.2, -0.4, 0.1)):
    xml, assets = (
        swimmer.get_model_and_assets(6) if name == "swimmer" else fish.get_model_and_assets()
    )
    model = mujoco.MjModel.from_xml_string(xml, assets)
    model.opt.viscosity, model.opt.wind[:] = viscosity, wind
    return model


def _state(model, seed: int):
    data = mujoco.MjData(model)
    _state_into(model, data, np.random.default_rng(seed))
    free = int(model.jnt_type[0]) == 0
    if not free:
        return jnp.asarray(data.qpos), jnp.asarray(data.qvel), np.array(data.qfrc_fluid)
    q, v = from_mujoco_state(data.qpos, data.qvel)
    rot = data.xmat[model.jnt_bodyid[0]].reshape(3, 3)
    ref = np.concatenate([rot.T @ data.qfrc_fluid[:3], data.qfrc_fluid[3:]])
    return q, v, ref


@pytest.mark.parametrize("name", ["swimmer", "fish"])
def test_fluid_force_matches_mujoco(name):
    model = _model(name)
    robot, params, fluid = mjcf_fluid(model)
    assert isinstance(robot, lx.chains.FloatingTree) == (name == "fish")
    force = jax.jit(lambda q, v, p: fluid(q, v, p))
    for seed in range(2):
        q, v, ref = _state(model, seed)
        err = np.max(np.abs(np.asarray(force(q, v, params)) - ref)) / np.max(np.abs(ref))
        assert err < 1e-12, err


def test_fluid_force_dissipates():
    model = _model("swimmer", wind=(0.0, 0.0, 0.0))
    _, params, fluid = mjcf_fluid(model)
    q, v, _ = _state(model, 3)
    force = jax.jit(lambda q, v, p: fluid(q, v, p))
    for scale in (0.1, 1.0, 3.0):
        assert float(v @ force(q, scale * v, params)) < 0.0


def _mujoco_jacobians(model, qpos, qvel, h=1e-6):
    """Central differences of MuJoCo's `qfrc_fluid` in `qpos` (hinges and slides only)
    and in `qvel`: `(∂/∂qpos, ∂/∂qvel)`."""
    data = mujoco.MjData(model)

    def at(pos, vel):
        data.qpos[:], data.qvel[:] = pos, vel
        mujoco.mj_forward(model, data)
        return np.array(data.qfrc_fluid)

    e_q, e_v = np.eye(model.nq), np.eye(model.nv)
    d_q = [(at(qpos + h * e, qvel) - at(qpos - h * e, qvel)) / (2 * h) for e in e_q]
    d_v = [(at(qpos, qvel + h * e) - at(qpos, qvel - h * e)) / (2 * h) for e in e_v]
    return np.stack(d_q, axis=1), np.stack(d_v, axis=1)


@pytest.mark.parametrize("name", ["swimmer", "fish"])
def test_fluid_derivatives_match_autodiff_and_mujoco(name):
    """`fluid.derivatives`: `∂τ/∂q̇` (analytic) against `jax.jacfwd` of the force to
    round-off, symmetric and negative semi-definite; both Jacobians against MuJoCo's
    `qfrc_fluid` by central differences (the fish's `∂τ/∂q̇` congruent by the base's
    rotation, `τ` and `v` converting alike; its `∂τ/∂q` in the quaternion is left out)."""
    model = _model(name)
    _, params, fluid = mjcf_fluid(model)
    q, v, _ = _state(model, 4)
    d_q, d_v = jax.jit(lambda a, b: fluid.derivatives(a, b, params))(q, v)
    ref_v = jax.jit(jax.jacfwd(lambda a, b: fluid(a, b, params), argnums=1))(q, v)
    assert rel_error(d_v, ref_v) < 1e-13
    assert rel_error(d_v, d_v.T) < 1e-13 and float(jnp.max(jnp.linalg.eigvalsh(d_v))) < 1e-12
    data = mujoco.MjData(model)
    rng = np.random.default_rng(4)  # the state `_state` drew, in MuJoCo's coordinates
    _state_into(model, data, rng)
    fd_q, fd_v = _mujoco_jacobians(model, np.array(data.qpos), np.array(data.qvel))
    if name == "swimmer":
        assert rel_error(d_q, fd_q) < 1e-8 and rel_error(d_v, fd_v) < 1e-8
        return
    t = np.eye(model.nv)
    t[:3, :3] = data.xmat[model.jnt_bodyid[0]].reshape(3, 3)
    assert rel_error(d_v, t.T @ fd_v @ t) < 1e-8


def _state_into(model, data, rng) -> None:
    """`_state`'s random MuJoCo state, set in `data`."""
    free = int(model.jnt_type[0]) == 0
    data.qpos[:] = model.qpos0
    if free:
        quat = rng.normal(size=4)
        data.qpos[3:7] = quat / np.linalg.norm(quat)
    data.qpos[7 if free else 0 :] += rng.uniform(-0.5, 0.5, model.nq - (7 if free else 0))
    data.qvel[:] = rng.uniform(-1.0, 1.0, model.nv)
    mujoco.mj_forward(model, data)


def test_shipped_files_point_to_mjcf_fluid():
    path = suite.__path__[0] + "/swimmer.xml"
    with pytest.raises(lx.MJCFError, match="fluid forces .*mjcf_fluid"):
        from_mjcf(path)
    robot, _, fluid = mjcf_fluid(path)
    assert robot.n == 3 and fluid.box.shape == (1, 3)  # the head on its planar base


def test_ellipsoid_fluid_model_is_refused():
    text = """<mujoco><option density="1000"/><worldbody><body><joint axis="0 0 1"/>
      <geom type="box" size="0.1 0.05 0.02" fluidshape="ellipsoid"/></body></worldbody>
      </mujoco>"""
    with pytest.raises(lx.MJCFError, match="ellipsoid fluid model"):
        mjcf_fluid(text)
