"""Every URDF that example-robot-data ships, loaded with default options and held to
Pinocchio.

For each file, lagrax's ``M`` (CRBA), bias ``C q̇ + G`` (RNEA) and forward dynamics
(ABA; a Cholesky solve for a robot with mimic joints) at three random states against
Pinocchio's model of the same file (``buildModelFromUrdf``, fixed base), joints matched by
name, continuous joints as ``(cos q, sin q)``: ``M`` and the bias to 1e-12 relative. The
accelerations equal Pinocchio's ABA, and solve Pinocchio's equations (the residual
``M a + b − τ`` against the size of its terms: the backward error), to 1e-12 relative
where ``M`` is well conditioned. Errors in the accelerations grow with the condition
number ``κ(M)`` (iCub's and TIAGo's reach 5e6–7e6, from gram-light finger and sensor
links on 30-kg bodies), and lagrax's ABA, in world coordinates, leaves a larger residual
there than Pinocchio's in link frames (TIAGo without hand: 4e-12 against 3e-14), so their
bound is ``1e-12 · max(1, κ / 1e4)``; only iCub (9.5e-11 at κ = 7e6) and TIAGo without
hand (7.9e-12 at κ = 5e6) need the slack.

Pinocchio's model is built without mimic support (its mimic parser refuses Romeo and
TALOS, whose mimic joints come before their masters), so a mimic joint is an independent
joint there, and the reference is its reduction by hand: ``Jᵀ M J`` and ``Jᵀ τ`` with ``J`` the
mimic map (``_helpers.pin_coupling``), the accelerations by solving the reduced equations.

The few files that cannot be a fixed-base robot fail with a ``URDFError`` naming why
(``FAILS``; the two single rigid bodies among them, ``FREE_BODIES``, load with a floating
base and are held to Pinocchio's free flyer there); the files whose inertias violate the
triangle inequality or whose mimic joints name a missing master load with a
``URDFWarning`` (``WARNS``).

With a floating base (``BASES``: ``from_urdf(..., floating_base=True)``) the reference
is Pinocchio's free-flyer model of the same file (``buildModelFromUrdf(path,
pin.JointModelFreeFlyer())``, the free flyer on the root link, the links fixed to it
merged into it) at states with a random unit quaternion; the base's six velocities come
first in both libraries, and a mimic joint is reduced by hand as above (``J =
blockdiag(I_6, J_joints)``). Every file that loads fixed loads floating too (TIAGo with a
``URDFWarning``: its antenna links, fixed to the base, have inertias that are not
positive-semidefinite, which the fixed base never reads).

Each robot's three functions are compiled once, as one program vmapped over the states
(a module-scoped fixture per robot and base). Compiling costs 2–15 s a robot on 2 cores
(it grows with the tree's depth: TIAGo, iCub and the human model are the slowest), 128
robot–base pairs in all, far beyond the suite's 15 minutes. So the suite holds the
dynamics of one robot of each kind to Pinocchio: ``QUICK`` (mimic joints, massless links,
continuous and prismatic joints, inconsistent inertias, ill-conditioned ``M``) and
``QUICK_FLOATING`` (a quadruped, a humanoid with mimic grippers, TIAGo's warned antennas,
the Panda's mimic finger, the two single rigid bodies), fourteen pairs; and every file's
model, with nothing to compile: its joints, their placements and the inertial parameters
lagrax reads (with the links fixed to each body merged into it) against Pinocchio's
(``test_every_robot_reads_as_pinocchio_does``). The dynamics of all the files, on both
bases, are the same test with ``LAGRAX_ALL_ROBOTS=1`` set (about 25 minutes on 2 cores),
as for ``test_robot_derivatives.py``.
"""

import os
import warnings
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import pin_coupling, pin_state, rel_error, robots_or_skip
from lagrax.chains import from_urdf

RTOL = 1e-12
N_STATES = 3
BASES = ["fixed", "floating"]

pin = pytest.importorskip(
    "pinocchio", reason="Pinocchio (pip install pin) is the reference for URDF dynamics"
)


ROBOTS = robots_or_skip()
URDFS = sorted(str(p.relative_to(ROBOTS)) for p in ROBOTS.rglob("*.urdf"))
XACROS = sorted(str(p.relative_to(ROBOTS)) for p in ROBOTS.rglob("*.xacro"))

# Single rigid bodies (only fixed joints): refused on a fixed base (what the URDFError
# says), loaded on a floating base (a free body: `q` of size 7, `v` of size 6).
FREE_BODIES = {
    "hector_description/robots/quadrotor_base.urdf": "no revolute, continuous or prismatic",
    "iris_description/robots/iris_simple.urdf": "no revolute, continuous or prismatic",
}
# Files that are not a fixed-base robot, with what the URDFError says.
FAILS = {
    **FREE_BODIES,
    # the hand joints move only massless finger links (mimic joints): M is singular
    "romeo_description/urdf/romeo.urdf": "joint 'LHand' moves no mass",
    # a principal moment of -0.0027 kg m² (5 % of the largest): not an inertia
    "romeo_description/urdf/romeo_laas_small.urdf": "'LHipPitch_link' <inertia> is not positive",
    # xacro's output of a macro file: an empty <robot>
    "ur_description/urdf/ur3.urdf": "no <link>",
}
# Files that load with a URDFWarning, and a name each warning is about.
WARNS = {
    "allegro_hand_description/urdf/allegro_left_hand.urdf": "link 'link_3.0'",
    "allegro_hand_description/urdf/allegro_right_hand.urdf": "link 'link_3.0'",
    "hyq_description/robots/hyq_no_sensors.urdf": "link 'lf_foot'",
    "pr2_description/urdf/pr2.urdf": "link 'sensor_mount_link'",
    "romeo_description/urdf/romeo_small.urdf": "link 'RShoulderYawLink'",
    "alex_description/urdf/alex_psyonic_hands.urdf": "joint 'Left_index_q2'",
}
LOADS = [u for u in URDFS if u not in FAILS]
QUICK = {
    "panda_description/urdf/panda.urdf",  # a mimic finger
    "pr2_description/urdf/pr2.urdf",  # mimic, continuous joints, inertia warnings
    "talos_data/robots/talos_full_v2_box.urdf",  # mimic joints before their masters
    "ur_description/urdf/ur5_robot.urdf",  # a massless ee_link
    "human_description/robots/human.urdf",  # massless links inside 3-axis joints
    "allegro_hand_description/urdf/allegro_right_hand.urdf",  # triangle inequality
    "tiago_description/robots/tiago_no_hand.urdf",  # prismatic torso, ill-conditioned
    "icub_description/robots/icub.urdf",  # point-mass links, ill-conditioned
}

QUICK_FLOATING = {
    "solo_description/robots/solo12.urdf",  # a quadruped
    "talos_data/robots/talos_full_v2_box.urdf",  # a humanoid with mimic grippers
    "tiago_description/robots/tiago_no_hand.urdf",  # antennas with bad inertias on the base
    "panda_description/urdf/panda.urdf",  # a mimic finger
    *FREE_BODIES,  # no joints: the base alone
}


def _load(rel: str, **options):
    """``from_urdf`` of one file, with the warnings it gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", lx.URDFWarning)
        tree, params = from_urdf(ROBOTS / rel, **options)
    return tree, params, [str(w.message) for w in caught]


def _equations(system, params):
    """``(M, bias, q̈)`` at a batch of states, one compiled program (XLA's backend
    optimizations off: they cost a third of the compile time, and these run once)."""

    def one(q, qd, tau):
        bias = system.inverse_dynamics(q, qd, jnp.zeros_like(qd), params)
        return system.mass_matrix(q, params), bias, system.forward_dynamics(q, qd, params, tau)

    def run(q, qd, tau):
        lowered = jax.jit(jax.vmap(one)).lower(q, qd, tau)
        return lowered.compile({"xla_backend_optimization_level": 0})(q, qd, tau)

    return run


ALL_ROBOTS = os.environ.get("LAGRAX_ALL_ROBOTS", "") not in ("", "0")
PAIRS = [(u, b) for u in LOADS for b in BASES] + [(u, "floating") for u in sorted(FREE_BODIES)]
if not ALL_ROBOTS:  # one robot of each kind (see the module docstring)
    PAIRS = [(u, b) for u, b in PAIRS if u in (QUICK if b == "fixed" else QUICK_FLOATING)]


@pytest.fixture(
    scope="module",
    params=[pytest.param(pair, id=f"{Path(pair[0]).stem}-{pair[1]}") for pair in PAIRS],
)
def robot(request):
    rel, base = request.param
    if base == "floating":
        robot, params, _ = _load(rel, floating_base=True)
        model = pin.buildModelFromUrdf(str(ROBOTS / rel), pin.JointModelFreeFlyer())
        tree = robot.tree
    else:
        tree, params, _ = _load(rel)
        model = pin.buildModelFromUrdf(str(ROBOTS / rel))
        robot = tree
    params = {**params, "damping": jnp.zeros(tree.n_bodies)}  # Pinocchio's ABA has none
    return rel, base, tree, params, model, _equations(robot.system(), params)


def _states(rng, n: int, floating: bool):
    """``(q, q̇, τ)`` at ``N_STATES`` random states: joints in ``[-1, 1]``; a floating
    base's position normal and its quaternion a random unit one."""
    joints, qd, tau = (rng.uniform(-1.0, 1.0, (N_STATES, n)) for _ in range(3))
    if not floating:
        return joints, qd, tau
    quat = rng.normal(size=(N_STATES, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    q = np.concatenate([rng.normal(size=(N_STATES, 3)), quat, joints], axis=1)
    base_v, base_f = rng.normal(size=(2, N_STATES, 6))
    return q, np.concatenate([base_v, qd], axis=1), np.concatenate([base_f, tau], axis=1)


def test_robot_matches_pinocchio(robot):
    rel, base, tree, params, model, equations = robot
    floating = base == "floating"
    nb = 6 if floating else 0  # the base's velocities, first in both libraries
    assert model.nv == nb + tree.n_bodies, (model.nv, tree.n_bodies)
    rng = np.random.default_rng(len(rel))
    q, qd, tau = _states(rng, tree.n, floating)
    mass, bias, forward = (np.asarray(x) for x in equations(q, qd, tau))
    data = model.createData()
    # J = blockdiag(I_6, J_joints) with a floating base (Pinocchio's base velocities first)
    jac = np.hstack([np.eye(model.nv)[:, :nb], pin_coupling(pin, model, tree)])
    worst = {}
    for k in range(N_STATES):
        qp, vp, _ = pin_state(pin, model, tree, q[k, 7 * floating :], qd[k, nb:])
        qp[: 7 * floating], vp[:nb] = q[k, : 7 * floating], qd[k, :nb]
        m_pin = pin.crba(model, data, qp)
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        m_ref = jac.T @ m_pin @ jac
        b_ref = jac.T @ pin.rnea(model, data, qp, vp, np.zeros(model.nv))
        if tree.mimic:  # the reduced equations, solved
            a_ref = np.linalg.solve(m_ref, tau[k] - b_ref)
        else:  # J is a permutation
            a_ref = jac.T @ pin.aba(model, data, qp, vp, jac @ tau[k])
        terms = (np.abs(m_ref) @ np.abs(forward[k]), np.abs(b_ref), np.abs(tau[k]))
        residual = m_ref @ forward[k] + b_ref - tau[k]
        kappa = np.linalg.cond(m_ref)
        errors = {
            "M": rel_error(mass[k], m_ref),
            "bias": rel_error(bias[k], b_ref),
            "backward": float(np.max(np.abs(residual) / sum(terms))) / max(1.0, kappa / 1e4),
            "ABA": rel_error(forward[k], a_ref) / max(1.0, kappa / 1e4),
        }
        worst = {key: max(worst.get(key, 0.0), e) for key, e in errors.items()}
    assert max(worst.values()) <= RTOL, worst


@pytest.mark.parametrize("rel", LOADS)
def test_every_robot_reads_as_pinocchio_does(rel):
    """Every file that loads, read with nothing compiled: lagrax's joints are Pinocchio's
    (by name, in an order where each parent comes first), with the same parents, joint
    placements, and inertial parameters in the joint frames (the masses, centres of mass
    and rotational inertias of the links fixed to each body merged into it, as Pinocchio
    merges them), to round-off."""
    tree, params, _ = _load(rel)
    model = pin.buildModelFromUrdf(str(ROBOTS / rel))
    ids = [model.getJointId(name) for name in tree.joint_names]
    assert len(tree.joint_names) == tree.n_bodies == model.njoints - 1
    assert all(i < model.njoints for i in ids), tree.joint_names
    parents = [ids[p] if p >= 0 else 0 for p in tree.parents]
    assert parents == [model.parents[i] for i in ids]
    inertias = [model.inertias[i] for i in ids]
    reference = {
        "m": [y.mass for y in inertias],
        "com": [y.lever for y in inertias],
        "inertia": [y.inertia for y in inertias],
        "offset": [model.jointPlacements[i].translation for i in ids],
    }
    scale = {"m": max(reference["m"]), "com": 1.0, "offset": 1.0}
    for key, ref in reference.items():
        ref = np.asarray(ref)
        size = scale.get(key, np.max(np.abs(ref)))
        assert np.max(np.abs(np.asarray(params[key]) - ref)) <= 1e-12 * size, key


def test_floating_base_merges_bad_inertias_with_a_warning():
    """TIAGo's antenna links, fixed to its base, have inertias that are not
    positive-semidefinite: a fixed base never reads them; a floating base merges them
    (as Pinocchio does) with a warning naming each."""
    *_, messages = _load("tiago_description/robots/tiago_no_hand.urdf", floating_base=True)
    assert any("link 'base_antenna_left_link'" in m for m in messages), messages


@pytest.mark.parametrize("rel", LOADS)
def test_robot_warnings(rel):
    """Exactly the files in ``WARNS`` warn, and name what they warn about."""
    *_, messages = _load(rel)
    if rel in WARNS:
        assert messages and any(WARNS[rel] in m for m in messages), messages
        assert all(m.startswith(("link '", "joint '")) for m in messages), messages
    else:
        assert not messages, messages


@pytest.mark.parametrize("rel", sorted(FAILS))
def test_refused_files_name_the_reason(rel):
    with pytest.raises(lx.URDFError, match=FAILS[rel].replace("(", r"\(")):
        _load(rel)


@pytest.mark.parametrize("rel", XACROS)
def test_xacro_files_are_not_robots(rel):
    with pytest.raises(lx.URDFError, match="xacro"):
        _load(rel)


def test_most_files_load():
    """The package ships 69 URDF files; all but the five in ``FAILS`` load, and two of
    those five (``FREE_BODIES``) load with a floating base."""
    assert len(URDFS) >= 60 and len(FAILS) <= 5
    assert set(FAILS) <= set(URDFS) and set(WARNS) <= set(LOADS)
    assert set(FREE_BODIES) <= set(FAILS)


# ------------------------------------------------------------------ options on shipped robots
def test_romeo_loads_with_its_hands_locked():
    """Romeo's hand joints move only massless finger links: refused as they are, loaded
    with the hands locked (their mimic fingers lock with them)."""
    tree, _, _ = _load("romeo_description/urdf/romeo.urdf", locked={"LHand": 0.0, "RHand": 0.0})
    assert "LHand" not in tree.joint_names and not tree.mimic
    assert tree.n == 31


def test_panda_with_fingers_locked_matches_pinocchio_reduced_model():
    """``locked=`` against ``pin.buildReducedModel`` (the Panda as DESIGN.md loads it):
    locking the master finger locks its mimic."""
    rel = "panda_description/urdf/panda.urdf"
    tree, params, _ = _load(rel, locked={"panda_finger_joint1": 0.03})
    assert tree.joint_names == tuple(f"panda_joint{i}" for i in range(1, 8))
    full = pin.buildModelFromUrdf(str(ROBOTS / rel))
    lock = [full.getJointId(f"panda_finger_joint{i}") for i in (1, 2)]
    q_ref = pin.neutral(full)
    for jid in lock:
        q_ref[full.joints[jid].idx_q] = 0.03
    model = pin.buildReducedModel(full, lock, q_ref)
    params = {**params, "damping": jnp.zeros(tree.n)}
    rng = np.random.default_rng(7)
    q, qd, tau = (rng.uniform(-1.0, 1.0, (N_STATES, tree.n)) for _ in range(3))
    mass, bias, forward = (np.asarray(x) for x in _equations(tree.system(), params)(q, qd, tau))
    data = model.createData()
    for k in range(N_STATES):
        m_pin = pin.crba(model, data, q[k])
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        assert rel_error(mass[k], m_pin) <= RTOL
        assert rel_error(bias[k], pin.rnea(model, data, q[k], qd[k], np.zeros(7))) <= RTOL
        assert rel_error(forward[k], pin.aba(model, data, q[k], qd[k], tau[k])) <= RTOL


def test_panda_mimic_matches_pinocchio_mimic_model():
    """The Panda's second finger mimics the first: lagrax's reduced equations equal
    Pinocchio's own mimic joints (``buildModelFromUrdf(..., mimic=True)``: CRBA and RNEA;
    its ABA does not support mimic joints)."""
    rel = "panda_description/urdf/panda.urdf"
    tree, params, _ = _load(rel)
    assert tree.n == 8 and tree.n_bodies == 9
    assert tree.system().coordinate_names == tree.joint_names[:8]
    model = pin.buildModelFromUrdf(str(ROBOTS / rel), mimic=True)
    assert model.nv == 8
    params = {**params, "damping": jnp.zeros(tree.n_bodies)}
    rng = np.random.default_rng(8)
    q, qd, tau = (rng.uniform(-1.0, 1.0, (N_STATES, tree.n)) for _ in range(3))
    mass, bias, _ = (np.asarray(x) for x in _equations(tree.system(), params)(q, qd, tau))
    data = model.createData()
    for k in range(N_STATES):
        m_pin = pin.crba(model, data, q[k])
        m_pin = np.triu(m_pin) + np.triu(m_pin, 1).T
        assert rel_error(mass[k], m_pin) <= RTOL
        assert rel_error(bias[k], pin.rnea(model, data, q[k], qd[k], np.zeros(8))) <= RTOL
