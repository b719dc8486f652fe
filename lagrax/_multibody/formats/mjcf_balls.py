"""MJCF ball joints as a tree's three revolute lanes (see
`lagrax._multibody.articulated.balls`), and where `from_mjcf` does not take them yet."""

import math

import numpy as np

from ..._core.errors import MJCFError
from ..articulated.balls import LANE_AXES
from .mjcf_parts import TreeBody


def ball_lanes(model, names, b: int, j: int, bodies: list[TreeBody], frame) -> tuple:
    """Append MuJoCo ball joint `j` of body `b` as its three revolute lanes about the
    body's `x`, `y`, `z` axes at the joint's anchor (`lagrax._multibody.articulated.balls`;
    the first lane turns by the quaternion), each lane's damping, armature and friction
    loss its dof's; the frame `(tree body, R, p)` that follows it (the last lane's)."""
    tb, rot, pos = frame
    anchor = np.asarray(model.jnt_pos[j], float)
    dof, body, joint = int(model.jnt_dofadr[j]), names("body", b), names("joint", j)
    last = j == int(model.body_jntadr[b]) + int(model.body_jntnum[b]) - 1
    effort = math.inf
    if bool(model.jnt_actfrclimited[j]):
        effort = float(np.max(np.abs(model.jnt_actfrcrange[j]))) or math.inf
    for k, axis in enumerate(LANE_AXES):
        bodies.append(
            TreeBody(
                body if last and k == 2 else f"{body}/{joint}_{'xyz'[k]}",
                f"{joint}_{'xyz'[k]}",
                "R",
                tb if k == 0 else len(bodies) - 1,
                rot if k == 0 else np.eye(3),
                pos + rot @ anchor if k == 0 else np.zeros(3),
                np.asarray(axis),
                float(model.dof_damping[dof + k]),
                (-math.inf, math.inf),  # a limited ball is refused (`unsupported`)
                effort,
                float(model.dof_armature[dof + k]),
                joint_id=j,
                frictionloss=float(model.dof_frictionloss[dof + k]),
                ball=k == 0,
            )
        )
    return len(bodies) - 1, np.eye(3), -anchor


def balls_supported(names, bodies: list[TreeBody], base, contact, n_parts: int) -> None:
    """`MJCFError` naming the first ball joint where lagrax does not model one yet: in a
    model of several parts, or with `contact=`."""
    ball = next((b for b in bodies if b.ball), None)
    if ball is None:
        return
    where = None
    if n_parts > 1:
        where = "in a model of several parts (free bodies)"
    elif contact is not False and contact is not None:
        where = "with contact="
    if where is not None:
        raise MJCFError(
            f"joint {names('joint', ball.joint_id)!r} is a ball joint {where}: lagrax has "
            "ball joints in a model of one robot (fixed or floating) without contact, so far"
        )
