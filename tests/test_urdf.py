"""URDF import (``lagrax.chains.from_urdf``) against Pinocchio, by hand, and on bad files.

- The project's two models (``lagrax/models/urdf``: a 7-DOF arm with a fixed gripper and a
  massless tool frame, a torso on a lift with a fixed head and two 3-link arms) loaded by
  lagrax and by Pinocchio's own URDF parser: ``M`` (CRBA), the bias ``C q̇ + G``, inverse
  dynamics (RNEA) and forward dynamics (ABA) agree to ~1e-12 relative at random states.
  Pinocchio keeps fixed joints as frames and appends their inertia to the parent body;
  lagrax merges them at import: equal ``M`` checks the merge.
- A fixed joint's merge (mass, centre of mass, inertia by the parallel-axis theorem with
  both rotations) against a hand computation.
- Massless links load where the dynamics stay defined (against Pinocchio), and a joint that
  moves no mass is refused by name; inertias that violate the triangle inequality warn.
- Mimic joints against Pinocchio's model of the independent joints reduced by hand
  (``Jᵀ M J``, ``Jᵀ τ``) and against its own mimic joints; locked joints against
  ``pin.buildReducedModel``.
- Bad URDFs raise ``URDFError`` naming the link or joint.
"""

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import pin_coupling, pin_state, rel_error
from lagrax.chains import from_urdf
from lagrax.models import urdf_path

RTOL = 1e-12
N_STATES = 4


# ------------------------------------------------------------------ against Pinocchio
@pytest.fixture(scope="module", params=["arm7", "torso_two_arms"])
def robot(request):
    """The model loaded by lagrax and by Pinocchio, with lagrax's equations compiled once
    (vmapped over states)."""
    pin = pytest.importorskip(
        "pinocchio", reason="Pinocchio (pip install pin) is the reference for URDF dynamics"
    )
    path = urdf_path(request.param)
    tree, params = from_urdf(path)
    model = pin.buildModelFromXML(path.read_text())
    system = tree.system()
    no_damping = {**params, "damping": jnp.zeros(tree.n)}
    funcs = {
        "mass": jax.jit(jax.vmap(lambda q: system.mass_matrix(q, no_damping))),
        "bias": jax.jit(
            jax.vmap(lambda q, qd: system.inverse_dynamics(q, qd, jnp.zeros_like(q), no_damping))
        ),
        "inverse": jax.jit(
            jax.vmap(lambda q, qd, qdd: system.inverse_dynamics(q, qd, qdd, no_damping))
        ),
        "forward": jax.jit(
            jax.vmap(lambda q, qd, tau: system.forward_dynamics(q, qd, no_damping, tau))
        ),
        "damped": jax.jit(jax.vmap(lambda q, qd, tau: system.forward_dynamics(q, qd, params, tau))),
    }
    return pin, tree, params, model, funcs


def test_models_match_pinocchio(robot):
    pin, tree, params, model, funcs = robot
    data = model.createData()
    assert model.nv == tree.n
    np.testing.assert_allclose(model.gravity.linear, [0.0, 0.0, -float(params["g"])])
    rng = np.random.default_rng(tree.n)
    n = tree.n
    q = rng.uniform(-np.pi, np.pi, (N_STATES, n))
    qd, qdd, tau = (rng.uniform(-2, 2, (N_STATES, n)) for _ in range(3))
    mass = np.asarray(funcs["mass"](q))
    bias = np.asarray(funcs["bias"](q, qd))
    inverse = np.asarray(funcs["inverse"](q, qd, qdd))
    forward = np.asarray(funcs["forward"](q, qd, tau))
    damped = np.asarray(funcs["damped"](q, qd, tau))
    b = np.asarray(params["damping"])
    worst = {}
    for k in range(N_STATES):
        qp, vp, order = pin_state(pin, model, tree, q[k], qd[k])
        m_pin = pin.crba(model, data, qp)
        m_pin = (np.triu(m_pin) + np.triu(m_pin, 1).T)[np.ix_(order, order)]
        a_pin = np.zeros(n)
        a_pin[order] = qdd[k]
        t_pin = np.zeros(n)
        t_pin[order] = tau[k]
        td_pin = np.zeros(n)
        td_pin[order] = tau[k] - b * qd[k]  # joint damping: a torque -b q̇
        results = {
            "M": (mass[k], m_pin),
            "bias": (bias[k], pin.rnea(model, data, qp, vp, np.zeros(n))[order]),
            "inverse": (inverse[k], pin.rnea(model, data, qp, vp, a_pin)[order]),
            "forward": (forward[k], pin.aba(model, data, qp, vp, t_pin)[order]),
            "damped": (damped[k], pin.aba(model, data, qp, vp, td_pin)[order]),
        }
        for key, (ours, theirs) in results.items():
            worst[key] = max(worst.get(key, 0.0), rel_error(ours, theirs))
    assert max(worst.values()) <= RTOL, worst


def test_model_structure():
    tree, params = from_urdf(urdf_path("arm7"))
    assert tree.joint_names == tuple(f"joint{i}" for i in range(1, 8))
    assert tree.parents == (-1, 0, 1, 2, 3, 4, 5)
    assert tree.limits[0] == (-2.96, 2.96)
    assert tree.effort_limits[0] == 176.0 and tree.velocity_limits[6] == 3.14
    np.testing.assert_allclose(params["damping"], [0.5, 0.5, 0.3, 0.3, 0.1, 0.1, 0.05])
    assert tree.system().coordinate_names == tree.joint_names
    # link 4's inertia is given along x in a frame pitched by -pi/2: along z after import
    r, length, m = 0.05, 0.2, 2700 * math.pi * 0.05**2 * 0.2
    np.testing.assert_allclose(
        np.diag(params["inertia"][3]),
        [m * (3 * r**2 + length**2) / 12] * 2 + [m * r**2 / 2],
        rtol=1e-8,
    )
    system, _ = lx.models.arm7()
    assert system.n_dof == 7 and system.coordinate_names == tree.joint_names
    assert lx.models.torso_two_arms()[0].n_dof == 8
    torso, _ = from_urdf(urdf_path("torso_two_arms"))
    assert torso.parents == (-1, 0, 1, 2, 3, 1, 5, 6)
    assert torso.joint_types == "PRRRRRRR"
    assert torso.limits[torso.joint_names.index("right_elbow")] == (-math.inf, math.inf)


def test_tip_keeps_the_chain_to_it():
    """``tip``: the joints from the root to that link, with links fixed to them; moving
    branches off the path are dropped."""
    tree, params = from_urdf(urdf_path("torso_two_arms"))
    chain, chain_params = from_urdf(urdf_path("torso_two_arms"), tip="left_forearm")
    assert chain.joint_names == tree.joint_names[:5]
    assert chain.parents == (-1, 0, 1, 2, 3)
    for key in ("m", "offset", "com", "inertia", "damping"):
        np.testing.assert_array_equal(chain_params[key], params[key][:5])
    arm, _ = from_urdf(urdf_path("arm7"), root="link2", tip="link5")
    assert arm.joint_names == ("joint3", "joint4", "joint5")


# ------------------------------------------------------------------ fixed joints by hand
def _rpy(r, p, y):
    def rx(a):
        return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])

    def ry(a):
        return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])

    def rz(a):
        return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])

    return rz(y) @ ry(p) @ rx(r)


def _link(name, mass, xyz="0 0 0", rpy="0 0 0", inertia=(0.1, 0.0, 0.0, 0.2, 0.0, 0.25)):
    ixx, ixy, ixz, iyy, iyz, izz = inertia
    return (
        f'<link name="{name}"><inertial><origin xyz="{xyz}" rpy="{rpy}"/>'
        f'<mass value="{mass}"/><inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" '
        f'iyz="{iyz}" izz="{izz}"/></inertial></link>'
    )


def _joint(name, kind, parent, child, xyz="0 0 0", rpy="0 0 0", axis="0 0 1"):
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/></joint>'
    )


def _mimic_joint(name, kind, parent, child, master, multiplier=1.0, offset=0.0, **place):
    return _joint(name, kind, parent, child, **place).replace(
        "</joint>",
        f'<mimic joint="{master}" multiplier="{multiplier}" offset="{offset}"/></joint>',
    )


def _robot(*parts):
    return '<robot name="r"><link name="base"/>' + "".join(parts) + "</robot>"


def test_fixed_joint_merges_by_parallel_axis():
    """Body A (2 kg, CoM (0.1, 0, 0.2), inertia rotated by its inertial rpy) carries B
    (3 kg) on a fixed joint at (0.3, 0.1, 0) turned by rpy (0.2, −0.4, 0.7), B's inertia
    given in a frame turned by its own rpy. Expected, in A's frame: ``m = m_A + m_B``,
    ``c = (m_A c_A + m_B c_B)/m`` with ``c_B = p + R c'_B``, and
    ``I = Σ R_k Ī_k R_kᵀ + m_k (|c_k − c|² 1 − (c_k − c)(c_k − c)ᵀ)``."""
    ia, ib = (0.1, 0.01, -0.02, 0.2, 0.03, 0.25), (0.05, 0.0, 0.01, 0.06, -0.01, 0.09)
    urdf = _robot(
        _joint("j", "revolute", "base", "a", xyz="0 0 1", axis="0 1 0"),
        _link("a", 2.0, xyz="0.1 0 0.2", rpy="0.3 0 0", inertia=ia),
        _joint("weld", "fixed", "a", "b", xyz="0.3 0.1 0", rpy="0.2 -0.4 0.7"),
        _link("b", 3.0, xyz="0 0.05 -0.1", rpy="0 0.5 0", inertia=ib),
    )
    tree, params = from_urdf(urdf)
    assert tree.n == 1 and tree.joint_names == ("j",)

    def tensor(i):
        return np.array([[i[0], i[1], i[2]], [i[1], i[3], i[4]], [i[2], i[4], i[5]]])

    r_a, r_f, r_b = _rpy(0.3, 0, 0), _rpy(0.2, -0.4, 0.7), _rpy(0, 0.5, 0)
    c_a = np.array([0.1, 0, 0.2])
    c_b = np.array([0.3, 0.1, 0]) + r_f @ np.array([0, 0.05, -0.1])
    i_a = r_a @ tensor(ia) @ r_a.T
    i_b = r_f @ r_b @ tensor(ib) @ r_b.T @ r_f.T
    m = 5.0
    c = (2.0 * c_a + 3.0 * c_b) / m

    def shift(mass, d):
        return mass * (d @ d * np.eye(3) - np.outer(d, d))

    expected = i_a + shift(2.0, c_a - c) + i_b + shift(3.0, c_b - c)
    np.testing.assert_allclose(params["m"], [m], rtol=1e-14)
    np.testing.assert_allclose(params["com"][0], c, rtol=1e-13)
    np.testing.assert_allclose(params["inertia"][0], expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(params["offset"][0], [0, 0, 1])


def test_links_fixed_to_the_world_place_the_joints_below():
    """A fixed joint between the root and the first moving joint moves and turns that
    joint; its link's mass is dropped (it never moves)."""
    urdf = _robot(
        _joint("mount", "fixed", "base", "plate", xyz="0 0 0.5", rpy="0 0 1.0"),
        _link("plate", 10.0),
        _joint("j", "revolute", "plate", "a", xyz="0.2 0 0"),
        _link("a", 1.0),
    )
    tree, params = from_urdf(urdf)
    np.testing.assert_allclose(params["offset"][0], [0.2 * np.cos(1.0), 0.2 * np.sin(1.0), 0.5])
    np.testing.assert_allclose(np.asarray(tree.rotations[0]), _rpy(0, 0, 1.0), atol=1e-15)
    np.testing.assert_allclose(params["m"], [1.0])


# ------------------------------------------------------------------ bad files
GOOD_A = _link("a", 1.0)
BAD = {
    "missing inertial": (
        _robot(_joint("j", "revolute", "base", "a"), '<link name="a"/>'),
        "'a'",
    ),
    "zero mass": (
        _robot(_joint("j", "revolute", "base", "a"), _link("a", 0.0, inertia=(0.0,) * 6)),
        "'j'",
    ),
    "massless leaf": (
        _robot(
            _joint("j1", "revolute", "base", "a"),
            GOOD_A,
            _joint("j2", "revolute", "a", "tool", xyz="0 0 0.2", axis="0 1 0"),
            '<link name="tool"/>',
        ),
        "'j2'",
    ),
    "coincident axes through a massless link": (
        _robot(
            _joint("j1", "revolute", "base", "a"),
            '<link name="a"/>',
            _joint("j2", "revolute", "a", "b"),
            _link("b", 1.0, xyz="0.3 0 0"),
        ),
        "'j2'",
    ),
    "negative mass": (_robot(_joint("j", "revolute", "base", "a"), _link("a", -1.0)), "'a'"),
    "not positive-semidefinite": (
        _robot(
            _joint("j", "revolute", "base", "a"),
            _link("a", 1.0, inertia=(0.1, 0.5, 0, 0.1, 0, 0.1)),
        ),
        "'a'",
    ),
    "two parents": (
        _robot(
            _joint("j1", "revolute", "base", "a"),
            GOOD_A,
            _link("b", 1.0),
            _joint("j2", "revolute", "b", "a"),
            _joint("j3", "revolute", "base", "b"),
        ),
        "'a'",
    ),
    "loop": (
        _robot(
            _joint("j0", "revolute", "base", "c"),
            _link("c", 1.0),
            GOOD_A,
            _link("b", 1.0),
            _joint("j1", "revolute", "a", "b"),
            _joint("j2", "revolute", "b", "a"),
        ),
        "loop",
    ),
    "unknown joint type": (_robot(_joint("hinge", "ball", "base", "a"), GOOD_A), "'hinge'"),
    "floating joint with an offset": (
        _robot(_joint("free", "floating", "base", "a", xyz="0 0 1"), GOOD_A),
        "floating joint 'free' has an <origin> offset",
    ),
    "planar joint without a normal": (
        _robot(_joint("slide", "planar", "base", "a", axis="0 0 0"), GOOD_A),
        "joint 'slide': its <axis xyz> is the zero vector",
    ),
    "unknown link": (_robot(_joint("j", "revolute", "base", "nowhere"), GOOD_A), "'nowhere'"),
    "malformed XML": ('<robot name="r"><link name="base"></robot>', "XML"),
    "bad number": (
        _robot(_joint("j", "revolute", "base", "a", xyz="0 zero 1"), GOOD_A),
        "'j'",
    ),
    "no moving joint": (_robot(_joint("j", "fixed", "base", "a"), GOOD_A), "'base'"),
    "mimic of a fixed joint": (
        _robot(
            _joint("weld", "fixed", "base", "plate"),
            _link("plate", 1.0),
            _mimic_joint("j2", "revolute", "plate", "a", "weld"),
            GOOD_A,
        ),
        "'weld'",
    ),
    "mimic loop": (
        _robot(
            _mimic_joint("j1", "revolute", "base", "a", "j2"),
            GOOD_A,
            _mimic_joint("j2", "revolute", "a", "b", "j1"),
            _link("b", 1.0),
        ),
        "loop",
    ),
    "mimic master dropped by tip": (
        _robot(
            _joint("j1", "revolute", "base", "a"),
            GOOD_A,
            _joint("j2", "revolute", "a", "b"),
            _link("b", 1.0),
            _mimic_joint("j3", "revolute", "a", "c", "j2"),
            _link("c", 1.0),
        ),
        "'j2'",
        {"tip": "c"},
    ),
    "xacro macros": (
        '<robot name="r" xmlns:xacro="http://www.ros.org/wiki/xacro">'
        '<xacro:macro name="arm"><link name="a"/></xacro:macro></robot>',
        "xacro:macro name='arm'",
    ),
    "no link": ('<robot name="r"></robot>', "no <link>"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_urdf_raises_naming_the_culprit(case):
    text, culprit, *options = BAD[case]
    with pytest.raises(lx.URDFError) as info:
        from_urdf(text, **(options[0] if options else {}))
    assert culprit in str(info.value), str(info.value)
    assert isinstance(info.value, lx.LagraxError)


def test_several_roots_need_root():
    text = _robot(_joint("j", "revolute", "base", "a"), GOOD_A, _link("island", 1.0))
    with pytest.raises(lx.URDFError, match="root"):
        from_urdf(text)
    tree, _ = from_urdf(text, root="base")
    assert tree.joint_names == ("j",)


def test_massless_frames_and_missing_meshes_are_fine():
    """A link without <inertial> on a fixed joint is a frame; a mesh that does not exist is
    never read. ``massless_links=True`` admits a moving link without mass."""
    text = _robot(
        _joint("j", "revolute", "base", "a"),
        GOOD_A.replace(
            "</link>",
            '<visual><geometry><mesh filename="package://nowhere/a.stl"/></geometry></visual>'
            "</link>",
        ),
        _joint("tool", "fixed", "a", "flange", xyz="0 0 0.1"),
        '<link name="flange"/>',
    )
    tree, params = from_urdf(text)
    np.testing.assert_allclose(params["m"], [1.0])
    massless = _robot(_joint("j", "revolute", "base", "a"), '<link name="a"/>')
    _, params = from_urdf(massless, massless_links=True)
    np.testing.assert_allclose(params["m"], [0.0])


def test_triangle_inequality_warns_or_refuses():
    """An inertia violating ``I1 + I2 ≥ I3`` (Allegro's and Romeo's, by CAD rounding) loads
    as given with a ``URDFWarning`` naming the link; ``strict_inertia=True`` refuses it."""
    text = _robot(
        _joint("j", "revolute", "base", "a"), _link("a", 1.0, inertia=(0.1, 0, 0, 0.1, 0, 0.3))
    )
    with pytest.warns(lx.URDFWarning, match=r"link 'a'.*triangle.*short by 33\.33%"):
        _, params = from_urdf(text)
    np.testing.assert_allclose(np.diag(params["inertia"][0]), [0.1, 0.1, 0.3])
    with pytest.raises(lx.URDFError, match="'a'.*triangle"):
        from_urdf(text, strict_inertia=True)


def _pin_model(pin, text, **options):
    """Pinocchio's model of a URDF string (urdfdom wants limits on revolute and prismatic
    joints: wide ones added)."""
    limit = '<limit lower="-10" upper="10" effort="100" velocity="10"/>'
    for kind in ("revolute", "prismatic"):
        text = text.replace(f'type="{kind}">', f'type="{kind}">{limit}')
    return pin.buildModelFromXML(text, **options)


def _check_against_pinocchio(pin, tree, params, model, reduce=True, seed=0, damping=False):
    """M, bias and forward dynamics (with the URDF's damping when ``damping``) against
    Pinocchio's model of the independent joints, reduced by the mimic map (``reduce``),
    or against a model with the same coordinates (Pinocchio's own mimic joints)."""
    system = tree.system()
    if not damping:
        params = {**params, "damping": jnp.zeros(tree.n_bodies)}
    data = model.createData()
    jac = pin_coupling(pin, model, tree) if reduce else np.eye(tree.n)
    rng = np.random.default_rng(seed)
    q, qd, tau = (rng.uniform(-1.0, 1.0, (3, tree.n)) for _ in range(3))

    def one(q, qd, tau):
        bias = system.inverse_dynamics(q, qd, jnp.zeros_like(q), params)
        return system.mass_matrix(q, params), bias, system.forward_dynamics(q, qd, params, tau)

    mass, bias, forward = jax.jit(jax.vmap(one))(q, qd, tau)
    worst = {}
    for k in range(3):
        if reduce:
            qp, vp, _ = pin_state(pin, model, tree, q[k], qd[k])
        else:
            qp, vp = q[k], qd[k]
        m_pin = pin.crba(model, data, qp)
        m_ref = jac.T @ (np.triu(m_pin) + np.triu(m_pin, 1).T) @ jac
        b_ref = jac.T @ pin.rnea(model, data, qp, vp, np.zeros(model.nv))
        b_damp = jac.T @ (np.asarray(params["damping"]) * (jac @ qd[k])) if damping else 0.0
        a_ref = np.linalg.solve(m_ref, tau[k] - b_ref - b_damp)
        pairs = {
            "M": (mass[k], m_ref),
            "bias": (bias[k], b_ref + b_damp),
            "forward": (forward[k], a_ref),
        }
        for key, (ours, ref) in pairs.items():
            worst[key] = max(worst.get(key, 0.0), rel_error(ours, ref))
    assert max(worst.values()) <= RTOL, worst


def test_massless_links_load_where_the_dynamics_are_defined():
    """A two-axis joint through a massless link, a massless tool frame on a fixed joint
    and a link with inertia but no mass: accepted by default, and equal to Pinocchio."""
    pin = pytest.importorskip("pinocchio")
    text = _robot(
        _joint("yaw", "revolute", "base", "gimbal", xyz="0 0 0.4"),
        '<link name="gimbal"/>',
        _joint("pitch", "revolute", "gimbal", "arm", axis="0 1 0"),
        _link("arm", 2.0, xyz="0.3 0 0"),
        _joint("flange", "fixed", "arm", "tool", xyz="0.6 0 0"),
        _link("tool", 0.0, inertia=(0.0,) * 6),
        _joint("wrist", "continuous", "arm", "disc", xyz="0.6 0 0", axis="1 0 0"),
        _link("disc", 0.0, inertia=(0.01, 0, 0, 0.005, 0, 0.005)),
    )
    tree, params = from_urdf(text)
    assert tree.joint_names == ("yaw", "pitch", "wrist")
    np.testing.assert_allclose(params["m"], [0.0, 2.0, 0.0])
    _check_against_pinocchio(pin, tree, params, _pin_model(pin, text))


# ------------------------------------------------------------------ mimic and locked joints
MIMIC = _robot(
    _joint("shoulder", "revolute", "base", "a", xyz="0 0 0.5"),
    _link("a", 1.5, xyz="0.1 0 0.2", inertia=(0.05, 0.001, 0, 0.06, 0.002, 0.04)),
    _joint("elbow", "revolute", "a", "b", xyz="0.4 0 0", axis="0 1 0"),
    _link("b", 1.0, xyz="0.2 0 0"),
    _mimic_joint("wrist", "revolute", "b", "c", "elbow", -1.5, 0.2, xyz="0.4 0 0", axis="0 1 0"),
    _link("c", 0.5, xyz="0.1 0.02 0", inertia=(0.01, 0, 0, 0.02, 0, 0.02)),
    _joint("slide", "prismatic", "a", "d", xyz="0 0.2 0", axis="1 0 0"),
    _link("d", 0.3, xyz="0 0 -0.05"),
    _mimic_joint("finger", "prismatic", "d", "e", "slide", -1.0, 0.0, axis="1 0 0"),
    _link("e", 0.2, xyz="0 0.05 0"),
)
for _name, _b in (("elbow", 0.7), ("wrist", 0.3)):  # damping: the wrist's brakes the elbow
    _tag = f'<joint name="{_name}" type="revolute">'
    MIMIC = MIMIC.replace(_tag, f'{_tag}<dynamics damping="{_b}"/>')


def test_mimic_joints_are_reduced_into_the_tree():
    """A revolute joint following another with multiplier −1.5 and offset 0.2 and a
    prismatic finger following a slide: the mimic joints are bodies, not coordinates; the
    equations (damping included: the wrist's brakes the elbow) are Pinocchio's of the
    independent joints reduced by the mimic map, and its own mimic model's."""
    pin = pytest.importorskip("pinocchio")
    tree, params = from_urdf(MIMIC)
    assert tree.n == 3 and tree.n_bodies == 5
    assert tree.system().coordinate_names == ("shoulder", "elbow", "slide")
    assert tree.mimic == ((2, 1, -1.5, 0.2), (4, 3, -1.0, 0.0))
    _check_against_pinocchio(pin, tree, params, _pin_model(pin, MIMIC), damping=True)
    _check_against_pinocchio(pin, tree, params, _pin_model(pin, MIMIC, mimic=True), reduce=False)


def test_mimic_tree_damping_is_per_joint():
    """A mimic tree damps every joint, the mimic ones too: a damping per coordinate (3
    numbers for 5 joints) is refused by name, not broadcast into a raw JAX error or
    read out of range."""
    tree, params = from_urdf(MIMIC)
    q = jnp.array([0.1, 0.2, 0.05])
    with pytest.raises(lx.ShapeError, match=r"params\['damping'\] has shape \(3,\).*\(5,\)"):
        tree.system().forward_dynamics(q, q, {**params, "damping": jnp.zeros(tree.n)})


def test_mimic_tree_paths_agree():
    """A tree with mimic joints: the reduced recursions equal the energies' autodiff (the
    pose maps through the mimic map), the Newton–Euler oracle, and their derivatives
    (``jax.jacfwd`` of the forward dynamics) equal the autodiff path's."""
    tree, params = from_urdf(MIMIC)
    system = tree.system()
    plain = dataclasses.replace(system, equations=None)
    rng = np.random.default_rng(3)
    q, qd, qdd, tau = (jnp.asarray(rng.uniform(-1, 1, tree.n)) for _ in range(4))
    pairs = [
        (system.mass_matrix(q, params), plain.mass_matrix(q, params)),
        (system.inverse_dynamics(q, qd, qdd, params), plain.inverse_dynamics(q, qd, qdd, params)),
        (system.forward_dynamics(q, qd, params, tau), plain.forward_dynamics(q, qd, params, tau)),
        (system.energy(q, qd, params), plain.energy(q, qd, params)),
        (
            lx.newton_euler.rnea(tree, q, qd, qdd, params),
            system.inverse_dynamics(q, qd, qdd, {**params, "damping": jnp.zeros(5)}),
        ),
    ]
    jac = jax.jacfwd(system.forward_dynamics, argnums=(0, 1))(q, qd, params, tau)
    ref = jax.jacfwd(plain.forward_dynamics, argnums=(0, 1))(q, qd, params, tau)
    pairs += list(zip(jac, ref, strict=True))
    assert max(rel_error(a, b) for a, b in pairs) <= 1e-11


def test_mimic_of_a_mimic_follows_the_chain():
    """``c`` mimics ``b`` (×2, +0.1), which mimics ``a`` (×−0.5, +0.3): ``θ_c = 2 (−0.5
    q_a + 0.3) + 0.1 = −q_a + 0.7``. A master missing from the file warns and leaves an
    independent joint, as in Pinocchio without mimic support."""
    text = _robot(
        _joint("a", "revolute", "base", "la"),
        _link("la", 1.0),
        _mimic_joint("b", "revolute", "la", "lb", "a", -0.5, 0.3, axis="0 1 0"),
        _link("lb", 1.0, xyz="0.2 0 0"),
        _mimic_joint("c", "revolute", "lb", "lc", "b", 2.0, 0.1, axis="0 1 0"),
        _link("lc", 1.0, xyz="0.2 0 0"),
    )
    tree, _ = from_urdf(text)
    assert tree.mimic == ((1, 0, -0.5, 0.3), (2, 0, -1.0, 0.7))
    np.testing.assert_allclose(tree.joint_angles(jnp.asarray([0.4])), [0.4, 0.1, 0.3])
    dangling = text.replace('<mimic joint="a"', '<mimic joint="nowhere"')
    with pytest.warns(lx.URDFWarning, match="joint 'b' mimics joint 'nowhere'"):
        tree, _ = from_urdf(dangling)
    assert tree.coordinate_names() == ("a", "b") and tree.mimic == ((2, 1, 2.0, 0.1),)


def test_locked_joints_match_pinocchio_reduced_model():
    """``locked=`` fixes a prismatic and a revolute joint at values, as
    ``pin.buildReducedModel`` does."""
    pin = pytest.importorskip("pinocchio")
    path = urdf_path("torso_two_arms")
    locks = {"lift": 0.12, "left_elbow": -0.7}
    tree, params = from_urdf(path, locked=locks)
    assert tree.n == 6 and "lift" not in tree.joint_names
    full = pin.buildModelFromXML(path.read_text())
    ids = [full.getJointId(name) for name in locks]
    q_ref = pin.neutral(full)
    for name, value in locks.items():
        q_ref[full.joints[full.getJointId(name)].idx_q] = value
    model = pin.buildReducedModel(full, ids, q_ref)
    _check_against_pinocchio(pin, tree, params, model)


def test_locking_a_master_locks_its_mimics():
    pin = pytest.importorskip("pinocchio")
    tree, params = from_urdf(MIMIC, locked={"elbow": 0.4})
    assert tree.joint_names == ("shoulder", "slide", "finger") and len(tree.mimic) == 1
    full = _pin_model(pin, MIMIC)
    ids = [full.getJointId(name) for name in ("elbow", "wrist")]
    q_ref = pin.neutral(full)
    q_ref[full.joints[ids[0]].idx_q], q_ref[full.joints[ids[1]].idx_q] = 0.4, -1.5 * 0.4 + 0.2
    _check_against_pinocchio(pin, tree, params, pin.buildReducedModel(full, ids, q_ref))


@pytest.mark.parametrize(
    ("locked", "message"),
    [
        ({"nowhere": 0.0}, "'nowhere' is not a joint"),
        ({"wrist": 0.0}, "'wrist' mimics joint 'elbow'; lock its master"),
        ({"elbow": math.nan}, "'elbow' needs a finite value"),
    ],
)
def test_bad_locked_joints(locked, message):
    with pytest.raises(lx.URDFError, match=message):
        from_urdf(MIMIC, locked=locked)


def test_tree_mimic_entries_are_checked():
    with pytest.raises(lx.ConfigurationError, match="itself a mimic"):
        lx.chains.Tree("RRR", (-1, 0, 1), mimic=[(1, 0, 1.0, 0.0), (2, 1, 1.0, 0.0)])
    with pytest.raises(lx.ConfigurationError, match="two different bodies"):
        lx.chains.Tree("RR", (-1, 0), mimic={1: (1, 1.0, 0.0)})


def test_sweep_labels_dof_by_joint_name():
    """A sweep of a URDF robot labels its ``dof`` axis with the joint names."""
    text = _robot(
        _joint("shoulder", "revolute", "base", "a", axis="0 1 0"),
        _link("a", 1.0, xyz="0 0 -0.3"),
        _joint("elbow", "continuous", "a", "b", xyz="0 0 -0.6", axis="0 1 0"),
        _link("b", 0.5, xyz="0 0 -0.2"),
    )
    tree, params = from_urdf(text)
    batch = {k: jnp.stack([v, v]) for k, v in params.items()}
    batch["m"] = jnp.stack([params["m"], 2 * params["m"]])
    ds = lx.sweep(tree.system(), [0.3, 0.1], [0.0, 0.0], batch, t1=0.05, progress=False)
    assert list(ds["dof"].values) == ["shoulder", "elbow"]
    assert bool(ds["ok"].all())
    assert ds["q"].sel(dof="elbow").shape == (2,)
