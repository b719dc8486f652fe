"""URDF's elements, read with the standard library's `xml.etree.ElementTree`: links'
`<inertial>`, joints with their `<origin>`, `<axis>`, `<limit>`, `<dynamics>` and
`<mimic>`, and the kinematic structure they form (see `lagrax._multibody.formats.urdf`).
Every error names the link or joint at fault."""

import math
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..._core.errors import ParameterError, URDFError, URDFWarning
from ..inertia import check_inertia

MOVING = {"revolute": "R", "continuous": "R", "prismatic": "P"}


def rpy_matrix(rpy: Any) -> np.ndarray:
    """URDF's fixed-axis roll–pitch–yaw: `R = Rz(yaw) Ry(pitch) Rx(roll)`."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        *(
            math.cos(y),
            math.sin(y),
        ),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


@dataclass
class _Inertial:
    mass: float
    com: np.ndarray  # in the link frame
    inertia: np.ndarray  # about the centre of mass, in the link frame


@dataclass
class JointElement:
    name: str
    kind: str
    parent: str
    child: str
    xyz: np.ndarray
    rot: np.ndarray
    axis: np.ndarray
    limits: tuple[float, float] = (-math.inf, math.inf)
    velocity: float = math.inf
    effort: float = math.inf
    damping: float = 0.0
    mimic: tuple[str, float, float] | None = None  # (master joint, multiplier, offset)


@dataclass
class Body:
    """A moving body: one moving joint and every link fixed to its child link."""

    joint: JointElement
    parent: int
    rot: np.ndarray  # the joint's fixed rotation in the parent body's frame
    offset: np.ndarray  # the joint's position in the parent body's frame
    mass: float = 0.0
    moment: np.ndarray = field(default_factory=lambda: np.zeros(3))  # Σ m c
    inertia_o: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))  # about origin


def _floats(element: ET.Element | None, attr: str, default: Any, n: int, where: str):
    if element is None or element.get(attr) is None:
        return default
    text = element.get(attr, "")
    try:
        values = [float(v) for v in text.split()]
    except ValueError:
        values = []
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise URDFError(f"{where}: <{element.tag} {attr}={text!r}> must be {n} finite number(s)")
    return values[0] if n == 1 else np.asarray(values)


def _origin(element: ET.Element, where: str) -> tuple[np.ndarray, np.ndarray]:
    origin = element.find("origin")
    xyz = _floats(origin, "xyz", np.zeros(3), 3, where)
    rpy = _floats(origin, "rpy", np.zeros(3), 3, where)
    return np.asarray(xyz, float), rpy_matrix(rpy)


def read_inertial(link: ET.Element, strict: bool = False, check: bool = True) -> _Inertial | None:
    """A link's `<inertial>` (`None`: it has none), checked: a negative mass, an
    `<inertia>` that is not symmetric positive-semidefinite are errors; one that violates
    the triangle inequality is a `URDFWarning` (an error with `strict`). `check=False`:
    the `<inertia>` as given (a link merged into a floating base, whose sum is checked)."""
    name = link.get("name")
    where = f"link {name!r}"
    inertial = link.find("inertial")
    if inertial is None:
        return None
    mass_el = inertial.find("mass")
    if mass_el is None or mass_el.get("value") is None:
        raise URDFError(f"{where}: <inertial> has no <mass value=...>")
    mass = _floats(mass_el, "value", None, 1, where)
    if mass < 0:
        raise URDFError(f"{where}: mass {mass:g} is negative; masses must be positive")
    xyz, rot = _origin(inertial, where)
    el = inertial.find("inertia")
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    if el is None or any(el.get(k) is None for k in keys):
        raise URDFError(
            f"{where}: <inertial> needs <inertia ixx= ixy= ixz= iyy= iyz= izz=> (all six)"
        )
    ixx, ixy, ixz, iyy, iyz, izz = (_floats(el, k, None, 1, where) for k in keys)
    tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
    if np.max(np.abs(tensor)) <= _POINT * max(mass, 1.0):
        # round-off around a point mass (`ixx="0" ... ixz="1.35525e-20"`, or -5.4e-20 on
        # the diagonal): its inertia about the centre of mass is zero
        tensor = np.zeros((3, 3))
    if not check:
        return _Inertial(mass, xyz, rot @ tensor @ rot.T)
    try:  # semidefinite: a point mass or a slender rod is physical
        check_inertia(
            tensor, name=f"{where} <inertia>", semidefinite=True, rtol=_RTOL, triangle=strict
        )
    except ParameterError as err:
        raise URDFError(f"{err} (in the URDF's <inertial> of {where})") from None
    _warn_triangle(tensor, where, _RTOL)
    return _Inertial(mass, xyz, rot @ tensor @ rot.T)


_RTOL = 1e-6  # of a link's <inertia> checks, relative to its largest principal moment
_POINT = 1e-12  # kg m² per kg (at least 1 kg): an <inertia> this small is a point mass's


def _warn_triangle(tensor: np.ndarray, where: str, rtol: float) -> None:
    """A `URDFWarning` naming the link if its principal moments violate `I1 + I2 ≥ I3`
    by more than `rtol` of `I3` (CAD exports and hand-edited files often do, by a
    little; Pinocchio accepts them, MuJoCo refuses them unless told to balance them)."""
    i1, i2, i3 = np.linalg.eigvalsh(tensor)
    if i1 + i2 < i3 - rtol * max(i3, 0.0):
        warnings.warn(
            f"{where}: its <inertia> violates the triangle inequality of principal moments, "
            f"I1 + I2 = {i1 + i2:.6g} < I3 = {i3:.6g} (short by {(i3 - i1 - i2) / i3:.2%} of "
            "I3): no rigid body has these moments. Loaded as given (the dynamics stay "
            "defined: the inertia is positive-semidefinite); pass strict_inertia=True to "
            "refuse such a file",
            URDFWarning,
            stacklevel=4,
        )


def _joint(element: ET.Element, links: dict) -> JointElement:
    name = element.get("name")
    if not name:
        raise URDFError("a <joint> has no name attribute")
    where = f"joint {name!r}"
    kind = element.get("type")
    if kind not in (*MOVING, "fixed", "floating", "planar"):
        raise URDFError(
            f"{where} has unknown type {kind!r}; URDF joints are revolute, continuous, "
            "prismatic, fixed, floating and planar"
        )
    ends = []
    for tag in ("parent", "child"):
        el = element.find(tag)
        link = None if el is None else el.get("link")
        if link is None:
            raise URDFError(f"{where} has no <{tag} link=...>")
        if link not in links:
            raise URDFError(f"{where}: its {tag} link {link!r} is not a <link> of the robot")
        ends.append(link)
    xyz, rot = _origin(element, where)
    axis = np.asarray(_floats(element.find("axis"), "xyz", np.array([1.0, 0, 0]), 3, where))
    if kind in (*MOVING, "planar") and np.linalg.norm(axis) == 0:
        raise URDFError(f"{where}: its <axis xyz> is the zero vector")
    joint = JointElement(name, kind, ends[0], ends[1], xyz, rot, axis)
    mimic = element.find("mimic")
    if mimic is not None and kind in MOVING:
        master = mimic.get("joint")
        if not master:
            raise URDFError(f"{where}: its <mimic> has no joint=... (the joint it follows)")
        multiplier = float(_floats(mimic, "multiplier", 1.0, 1, where))
        offset = float(_floats(mimic, "offset", 0.0, 1, where))
        joint.mimic = (master, multiplier, offset)
    limit = element.find("limit")
    if limit is not None and kind in MOVING:
        if kind != "continuous":
            lower = _floats(limit, "lower", 0.0, 1, where)
            upper = _floats(limit, "upper", 0.0, 1, where)
            if lower > upper:
                raise URDFError(f"{where}: <limit lower={lower:g}> exceeds upper={upper:g}")
            joint.limits = (lower, upper) if lower < upper else (-math.inf, math.inf)
        velocity = _floats(limit, "velocity", math.inf, 1, where)
        effort = _floats(limit, "effort", math.inf, 1, where)
        joint.velocity = velocity if velocity > 0 else math.inf
        joint.effort = effort if effort > 0 else math.inf
    damping = _floats(element.find("dynamics"), "damping", 0.0, 1, where)
    if damping < 0:
        raise URDFError(f"{where}: <dynamics damping={damping:g}> is negative")
    joint.damping = damping
    return joint


_XACRO = ("{http://www.ros.org/wiki/xacro}", "{http://wiki.ros.org/xacro}", "xacro:")


def parse(text: str) -> tuple[dict, list[JointElement]]:
    try:
        robot = ET.fromstring(text)
    except ET.ParseError as err:
        if "xacro:" in text:
            raise URDFError(
                f"not a URDF but a xacro file (XML with xacro macros): {err}; expand it into "
                "a robot first: `xacro robot.urdf.xacro > robot.urdf`"
            ) from None
        raise URDFError(f"malformed URDF (not well-formed XML): {err}") from None
    if robot.tag != "robot":
        raise URDFError(f"a URDF's top element is <robot>, got <{robot.tag}>")
    for el in robot.iter():
        if isinstance(el.tag, str) and el.tag.startswith(_XACRO):
            what = el.tag.rsplit("}", 1)[-1].removeprefix("xacro:")
            label = f" name={el.get('name')!r}" if el.get("name") else ""
            raise URDFError(
                f"not a URDF but a xacro file: it contains <xacro:{what}{label}>, a xacro "
                "macro, not a robot. Expand it into a robot first (`xacro robot.urdf.xacro "
                "> robot.urdf`, with the macro called)"
            )
    links: dict[str, ET.Element] = {}
    for link in robot.findall("link"):
        name = link.get("name")
        if not name:
            raise URDFError("a <link> has no name attribute")
        if name in links:
            raise URDFError(f"link {name!r} is defined twice")
        links[name] = link
    if not links:
        hint = (
            " (an empty <robot> that declares the xacro namespace: xacro's output from a "
            "file of macros that no robot calls)"
            if "xacro" in text
            else ""
        )
        raise URDFError(f"the URDF has no <link>: its <robot> describes no robot{hint}")
    joints = [_joint(el, links) for el in robot.findall("joint")]
    names = [j.name for j in joints]
    for name in names:
        if names.count(name) > 1:
            raise URDFError(f"joint {name!r} is defined twice")
    return links, joints


def planar_parts(j: JointElement) -> list[JointElement]:
    """A `planar` joint (motion in the plane normal to its axis) as three joints in a
    row: slides along two directions of the plane (`name/x`, `name/y`, in the joint's
    frame), then a continuous rotation about the axis (`name`): `q = (x, y, θ)`, the
    translation in the joint's frame (Pinocchio's planar joint has `(x, y, cos θ,
    sin θ)`, with the velocity in the moving frame)."""
    normal = j.axis / np.linalg.norm(j.axis)
    seed = np.eye(3)[int(np.argmin(np.abs(normal)))]
    e1 = np.cross(normal, seed)
    e1 = e1 / np.linalg.norm(e1)
    if np.allclose(np.abs(normal), [0.0, 0.0, 1.0]):
        e1 = np.array([1.0, 0.0, 0.0])  # the joint frame's own x and y in the xy plane
    e2 = np.cross(normal, e1)
    zero, eye = np.zeros(3), np.eye(3)
    parts = [
        JointElement(f"{j.name}/x", "prismatic", j.parent, f"{j.child}/x", j.xyz, j.rot, e1),
        JointElement(f"{j.name}/y", "prismatic", f"{j.child}/x", f"{j.child}/y", zero, eye, e2),
        JointElement(j.name, "continuous", f"{j.child}/y", j.child, zero, eye, normal),
    ]
    for part in parts:
        part.damping = j.damping
    return parts


def floating_joint(
    joints: list[JointElement], root: str | None
) -> tuple[list[JointElement], str | None, bool]:
    """`(joints, root, floating)`: a URDF `floating` joint (Pinocchio's free flyer) from
    the root link (a world link, carrying nothing else) with an identity origin is the
    floating base at its child: the joints without it, the child as the root, `True`;
    without one, the arguments and `False`. `URDFError` for several floating joints, or
    one elsewhere (below a moving joint, beside other joints on its parent, or with an
    `<origin>` offset)."""
    free = [j for j in joints if j.kind == "floating"]
    if not free:
        return joints, root, False
    joint = free[0]
    where = f"floating joint {joint.name!r}"
    if len(free) > 1:
        raise URDFError(
            f"the URDF has {len(free)} floating joints ({joint.name!r}, {free[1].name!r}, "
            "...): lagrax loads one floating base"
        )
    if any(j.child == joint.parent for j in joints):
        raise URDFError(f"{where}: its parent link {joint.parent!r} is not the root link")
    if any(j.parent == joint.parent and j is not joint for j in joints):
        raise URDFError(
            f"{where}: its parent link {joint.parent!r} carries other joints too; lagrax "
            "loads a floating robot or a robot fixed to the world, not both"
        )
    if np.any(joint.xyz != 0) or not np.allclose(joint.rot, np.eye(3), atol=0):
        raise URDFError(
            f"{where} has an <origin> offset; a floating base starts at the world's frame "
            "(move the offset into the initial state)"
        )
    if root not in (None, joint.parent, joint.child):
        raise URDFError(f"root={root!r} is not the floating base {joint.child!r} of the {where}")
    return [j for j in joints if j is not joint], joint.child, True


def structure(links: dict, joints: list[JointElement], root: str | None) -> tuple[str, dict, dict]:
    """The root link, each link's parent joint and each link's child joints (file order);
    refuses a link with two parents, a loop, and an ambiguous root."""
    parent_of: dict[str, JointElement] = {}
    children: dict[str, list[JointElement]] = {name: [] for name in links}
    for j in joints:
        if j.child in parent_of:
            raise URDFError(
                f"link {j.child!r} has two parents (joints {parent_of[j.child].name!r} and "
                f"{j.name!r}): a URDF is a tree, closed loops are not allowed"
            )
        if j.child == j.parent:
            raise URDFError(f"joint {j.name!r} connects link {j.child!r} to itself")
        parent_of[j.child] = j
        children[j.parent].append(j)
    for start in links:  # every link has at most one parent: follow them
        seen, link = {start}, start
        while link in parent_of:
            link = parent_of[link].parent
            if link in seen:
                raise URDFError(
                    f"the joints form a loop through link {link!r} (joint "
                    f"{parent_of[link].name!r}): a URDF is a tree"
                )
            seen.add(link)
    roots = [name for name in links if name not in parent_of]
    if root is None:
        if len(roots) > 1:
            raise URDFError(f"the URDF has several root links {roots}: pick one with root=...")
        root = roots[0]
    elif root not in links:
        raise URDFError(f"root={root!r} is not a link of the robot (links: {list(links)})")
    return root, parent_of, children


def keep_links(root: str, tip: str | None, links: dict, parent_of: dict, children: dict) -> set:
    """Links kept: all below `root`; with a `tip`, the path root → tip and every link
    fixed to a link of that path (moving branches off the path are dropped)."""
    if tip is None:
        out, stack = set(), [root]
        while stack:
            link = stack.pop()
            out.add(link)
            stack.extend(j.child for j in children[link])
        return out
    if tip not in links:
        raise URDFError(f"tip={tip!r} is not a link of the robot (links: {list(links)})")
    path, link = [tip], tip
    while link != root:
        if link not in parent_of:
            raise URDFError(f"tip link {tip!r} is not below root link {root!r}")
        link = parent_of[link].parent
        path.append(link)
    out, stack = set(path), list(path)
    while stack:
        for j in children[stack.pop()]:
            if j.kind == "fixed" and j.child not in out:
                out.add(j.child)
                stack.append(j.child)
    return out
