"""MJCF import (``lagrax.chains.from_mjcf``) against MuJoCo itself, and on models it refuses.

- Three small models written for these tests (``tests/mjcf``: a 3-link hinge arm with
  joint anchors off the body origins, rotated bodies, a joint ``ref``, a welded body and
  tilted gravity; a cart-pole of slide and hinge joints in degrees with refs; a branched
  tree with a two-joint body, a slide and bodies welded to the world and to a moving
  body), a model of MJX's test data (the 24-joint Shadow hand, with its armature: the
  mujoco-mjx package) and the project's two URDF robots read by MuJoCo: ``M``
  against ``mj_fullM`` and ``q̈`` against ``mj_forward``'s ``qacc`` (contacts, limits and
  actuators off, ``qfrc_applied = τ``) at random states, in MuJoCo's own coordinates.
- A URDF read by MuJoCo equals the same URDF read by ``from_urdf``.
- A free joint makes a floating base (``tests/mjcf/floating.xml``; and a lone free body,
  with no joints), against MuJoCo through the state conversions.
- Constructs lagrax does not model raise ``MJCFError`` naming them.
"""

import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import _helpers
import lagrax as lx
from _helpers import mjx_test_data, rel_error
from lagrax.chains import from_mjcf, from_urdf
from lagrax.models import urdf_path

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is the reference for MJCF dynamics")

HERE = Path(__file__).parent / "mjcf"
RTOL = 1e-12
N_STATES = 3


def _rel(a, b) -> float:
    """`max |a − b| / max |b|`: relative to the matrix's own scale (a hand's `M` is
    ~1e-4, so `rel_error`'s floor of 1 would make it an absolute test)."""
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def _model(name):
    if name in ("arm7", "torso_two_arms"):
        return mujoco.MjModel.from_xml_path(str(urdf_path(name)))
    if name == "shadow_hand":
        path = mjx_test_data("shadow_hand/right_hand.xml")
        return mujoco.MjModel.from_xml_path(str(path))
    return mujoco.MjModel.from_xml_path(str(HERE / f"{name}.xml"))


@pytest.mark.parametrize(
    "name", ["arm3", "cartpole", "branched", "shadow_hand", "arm7", "torso_two_arms"]
)
def test_mass_matrix_and_accelerations_match_mujoco(name):
    model = _model(name)
    tree, params = from_mjcf(model)
    if name == "shadow_hand":  # armature: M gains diag(armature)
        np.testing.assert_array_equal(params["armature"], model.dof_armature)
        assert np.all(model.dof_armature > 0)
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_LIMIT | off.mjDSBL_ACTUATION
    assert tree.n == model.nv == model.nq
    system = tree.system()
    mass = jax.jit(jax.vmap(lambda q: system.mass_matrix(q, params)))
    forward = jax.jit(jax.vmap(lambda q, qd, tau: system.forward_dynamics(q, qd, params, tau)))
    rng = np.random.default_rng(tree.n)
    q = model.qpos0 + rng.uniform(-1.0, 1.0, (N_STATES, tree.n))
    qd, tau = (rng.uniform(-2.0, 2.0, (N_STATES, tree.n)) for _ in range(2))
    m_lx = np.asarray(mass(jnp.asarray(q)))
    a_lx = np.asarray(forward(jnp.asarray(q), jnp.asarray(qd), jnp.asarray(tau)))
    data = mujoco.MjData(model)
    worst_m = worst_a = 0.0
    for k in range(N_STATES):
        data.qpos[:], data.qvel[:], data.qfrc_applied[:] = q[k], qd[k], tau[k]
        mujoco.mj_forward(model, data)
        m_mj = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, m_mj)
        worst_m = max(worst_m, _rel(m_lx[k], m_mj))
        worst_a = max(worst_a, rel_error(a_lx[k], data.qacc))
    print(f"{name}: M {worst_m:.1e}, qacc {worst_a:.1e} relative to MuJoCo")
    assert worst_m < RTOL and worst_a < RTOL, (worst_m, worst_a)


def _check_floating_against_mujoco(robot, params, model, base: int, seed: int) -> None:
    """At random states (random unit quaternions and base positions, contacts off): `M`
    equals `Tᵀ M_mj T` (`T` takes the base's linear velocity from the base frame to
    MuJoCo's world frame) and `q̈` MuJoCo's `qacc` through `from_mujoco_state`; the
    conversions are inverse to each other (`base`: the free body's MuJoCo index)."""
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    system = robot.system()
    data = mujoco.MjData(model)
    rng = np.random.default_rng(seed)
    for _ in range(N_STATES):
        qpos = np.array(model.qpos0)
        qpos[:3] += rng.normal(size=3)
        quat = rng.normal(size=4)
        qpos[3:7] = quat / np.linalg.norm(quat)
        qpos[7:] += rng.uniform(-1.0, 1.0, robot.n)
        qvel, force = (rng.uniform(-2.0, 2.0, model.nv) for _ in range(2))
        data.qpos[:], data.qvel[:], data.qfrc_applied[:] = qpos, qvel, force
        mujoco.mj_forward(model, data)
        q, v = (np.asarray(x) for x in lx.chains.from_mujoco_state(qpos, qvel))
        back = lx.chains.to_mujoco_state(q, v)
        np.testing.assert_allclose(back[0], qpos, rtol=0, atol=1e-15)
        np.testing.assert_allclose(back[1], qvel, rtol=0, atol=1e-14)
        rot = data.xmat[base].reshape(3, 3)
        np.testing.assert_allclose(v[:3], rot.T @ qvel[:3], rtol=0, atol=1e-14)
        tau = np.concatenate([rot.T @ force[:3], force[3:]])  # a force converts like v
        a = np.asarray(system.forward_dynamics(jnp.asarray(q), jnp.asarray(v), params, tau))
        assert rel_error(lx.chains.to_mujoco_acceleration(q, v, a), data.qacc) < RTOL
        m_mj = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, m_mj)
        t = np.eye(model.nv)
        t[:3, :3] = rot
        m_lx = np.asarray(system.mass_matrix(jnp.asarray(q), params))
        assert _rel(m_lx, t.T @ m_mj @ t) < RTOL


def test_free_joint_is_a_floating_base_matching_mujoco():
    """``floating.xml``: a free torso (a welded head, legs of hinges and a slide, a floor
    welded to the world) is a `FloatingTree` equal to MuJoCo's model
    (`_check_floating_against_mujoco`)."""
    robot, params = from_mjcf(HERE / "floating.xml")
    assert isinstance(robot, lx.chains.FloatingTree)
    assert robot.joint_names == ("l_hip", "l_knee", "r_hip", "r_ankle")
    model = _model("floating")
    # the base carries the torso and the head, not the floor
    assert float(params["base_m"]) == pytest.approx(model.body_mass[2] + model.body_mass[3])
    _check_floating_against_mujoco(robot, params, model, base=2, seed=5)  # body 1: the floor


FREE_BODY = (
    "<mujoco><worldbody>"
    '<body name="drone" pos="0 0 1"><freejoint name="root"/>'
    '<geom type="box" size="0.3 0.2 0.05" pos="0.05 -0.02 0.01" euler="10 5 0" mass="1.5"/>'
    '<body name="camera" pos="0.25 0.1 -0.05"><geom size="0.04" mass="0.2"/></body>'
    "</body></worldbody></mujoco>"
)


def test_a_lone_free_body_is_a_floating_base_with_no_joints():
    """One body with only a free joint (a welded camera merged into it): a
    `FloatingTree` of no joints (`q` of size 7, `v` of size 6) equal to MuJoCo's model."""
    robot, params = from_mjcf(FREE_BODY)
    assert isinstance(robot, lx.chains.FloatingTree) and robot.n == 0
    assert robot.base_name == "drone" and robot.joint_names == ()
    assert float(params["base_m"]) == pytest.approx(1.7)
    model = mujoco.MjModel.from_xml_string(FREE_BODY)
    assert model.nq == 7 and model.nv == 6
    _check_floating_against_mujoco(robot, params, model, base=1, seed=6)


def test_several_free_bodies_and_a_fixed_robot_beside_them_are_a_forest():
    """Two free bodies, and a robot fixed to the world beside a floating one, load as a
    `Forest` of their parts in MuJoCo's order (held to MuJoCo in test_mjcf_equality); a
    free joint with damping is still refused by name."""
    two = _xml(
        '<body name="a"><freejoint name="fa"/><geom size="0.1"/>'
        '<body name="a1"><joint name="ja"/><geom size="0.1"/></body></body>'
        '<body name="b"><freejoint name="fb"/><geom size="0.1"/></body>'
    )
    forest, params = from_mjcf(two)
    assert isinstance(forest, lx.chains.Forest) and forest.names == ("a", "b")
    assert [p.n for p in forest.parts] == [1, 0] and len(params) == 2
    beside = _xml(
        '<body name="a"><freejoint name="fa"/><geom size="0.1"/>'
        '<body name="a1"><joint name="ja"/><geom size="0.1"/></body></body>'
        '<body name="arm"><joint name="fixed_arm"/><geom size="0.1"/></body>'
    )
    forest, _ = from_mjcf(beside)
    assert isinstance(forest.parts[1], lx.chains.Tree)
    assert forest.joint_names == ("ja", "fixed_arm")
    damped = two.replace('<freejoint name="fa"/>', '<joint name="fa" type="free" damping="1"/>')
    damped = damped[: damped.index('<body name="b">')] + "</worldbody></mujoco>"
    with pytest.raises(lx.MJCFError, match="damping on the free joint 'fa'"):
        from_mjcf(damped)


def test_floating_mjcf_stops_its_joints_at_their_limits():
    """A free base with a limited knee (`limits="impact"`, restitution 0.5): the knee's
    event sees the joint at `q[7 + 1]`; the knee, driven at its stop, hits it, never
    passes it, and the hit leaves the momentum of the whole robot unchanged (zero
    gravity)."""
    text = (HERE / "floating.xml").read_text()
    text = text.replace('ref="20"/>', 'ref="20" range="-30 30"/>')
    text = text.replace('gravity="0 0 -9.81"', 'gravity="0 0 0"')
    robot, params = from_mjcf(text, limits="impact", restitution=0.5)
    assert float(params["restitution"][1]) == 0.5 and params["restitution"].shape == (4,)
    [event] = lx.chains.limit_events(robot)
    system = robot.system()
    q = np.zeros(7 + robot.n)
    q[6] = 1.0
    q[8] = np.deg2rad(29.0)  # the knee just inside its upper stop (ref folded in)
    v = np.zeros(6 + robot.n)
    v[7] = 2.0  # the knee towards the stop
    sol = lx.simulate(system, q, v, params, t1=0.2, events=[event], rtol=1e-10, atol=1e-10)
    hit = sol.events[0]
    assert int(hit.count) >= 1
    t_hit = float(hit.times[0])
    assert 0.0 < t_hit < 0.2
    finite = np.isfinite(np.asarray(sol.q[:, 8]))
    assert np.max(np.asarray(sol.q[:, 8])[finite]) <= np.deg2rad(30.0) + 1e-9
    h = jax.vmap(lambda a, b: system.momentum(a, b, params))(sol.q, sol.qd)
    assert rel_error(h[-1], h[0]) < 1e-8


def test_a_body_with_two_joints_is_a_chain_of_tree_bodies():
    """``branched.xml``'s "left" body has two hinges: a massless tree body for the first,
    the body's inertia on the second (its dynamics are checked against MuJoCo above)."""
    tree, params = from_mjcf(HERE / "branched.xml")
    assert tree.joint_names == ("waist", "l_pitch", "l_roll", "l_elbow", "r_pitch", "r_extend")
    assert tree.body_names[1:3] == ("left/l_pitch", "left")
    assert tree.parents == (-1, 0, 1, 2, 0, 4) and tree.joint_types == "RRRRRP"
    assert float(params["m"][1]) == 0.0 and float(params["m"][2]) > 0.0
    # "stand" is welded to the world (dropped), "head" to the torso (merged)
    assert float(params["m"][0]) == pytest.approx(3.0 + 0.7, rel=1e-14)


def test_structure_names_limits_and_gravity():
    tree, params = from_mjcf(HERE / "arm3.xml")
    assert tree.joint_names == ("shoulder", "elbow", "wrist")
    assert tree.body_names == ("upper", "fore", "hand")
    np.testing.assert_allclose(tree.limits, [(-2, 2), (-1.5, 1.8), (-1, 1)])
    np.testing.assert_allclose(params["damping"], [0.4, 0.0, 0.1])
    gravity = np.array([0.5, -2.0, -9.5])
    np.testing.assert_allclose(float(params["g"]), np.linalg.norm(gravity), rtol=1e-15)
    np.testing.assert_allclose(tree.up, -gravity / np.linalg.norm(gravity), rtol=1e-15)
    # the welded "sensor" body's mass is on "fore"
    assert float(params["m"][1]) == pytest.approx(0.8 + 0.2, rel=1e-15)
    assert tree.effort_limits == (np.inf, np.inf, 5.0)  # actuatorfrcrange="-4 5"
    cart, _ = from_mjcf((HERE / "cartpole.xml").read_text())  # XML text
    np.testing.assert_allclose(cart.limits[0], (-1.0, 1.0))
    assert cart.limits[1] == (-np.inf, np.inf)


def test_limits_impact_stops_the_joints_of_an_mjcf_model():
    """The cart's rail range [-1, 1] (slide, ref 0.25: in qpos) stops it; the pole's
    hinge is unlimited, so one event."""
    tree, params = from_mjcf(HERE / "cartpole.xml", limits="impact", restitution=0.25)
    np.testing.assert_allclose(params["restitution"], [0.25] * 3)
    (rail,) = lx.chains.limit_events(tree)
    q, qd = jnp.array([1.0, 0.2, 0.0]), jnp.array([1.5, -0.3, 0.1])
    assert float(rail.condition(0.0, q, qd, params)) == 0.0
    _, qd_after = rail.reset(0.0, q, qd, params)
    assert float(qd_after[0]) == pytest.approx(-0.25 * 1.5, rel=1e-13)


@pytest.mark.parametrize("name", ["arm7", "torso_two_arms"])
def test_urdf_read_by_mujoco_equals_from_urdf(name):
    """MuJoCo's URDF reader and lagrax's agree: same joints, limits, damping and
    dynamics (MuJoCo diagonalizes each inertia: equal to rounding)."""
    t_mj, p_mj = from_mjcf(urdf_path(name))
    t_ur, p_ur = from_urdf(urdf_path(name))
    assert t_mj.joint_names == t_ur.joint_names
    assert t_mj.joint_types == t_ur.joint_types and t_mj.parents == t_ur.parents
    np.testing.assert_allclose(t_mj.limits, t_ur.limits, rtol=1e-15)
    np.testing.assert_allclose(p_mj["damping"], p_ur["damping"], rtol=1e-15)
    rng = np.random.default_rng(7)
    q, qd, tau = (jnp.asarray(rng.uniform(-1, 1, t_ur.n)) for _ in range(3))
    s_mj, s_ur = t_mj.system(), t_ur.system()
    assert _rel(s_mj.mass_matrix(q, p_mj), s_ur.mass_matrix(q, p_ur)) < RTOL
    a_mj = s_mj.forward_dynamics(q, qd, p_mj, tau)
    assert rel_error(a_mj, s_ur.forward_dynamics(q, qd, p_ur, tau)) < RTOL


# ------------------------------------------------------------------ refused constructs
def _xml(body: str, extra: str = "") -> str:
    return f"<mujoco><worldbody>{body}</worldbody>{extra}</mujoco>"


ARM = '<body name="b1"><joint name="j1" axis="0 1 0"/><geom size="0.1" mass="1"/></body>'
FREE = '<body name="b0"><freejoint/><geom size="0.1" mass="1"/></body>'
BAD = {
    "ball joint stiffness": (
        _xml(
            '<body name="b"><joint name="hip" type="ball" stiffness="2"/><geom size="0.1"/></body>'
        ),
        ["stiffness 2 on the ball joint 'hip'"],
    ),
    "free joint armature": (
        _xml(FREE.replace("<freejoint/>", '<joint name="root" type="free" armature="0.25"/>')),
        ["armature on the free joint 'root'", "ignore_unsupported"],
    ),
    "free joint stiffness": (
        _xml(FREE.replace("<freejoint/>", '<joint name="root" type="free" stiffness="2"/>')),
        ["stiffness on the free joint 'root'"],
    ),
    "spatial tendon": (
        _xml(
            ARM.replace('mass="1"/>', 'mass="1"/><site name="s1" pos="0.3 0 0"/>')
            + '<site name="s0" pos="0 0 0.5"/>',
            '<tendon><spatial name="t1" stiffness="10"><site site="s0"/><site site="s1"/>'
            "</spatial></tendon>",
        ),
        ["spatial tendon 't1'", "stiffness 10", "fixed tendons only"],
    ),
    "tendon armature": (
        _xml(
            ARM,
            '<tendon><fixed name="t1" armature="0.2"><joint joint="j1" coef="1"/></fixed></tendon>',
        ),
        ["armature (inertia added to M along the tendon) 0.2 on tendon 't1'"],
    ),
    "dead-band tendon spring": (
        _xml(
            ARM,
            '<tendon><fixed name="t1" stiffness="1" springlength="0.1 0.3">'
            '<joint joint="j1" coef="1"/></fixed></tendon>',
        ),
        ["a dead-band spring length [0.1, 0.3] on tendon 't1'"],
    ),
    "tendon friction loss": (
        _xml(
            ARM,
            '<tendon><fixed name="t1" frictionloss="0.5"><joint joint="j1" coef="1"/></fixed>'
            "</tendon>",
        ),
        ["friction loss (a constraint) 0.5 on tendon 't1'"],
    ),
    "gravcomp": (_xml(ARM.replace('name="b1"', 'name="b1" gravcomp="1"')), ["gravity comp"]),
    "no joint": (
        _xml('<body name="b"><geom size="0.1"/></body>'),
        ["no hinge or slide joint and no free joint"],
    ),
    "mujoco refuses": (
        "<mujoco><worldbody><body><joint type='twist'/></body></worldbody></mujoco>",
        ["twist"],
    ),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_refused_constructs_are_named(case):
    text, words = BAD[case]
    with pytest.raises(lx.MJCFError) as info:
        from_mjcf(text)
    for word in words:
        assert word in str(info.value), str(info.value)
    assert isinstance(info.value, lx.LagraxError)


def test_ignore_unsupported_drops_with_a_warning():
    text = _xml(ARM.replace('name="b1"', 'name="b1" gravcomp="1"'))
    with pytest.warns(UserWarning, match="gravity compensation"):
        tree, _ = from_mjcf(text, ignore_unsupported=True)
    assert tree.joint_names == ("j1",)
    ball = '<body name="b"><joint name="hip" type="ball"/><geom size="0.1"/></body>'
    with pytest.raises(lx.MJCFError, match="ball joint 'hip'"):  # still: not modelled
        from_mjcf(
            _xml(ball, '<equality><connect body1="b" body2="world" anchor="0 0 0"/></equality>'),
            ignore_unsupported=True,
        )


def test_missing_file_and_missing_mujoco(monkeypatch, tmp_path):
    # a lagrax error, and the builtin it refines
    with pytest.raises(lx.MissingFileError, match="nowhere.xml") as caught:
        from_mjcf(tmp_path / "nowhere.xml")
    assert isinstance(caught.value, FileNotFoundError)
    with pytest.raises(lx.MissingFileError, match="nowhere.urdf"):
        from_urdf(tmp_path / "nowhere.urdf")
    monkeypatch.setitem(sys.modules, "mujoco", None)
    with pytest.raises(lx.MJCFError, match="pip install mujoco"):
        from_mjcf(_xml(ARM))


def test_a_missing_reference_file_fails_in_ci_and_skips_elsewhere(monkeypatch):
    """MJX's test models are found where the mujoco-mjx package puts them; one that is
    missing fails the test under CI (`CI=true`: `.ci/run`) and skips it elsewhere."""
    assert mjx_test_data("shadow_hand/right_hand.xml").is_file()
    monkeypatch.setattr(_helpers, "IN_CI", True)
    with pytest.raises(pytest.fail.Exception, match="CI: a reference .* missing: MJX's"):
        mjx_test_data("no_such_model.xml")
    monkeypatch.setattr(_helpers, "IN_CI", False)
    with pytest.raises(pytest.skip.Exception, match="pip install mujoco-mjx"):
        mjx_test_data("no_such_model.xml")
