"""MuJoCo's equality constraints and several free bodies, read by ``from_mjcf``.

- The constraint functions against MuJoCo: ``φ(q)`` equals MuJoCo's equality residual
  ``efc_pos`` and lagrax's constraint matrix its Jacobian ``efc_J``, for ``connect`` and
  ``weld`` (body and site semantics, an anchor, a ``relpose``, a ``torquescale``),
  ``joint`` (a quartic ``polycoef``) and ``tendon`` (fixed tendons) equalities, at random
  configurations of a small model.
- The constrained accelerations: against a hand reduction (a joint coupled to another
  by a quadratic, ``q₂ = f(q₁)``, so ``q̈ = T s̈ + c``), and against the KKT system built
  from MuJoCo's ``M``, bias and ``efc_J`` for linear couplings.
- A ball on a string hanging from a free box (two free bodies, a ``connect``): the
  unconstrained forest's ``v̇`` against ``mj_forward`` with equality disabled, the
  MuJoCo state conversions both ways, and the constraint residual at round-off over a
  short simulation (the floating bases' quaternions on the unit sphere).
- Bad input: an equality on a spatial tendon (refused by name, or dropped with a
  warning).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import rel_error
from lagrax.chains import from_mjcf, from_mujoco_state, to_mujoco_acceleration, to_mujoco_state

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is the reference for MJCF dynamics")

RTOL = 1e-10

# two robots fixed to the world (a 2-link arm; a hinge with a slide) and every kind of
# equality between them: far more rows than coordinates (compared row by row with
# MuJoCo, never solved)
COUPLED = """
<mujoco>
  <option jacobian="dense"/>
  <worldbody>
    <body name="a1" pos="0 0 1">
      <joint name="j1" type="hinge" axis="0 1 0" ref="0.1"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
      <body name="a2" pos="0.5 0 0" quat="0.9 0.1 0.3 0.2">
        <joint name="j2" type="hinge" axis="0 0.6 0.8" pos="0.02 0 0"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
        <site name="s2" pos="0.4 0.01 0" quat="0.9 0.1 0.2 0.3"/>
      </body>
    </body>
    <body name="b1" pos="1 0 1" euler="10 20 30">
      <joint name="k1" type="hinge" axis="0 1 0"/>
      <joint name="k2" type="slide" axis="1 0 0" ref="0.05"/>
      <geom type="box" size="0.1 0.05 0.05" pos="0.2 0 0"/>
      <site name="t1" pos="0.1 0 0.02" quat="0.8 0.3 0.1 0.2"/>
    </body>
  </worldbody>
  <tendon>
    <fixed name="ta"><joint joint="j1" coef="1"/><joint joint="j2" coef="-0.5"/></fixed>
    <fixed name="tb"><joint joint="k1" coef="2"/><joint joint="k2" coef="0.3"/></fixed>
  </tendon>
  <equality>
    <connect name="pin" body1="a2" body2="b1" anchor="0.4 0 0"/>
    <weld name="glue" body1="a2" body2="b1" anchor="0.1 0.2 0" torquescale="2"/>
    <weld body1="b1" relpose="0.1 0.2 0.3 0.9 0.1 0.2 0.3"/>
    <connect site1="s2" site2="t1"/>
    <weld site1="s2" site2="t1" torquescale="0.5"/>
    <joint joint1="j2" joint2="k1" polycoef="0.1 0.5 0.2 0.1 0.05"/>
    <joint joint1="k2" polycoef="0.2 0 0 0 0"/>
    <tendon tendon1="ta" tendon2="tb" polycoef="0 1.5 0.3 0 0"/>
  </equality>
</mujoco>
"""


def _mujoco_rows(model, qpos, qvel=None):
    """MuJoCo's equality rows at `qpos`: `(efc_pos, efc_J)` (limits, contact off)."""
    model.opt.disableflags |= (
        mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_LIMIT
    )
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    if qvel is not None:
        data.qvel[:] = qvel
    mujoco.mj_forward(model, data)
    n = data.nefc
    return np.array(data.efc_pos[:n]), np.array(data.efc_J[: n * model.nv]).reshape(n, model.nv)


def test_constraints_are_mujocos_residuals_and_jacobians():
    robot, params = from_mjcf(COUPLED)
    assert isinstance(robot, lx.chains.ConstrainedRobot)
    assert robot.constraint_names[:2] == ("pin", "glue")
    model = mujoco.MjModel.from_xml_string(COUPLED)
    system = robot.system()
    phi = jax.jit(lambda q: system.violation(q, params))
    jac = jax.jit(lambda q: system.constraint_matrix(q, params))
    rng = np.random.default_rng(0)
    for _ in range(3):
        qpos = model.qpos0 + rng.uniform(-0.4, 0.4, model.nq)
        pos, jac_mj = _mujoco_rows(model, qpos)
        assert pos.shape == (3 + 6 + 6 + 3 + 6 + 1 + 1 + 1,)
        assert rel_error(phi(jnp.asarray(qpos)), pos) < RTOL
        assert rel_error(jac(jnp.asarray(qpos)), jac_mj) < RTOL


# two hinges, the second coupled to the first by a quadratic (MuJoCo's joint equality)
QUADRATIC = """
<mujoco>
  <option jacobian="dense"/>
  <worldbody>
    <body pos="0 0 1">
      <joint name="h1" type="hinge" axis="0 1 0" ref="10" damping="0.1"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
      <body pos="0.5 0 0">
        <joint name="h2" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04"/>
      </body>
    </body>
    <body pos="1 0 1">
      <joint name="h3" type="hinge" axis="1 0 0"/>
      <joint name="h4" type="slide" axis="0 0 1"/>
      <geom type="box" size="0.1 0.05 0.05" pos="0 0.2 0"/>
    </body>
  </worldbody>
  <tendon>
    <fixed name="t34"><joint joint="h3" coef="1"/><joint joint="h4" coef="-2"/></fixed>
  </tendon>
  <equality>
    <joint joint1="h2" joint2="h1" polycoef="0.05 0.7 0.4 0 0"/>
    <tendon tendon1="t34" polycoef="0.1 0 0 0 0"/>
  </equality>
</mujoco>
"""


def _mujoco_terms(model, qpos, qvel, force):
    """`(M, bias, efc_J)` of MuJoCo at a state (`bias = qfrc_bias + damping`), and its
    unconstrained `qacc` with equality disabled."""
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_LIMIT
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:], data.qfrc_applied[:] = qpos, qvel, force
    mujoco.mj_forward(model, data)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    bias = np.array(data.qfrc_bias) - np.array(data.qfrc_passive)
    jac = np.array(data.efc_J[: data.nefc * model.nv]).reshape(data.nefc, model.nv)
    return mass, bias, jac


@pytest.fixture(scope="module")
def quadratic():
    robot, params = from_mjcf(QUADRATIC)
    system = robot.system()
    forward = jax.jit(lambda q, v, f: system.forward_dynamics(q, v, params, f))
    return mujoco.MjModel.from_xml_string(QUADRATIC), forward


def test_constrained_accelerations_match_a_hand_reduction(quadratic):
    """`h2 = a0 + a1 d + a2 d²` with `d = h1 − r1` (`r1` h1's `ref`): `(h1, h2) = (s, f(s))`,
    `q̇ = T ṡ`, `q̈ = T s̈ + c` with `T = (1, f'(s))`, `c = (0, 2 a2 ṡ²)`, and
    `s̈ = (TᵀMT)⁻¹ Tᵀ(τ − b − M c)` from MuJoCo's `M` and bias (the other robot held by
    its own, linear, tendon coupling: `h3 − 2 h4 = 0.1`, reduced the same way)."""
    model, forward = quadratic
    rng = np.random.default_rng(1)
    a0, a1, a2 = 0.05, 0.7, 0.4
    ref = model.qpos0[0]  # h1's ref, 10 degrees
    s, sd = ref + rng.uniform(-0.5, 0.5), rng.uniform(-1, 1)
    d = s - ref
    h4, h4d = rng.uniform(-0.3, 0.3), rng.uniform(-1, 1)
    qpos = np.array([s, a0 + a1 * d + a2 * d**2, 0.1 + 2 * h4, h4])
    slope = a1 + 2 * a2 * d
    qvel = np.array([sd, slope * sd, 2 * h4d, h4d])
    force = rng.uniform(-1, 1, 4)
    mass, bias, _ = _mujoco_terms(model, qpos, qvel, force)
    t = np.array([[1.0, 0.0], [slope, 0.0], [0.0, 2.0], [0.0, 1.0]])
    c = np.array([0.0, 2 * a2 * sd**2, 0.0, 0.0])
    sdd = np.linalg.solve(t.T @ mass @ t, t.T @ (force - bias - mass @ c))
    qacc = forward(jnp.asarray(qpos), jnp.asarray(qvel), jnp.asarray(force))
    assert rel_error(qacc, t @ sdd + c) < RTOL


def test_constrained_accelerations_match_the_kkt_system_of_mujocos_terms(quadratic):
    """With `φ = 0` and `J q̇ = 0` the Baumgarte terms vanish; for the linear tendon
    coupling `J̇ = 0`, so the constrained `q̈` of the tendon's robot solves `[[M, Jᵀ],
    [J, 0]] (q̈, −λ) = (τ − b, −J̇ q̇)` with MuJoCo's `M`, bias and `efc_J` (the quadratic
    coupling's `J̇ q̇ = −2 a2 ḣ1²` on its row)."""
    model, forward = quadratic
    rng = np.random.default_rng(2)
    d, dd = rng.uniform(-0.4, 0.4), rng.uniform(-1, 1)
    h4, h4d = rng.uniform(-0.3, 0.3), rng.uniform(-1, 1)
    qpos = np.array([model.qpos0[0] + d, 0.05 + 0.7 * d + 0.4 * d**2, 0.1 + 2 * h4, h4])
    qvel = np.array([dd, (0.7 + 0.8 * d) * dd, 2 * h4d, h4d])
    force = rng.uniform(-1, 1, 4)
    mass, bias, jac = _mujoco_terms(model, qpos, qvel, force)
    gamma = np.array([2 * 0.4 * dd**2, 0.0])  # −J̇ q̇ of the two rows
    kkt = np.block([[mass, jac.T], [jac, np.zeros((2, 2))]])
    expected = np.linalg.solve(kkt, np.concatenate([force - bias, gamma]))[:4]
    qacc = forward(jnp.asarray(qpos), jnp.asarray(qvel), jnp.asarray(force))
    assert rel_error(qacc, expected) < RTOL


# a ball on a string (a massless rod: a connect at the string's length) hanging from a
# free box, with a hinged flap on a third, fixed, robot between them in the body order
STRING = """
<mujoco>
  <worldbody>
    <body name="box" pos="0 0 2" euler="5 10 15">
      <freejoint name="box_root"/>
      <geom type="box" size="0.2 0.1 0.05" mass="2"/>
      <body name="lid" pos="0.1 0 0.1"><geom type="sphere" size="0.05" mass="0.3"/></body>
    </body>
    <body name="flap" pos="1 0 1">
      <joint name="flap_hinge" type="hinge" axis="0 1 0"/>
      <geom type="box" size="0.1 0.05 0.01" pos="0.1 0 0"/>
    </body>
    <body name="ball" pos="0.3 0.1 1.4">
      <freejoint name="ball_root"/>
      <geom type="sphere" size="0.05" mass="0.5"/>
    </body>
  </worldbody>
  <equality>
    <connect name="string" body1="ball" body2="box" anchor="-0.3 -0.1 0.6"/>
  </equality>
</mujoco>
"""


@pytest.fixture(scope="module")
def string():
    robot, params = from_mjcf(STRING)
    return robot, params, mujoco.MjModel.from_xml_string(STRING)


def test_several_free_bodies_form_a_forest_in_mujocos_order(string):
    robot, params, model = string
    forest = robot.robot
    assert isinstance(forest, lx.chains.Forest)
    assert [type(p).__name__ for p in forest.parts] == ["FloatingTree", "Tree", "FloatingTree"]
    assert forest.names == ("box", "world", "ball")
    system = forest.system()
    assert (system.n_configuration, system.n_dof) == (model.nq, model.nv)
    assert system.configuration_names[:4] == ("box_x", "box_y", "box_z", "box_qx")
    assert float(params[0]["base_m"]) == pytest.approx(2.3)  # the lid welded to the box
    # the unconstrained forest against MuJoCo with equality disabled
    rng = np.random.default_rng(3)
    qpos = np.array(model.qpos0)
    for a in (0, 8):
        qpos[a : a + 3] += rng.normal(size=3)
        quat = rng.normal(size=4)
        qpos[a + 3 : a + 7] = quat / np.linalg.norm(quat)
    qpos[7] = 0.4
    qvel, force = rng.uniform(-1, 1, model.nv), rng.uniform(-1, 1, model.nv)
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_EQUALITY
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:], data.qfrc_applied[:] = qpos, qvel, force
    mujoco.mj_forward(model, data)
    q, v = from_mujoco_state(qpos, qvel, robot)
    _, tau = from_mujoco_state(qpos, force, robot)
    back = to_mujoco_state(q, v, robot)
    assert rel_error(back[0], qpos) < 1e-15 and rel_error(back[1], qvel) < 1e-15
    a = system.forward_dynamics(q, v, params, tau)
    qacc = to_mujoco_acceleration(q, v, a, robot)  # every free joint's, where it is
    assert rel_error(qacc, data.qacc) < RTOL
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    assert np.all(np.asarray(system.mass_matrix(q, params))[:6, 6:] == 0)  # block-diagonal


def test_a_ball_on_a_string_keeps_its_length(string):
    """The connect solved exactly: the residual stays at round-off over a simulation
    (Baumgarte-stabilized, the floating bases' quaternions renormalized), and the energy
    is conserved."""
    robot, params, model = string
    system = robot.system()
    qpos, qvel = np.array(model.qpos0), np.zeros(model.nv)
    qvel[7:10] = (0.3, -0.2, 0.5)  # the ball swings
    qvel[0:3] = (0.1, 0.0, 0.2)
    q, v = from_mujoco_state(qpos, qvel, robot)
    sol = lx.simulate(system, q, v, params, t1=0.5, n_save=6, rtol=1e-12, atol=1e-12)
    assert bool(sol.ok)
    assert np.max(np.abs(sol.constraint_violation)) < 1e-12
    assert np.max(np.abs(sol.energy_error)) < 1e-8
    for a in (3, 11):  # the box's and the ball's quaternions
        quats = np.asarray(sol.q)[:, a : a + 4]
        assert np.max(np.abs(np.linalg.norm(quats, axis=1) - 1)) < 1e-12
    with pytest.raises(lx.ConfigurationError, match="not available for constraints on a"):
        system.forward_dynamics_derivatives(q, v, params)


def test_an_equality_on_a_spatial_tendon_is_refused():
    xml = """
    <mujoco><worldbody>
      <body><joint name="a" type="slide"/><geom size="0.1"/><site name="s1"/></body>
      <site name="s0" pos="0 0 1"/>
    </worldbody>
    <tendon><spatial name="rope"><site site="s0"/><site site="s1"/></spatial></tendon>
    <equality><tendon name="hold" tendon1="rope"/></equality></mujoco>"""
    with pytest.raises(lx.MJCFError, match="'hold' couples the spatial tendon 'rope'"):
        from_mjcf(xml)
    with pytest.warns(UserWarning, match="ignores the equality constraints"):
        robot, _ = from_mjcf(xml, ignore_unsupported=True)
    assert isinstance(robot, lx.chains.Tree)
