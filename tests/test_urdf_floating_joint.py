"""A URDF ``floating`` joint from the world link: the floating base at its child, as
Pinocchio reads it (a free flyer, ``pin.buildModelFromXML``).

- The project's 7-joint arm hung from a world link by a floating joint: the same robot
  and params as ``floating_base=True``, and ``M`` and ``q̈`` against Pinocchio's CRBA and
  ABA at a random state.
- Floating joints lagrax cannot read are refused by name: two of them, one with an
  ``<origin>`` offset, one below a moving joint.
- A ``planar`` joint, as three coordinates ``(x, y, θ)``: ``M`` and ``G`` against
  Pinocchio's planar joint through the map between the two velocities.
"""

import re
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import pin_state, rel_error
from lagrax.chains import from_urdf
from lagrax.models import urdf_path

pin = pytest.importorskip("pinocchio", reason="Pinocchio is the reference for URDF dynamics")

ARM = Path(urdf_path("arm7")).read_text(encoding="utf-8")
ROOT = re.search(r'<link name="([^"]+)"', ARM).group(1)


def _hung(joint: str = '<joint name="free" type="floating">', extra: str = "") -> str:
    """The arm with a world link and `joint` (closed here) from it to the arm's root."""
    link = f'<link name="{ROOT}"'
    head = f'<link name="world"/>{joint}<parent link="world"/><child link="{ROOT}"/>'
    return ARM.replace(link, f"{head}{extra}</joint>\n  {link}", 1)


def test_floating_joint_is_pinocchios_free_flyer():
    robot, params = from_urdf(_hung())
    same, same_params = from_urdf(urdf_path("arm7"), floating_base=True)
    assert isinstance(robot, lx.chains.FloatingTree) and robot.tree.joint_names == (
        same.tree.joint_names
    )
    for key, value in same_params.items():
        assert np.array_equal(np.asarray(params[key]), np.asarray(value)), key
    params = dict(params, damping=jnp.zeros_like(params["damping"]))  # Pinocchio: none
    model = pin.buildModelFromXML(_hung())
    data = model.createData()
    assert model.joints[1].shortname() == "JointModelFreeFlyer"
    rng = np.random.default_rng(0)
    quat = rng.normal(size=4)
    q = np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat), rng.normal(size=7)])
    v, tau = rng.normal(size=13), rng.normal(size=13)
    qp, vp, order = pin_state(pin, model, robot.tree, q[7:], v[6:])
    qp[:7], vp[:6] = q[:7], v[:6]
    idx = np.concatenate([np.arange(6), order])
    tau_p = np.zeros(13)
    tau_p[idx] = tau
    system = robot.system()
    qdd = system.forward_dynamics(jnp.asarray(q), jnp.asarray(v), params, jnp.asarray(tau))
    assert rel_error(qdd, pin.aba(model, data, qp, vp, tau_p)[idx]) < 1e-10
    mass = pin.crba(model, data, qp)
    mass = np.triu(mass) + np.triu(mass, 1).T
    assert rel_error(system.mass_matrix(jnp.asarray(q), params), mass[np.ix_(idx, idx)]) < 1e-10


@pytest.mark.parametrize(
    "text, words",
    [
        (
            _hung('<joint name="free" type="floating"><origin xyz="0 0 1"/>'),
            "floating joint 'free' has an <origin> offset",
        ),
        (
            _hung().replace(
                "</robot>",
                '<link name="ball"><inertial><mass value="1"/><inertia ixx="1" iyy="1" '
                'izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link><joint name="free2" '
                'type="floating"><parent link="world"/><child link="ball"/></joint></robot>',
            ),
            "2 floating joints",
        ),
        (
            'type="floating"'.join(ARM.rsplit('type="revolute"', 1)),  # the last joint
            "is not the root link",
        ),
    ],
)
def test_floating_joints_lagrax_cannot_read_are_named(text, words):
    with pytest.raises(lx.URDFError, match=re.escape(words)):
        from_urdf(text)


def _link(name: str, mass: float, xyz: str) -> str:
    return (
        f'<link name="{name}"><inertial><origin xyz="{xyz}" rpy="0.1 0.2 0.3"/>'
        f'<mass value="{mass}"/><inertia ixx="0.02" iyy="0.03" izz="0.04" ixy="0.001" '
        'ixz="0.002" iyz="-0.001"/></inertial></link>'
    )


PLANAR = f"""<robot name="puck"><link name="table"/>
  {_link("puck", 1.5, "0.05 -0.02 0.01")}{_link("arm", 0.4, "0.2 0 0")}
  <joint name="slide" type="planar"><parent link="table"/><child link="puck"/>
    <origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 0.5"/><axis xyz="0 0 1"/></joint>
  <joint name="elbow" type="revolute"><parent link="puck"/><child link="arm"/>
    <origin xyz="0.1 0 0"/><axis xyz="0 1 1"/><limit lower="-2" upper="2" effort="1"
    velocity="1"/></joint>
</robot>"""


def test_planar_joint_is_pinocchios_planar_joint():
    """A puck sliding and turning on a tilted table, with an arm: ``M`` and ``G`` against
    Pinocchio's (``JointModelPlanar``) by the congruence of the velocities, Pinocchio's
    ``v = (R(θ)ᵀ (ẋ, ẏ), θ̇)``; the same Lagrangian, so the same equations."""
    tree, params = from_urdf(PLANAR)
    assert tree.joint_names == ("slide/x", "slide/y", "slide", "elbow")
    model = pin.buildModelFromXML(PLANAR)
    data = model.createData()
    assert model.joints[1].shortname() == "JointModelPlanar"
    q = np.array([0.3, -0.4, 0.8, 0.6])
    c, s = np.cos(q[2]), np.sin(q[2])
    qp = np.array([q[0], q[1], c, s, q[3]])
    jac = np.eye(4)  # v_pin = J q̇
    jac[:2, :2] = [[c, s], [-s, c]]
    system = tree.system()
    mass = pin.crba(model, data, qp)
    mass = np.triu(mass) + np.triu(mass, 1).T
    assert rel_error(system.mass_matrix(jnp.asarray(q), params), jac.T @ mass @ jac) < 1e-12
    gravity = pin.computeGeneralizedGravity(model, data, qp)
    assert rel_error(system.gravity(jnp.asarray(q), params), jac.T @ gravity) < 1e-12
