"""Ball joints (MJCF ``type="ball"``, Pinocchio's ``JointModelSpherical``): a tree's
ball joint is three revolute lanes with its rotation from a quaternion and a
velocity-product correction (``lagrax._multibody.articulated.balls``).

Checked against independent sources:

- MuJoCo: ``M`` against ``mj_fullM`` and ``v̇`` against ``mj_forward``'s ``qacc`` with
  contact and constraints disabled, at random states, on a chain of three bodies on ball
  joints with a hinge among them (offset anchors, rotated bodies and inertias, damping and
  armature on a ball), on a ball-hinge arm under a free joint, and on a file we did not
  write (the MJX sensor test model);
- Pinocchio's MJCF reader (``JointModelSpherical``, fixed and free-flyer): ``crba``,
  ``aba``, ``rnea``, ``computeABADerivatives`` / ``computeRNEADerivatives`` and
  ``integrate``; the analytic tangent derivatives also against plain forward-mode
  autodiff along the exact ``q ⊕ ξ``;
- an invariant: an undamped ball chain's energy over a ``simulate`` run, with its
  quaternions on the unit sphere;
- bad input: a zero quaternion, a spring or a limit on a ball.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import mjx_test_data

mujoco = pytest.importorskip("mujoco")

_CHAIN = """
<mujoco>
  <option><flag contact="disable" constraint="disable"/></option>
  <worldbody>
    <body name="a" pos="0.1 0.2 1.5" quat="0.9 0.1 0.3 -0.2">
      <joint name="ja" type="ball" pos="0.02 -0.03 0.1" damping="{damping}" armature="{armature}"/>
      <geom type="box" size="0.1 0.05 0.2" pos="0.05 0.02 -0.2" quat="0.8 0.2 -0.1 0.3"/>
      <body name="b" pos="0.03 0.01 -0.45" quat="0.95 -0.2 0.1 0.1">
        <joint name="jb" type="ball"/>
        <geom type="capsule" size="0.04 0.15" pos="0.01 0 -0.17" quat="0.9 0.3 0 0.2"/>
        <body name="h" pos="0 0.02 -0.35">
          <joint name="hinge" type="hinge" axis="0.3 1 0.2" pos="0.01 0 0.02" damping="{damping}"/>
          <geom type="ellipsoid" size="0.05 0.08 0.12" pos="0.02 0.01 -0.1"/>
          <body name="c" pos="0.01 -0.02 -0.25">
            <joint name="jc" type="ball" pos="0 0.01 0"/>
            <geom type="box" size="0.06 0.04 0.09" pos="0.03 0.0 -0.1" quat="0.7 0.1 0.7 0.1"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""
CHAIN = _CHAIN.format(damping=0.3, armature=0.05)


FREE = """
<mujoco>
  <option><flag contact="disable" constraint="disable"/></option>
  <worldbody>
    <body name="torso" pos="0.1 -0.2 1.0" quat="0.9 0.1 -0.2 0.3">
      <freejoint name="root"/>
      <geom type="box" size="0.15 0.1 0.08" pos="0.02 0.01 -0.01" quat="0.9 0.2 0.1 -0.1"/>
      <body name="upper" pos="0.12 0.05 -0.05" quat="0.8 0.3 -0.1 0.2">
        <joint name="shoulder" type="ball" pos="0.01 0.02 0.03" damping="0.2" armature="0.03"/>
        <geom type="capsule" size="0.03 0.1" pos="0.0 0.02 -0.11" quat="0.95 0.1 0.2 0"/>
        <body name="lower" pos="0.0 0.03 -0.24">
          <joint name="elbow" type="hinge" axis="0.2 1 0.1" damping="0.1"/>
          <geom type="ellipsoid" size="0.04 0.05 0.09" pos="0.01 0 -0.08"/>
        </body>
      </body>
      <geom type="box" size="0.05 0.03 0.02" pos="-0.2 0.01 0" quat="0.7 0.1 0.7 0.1"/>
    </body>
  </worldbody>
</mujoco>
"""


def _random_state(model, rng):
    """A random MuJoCo `(qpos, qvel, qfrc)`, every ball's and free joint's quaternion a
    unit one."""
    qpos = rng.normal(size=model.nq)
    for j in range(model.njnt):
        kind = model.jnt_type[j]
        if kind in (mujoco.mjtJoint.mjJNT_BALL, mujoco.mjtJoint.mjJNT_FREE):
            a = model.jnt_qposadr[j] + (3 if kind == mujoco.mjtJoint.mjJNT_FREE else 0)
            qpos[a : a + 4] /= np.linalg.norm(qpos[a : a + 4])
    return qpos, rng.normal(size=model.nv), rng.normal(size=model.nv)


@pytest.fixture(scope="module")
def chain():
    tree, params = lx.chains.from_mjcf(CHAIN)
    system = tree.system()
    fd = jax.jit(lambda q, v, tau: system.forward_dynamics(q, v, params, tau))
    mass = jax.jit(lambda q: system.mass_matrix(q, params))
    return tree, params, system, fd, mass


def test_chain_of_balls_matches_mujoco(chain):
    """`M` and `v̇` at random states equal MuJoCo's to 1e-10 relative (measured about
    1e-14), through `from_mujoco_state`, and the state converts back unchanged; the
    bodies' rotations and centres of mass are MuJoCo's `xmat` and `xipos`."""
    tree, params, system, fd, mass = chain
    assert isinstance(system, lx.chains.BallTreeSystem)
    model = mujoco.MjModel.from_xml_string(CHAIN)
    data = mujoco.MjData(model)
    assert (system.n_configuration, system.n_dof) == (model.nq, model.nv)
    rng = np.random.default_rng(0)
    for _ in range(3):
        qpos, qvel, qfrc = _random_state(model, rng)
        data.qpos[:], data.qvel[:], data.qfrc_applied[:] = qpos, qvel, qfrc
        mujoco.mj_forward(model, data)
        m_mj = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, m_mj)
        q, v = lx.chains.from_mujoco_state(qpos, qvel, tree)
        np.testing.assert_allclose(mass(q), m_mj, rtol=0, atol=1e-10 * np.abs(m_mj).max())
        qdd = np.asarray(fd(q, v, qfrc))
        np.testing.assert_allclose(qdd, data.qacc, rtol=0, atol=1e-10 * np.abs(data.qacc).max())
        back = lx.chains.to_mujoco_state(q, v, tree)
        np.testing.assert_array_equal(back[0], qpos)
        np.testing.assert_array_equal(back[1], qvel)
    # the kinematics: each body's rotation and centre of mass (on a ball's last lane)
    lanes = np.array([2, 5, 6, 9])  # the bodies a, b, h, c
    rots, coms = jax.jit(lambda q: (tree.frames(q, params)[1], tree.com_positions(q, params)))(q)
    np.testing.assert_allclose(rots[lanes], data.xmat[1:].reshape(-1, 3, 3), atol=1e-14)
    np.testing.assert_allclose(coms[lanes], data.xipos[1:], atol=1e-14)


def test_chain_of_balls_matches_pinocchio(chain):
    """`M`, `v̇`, `τ` and the ABA and RNEA derivatives (on the tangent, Pinocchio's
    `integrate`) equal Pinocchio's on its own reading of the file (`JointModelSpherical`),
    to 1e-10 relative (Pinocchio has no damping, added to its `τ` here); the analytic
    tangent derivatives equal plain autodiff; `linearize`'s `∂ξ̇/∂ξ` equals central
    differences of Pinocchio's `difference` along its `integrate`."""
    pin = pytest.importorskip("pinocchio")
    tree, params, system, fd, mass = chain
    model = pin.buildModelFromMJCF(_write(CHAIN))
    data = model.createData()
    model.gravity.linear[:] = [0.0, 0.0, -9.81]
    rng = np.random.default_rng(1)
    q = np.asarray(pin.randomConfiguration(model, -np.ones(model.nq), np.ones(model.nq)))
    v, tau, vdot = (rng.normal(size=model.nv) for _ in range(3))
    damping = np.asarray(params["damping"])

    def close(ours, theirs):
        theirs = np.asarray(theirs)
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-10 * np.abs(theirs).max())

    m_pin = pin.crba(model, data, q)
    close(mass(q), np.triu(m_pin) + np.triu(m_pin, 1).T)
    close(fd(q, v, tau), pin.aba(model, data, q, v, tau - damping * v))
    close(
        system.inverse_dynamics(q, v, vdot, params), pin.rnea(model, data, q, v, vdot) + damping * v
    )
    out = system.forward_dynamics_derivatives(q, v, params, tau)
    pin.computeABADerivatives(model, data, q, v, tau - damping * v)
    m_inv = np.triu(data.Minv) + np.triu(data.Minv, 1).T
    close(out.dq, data.ddq_dq)
    close(out.dqd, data.ddq_dv - m_inv * damping[None, :])
    close(out.dtau, m_inv)
    inv = system.inverse_dynamics_derivatives(q, v, vdot, params)
    pin.computeRNEADerivatives(model, data, q, v, vdot)
    close(inv.dq, data.dtau_dq)
    close(inv.dqd, data.dtau_dv + np.diag(damping))
    # the analytic tangent terms against plain forward-mode autodiff of the inverse
    # dynamics along the exact `q ⊕ ξ` (a ball's quaternion times `exp(ξ/2)`)
    jq = jax.jit(jax.jacfwd(lambda xi: system.inverse_dynamics(_moved(q, xi), v, vdot, params)))
    close(inv.dq, jq(jnp.zeros(system.n_dof)))
    # linearize's `∂ξ̇/∂ξ` (a ball's `−½ [ω]×`): central differences of Pinocchio's
    # `difference` along its `integrate`, and its lower rows the derivatives'
    a_mat, b_mat = system.linearize(q, v, params, tau)
    n, h = model.nv, 1e-5

    def xi_rate(xi):
        moved = pin.integrate(model, q, xi)
        ahead, back = (pin.integrate(model, moved, s * h * v) for s in (1, -1))
        return (pin.difference(model, q, ahead) - pin.difference(model, q, back)) / (2 * h)

    rates = [(xi_rate(h * e) - xi_rate(-h * e)) / (2 * h) for e in np.eye(n)]
    np.testing.assert_allclose(a_mat[:n, :n], np.stack(rates, axis=1), rtol=0, atol=1e-5)
    close(a_mat[n:], np.hstack([out.dq, out.dqd]))
    close(b_mat[n:], m_inv)


def _moved(q, xi):
    """`q ⊕ ξ` of the chain (balls `ja`, `jb`, a hinge, `jc`): each quaternion
    `(x, y, z, w)` times `exp(ξ/2) = (sin(|ξ|/2) ξ/|ξ|, cos(|ξ|/2))`, the hinge plus its
    `ξ`."""

    def times_exp(quat, w):
        half = 0.5 * jnp.sqrt(w @ w + 1e-300)
        e = jnp.concatenate([jnp.sin(half) / (2 * half) * w, jnp.cos(half)[None]])
        vec, s, ev, es = quat[:3], quat[3], e[:3], e[3]
        return jnp.concatenate([s * ev + es * vec + jnp.cross(vec, ev), (s * es - vec @ ev)[None]])

    parts = [times_exp(q[0:4], xi[0:3]), times_exp(q[4:8], xi[3:6]), (q[8] + xi[6])[None]]
    return jnp.concatenate([*parts, times_exp(q[9:13], xi[7:10])])


def test_balls_under_a_free_joint_match_mujoco_and_pinocchio():
    """A free body carrying a ball-hinge arm (damping and armature on the ball): `v̇`
    against MuJoCo's `qacc` (its free joint's linear part in the world frame,
    `R (v̇_b + ω_b × v_b)`), `M` against `mj_fullM` (congruent by `R`), the state
    converted both ways; `M`, `v̇`, `τ` and the ABA derivatives (analytic) against
    Pinocchio's free flyer with `JointModelSpherical`; `q̇ = N(q) v` against
    Pinocchio's `integrate`."""
    robot, params = lx.chains.from_mjcf(FREE)
    system = robot.system()
    assert isinstance(robot, lx.chains.FloatingTree) and robot.tree.balls == (0,)
    model = mujoco.MjModel.from_xml_string(FREE)
    data = mujoco.MjData(model)
    qpos, qvel, qfrc = _random_state(model, np.random.default_rng(4))
    data.qpos[:], data.qvel[:] = qpos, qvel
    mujoco.mj_forward(model, data)
    q, v = lx.chains.from_mujoco_state(qpos, qvel, robot)
    back = lx.chains.to_mujoco_state(q, v, robot)
    np.testing.assert_allclose(back[0], qpos, rtol=0, atol=1e-15)
    np.testing.assert_allclose(back[1], qvel, rtol=0, atol=1e-15)
    dynamics = jax.jit(
        lambda q, v, tau, vdot: (
            system.mass_matrix(q, params),
            system.forward_dynamics(q, v, params, tau),
            system.inverse_dynamics(q, v, vdot, params),
        )
    )
    mass, vdot, _ = dynamics(q, v, 0 * v, v)
    rot = np.asarray(data.xmat[1]).reshape(3, 3)
    qacc = lx.chains.to_mujoco_acceleration(q, v, vdot, robot)
    np.testing.assert_allclose(qacc, data.qacc, rtol=0, atol=1e-10 * np.abs(data.qacc).max())
    m_mj = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, m_mj)
    t = np.eye(model.nv)
    t[:3, :3] = rot
    np.testing.assert_allclose(mass, t.T @ m_mj @ t, rtol=0, atol=1e-10 * np.abs(m_mj).max())

    pin = pytest.importorskip("pinocchio")
    pmodel = pin.buildModelFromMJCF(_write(FREE))
    pdata = pmodel.createData()
    pmodel.gravity.linear[:] = [0.0, 0.0, -9.81]
    rng = np.random.default_rng(5)
    q = np.asarray(pin.randomConfiguration(pmodel, -np.ones(pmodel.nq), np.ones(pmodel.nq)))
    v, tau, vdot = (rng.normal(size=pmodel.nv) for _ in range(3))
    damping = np.r_[np.zeros(6), np.asarray(params["damping"])]

    def close(ours, theirs):
        theirs = np.asarray(theirs)
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-10 * np.abs(theirs).max())

    m_pin = pin.crba(pmodel, pdata, q)
    mass, qdd, inverse = dynamics(q, v, tau, vdot)
    close(mass, np.triu(m_pin) + np.triu(m_pin, 1).T)
    close(qdd, pin.aba(pmodel, pdata, q, v, tau - damping * v))
    close(inverse, pin.rnea(pmodel, pdata, q, v, vdot) + damping * v)
    out = system.forward_dynamics_derivatives(q, v, params, tau)
    pin.computeABADerivatives(pmodel, pdata, q, v, tau - damping * v)
    m_inv = np.triu(pdata.Minv) + np.triu(pdata.Minv, 1).T
    close(out.dq, pdata.ddq_dq)
    close(out.dqd, pdata.ddq_dv - m_inv * damping[None, :])
    close(out.dtau, m_inv)
    h = 1e-6  # q̇ = N(q) v: the central difference of Pinocchio's integrate
    rate = (pin.integrate(pmodel, q, h * v) - pin.integrate(pmodel, q, -h * v)) / (2 * h)
    np.testing.assert_allclose(system.configuration_rate(q, v), rate, rtol=0, atol=1e-8)


def _write(xml: str) -> str:
    import os
    import tempfile

    fd, path = tempfile.mkstemp(suffix=".xml")
    with os.fdopen(fd, "w") as f:
        f.write(xml)
    return path


def test_undamped_ball_pendulum_conserves_energy():
    """An undamped chain on ball joints (no armature either) keeps `T + V` to 1e-9
    relative over 2 s of `simulate`, and its quaternions stay on the unit sphere."""
    tree, params = lx.chains.from_mjcf(_CHAIN.format(damping=0.0, armature=0.0))
    system = tree.system()
    model = mujoco.MjModel.from_xml_string(CHAIN)
    qpos, qvel, _ = _random_state(model, np.random.default_rng(2))
    q0, v0 = lx.chains.from_mujoco_state(qpos, qvel, tree)
    sol = lx.simulate(
        system, q0, v0, params, t1=2.0, n_save=5, solver="dopri8", rtol=1e-11, atol=1e-11
    )
    assert bool(sol.ok)
    energy = np.asarray(jax.vmap(lambda q, v: system.energy(q, v, params))(sol.q, sol.qd))
    assert np.max(np.abs(energy - energy[0])) < 1e-9 * np.max(np.abs(energy))
    # the saves are interpolated between projected steps; the last one is a step
    assert float(np.max(np.abs(sol.constraint_violation))) < 1e-10
    assert float(np.max(np.abs(sol.constraint_violation[-1]))) < 1e-14
    assert not np.allclose(sol.q[-1], sol.q[0])  # it moved


def test_ball_joint_bad_input(chain):
    tree, params, system, fd, mass = chain
    q = jnp.zeros(system.n_configuration).at[3].set(1.0).at[7].set(1.0).at[12].set(1.0)
    zero = q.at[4:8].set(0.0)  # the second ball's quaternion
    with pytest.raises(lx.ShapeError, match="'jb'.*q\\[4:8\\]"):
        system.forward_dynamics(zero, jnp.zeros(system.n_dof), params)
    with pytest.raises(lx.ShapeError, match="'jb'"):
        system.check_state(zero, jnp.zeros(system.n_dof), params)
    with pytest.raises(lx.ShapeError, match="13"):
        system.forward_dynamics(jnp.zeros(10), jnp.zeros(10), params)
    spring = CHAIN.replace('type="ball"/>', 'type="ball" stiffness="2"/>')
    with pytest.raises(lx.MJCFError, match="stiffness 2 on the ball joint 'jb'"):
        lx.chains.from_mjcf(spring)
    limited = CHAIN.replace('type="ball"/>', 'type="ball" range="0 30"/>')
    with pytest.raises(lx.MJCFError, match="limit 0.523599 on the ball joint 'jb'"):
        lx.chains.from_mjcf(limited)


def test_real_file_with_ball_joints_matches_mujoco():
    """A file we did not write, MJX's sensor test model (the mujoco-mjx package; two
    ball joints with anchors, hinges and slides, motors): `M` and `v̇` equal MuJoCo's to
    1e-10 relative with contact, constraints and actuation off (measured 2e-16 and
    5e-15), and the motors' `τ` equals `qfrc_actuator` for a random `ctrl`."""
    path = mjx_test_data("sensor/model.xml")
    tree, params = lx.chains.from_mjcf(path)
    system, actuation = tree.system(), lx.chains.mjcf_actuation(path)
    assert len(tree.balls) == 2
    model = mujoco.MjModel.from_xml_path(str(path))
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_CONSTRAINT
    data = mujoco.MjData(model)
    rng = np.random.default_rng(3)
    qpos, qvel, qfrc = _random_state(model, rng)
    ctrl = rng.uniform(-1, 1, size=model.nu)
    data.qpos[:], data.qvel[:], data.qfrc_applied[:], data.ctrl[:] = qpos, qvel, qfrc, ctrl
    mujoco.mj_forward(model, data)
    m_mj = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, m_mj)
    q, v = lx.chains.from_mujoco_state(qpos, qvel, tree)
    tau = np.asarray(actuation(ctrl, q, v))
    np.testing.assert_allclose(tau, data.qfrc_actuator, rtol=0, atol=1e-12)
    mass, qdd = jax.jit(
        lambda q, v, f: (system.mass_matrix(q, params), system.forward_dynamics(q, v, params, f))
    )(q, v, qfrc + tau)
    np.testing.assert_allclose(mass, m_mj, rtol=0, atol=1e-10 * np.abs(m_mj).max())
    np.testing.assert_allclose(qdd, data.qacc, rtol=0, atol=1e-10 * np.abs(data.qacc).max())
