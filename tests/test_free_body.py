"""A single rigid body on a floating base: a [`FloatingTree`][lagrax.chains.FloatingTree]
whose joint tree has no joints (``n = 0``: ``q`` of size 7, ``v`` of size 6).

- example-robot-data's two single-body URDFs (the Hector quadrotor, the Iris drone) load
  with ``floating_base=True`` and agree with Pinocchio's free-flyer model in ``M``, the
  bias and the forward dynamics to 1e-12 relative; with a fixed base they are refused by
  name.
- Closed forms: a body falls with ``v̇_b = Rᵀ g`` (base frame) and spins by Euler's
  equation ``I ω̇ + ω × I ω = 0`` (COM at the base origin); with the COM off the origin,
  against Pinocchio.
- ``simulate`` of a tumbling body in zero gravity conserves its energy and momentum and
  keeps the quaternion on the unit sphere.
- ``Tree("", ())`` is a floating base's empty joint tree; fixed to the world it has no
  system. MJCF: a lone ``<freejoint/>`` body loads as the same free body.
"""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import assert_free_motion_conserved, example_robot_data, rel_error

pin = pytest.importorskip(
    "pinocchio", reason="Pinocchio (pip install pin) is the reference for floating-base dynamics"
)

RTOL = 1e-12
FREE_BODIES = (
    "hector_description/robots/quadrotor_base.urdf",
    "iris_description/robots/iris_simple.urdf",
)
BASE_V = ("base_vx", "base_vy", "base_vz", "base_wx", "base_wy", "base_wz")
INERTIA = np.array([[0.30, 0.02, -0.01], [0.02, 0.45, 0.03], [-0.01, 0.03, 0.60]])


def _urdf(rel: str) -> Path:
    share = example_robot_data()
    if share is None:
        pytest.skip("example-robot-data is not installed (pip install example-robot-data)")
    return share / "robots" / rel


def _random_states(rng, k: int):
    """``k`` random ``(q, v, τ)``: normal position, a random unit quaternion."""
    quat = rng.normal(size=(k, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    q = np.concatenate([rng.normal(size=(k, 3)), quat], axis=1)
    return q, rng.normal(size=(k, 6)), rng.normal(size=(k, 6))


def _body(com=(0.0, 0.0, 0.0), g=9.81):
    """A 2.5 kg body with an asymmetric, non-diagonal inertia."""
    robot = lx.chains.FloatingTree(lx.chains.Tree("", ()), base_name="body")
    params = robot.params(base_m=2.5, base_inertia=INERTIA, base_com=com, g=g)
    return robot, params


def _equations(system, params):
    """``(M, bias, v̇)`` at a batch of states, one compiled program."""

    def one(q, v, tau):
        return (
            system.mass_matrix(q, params),
            system.bias(q, v, params),
            system.forward_dynamics(q, v, params, tau),
        )

    return jax.jit(jax.vmap(one))


def _pin_errors(model, equations, q, v, tau) -> dict:
    """The largest relative errors of ``equations`` against Pinocchio's ``crba``,
    ``nonLinearEffects`` and ``aba`` (the free flyer's coordinates are lagrax's)."""
    mass, bias, forward = (np.asarray(x) for x in equations(q, v, tau))
    data = model.createData()
    worst = {"M": 0.0, "bias": 0.0, "ABA": 0.0}
    for k in range(q.shape[0]):
        m_pin = pin.crba(model, data, q[k])
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        errors = {
            "M": rel_error(mass[k], m_pin),
            "bias": rel_error(bias[k], pin.nonLinearEffects(model, data, q[k], v[k])),
            "ABA": rel_error(forward[k], pin.aba(model, data, q[k], v[k], tau[k])),
        }
        worst = {key: max(worst[key], e) for key, e in errors.items()}
    return worst


@pytest.fixture(scope="module", params=FREE_BODIES, ids=lambda rel: Path(rel).stem)
def drone(request):
    path = _urdf(request.param)
    robot, params = lx.chains.from_urdf(path, floating_base=True)
    model = pin.buildModelFromUrdf(str(path), pin.JointModelFreeFlyer())
    return path, robot, params, model


def test_single_body_urdf_matches_pinocchio(drone):
    path, robot, params, model = drone
    system = robot.system()
    assert isinstance(robot, lx.chains.FloatingTree) and robot.n == 0
    assert system.n_configuration == model.nq == 7 and system.n_dof == model.nv == 6
    assert system.coordinate_names == BASE_V and len(system.configuration_names) == 7
    assert float(params["base_m"]) == pytest.approx(pin.computeTotalMass(model), rel=1e-15)
    q, v, tau = _random_states(np.random.default_rng(3), 4)
    worst = _pin_errors(model, _equations(system, params), q, v, tau)
    assert max(worst.values()) <= RTOL, worst


def test_single_body_urdf_refused_on_a_fixed_base(drone):
    path, *_ = drone
    with pytest.raises(lx.URDFError, match="no revolute, continuous or prismatic.*floating_base"):
        lx.chains.from_urdf(path)


def _rotation(quat) -> np.ndarray:
    """The rotation of a unit quaternion ``(x, y, z, w)`` (world from body)."""
    x, y, z, w = quat
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def test_free_fall_and_euler_equations():
    """COM at the origin: the linear and angular equations decouple, ``v̇_b = Rᵀ g −
    ω × v_b`` (the base frame turns) and ``I ω̇ = −ω × I ω`` (Euler); at rest
    ``v̇ = (Rᵀ g, 0)``; ``M = diag(m 1, I)``."""
    robot, params = _body()
    system = robot.system()
    q, v, _ = _random_states(np.random.default_rng(5), 3)
    gravity = np.array([0.0, 0.0, -9.81])
    block = np.block([[2.5 * np.eye(3), np.zeros((3, 3))], [np.zeros((3, 3)), INERTIA]])
    for qk, vk in zip(q, v, strict=True):
        rot = _rotation(qk[3:7])
        vb, omega = vk[:3], vk[3:]
        vdot = np.asarray(system.forward_dynamics(qk, vk, params))
        assert rel_error(vdot[:3], rot.T @ gravity - np.cross(omega, vb)) < 1e-13
        euler = np.linalg.solve(INERTIA, -np.cross(omega, INERTIA @ omega))
        assert rel_error(vdot[3:], euler) < 1e-13
        at_rest = np.asarray(system.forward_dynamics(qk, np.zeros(6), params))
        assert rel_error(at_rest, np.concatenate([rot.T @ gravity, np.zeros(3)])) < 1e-14
        assert rel_error(system.mass_matrix(qk, params), block) < 1e-15


def _pin_body(com):
    """Pinocchio's model of `_body(com)`: one free flyer carrying the body."""
    model = pin.Model()
    joint = model.addJoint(0, pin.JointModelFreeFlyer(), pin.SE3.Identity(), "root")
    model.appendBodyToJoint(joint, pin.Inertia(2.5, np.asarray(com), INERTIA), pin.SE3.Identity())
    return model


def test_offset_com_matches_pinocchio():
    """The COM off the base origin couples the linear and angular equations: ``M``,
    bias, ``aba``, ``rnea``, the momentum, centre of mass and energy against Pinocchio."""
    com = (0.12, -0.07, 0.2)
    robot, params = _body(com)
    system = robot.system()
    model = _pin_body(com)
    q, v, tau = _random_states(np.random.default_rng(9), 4)
    worst = _pin_errors(model, _equations(system, params), q, v, tau)
    assert max(worst.values()) <= RTOL, worst
    data = model.createData()
    for qk, vk, ak in zip(q, v, tau, strict=True):
        tau_pin = pin.rnea(model, data, qk, vk, ak)
        assert rel_error(system.inverse_dynamics(qk, vk, ak, params), tau_pin) < RTOL
        c = np.asarray(system.center_of_mass(qk, params))
        assert rel_error(c, pin.centerOfMass(model, data, qk)) < 1e-14
        h = np.asarray(system.momentum(qk, vk, params))  # (L about the world origin, p)
        h_g = pin.computeCentroidalMomentum(model, data, qk, vk)  # (p, L about the CoM)
        assert rel_error(h[3:], h_g.linear) < 1e-14
        assert rel_error(h[:3] - np.cross(c, h[3:]), h_g.angular) < 1e-14
        energy = pin.computeKineticEnergy(model, data, qk, vk)
        energy += pin.computePotentialEnergy(model, data, qk)
        assert rel_error(system.energy(qk, vk, params), energy) < 1e-14


def test_tumbling_body_conserves_energy_and_momentum():
    """Zero gravity, COM off the origin, spun near its intermediate axis and drifting:
    over 4 s (Dopri8, tolerances 1e-14) energy and momentum stay constant to 1e-10
    relative (measured: energy 1.3e-11, angular momentum 1.7e-11, linear 3.0e-11; the
    integrator's error: 5-10x more at tolerances 1e-13) and the quaternion stays on the
    unit sphere."""
    robot, params = _body(com=(0.05, -0.03, 0.08), g=0.0)
    system = robot.system()
    q0 = jnp.array([0.3, -0.2, 1.0, 0.1, -0.2, 0.3, 0.9])
    v0 = jnp.array([0.4, -0.1, 0.2, 0.05, 3.0, 0.1])
    sol = lx.simulate(
        system, q0, v0, params, t1=4.0, solver="dopri8", rtol=1e-14, atol=1e-14, n_save=41
    )
    assert sol.q.shape == (41, 7) and sol.qd.shape == (41, 6)
    assert_free_motion_conserved(system, params, sol)
    omega = np.asarray(sol.qd[:, 3:])
    assert np.ptp(omega[:, 1]) > 0.1  # it tumbles: the body-frame spin changes


def test_empty_tree_is_a_floating_base_only():
    """``Tree("", ())`` has no coordinates: its params are empty arrays, and fixed to the
    world it has no system; on a floating base it is the single rigid body."""
    tree = lx.chains.Tree("", ())
    assert tree.n == tree.n_bodies == 0 and tree.joint_names == ()
    params = tree.params()
    assert params["m"].shape == (0,) and params["inertia"].shape == (0, 3, 3)
    with pytest.raises(lx.ConfigurationError, match="no joints.*FloatingTree"):
        tree.system()
    with pytest.raises(lx.ConfigurationError, match="joint_types"):
        lx.chains.SpatialChain("")  # a chain still needs a joint
    robot = lx.chains.FloatingTree(tree)
    system = robot.system()
    assert system.n_dof == 6 and system.n_configuration == 7
    assert system.coordinate_names == BASE_V
