"""Armature, joint springs and fixed tendons (``lagrax._multibody.joint_space``) on fixed
and floating bases.

- A small MJCF model written for these tests (``MODEL``: a branched tree of hinges and a
  slide with armature, springs about ``springref`` with a joint ``ref``, damping and two
  fixed tendons, one with a spring and damping, one with damping only), on a fixed base
  and on a free joint: ``M`` against ``mj_fullM`` and ``q̈`` against ``mj_forward``'s
  ``qacc`` (constraints off).
- The same tree's recursions against its energies differentiated (``equations=None``:
  ``T ⊃ ½ Σ a q̇²``, ``V ⊃`` the springs, ``D ⊃`` the tendons' damping): ``q̈``, ``M``,
  the energy; the Newton–Euler oracle (``τ − ∂D/∂q̇``); ``forward_dynamics_derivatives``
  against central differences of the autodiff accelerations (1e-7), and a floating
  base's along ``q ⊕ δ``.
- Armature against Pinocchio's ``model.armature``: ``aba`` and
  ``computeABADerivatives`` of the project's 7-joint URDF arm, fixed and on a free flyer.
- Bad params are named.
"""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import pin_state, rel_error
from lagrax._multibody.floating.derivatives import retract
from lagrax.chains import from_mjcf, from_mujoco_state, to_mujoco_acceleration
from lagrax.models import urdf_path

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is the reference for MJCF dynamics")

RTOL = 1e-10
TREE = """
<body name="a" pos="0 0 1">
  <joint name="j0" axis="0 1 0" armature="0.3" stiffness="2" springref="0.4" damping="0.1"
         ref="0.2"/>
  <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
  <body name="b" pos="0.5 0 0">
    <joint name="j1" axis="1 0 1" armature="0.1" stiffness="1"/>
    <geom type="box" size="0.1 0.2 0.05" pos="0.2 0 0"/>
    <body name="c" pos="0.3 0 0">
      <joint name="j2" type="slide" axis="1 0 0" armature="0.05" damping="0.2"/>
      <geom size="0.07"/>
    </body>
  </body>
</body>
<body name="d" pos="0 0.3 0.5">
  <joint name="j3" axis="0 0 1" armature="0.2"/>
  <geom type="box" size="0.1 0.2 0.05" pos="0.2 0 0"/>
</body>"""
TENDONS = """<tendon>
  <fixed name="t1" stiffness="3" damping="0.4" springlength="0.1">
    <joint joint="j0" coef="1"/><joint joint="j1" coef="-0.5"/><joint joint="j3" coef="0.7"/>
  </fixed>
  <fixed name="t2" damping="0.3"><joint joint="j2" coef="2"/></fixed>
</tendon>"""
HEAD = '<mujoco><compiler angle="radian"/><option gravity="0.3 -1 -9.8"/>'
FIXED = f"{HEAD}<worldbody>{TREE}</worldbody>{TENDONS}</mujoco>"
FLOATING = FIXED.replace(
    f"<worldbody>{TREE}</worldbody>",
    '<worldbody><body name="base" pos="0 0 1"><freejoint name="root"/>'
    f'<geom type="box" size="0.2 0.1 0.1"/>{TREE}</body></worldbody>',
)


@pytest.fixture(scope="module")
def fixed():
    tree, params = from_mjcf(FIXED)
    return tree, params, tree.system()


@pytest.fixture(scope="module")
def floating():
    robot, params = from_mjcf(FLOATING)
    return robot, params, robot.system()


def _mujoco_model(text):
    model = mujoco.MjModel.from_xml_string(text)
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    return model


def test_params_hold_the_terms(fixed):
    tree, params, _ = fixed
    assert tree.joint_terms
    np.testing.assert_allclose(params["armature"], [0.3, 0.1, 0.05, 0.2])
    np.testing.assert_allclose(params["stiffness"], [2.0, 1.0, 0.0, 0.0])
    np.testing.assert_allclose(params["springref"], [0.4, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(params["tendon"], [[1.0, -0.5, 0.0, 0.7], [0.0, 0.0, 2.0, 0.0]])
    np.testing.assert_allclose(params["tendon_stiffness"], [3.0, 0.0])
    np.testing.assert_allclose(params["tendon_length"], [0.1, 0.0])  # t2: no spring
    np.testing.assert_allclose(params["tendon_damping"], [0.4, 0.3])


FD_RTOL = 1e-7  # central differences of step 1e-5 against analytic derivatives


def _central(f, x, h=1e-5):
    """The Jacobian of `f` at `x` by central differences, one column per coordinate."""
    cols = [(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(x.shape[0])]
    return np.stack([np.asarray(c) for c in cols], axis=-1)


@pytest.fixture(scope="module")
def fixed_state(fixed):
    """One random state and force, with the energies' (autodiff) results at it, each
    from one small compiled function: `q̈`, `M`, `T + V`, and the Jacobians of `q̈` in
    `q`, `q̇`, `τ` and of `τ` in `q` by central differences of the autodiff ones."""
    tree, params, system = fixed
    auto = dataclasses.replace(system, equations=None)  # the energies differentiated
    rng = np.random.default_rng(1)
    q, qd, tau = (jnp.asarray(rng.normal(size=tree.n)) for _ in range(3))
    forward = jax.jit(lambda q, qd, tau: auto.forward_dynamics(q, qd, params, tau))
    inverse = jax.jit(lambda q, qd, qdd: auto.inverse_dynamics(q, qd, qdd, params))
    qdd = forward(q, qd, tau)
    jac = (
        _central(lambda x: forward(x, qd, tau), q),
        _central(lambda x: forward(q, x, tau), qd),
        _central(lambda x: forward(q, qd, x), tau),
    )
    d_inverse = _central(lambda x: inverse(x, qd, qdd), q)
    energy = jax.jit(lambda q, qd: auto.energy(q, qd, params))(q, qd)
    mass = jax.jit(lambda q: auto.mass_matrix(q, params))(q)
    return (q, qd, tau), (qdd, mass, energy, jac, d_inverse)


def test_fixed_base_matches_mujoco_and_its_energies(fixed, fixed_state):
    tree, params, system = fixed
    (q, qd, tau), (qdd_auto, m_auto, energy, *_) = fixed_state
    model = _mujoco_model(FIXED)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:], data.qfrc_applied[:] = q, qd, tau
    mujoco.mj_forward(model, data)
    m_mj = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, m_mj)
    qdd = system.forward_dynamics(q, qd, params, tau)
    damping = jax.grad(system.dissipation, 1)(q, qd, params)  # joints' and tendons'
    assert rel_error(qdd, data.qacc) < RTOL
    assert rel_error(system.mass_matrix(q, params), m_mj) < RTOL
    assert rel_error(qdd_auto, qdd) < RTOL
    assert rel_error(m_auto, m_mj) < RTOL
    assert rel_error(energy, system.energy(q, qd, params)) < RTOL
    assert rel_error(system.inverse_dynamics(q, qd, qdd, params), tau) < RTOL
    assert rel_error(lx.newton_euler.rnea(tree, q, qd, qdd, params), tau - damping) < RTOL


def test_fixed_base_derivatives_equal_autodiff(fixed, fixed_state):
    tree, params, system = fixed
    (q, qd, tau), (_, m_auto, _, (jq, jv, jt), d_inverse) = fixed_state
    out = system.forward_dynamics_derivatives(q, qd, params, tau)
    for ours, theirs in ((out.dq, jq), (out.dqd, jv), (out.dtau, jt)):
        assert rel_error(ours, theirs) < FD_RTOL
    inv = system.inverse_dynamics_derivatives(q, qd, out.qdd, params)
    assert rel_error(inv.tau, tau) < RTOL
    assert rel_error(inv.dqdd, m_auto) < RTOL
    assert rel_error(inv.dq, d_inverse) < FD_RTOL


def test_fixed_base_conserves_energy_without_damping(fixed):
    """Springs and armature with the damping taken out: `T + V` (armature's and springs'
    terms in it) is conserved along a simulation."""
    tree, params, system = fixed
    params = dict(params, damping=jnp.zeros(4), tendon_damping=jnp.zeros(2))
    sol = lx.simulate(system, jnp.full(4, 0.3), jnp.ones(4), params, t1=1.0, rtol=1e-11, atol=1e-11)
    assert float(jnp.max(jnp.abs(sol.energy_error))) < 1e-8


def test_floating_base_matches_mujoco_and_central_differences(floating):
    robot, params, system = floating
    model = _mujoco_model(FLOATING)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    quat = rng.normal(size=4)
    qpos = np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat), rng.normal(size=4)])
    qvel, force = rng.normal(size=10), rng.normal(size=10)
    data.qpos[:], data.qvel[:], data.qfrc_applied[:] = qpos, qvel, force
    mujoco.mj_forward(model, data)
    q, v = from_mujoco_state(qpos, qvel)
    rot = data.xmat[1].reshape(3, 3)
    tau = jnp.asarray(np.concatenate([rot.T @ force[:3], force[3:]]))
    a = system.forward_dynamics(q, v, params, tau)
    assert rel_error(to_mujoco_acceleration(q, v, a), data.qacc) < RTOL
    out = system.forward_dynamics_derivatives(q, v, params, tau)

    forward = jax.jit(lambda q, v: system.forward_dynamics(q, v, params, tau))
    # along q ⊕ δ (to first order in δ: exact at second order in the central difference)
    jq = _central(lambda d: forward(retract(q, d), v), jnp.zeros(10))
    jv = _central(lambda x: forward(q, x), v)
    assert rel_error(out.dq, jq) < FD_RTOL and rel_error(out.dqd, jv) < FD_RTOL
    inv = system.inverse_dynamics_derivatives(q, v, out.qdd, params)
    assert rel_error(inv.tau, tau) < RTOL


@pytest.mark.parametrize("base", ["fixed", "free flyer"])
def test_armature_matches_pinocchio(base):
    """The 7-joint URDF arm with a random armature, against Pinocchio's
    `model.armature`: `aba`, `computeABADerivatives` (`ddq_dq`, `ddq_dv`, `Minv`)."""
    pin = pytest.importorskip("pinocchio", reason="Pinocchio is the second reference")
    xml = urdf_path("arm7").read_text()
    floating = base == "free flyer"
    robot, params = lx.chains.from_urdf(xml, floating_base=floating)
    tree = robot.tree if floating else robot
    rng = np.random.default_rng(4)
    rotor = rng.uniform(0.05, 0.5, tree.n)
    params = dict(params, damping=jnp.zeros(tree.n), armature=jnp.asarray(rotor))
    model = (
        pin.buildModelFromXML(xml, pin.JointModelFreeFlyer())
        if floating
        else pin.buildModelFromXML(xml)
    )
    data = model.createData()
    k = 6 if floating else 0
    q = rng.uniform(-1.0, 1.0, tree.n)
    qd, tau = rng.normal(size=k + tree.n), rng.normal(size=k + tree.n)
    qp, vp, order = pin_state(pin, model, tree, q, qd[k:])
    if floating:
        quat = rng.normal(size=4)
        base_q = np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat)])
        qp[:7], vp[:6] = base_q, qd[:6]
        order = np.concatenate([np.arange(6), order])
        q = np.concatenate([base_q, q])
    armature = np.zeros(model.nv)
    armature[order[k:]] = rotor
    model.armature = armature
    t_pin = np.zeros(model.nv)
    t_pin[order] = tau
    pin.computeABADerivatives(model, data, qp, vp, t_pin)
    ix = np.ix_(order, order)
    system = robot.system()
    out = system.forward_dynamics_derivatives(jnp.asarray(q), jnp.asarray(qd), params, tau)
    m_inv = np.triu(data.Minv) + np.triu(data.Minv, 1).T
    assert rel_error(out.qdd, data.ddq[order]) < RTOL
    assert rel_error(out.dq, data.ddq_dq[ix]) < RTOL
    assert rel_error(out.dqd, data.ddq_dv[ix]) < RTOL
    assert rel_error(out.dtau, m_inv[ix]) < RTOL


def test_tree_params_take_the_terms_and_name_bad_ones():
    tree = lx.chains.Tree("RR", parents=(-1, 0), axes=[(0, 0, 1), (0, 1, 0)], joint_terms=True)
    params = tree.params(offset=(0.2, 0, 0), armature=0.1, stiffness=[1.0, 2.0], springref=0.3)
    np.testing.assert_allclose(params["armature"], [0.1, 0.1])
    np.testing.assert_allclose(params["springref"], [0.3, 0.3])
    with pytest.raises(lx.ParameterError, match="armature"):
        tree.params(armature=-1.0)
    system = tree.system()
    q, qd = jnp.array([0.4, -0.2]), jnp.array([0.3, 0.5])
    auto = dataclasses.replace(system, equations=None)
    expected = jax.jit(lambda q, qd: auto.forward_dynamics(q, qd, params))(q, qd)
    assert rel_error(system.forward_dynamics(q, qd, params), expected) < RTOL
    bad = dict(params, armature=jnp.ones(3))
    with pytest.raises(lx.ShapeError, match="armature"):
        system.forward_dynamics(q, qd, bad)
