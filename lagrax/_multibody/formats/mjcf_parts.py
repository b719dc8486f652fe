"""A MuJoCo model split into the robots it holds, for [`lagrax.chains.from_mjcf`][]:
each free body (a body hanging from the world whose only joint is a free joint) with the
bodies below it is a floating robot, and the bodies hanging from the world between two
free bodies, with their joints, one robot fixed to the world.

MuJoCo numbers bodies depth-first, and joints (so `qpos` and `qvel`) by body, so each
part's joints are one run of MuJoCo's joints and the parts, in body order, lay the state
out as MuJoCo does.
"""

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..._core.errors import MJCFError

_FREE = 0  # mujoco.mjtJoint.mjJNT_FREE


@dataclass
class Part:
    """One robot of a model: `free`, its free body (`None`: fixed to the world); `bodies`,
    the MuJoCo bodies it holds, in order; `joints`, its MuJoCo joints, in order."""

    free: int | None
    bodies: list[int] = field(default_factory=list)
    joints: list[int] = field(default_factory=list)


def _subtree(model, root: int) -> list[int]:
    """`root` and the bodies below it, in MuJoCo's order."""
    out, inside = [], {root}
    for b in range(root, model.nbody):
        if b == root or int(model.body_parentid[b]) in inside:
            inside.add(b)
            out.append(b)
    return out


def split_parts(model, names) -> list[Part]:
    """The model's robots in body order: a `Part` per free body, and one per run of
    world-hanging subtrees without free joint that has joints (a run without joints is
    welded to the world and left out).

    **Raises:** `MJCFError` naming a free joint that is not the only joint of a body
    hanging from the world (a free joint inside a robot), or a model whose joints do not
    follow its bodies' order."""
    parts: list[Part] = []
    fixed = Part(None)
    for child in range(1, model.nbody):
        if int(model.body_parentid[child]) != 0:
            continue
        bodies = _subtree(model, child)
        joints = [j for b in bodies for j in _joints(model, b)]
        free = [j for j in joints if int(model.jnt_type[j]) == _FREE]
        for j in free:
            b = int(model.jnt_bodyid[j])
            if b != child or int(model.body_jntnum[b]) != 1:
                raise MJCFError(
                    f"free joint {names('joint', j)!r} (body {names('body', b)!r}): a "
                    "floating base is a body hanging from the world whose only joint is the "
                    "free joint"
                )
        if free:
            if fixed.joints:
                parts.append(fixed)
            fixed = Part(None)
            parts.append(Part(child, bodies, joints))
        else:
            fixed.bodies += bodies
            fixed.joints += joints
    if fixed.joints:
        parts.append(fixed)
    order = [j for p in parts for j in p.joints]
    if order != list(range(model.njnt)):
        raise MJCFError(
            "the model's joints do not follow its bodies' order (MuJoCo's depth-first "
            "numbering): lagrax lays the state out by body"
        )
    return parts


def _joints(model, b: int) -> range:
    first = int(model.body_jntadr[b])
    return range(first, first + int(model.body_jntnum[b])) if first >= 0 else range(0)


def quat_matrix(quat: Any) -> np.ndarray:
    """The rotation of a unit quaternion `(w, x, y, z)` (MuJoCo's order)."""
    w, x, y, z = np.asarray(quat, float) / np.linalg.norm(quat)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


@dataclass
class TreeBody:
    """A body of `from_mjcf`'s tree: one MuJoCo joint, and the inertia of every MuJoCo body it
    carries (sums about the tree body's origin, in its frame)."""

    name: str
    joint: str
    kind: str
    parent: int
    rot: np.ndarray
    offset: np.ndarray
    axis: np.ndarray
    damping: float
    limits: tuple[float, float]
    effort: float
    armature: float = 0.0
    stiffness: float = 0.0
    springref: float = 0.0
    joint_id: int = -1
    frictionloss: float = 0.0
    ball: bool = False  # the first of a ball joint's three lanes
    mass: float = 0.0
    moment: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia_o: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
