"""URDF import: a robot description file as a [`Tree`][lagrax.chains.Tree] and its params.

Read with the standard library's `xml.etree.ElementTree`: lagrax needs only the
kinematic and inertial elements of URDF (`<link><inertial>`, `<joint>` with its
`<origin>`, `<axis>`, `<limit>`, `<dynamics>`), which are a few attributes each;
geometry is read only for `contact=` (`<collision>`, `collision.py`; meshes with
`trimesh`), so without it a missing mesh file cannot be an error. Reading the elements
here also lets every error name the link or joint at fault.
"""

import math
import os
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import jax.numpy as jnp
import numpy as np

from ..._core.errors import MissingFileError, URDFError, URDFWarning
from ..articulated.trees import Tree
from ..common import about_centres, float_dtype, steiner
from ..limits import with_limits
from .collision import check_meshes, urdf_points
from .contact_scene import contact_friction, contact_scene, limits_need_contact, robot_up
from .urdf_elements import (
    MOVING,
    Body,
    JointElement,
    floating_joint,
    keep_links,
    parse,
    planar_parts,
    read_inertial,
    structure,
)


def from_urdf(
    source: str | os.PathLike,
    *,
    root: str | None = None,
    tip: str | None = None,
    up: Any = (0.0, 0.0, 1.0),
    g: float = 9.81,
    massless_links: bool = False,
    dtype: Any = None,
    locked: Mapping[str, float] | None = None,
    strict_inertia: bool = False,
    limits: str | None = None,
    restitution: Any = 0.0,
    floating_base: bool = False,
    contact: bool | Sequence[str] = False,
    meshes: str = "bounding_sphere",
    package_dirs: Sequence[str] = (),
    friction: float | None = None,
) -> tuple[Any, dict]:
    r"""A robot from a URDF file (or string) as a [`Tree`][lagrax.chains.Tree] and its params.

    Each revolute, continuous or prismatic joint becomes a body of the tree, a planar
    joint three (a slide along `name/x` and `name/y` in its plane, then a continuous
    rotation `name` about its axis: `q = (x, y, θ)`, the translation in the joint's
    frame; Pinocchio's planar joint has `(x, y, cos θ, sin θ)` with the velocity in the
    moving frame) (bodies are
    numbered depth-first from the root, children in file order), with its
    `<origin xyz rpy>` as the placement (`offset` in `params`, the rotation
    `Rz(yaw) Ry(pitch) Rx(roll)` in the structure), its `<axis>`, `<limit>` (kept in
    `tree.limits`, `velocity_limits`, `effort_limits`; continuous joints are
    unlimited) and `<dynamics damping>` (`params["damping"]`, a Rayleigh dissipation;
    `friction` is not modelled). Joint names become `tree.joint_names` and the
    system's `coordinate_names`.

    **Continuous joints** are revolute joints without limits, and their coordinate is
    the angle `q` (any real number; `q` and `q + 2π` are the same pose). Pinocchio
    stores such a joint's configuration as the unit vector `(cos q, sin q)` (two entries
    of its `q`, one of its `v`): to compare, map the angle to `(cos q, sin q)` (and back
    with `atan2`); velocities, accelerations and torques are the same numbers.

    A link's `<inertial>` gives its mass `m`, centre of mass `c` (`<origin xyz>`)
    and inertia `R Ī Rᵀ` with `Ī` the `<inertia>` entries and `R` the
    `<origin rpy>` rotation (URDF states the inertia in that rotated frame). **Fixed
    joints are merged**: a link fixed (directly or through other fixed joints) to a moving
    body at placement `(R_f, p_f)` adds `m`, the first moment `m (p_f + R_f c)` and
    the inertia about the body's origin `R_f Ī' R_fᵀ + m (|c'|² 1 − c' c'ᵀ)`
    (`c' = p_f + R_f c`; the parallel-axis theorem) to that body; the body's centre of
    mass and inertia about it follow from the sums. Links fixed to the root (the world)
    do not move and are dropped; joints below them are placed through them.

    **Massless links** (no `<inertial>`, or mass zero: a tool frame, a sensor, the
    intermediate link of a two- or three-axis joint) are accepted wherever the
    dynamics stay defined: fixed to a massive link, or moving a massive subtree. After
    loading, the mass matrix is checked at two random configurations; if it is singular
    at both (a joint that moves no mass, or only what the joints before it already move),
    `from_urdf` raises a `URDFError` naming that joint.

    **Mimic joints** (`<mimic joint="master" multiplier="a" offset="b"/>`: a gripper's
    second finger) are not coordinates: the joint's angle is `a q_master + b`, and the
    tree's equations are reduced by that map (`M = Jᵀ M_θ J`, the master's generalized
    force includes the mimic's; see [`Tree`][lagrax.chains.Tree]). `tree.joint_names`
    lists every moving joint (mimics included, as do `tree.limits` etc.);
    the system's `coordinate_names` and `q` only the independent ones. A mimic of a
    mimic follows the end of the chain (multipliers and offsets composed).

    Geometry (`<visual>`, `<collision>`, meshes) is ignored unless `contact=` asks for
    the `<collision>` elements: without it a missing mesh file is no error.

    **Contact** (`contact=True`, or a list of link names): each `<collision>` shape of
    the chosen links becomes [`Sphere`][lagrax.contact.Sphere]s fixed to its body (by
    [`body_sphere`][lagrax.contact.body_sphere], the tree's own kinematics): a `<sphere>`
    itself, a `<box>` its 8 corners (radius 0), a `<capsule radius length>` its 2 end
    spheres, a `<cylinder>` 8 points on each end's rim (radius 0: exact standing or tilted
    on a face, an octagon rolling on its side), a `<mesh>` its smallest bounding sphere
    (`meshes="bounding_sphere"`, read with `trimesh`) or its convex hull's vertices
    (`meshes="vertices"`). The result is then a
    [`ContactSystem`][lagrax.contact.ContactSystem] of the robot's system on the ground
    `z = 0` (normal `up`), with the contact's default coefficients (scaled from the scene)
    and one friction coefficient per sphere in `params["contact_friction"]`: `friction`
    if given, else the link's Bullet `<contact><lateral_friction value>`, else 1
    (MuJoCo's default). Links fixed to the world on a fixed base do not move and are
    skipped. A link's bounding sphere can reach below the part that should touch the
    ground (solo12's lower leg, with its foot): name the links that touch,
    `contact=["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]`.

    **Arguments:**

    - `source`: a path to a `.urdf` file, or the URDF XML itself (a string starting
      with `<`).
    - `root`: the link fixed to the world (default: the URDF's only root link). The tree
      is everything below it.
    - `tip`: a link below `root`: keep only the chain of joints from `root` to
      `tip` (with every link fixed to one of its links); branches off the path are
      dropped.
    - `up`: the direction opposite to gravity (default `(0, 0, 1)`: gravity along −z,
      as in Pinocchio and MuJoCo).
    - `g`: gravity's magnitude (`params["g"]`).
    - `massless_links`: skip the check of the mass matrix (see above): load even a robot
      whose mass matrix is singular (its forward dynamics are then NaN), e.g. to use its
      kinematics. Massless links that leave the dynamics defined load without it.
    - `dtype`: of the params (default float64 with x64).
    - `locked`: `{joint name: value}`: joints fixed at these values (radians or
      metres), as Pinocchio's `buildReducedModel` does: each becomes a fixed joint
      whose transform includes the motion by the value, and its child link is merged
      like any fixed link (e.g. `{"panda_finger_joint1": 0.02}` for the Panda with its
      fingers locked). Locking a mimic joint's master locks the mimic joint too (at
      `a · value + b`); a mimic joint itself cannot be locked.
    - `strict_inertia`: refuse an `<inertia>` whose principal moments violate the
      triangle inequality `I1 + I2 ≥ I3` (more than `1e-6 I3`). By default such a
      link is loaded as given, with a [`lagrax.URDFWarning`][] naming it and the
      shortfall: no rigid body has such moments, but the body's spatial inertia stays
      positive-semidefinite and the dynamics are defined (Pinocchio accepts them too).

    - `limits`: `None` (default): the `<limit>`s are kept in `tree.limits` and not
      enforced; `"impact"`: joints stop at their limits by impacts with coefficient of
      restitution `restitution` (the params gain `"restitution"`, one per joint; pass
      [`lagrax.chains.limit_events`][]`(tree)` to [`lagrax.simulate`][]'s `events=`,
      and the hits are in `Solution.events`); `"contact"` (with `contact=`): each
      finite limit is a compliant stop of the contact scene, the ground contact's normal
      law in joint space (a [`JointLimit`][lagrax.contact.JointLimit]; its energy and
      dissipation in the scene's energy balance, its coefficients scaled from the scene).
    - `restitution`: with `limits="impact"`, a number in `[0, 1]` or one per joint
      (default `0`: the joint stops dead at its limit).
    - `floating_base`: `True` for a robot that is not bolted to the world (a quadruped,
      a humanoid): the root link, with every link fixed to it, becomes a free-floating
      base and the result a [`FloatingTree`][lagrax.chains.FloatingTree] whose state is
      Pinocchio's free-flyer `q = (x, y, z, qx, qy, qz, qw, joints…)`,
      `v = (base linear, base angular velocity in the base frame, joint rates…)`; its
      params gain `base_m`, `base_com`, `base_inertia`. The root link, with the links
      fixed to it, must then have a positive mass (as Pinocchio's
      `buildModelFromUrdf(path, pin.JointModelFreeFlyer())`, which puts the free flyer on
      the root link). A link fixed to the base whose own `<inertia>` is not
      positive-semidefinite (TIAGo's antennas) is merged with a
      [`lagrax.URDFWarning`][] naming it, when the base's merged inertia is. Mimic
      joints are supported as on a fixed base, and so are `limits="impact"`
      ([`lagrax.chains.limit_events`][] stops the joints `q[7:]`; a stop's impulse
      acts on its joint alone, not on the base). A robot with no moving joint (a single
      rigid body: a quadrotor, every link fixed to the root) is the base alone, a
      `FloatingTree` of a [`Tree`][lagrax.chains.Tree] with no joints: `q = (x, y, z,
      qx, qy, qz, qw)`, `v = (v_b, ω_b)`. A URDF `floating` joint from the root link
      (a world link, carrying nothing else) with no `<origin>` offset is the same: its
      child becomes the floating base (as Pinocchio reads it, a free flyer), with or
      without `floating_base=True`.

    **Returns:** `(tree, params)`: the [`Tree`][lagrax.chains.Tree] (`tree.system()` gives the
    system) and `{"m", "offset", "com", "inertia", "damping", "g"}` (one row per
    body, mimic ones included; and `"restitution"` with `limits="impact"`). With
    `contact`: `(scene, params)`, the `ContactSystem` (`scene.system` the robot's system,
    `scene.spheres` in the order the links and their `<collision>` elements appear) and
    the params plus `"contact_friction"`.

    **Raises:** [`lagrax.URDFError`][] naming the link or joint for: malformed XML, a xacro
    file (macros, not a robot) or a `<robot>` without links, an incomplete `<inertial>`, a
    negative mass, an inertia that is not positive-semidefinite (or, with `strict_inertia`,
    violates the triangle inequality), a joint that moves no mass (a singular mass matrix),
    a link with two parents, a loop, several roots without `root=`, an unknown joint type, a
    locked planar joint, several floating joints or one that is not the root's only joint
    with an identity origin, a mimic joint whose master is missing, fixed, dropped by `tip`
    or part of a mimic loop, a `locked` name that is not a moving joint (or is a mimic
    joint) or a value that is not finite, a robot with no moving joint below `root` on a
    fixed base (a single rigid body needs `floating_base=True`).
    [`lagrax.MissingFileError`][] (a `FileNotFoundError`) for a missing file. Warns
    [`lagrax.URDFWarning`][] for an inertia that violates the triangle inequality (unless
    `strict_inertia`).

    **Example:**

    ```python
    tree, params = lagrax.chains.from_urdf("arm7.urdf")
    system = tree.system()
    qdd = system.forward_dynamics(q, qd, params, tau)
    tree.joint_names, tree.limits
    panda, params = lagrax.chains.from_urdf(panda_urdf, locked={"panda_finger_joint1": 0.0})
    ```
    """
    check_meshes(meshes)
    limits_need_contact(limits, contact)
    links, joints = parse(_read(source))
    joints, root, floating = floating_joint(joints, root)
    floating_base = floating_base or floating
    _lock(joints, locked)
    root, parent_of, children = structure(links, joints, root)
    keep = keep_links(root, tip, links, parent_of, children)
    bodies, place, order = _place_bodies(root, keep, children)
    if not bodies and not floating_base:
        raise URDFError(
            f"the robot has no revolute, continuous or prismatic joint below {root!r} (none "
            "that is not locked): fixed to the world, it cannot move. A single rigid body "
            "(a quadrotor) moves on a floating base: pass floating_base=True"
        )
    mimic = _mimic_map(bodies, joints)
    _merge_inertials(bodies, place, order, links, strict_inertia)
    tree, params = _tree_and_params(bodies, mimic, up, g, dtype)
    if not massless_links and bodies:
        _check_mass_matrix(tree, params, bodies)
    if floating_base:
        from ..floating.loading import base_from_urdf

        robot, params = base_from_urdf(tree, params, place, order, links, root, read_inertial)
        params = with_limits(tree, params, limits, restitution)[1]
    else:
        robot, params = with_limits(tree, params, limits, restitution)
    if contact is False or contact is None:
        return robot, params
    text = os.fspath(source)
    folder = None if text.lstrip().startswith("<") else os.path.dirname(os.path.abspath(text))
    mesh_info = (folder, tuple(os.fspath(d) for d in package_dirs), meshes)
    points = urdf_points(links, order, place, contact, floating_base, mesh_info)
    ground = (robot_up(robot), 0.0, None)
    return contact_scene(robot, params, points, ground, contact_friction(friction), limits)


def _read(source: str | os.PathLike) -> str:
    """The URDF text: `source` itself if it starts with `<`, else the file it names."""
    text = os.fspath(source)
    if not text.lstrip().startswith("<"):
        if not os.path.exists(text):
            raise MissingFileError(f"no URDF file at {text!r}")
        with open(text, encoding="utf-8") as f:
            text = f.read()
    return text


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """`Rot(axis, angle)` by Rodrigues' formula (unit `axis`)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def _lock(joints: list[JointElement], locked: Mapping[str, float] | None) -> None:
    """Turn every `locked` joint (and every mimic joint of a locked master, at
    `a · value + b`) into a fixed joint whose transform includes its motion by the value:
    a revolute joint's rotation `S Rot(axis, value)`, a prismatic one's origin
    `xyz + S axis value`."""
    if not locked:
        return
    by_name = {j.name: j for j in joints}
    values: dict[str, float] = {}
    for name, value in dict(locked).items():
        j = by_name.get(name)
        if j is None:
            moving = [k.name for k in joints if k.kind != "fixed"]
            raise URDFError(
                f"locked: {name!r} is not a joint of the robot (its moving joints: {moving})"
            )
        if j.kind == "fixed":
            raise URDFError(f"locked: joint {name!r} is a fixed joint already")
        if j.kind == "planar":
            raise URDFError(f"locked: joint {name!r} is planar (three coordinates)")
        if j.mimic is not None:
            raise URDFError(
                f"locked: joint {name!r} mimics joint {j.mimic[0]!r}; lock its master "
                f"{j.mimic[0]!r} instead (the mimic joint follows it)"
            )
        try:
            v = float(value)
        except (TypeError, ValueError):
            v = math.nan
        if not math.isfinite(v):
            raise URDFError(f"locked: joint {name!r} needs a finite value, got {value!r}")
        values[name] = v
    changed = True
    while changed:  # mimic joints follow their locked masters (mimics of mimics too)
        changed = False
        for j in joints:
            if j.mimic is not None and j.name not in values and j.mimic[0] in values:
                master, multiplier, offset = j.mimic
                values[j.name] = multiplier * values[master] + offset
                changed = True
    for name, v in values.items():
        j = by_name[name]
        axis = j.axis / np.linalg.norm(j.axis)
        if MOVING[j.kind] == "R":
            j.rot = j.rot @ _axis_rotation(axis, v)
        else:
            j.xyz = j.xyz + j.rot @ axis * v
        j.kind, j.mimic = "fixed", None


def _mimic_map(bodies: list["Body"], joints: list[JointElement]) -> tuple:
    """`(body, master body, multiplier, offset)` of every body on a mimic joint, a chain
    of mimics followed to its end: `θ = a (a' θ'' + b') + b`."""
    index = {b.joint.name: i for i, b in enumerate(bodies)}
    by_name = {j.name: j for j in joints}
    out = []
    for i, b in enumerate(bodies):
        j, a, off, seen = b.joint, 1.0, 0.0, [b.joint.name]
        while j.mimic is not None:
            name, multiplier, offset = j.mimic
            master = by_name.get(name)
            if master is None:  # a dangling reference: the joint is its own coordinate
                if j is b.joint:
                    warnings.warn(
                        f"joint {j.name!r} mimics joint {name!r}, which is not a joint of the "
                        "robot: loaded as an independent joint (a coordinate of its own), as "
                        "Pinocchio does without mimic support",
                        URDFWarning,
                        stacklevel=3,
                    )
                break
            if master.kind == "fixed":
                raise URDFError(
                    f"joint {j.name!r} mimics joint {name!r}, which is a fixed joint: a mimic "
                    "joint follows a revolute, continuous or prismatic one"
                )
            if name in seen:
                raise URDFError(
                    f"the mimic joints {seen} follow each other in a loop back to {name!r}: "
                    "one of them must be an independent joint"
                )
            seen.append(name)
            a, off = a * multiplier, a * offset + off
            j = master
        if j is b.joint:
            continue
        if j.name not in index:
            raise URDFError(
                f"joint {b.joint.name!r} mimics joint {j.name!r}, which is not in the tree "
                "(root= or tip= dropped it): keep its master, or lock the mimic joint's master"
            )
        out.append((i, index[j.name], a, off))
    return tuple(out)


_Place = dict[str, tuple[int, np.ndarray, np.ndarray]]


def _place_bodies(root: str, keep: set, children: dict) -> tuple[list[Body], _Place, list[str]]:
    """One body per moving joint below `root`, depth-first (pre-order: a parent before
    its children) in file order, and every kept link's place `(body index, R, p)`: its
    frame in its body's frame (body −1: the world; a link on a fixed joint is placed in
    the body it is fixed to)."""
    bodies: list[Body] = []
    place: _Place = {}
    order: list[str] = []
    stack: list[tuple[str, JointElement | None]] = [(root, None)]
    while stack:
        link, j = stack.pop()
        if j is None:
            place[link] = (-1, np.eye(3), np.zeros(3))
        else:
            body, rot, pos = place[j.parent]
            joint_rot, joint_pos = rot @ j.rot, pos + rot @ j.xyz
            if j.kind == "fixed":
                place[link] = (body, joint_rot, joint_pos)
            elif j.kind == "planar":  # three bodies in a row, the link on the last
                for k, part in enumerate(planar_parts(j)):
                    at = (joint_rot, joint_pos) if k == 0 else (part.rot, part.xyz)
                    bodies.append(Body(part, body if k == 0 else len(bodies) - 1, *at))
                place[link] = (len(bodies) - 1, np.eye(3), np.zeros(3))
            else:
                bodies.append(Body(j, body, joint_rot, joint_pos))
                place[link] = (len(bodies) - 1, np.eye(3), np.zeros(3))
        order.append(link)
        stack.extend((c.child, c) for c in reversed(children[link]) if c.child in keep)
    return bodies, place, order


def _merge_inertials(
    bodies: list[Body], place: _Place, order: list[str], links: dict, strict: bool
) -> None:
    """Add every link's `<inertial>` to its body: the mass, the first moment and the
    inertia about the body's origin (parallel-axis theorem); links fixed to the world are
    skipped, and a link without `<inertial>` adds nothing (whether the bodies still
    have a regular mass matrix is checked on the tree: `_check_mass_matrix`)."""
    for link in order:
        body, rot, pos = place[link]
        if body < 0:
            continue  # fixed to the world
        inertial = read_inertial(links[link], strict)
        if inertial is None:
            continue
        c = pos + rot @ inertial.com
        b = bodies[body]
        b.mass += inertial.mass
        b.moment = b.moment + inertial.mass * c
        shift = steiner(inertial.mass, c)
        b.inertia_o = b.inertia_o + rot @ inertial.inertia @ rot.T + shift


def _tree_and_params(
    bodies: list[Body], mimic: tuple, up: Any, g: float, dtype: Any
) -> tuple[Tree, dict]:
    """The [`Tree`][lagrax.chains.Tree] of the merged bodies and its params: each body's
    centre of mass and its inertia about it from the sums (the triangle inequality was
    checked link by link: `read_inertial`)."""
    masses, coms, inertias = about_centres(bodies)
    joint_list = [b.joint for b in bodies]
    tree = Tree(
        "".join(MOVING[j.kind] for j in joint_list),
        [b.parent for b in bodies],
        axes=[j.axis for j in joint_list],
        rotations=[b.rot for b in bodies],
        up=up,
        joint_names=[j.name for j in joint_list],
        body_names=[j.child for j in joint_list],
        limits=[j.limits for j in joint_list],
        velocity_limits=[j.velocity for j in joint_list],
        effort_limits=[j.effort for j in joint_list],
        mimic=mimic,
    )
    params = tree.params(
        m=masses,
        offset=np.reshape([b.offset for b in bodies], (-1, 3)),
        com=coms,
        damping=np.array([j.damping for j in joint_list]),
        inertia=np.zeros_like(inertias),
        g=g,
        dtype=float_dtype(dtype),
    )
    # The links' inertias were checked one by one (`read_inertial`: semidefinite, and the
    # triangle inequality warned about); the bodies' are their sums by the parallel-axis
    # theorem, so a second check here could only trip on round-off (a point-mass link:
    # moments of 1e-20 about its centre of mass) or repeat a warning as an error.
    params["inertia"] = jnp.asarray(inertias, params["m"].dtype)
    return tree, params


# A Cholesky pivot of M below this fraction of its diagonal entry: that coordinate moves
# nothing the coordinates before it do not (an exact zero for a joint moving no mass;
# round-off is ~1e-16 of it).
_SINGULAR_RTOL = 1e-9


def _mass_matrix(tree: Tree, params: dict, q: np.ndarray) -> np.ndarray:
    """`M(q) = Jᵀ M_θ J` in NumPy by the composite-rigid-body algorithm (world frame,
    the same conventions as `lagrax._multibody.algorithms.recursions`)."""
    big_a, big_b, big_c, slide = tree.joint_constants()
    k, a, b = tree.coupling()
    theta = q[k] * a + b
    keys = ("m", "offset", "com", "inertia")
    m, offset, com, inertia = (np.asarray(params[x], float) for x in keys)
    n = tree.n_bodies
    rots, origins = np.zeros((n, 3, 3)), np.zeros((n, 3))
    s, spatial = np.zeros((n, 6)), np.zeros((n, 6, 6))
    for i, kind in enumerate(tree.joint_types):
        p = tree.parents[i]
        rot_p, o_p = (np.eye(3), np.zeros(3)) if p < 0 else (rots[p], origins[p])
        origins[i] = o_p + rot_p @ (offset[i] + theta[i] * slide[i])
        rot = rot_p @ (big_a[i] + np.sin(theta[i]) * big_b[i] + (1 - np.cos(theta[i])) * big_c[i])
        rots[i] = rot
        z = rot @ np.asarray(tree.axes[i])
        s[i] = np.concatenate([z, np.cross(origins[i], z)]) if kind == "R" else np.r_[0, 0, 0, z]
        c = origins[i] + rot @ com[i]
        cx = np.array([[0, -c[2], c[1]], [c[2], 0, -c[0]], [-c[1], c[0], 0]])
        top = rot @ inertia[i] @ rot.T + steiner(m[i], c)
        spatial[i] = np.block([[top, m[i] * cx], [m[i] * cx.T, m[i] * np.eye(3)]])
    for i in reversed(range(n)):  # composite inertias: each body's subtree
        if tree.parents[i] >= 0:
            spatial[tree.parents[i]] += spatial[i]
    full = np.zeros((n, n))
    for i in range(n):
        f, j = spatial[i] @ s[i], i
        while j >= 0:  # M_ji = S_j · I^c_i S_i for j on i's path to the base
            full[j, i] = full[i, j] = s[j] @ f
            j = tree.parents[j]
    jac = tree.coupling_matrix()
    return jac.T @ full @ jac


def _singular_pivot(mass: np.ndarray) -> tuple[int, float] | None:
    """The first coordinate whose Cholesky pivot is `<= _SINGULAR_RTOL` of its diagonal
    entry (it moves only what earlier ones move), with that pivot; `None`: regular. A
    singular column is skipped so later ones are judged on their own."""
    n = mass.shape[0]
    low = np.zeros((n, n))
    for j in range(n):
        d = mass[j, j] - low[j, :j] @ low[j, :j]
        if d <= _SINGULAR_RTOL * mass[j, j]:
            return j, float(d)
        low[j, j] = math.sqrt(d)
        low[j + 1 :, j] = (mass[j + 1 :, j] - low[j + 1 :, :j] @ low[j, :j]) / low[j, j]
    return None


def _check_mass_matrix(tree: Tree, params: dict, bodies: list[Body]) -> None:
    """A `URDFError` naming the joint if `M` is singular at two random configurations
    (structurally singular: a joint moving no mass); a configuration-dependent
    singularity (a gimbal lock of massless links) is generically missed by both."""
    rng = np.random.default_rng(0)
    found = None
    for _ in range(2):
        q = rng.uniform(-2.0, 2.0, tree.n)
        found = _singular_pivot(_mass_matrix(tree, params, q))
        if found is None:
            return
    assert found is not None
    k, pivot = found
    body = tree.coordinates[k]
    joint, link = tree.joint_names[body], tree.body_names[body]
    below = [i for i in range(tree.n_bodies) if _is_below(tree.parents, i, body)]
    mass = float(np.sum(np.asarray(params["m"])[below]))
    what = (
        f"the links it moves (link {link!r} and below) have no mass or inertia"
        if mass == 0 and not np.any(np.asarray(params["inertia"])[below])
        else f"it moves only what the joints before it already move (the pivot of the mass "
        f"matrix is {pivot:.3g}, mass moved {mass:.6g} kg)"
    )
    raise URDFError(
        f"joint {joint!r} moves no mass of its own: {what}, so the mass matrix is singular "
        "and the accelerations are undefined. Give link "
        f"{link!r} (or a link below it) an <inertial>, lock the joint (locked={{{joint!r}: "
        "0.0}), or pass massless_links=True to load it anyway (its kinematics stay usable)"
    )


def _is_below(parents: tuple[int, ...], i: int, body: int) -> bool:
    """Whether body `i` is `body` or hangs below it."""
    while i >= 0:
        if i == body:
            return True
        i = parents[i]
    return False
