"""URDF import: a robot description file as a [`Tree`][lagrax.chains.Tree] and its params.

Read with the standard library's `xml.etree.ElementTree`: lagrax needs only the
kinematic and inertial elements of URDF (`<link><inertial>`, `<joint>` with its
`<origin>`, `<axis>`, `<limit>`, `<dynamics>`), which are a few attributes each;
geometry (`<visual>`, `<collision>`, meshes) is never read, so a missing mesh file
cannot be an error, and no dependency (`yourdfpy` brings `trimesh` and `lxml` to
load meshes lagrax does not use) is added. Reading the elements here also lets every error
name the link or joint at fault.
"""

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._core.errors import ConfigurationError, ParameterError, URDFError
from .common import float_dtype
from .inertia import check_inertia
from .limits import with_limits
from .trees import Tree

_MOVING = {"revolute": "R", "continuous": "R", "prismatic": "P"}
_UNSUPPORTED = {
    "floating": "a floating base is not supported yet (lagrax trees are fixed to the world)",
    "planar": "planar joints are not supported (model them as two prismatic joints and a "
    "revolute one)",
}


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
class _Joint:
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


@dataclass
class _Body:
    """A moving body: one moving joint and every link fixed to its child link."""

    joint: _Joint
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


def _inertial(link: ET.Element) -> _Inertial | None:
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
    try:  # semidefinite: a point mass or a slender rod is physical
        check_inertia(tensor, name=f"{where} <inertia>", semidefinite=True, rtol=1e-6)
    except ParameterError as err:
        raise URDFError(f"{err} (in the URDF's <inertial> of {where})") from None
    return _Inertial(mass, xyz, rot @ tensor @ rot.T)


def _joint(element: ET.Element, links: dict) -> _Joint:
    name = element.get("name")
    if not name:
        raise URDFError("a <joint> has no name attribute")
    where = f"joint {name!r}"
    kind = element.get("type")
    if kind in _UNSUPPORTED:
        raise URDFError(f"{where} has type {kind!r}: {_UNSUPPORTED[kind]}")
    if kind not in (*_MOVING, "fixed"):
        raise URDFError(
            f"{where} has unknown type {kind!r}; URDF joints are revolute, continuous, "
            "prismatic, fixed (and floating, planar: not supported)"
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
    if element.find("mimic") is not None:
        raise URDFError(
            f"{where} mimics another joint: mimic joints (a constraint between coordinates) "
            "are not supported; make it an independent joint or a fixed one"
        )
    xyz, rot = _origin(element, where)
    axis = np.asarray(_floats(element.find("axis"), "xyz", np.array([1.0, 0, 0]), 3, where))
    if kind in _MOVING and np.linalg.norm(axis) == 0:
        raise URDFError(f"{where}: its <axis xyz> is the zero vector")
    joint = _Joint(name, kind, ends[0], ends[1], xyz, rot, axis)
    limit = element.find("limit")
    if limit is not None and kind != "fixed":
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


def _parse(text: str) -> tuple[dict, list[_Joint]]:
    try:
        robot = ET.fromstring(text)
    except ET.ParseError as err:
        raise URDFError(f"malformed URDF (not well-formed XML): {err}") from None
    if robot.tag != "robot":
        raise URDFError(f"a URDF's top element is <robot>, got <{robot.tag}>")
    links: dict[str, ET.Element] = {}
    for link in robot.findall("link"):
        name = link.get("name")
        if not name:
            raise URDFError("a <link> has no name attribute")
        if name in links:
            raise URDFError(f"link {name!r} is defined twice")
        links[name] = link
    if not links:
        raise URDFError("the URDF has no <link>")
    joints = [_joint(el, links) for el in robot.findall("joint")]
    names = [j.name for j in joints]
    for name in names:
        if names.count(name) > 1:
            raise URDFError(f"joint {name!r} is defined twice")
    return links, joints


def _structure(links: dict, joints: list[_Joint], root: str | None) -> tuple[str, dict, dict]:
    """The root link, each link's parent joint and each link's child joints (file order);
    refuses a link with two parents, a loop, and an ambiguous root."""
    parent_of: dict[str, _Joint] = {}
    children: dict[str, list[_Joint]] = {name: [] for name in links}
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


def _keep(root: str, tip: str | None, links: dict, parent_of: dict, children: dict) -> set:
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


def from_urdf(
    source: str | os.PathLike,
    *,
    root: str | None = None,
    tip: str | None = None,
    up: Any = (0.0, 0.0, 1.0),
    g: float = 9.81,
    massless_links: bool = False,
    dtype: Any = None,
    limits: str | None = None,
    restitution: Any = 0.0,
    floating_base: bool = False,
) -> tuple[Tree, dict]:
    r"""A robot from a URDF file (or string) as a [`Tree`][lagrax.chains.Tree] and its params.

    Each revolute, continuous or prismatic joint becomes a body of the tree (bodies are
    numbered depth-first from the root, children in file order), with its
    `<origin xyz rpy>` as the placement (`offset` in `params`, the rotation
    `Rz(yaw) Ry(pitch) Rx(roll)` in the structure), its `<axis>`, `<limit>` (kept in
    `tree.limits`, `velocity_limits`, `effort_limits`; continuous joints are
    unlimited) and `<dynamics damping>` (`params["damping"]`, a Rayleigh dissipation;
    `friction` is not modelled). Joint names become `tree.joint_names` and the
    system's `coordinate_names`.

    A link's `<inertial>` gives its mass `m`, centre of mass `c` (`<origin xyz>`)
    and inertia `R Ī Rᵀ` with `Ī` the `<inertia>` entries and `R` the
    `<origin rpy>` rotation (URDF states the inertia in that rotated frame). **Fixed
    joints are merged**: a link fixed (directly or through other fixed joints) to a moving
    body at placement `(R_f, p_f)` adds `m`, the first moment `m (p_f + R_f c)` and
    the inertia about the body's origin `R_f Ī' R_fᵀ + m (|c'|² 1 − c' c'ᵀ)`
    (`c' = p_f + R_f c`; the parallel-axis theorem) to that body; the body's centre of
    mass and inertia about it follow from the sums. Links fixed to the root (the world)
    do not move and are dropped; joints below them are placed through them.

    Geometry (`<visual>`, `<collision>`, meshes) is ignored: a missing mesh file is no
    error.

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
    - `massless_links`: accept moving links without `<inertial>` or with zero mass
      (the mass matrix may then be singular). By default they are refused; links fixed to
      a moving link may always lack `<inertial>` (frames such as a tool flange).
    - `dtype`: of the params (default float64 with x64).
    - `limits`: `None` (default): the `<limit>`s are kept in `tree.limits` and not
      enforced; `"impact"`: joints stop at their limits by impacts with coefficient of
      restitution `restitution` (the params gain `"restitution"`, one per joint; pass
      [`lagrax.chains.limit_events`][]`(tree)` to [`lagrax.simulate`][]'s `events=`,
      and the hits are in `Solution.events`).
    - `restitution`: with `limits="impact"`, a number in `[0, 1]` or one per joint
      (default `0`: the joint stops dead at its limit).
    - `floating_base`: `True` for a robot that is not bolted to the world (a quadruped,
      a humanoid): the root link, with every link fixed to it, becomes a free-floating
      base and the result a [`FloatingTree`][lagrax.chains.FloatingTree] whose state is
      Pinocchio's free-flyer `q = (x, y, z, qx, qy, qz, qw, joints…)`,
      `v = (base linear, base angular velocity in the base frame, joint rates…)`; its
      params gain `base_m`, `base_com`, `base_inertia`. The root link must then have a
      positive mass.

    **Returns:** `(tree, params)`: the [`Tree`][lagrax.chains.Tree] (`tree.system()` gives the
    system) and `{"m", "offset", "com", "inertia", "damping", "g"}` (and `"restitution"`
    with `limits="impact"`).

    **Raises:** [`lagrax.URDFError`][] naming the link or joint for: malformed XML, a
    missing or incomplete `<inertial>` on a moving link, a negative or zero mass, an
    inertia that is not positive-semidefinite or violates the triangle inequality
    `I1 + I2 ≥ I3`, a link with two parents, a loop, several roots without `root=`, an
    unknown joint type, a floating or planar joint (not supported), a mimic joint, a
    robot with no moving joint below `root`. `FileNotFoundError` for a missing file.

    **Example:**

    ```python
    tree, params = lagrax.chains.from_urdf("arm7.urdf")
    system = tree.system()
    qdd = system.forward_dynamics(q, qd, params, tau)
    tree.joint_names, tree.limits
    ```
    """
    links, joints = _parse(_read(source))
    root, parent_of, children = _structure(links, joints, root)
    keep = _keep(root, tip, links, parent_of, children)
    bodies, place, order = _place_bodies(root, keep, children)
    _merge_inertials(bodies, place, order, links, massless_links)
    tree, params = _tree_and_params(bodies, up, g, dtype)
    if floating_base:
        if limits is not None:
            raise ConfigurationError(
                f"from_urdf: limits={limits!r} is not supported with floating_base=True yet "
                "(the limit events index the joints of a fixed-base tree)"
            )
        from .floating import base_from_urdf

        return base_from_urdf(tree, params, place, order, links, root, _inertial)  # type: ignore[return-value]
    return with_limits(tree, params, limits, restitution)


def _read(source: str | os.PathLike) -> str:
    """The URDF text: `source` itself if it starts with `<`, else the file it names."""
    text = os.fspath(source)
    if not text.lstrip().startswith("<"):
        with open(text, encoding="utf-8") as f:
            text = f.read()
    return text


_Place = dict[str, tuple[int, np.ndarray, np.ndarray]]


def _place_bodies(root: str, keep: set, children: dict) -> tuple[list[_Body], _Place, list[str]]:
    """One body per moving joint below `root`, depth-first (pre-order: a parent before
    its children) in file order, and every kept link's place `(body index, R, p)`: its
    frame in its body's frame (body −1: the world; a link on a fixed joint is placed in
    the body it is fixed to)."""
    bodies: list[_Body] = []
    place: _Place = {}
    order: list[str] = []
    stack: list[tuple[str, _Joint | None]] = [(root, None)]
    while stack:
        link, j = stack.pop()
        if j is None:
            place[link] = (-1, np.eye(3), np.zeros(3))
        else:
            body, rot, pos = place[j.parent]
            joint_rot, joint_pos = rot @ j.rot, pos + rot @ j.xyz
            if j.kind == "fixed":
                place[link] = (body, joint_rot, joint_pos)
            else:
                bodies.append(_Body(j, body, joint_rot, joint_pos))
                place[link] = (len(bodies) - 1, np.eye(3), np.zeros(3))
        order.append(link)
        stack.extend((c.child, c) for c in reversed(children[link]) if c.child in keep)
    if not bodies:
        raise URDFError(f"the robot has no revolute, continuous or prismatic joint below {root!r}")
    return bodies, place, order


def _merge_inertials(
    bodies: list[_Body], place: _Place, order: list[str], links: dict, massless_links: bool
) -> None:
    """Add every link's `<inertial>` to its body: the mass, the first moment and the
    inertia about the body's origin (parallel-axis theorem); links fixed to the world are
    skipped."""
    for link in order:
        body, rot, pos = place[link]
        if body < 0:
            continue  # fixed to the world
        moving = link == bodies[body].joint.child
        inertial = _inertial(links[link])
        if inertial is None:
            if moving and not massless_links:
                raise URDFError(
                    f"link {link!r} (moved by joint {bodies[body].joint.name!r}) has no "
                    "<inertial>: give its mass and inertia, or pass massless_links=True"
                )
            continue
        if inertial.mass <= 0 and not massless_links:
            raise URDFError(
                f"link {link!r}: mass {inertial.mass:g} is not positive; a moving link needs "
                "a positive mass (or pass massless_links=True)"
            )
        c = pos + rot @ inertial.com
        b = bodies[body]
        b.mass += inertial.mass
        b.moment = b.moment + inertial.mass * c
        shift = inertial.mass * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
        b.inertia_o = b.inertia_o + rot @ inertial.inertia @ rot.T + shift


def _tree_and_params(bodies: list[_Body], up: Any, g: float, dtype: Any) -> tuple[Tree, dict]:
    """The [`Tree`][lagrax.chains.Tree] of the merged bodies and its params: each body's
    centre of mass and its inertia about it from the sums."""
    masses = np.array([b.mass for b in bodies])
    coms = np.stack([b.moment / b.mass if b.mass > 0 else np.zeros(3) for b in bodies])
    inertias = np.stack(
        [
            b.inertia_o - b.mass * (np.dot(c, c) * np.eye(3) - np.outer(c, c))
            for b, c in zip(bodies, coms, strict=True)
        ]
    )
    inertias = 0.5 * (inertias + np.swapaxes(inertias, 1, 2))
    joint_list = [b.joint for b in bodies]
    tree = Tree(
        "".join(_MOVING[j.kind] for j in joint_list),
        [b.parent for b in bodies],
        axes=[j.axis for j in joint_list],
        rotations=[b.rot for b in bodies],
        up=up,
        joint_names=[j.name for j in joint_list],
        body_names=[j.child for j in joint_list],
        limits=[j.limits for j in joint_list],
        velocity_limits=[j.velocity for j in joint_list],
        effort_limits=[j.effort for j in joint_list],
    )
    params = tree.params(
        m=masses,
        offset=np.stack([b.offset for b in bodies]),
        com=coms,
        inertia=inertias,
        damping=np.array([j.damping for j in joint_list]),
        g=g,
        dtype=float_dtype(dtype),
    )
    return tree, params
