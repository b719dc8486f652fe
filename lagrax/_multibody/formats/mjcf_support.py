"""What `from_mjcf` refuses in a compiled MuJoCo model (or drops with a warning under
`ignore_unsupported=True`): each construct lagrax does not model, named with its value."""

import numpy as np

from ..._core.errors import MJCFError
from .mjcf_tendons import tendons_unsupported

FREE, BALL = 0, 1  # MuJoCo's mjtJoint values of a free and a ball joint


def _ball_joints(mujoco, model, names) -> list[str]:
    """What lagrax does not model on a ball joint (its stiffness, its limit: both act on
    the quaternion), each a sentence; `MJCFError` for equality constraints beside one
    (MuJoCo itself refuses a fixed tendon through one)."""
    balls = [j for j, kind in enumerate(model.jnt_type) if kind == BALL]
    found: list[str] = []
    if not balls:
        return found
    disabled, off = int(model.opt.disableflags), mujoco.mjtDisableBit
    for j in balls:
        who = f"the ball joint {names('joint', j)!r}"
        if model.jnt_stiffness[j] and not disabled & int(off.mjDSBL_SPRING):
            found.append(
                f"stiffness {model.jnt_stiffness[j]:g} on {who} (a spring on its rotation)"
            )
        if model.jnt_limited[j]:
            found.append(f"a limit {model.jnt_range[j][1]:g} on {who} (a cone on its rotation)")
    if model.neq and not disabled & int(off.mjDSBL_EQUALITY):
        raise MJCFError(
            f"the model has equality constraints and the ball joint "
            f"{names('joint', balls[0])!r}: lagrax does not take equality constraints in a "
            "model with ball joints yet"
        )
    return found


def unsupported(mujoco, model, names) -> list[str]:
    """What lagrax does not model in `model`, each a sentence naming it and its value;
    equality constraints beside a ball joint are refused in any case (`MJCFError`)."""
    found: list[str] = _ball_joints(mujoco, model, names)
    disabled = int(model.opt.disableflags)
    off = mujoco.mjtDisableBit

    def first_nonzero(values, what: str, obj: str, flag=None) -> None:
        """Adds `what` of the first `obj` (joint, dof: named by its joint, body) with a
        nonzero value, unless `flag` disables it."""
        values = np.asarray(values, float)
        if values.size == 0:
            return
        values = values.reshape(len(values), -1)
        if (flag is not None and disabled & int(flag)) or not np.any(values):
            return
        i = int(np.argmax(np.any(values != 0, axis=1)))
        row = values[i]
        shown = f"{row[0]:g}" if row.size == 1 else str(row.tolist())
        who = f"joint {names('joint', int(model.dof_jntid[i]))!r}" if obj == "dof" else None
        who = who or f"{obj} {names(obj, i)!r}"
        found.append(f"{what} {shown} on {who}")

    free = [j for j, kind in enumerate(model.jnt_type) if kind == FREE]
    for j in free:  # a floating base has no damping, armature or spring of its own
        dofs = [int(model.jnt_dofadr[j]) + k for k in range(6)]
        for what, values, flag in (
            ("damping", model.dof_damping, off.mjDSBL_DAMPER),
            ("armature", model.dof_armature, None),
            ("friction loss", model.dof_frictionloss, off.mjDSBL_FRICTIONLOSS),
        ):
            if np.any(np.asarray(values)[dofs]) and not (flag and disabled & int(flag)):
                found.append(
                    f"{what} on the free joint {names('joint', j)!r} (a floating base has "
                    "none in lagrax)"
                )
        if model.jnt_stiffness[j] and not disabled & int(off.mjDSBL_SPRING):
            found.append(f"stiffness on the free joint {names('joint', j)!r}")
    # fields of newer MuJoCo releases (None in an older one, which has no such construct)
    for field, what, kind, flag in (
        ("jnt_springyield", "joint spring yield (plasticity)", "joint", None),
        ("jnt_stiffnesspoly", "nonlinear joint stiffness", "joint", off.mjDSBL_SPRING),
        ("dof_dampingpoly", "nonlinear joint damping", "dof", off.mjDSBL_DAMPER),
    ):
        if (values := getattr(model, field, None)) is not None:
            first_nonzero(values, what, kind, flag)
    first_nonzero(model.body_gravcomp, "gravity compensation", "body")
    found += tendons_unsupported(mujoco, model, names)
    if model.opt.density > 0 or model.opt.viscosity > 0:
        found.append(
            f"fluid forces (opt density={model.opt.density:g}, viscosity={model.opt.viscosity:g}"
            "; lagrax.chains.mjcf_fluid loads the model with them as an applied force)"
        )
    return found
