"""A loaded robot and the contact spheres read from its file as one
[`ContactSystem`][lagrax.contact.ContactSystem] on a ground plane (`from_urdf` and
`from_mjcf` with `contact=`)."""

import math
from collections.abc import Sequence
from typing import Any

import jax.numpy as jnp
import numpy as np

from ..._contact.geometry import Plane
from ..._contact.system import ContactSystem
from ..._core.errors import ConfigurationError
from ..floating.system import FloatingTree
from ..limits import contact_limits
from ..spheres import body_sphere
from .collision import ContactPoint

DEFAULT_FRICTION = 1.0  # MuJoCo's default sliding friction


def limits_need_contact(limits: Any, contact: Any) -> None:
    """`ConfigurationError` for `limits="contact"` without `contact=`: the stops are
    a contact scene's, scaled by the weight on its ground."""
    if limits == "contact" and (contact is False or contact is None):
        raise ConfigurationError(
            "limits='contact' enforces the joint limits as compliant contacts of the "
            "contact scene, which contact= builds (its defaults are scaled by the weight on "
            "the ground): pass contact=True as well, or limits='impact'"
        )


def contact_friction(value: Any) -> float | None:
    """`friction=` of the loaders: `None` (read from the file) or a finite number `>= 0`."""
    if value is None:
        return None
    try:
        mu = float(value)
    except (TypeError, ValueError):
        mu = math.nan
    if not (math.isfinite(mu) and mu >= 0) or isinstance(value, bool):
        raise ConfigurationError(
            f"friction must be a finite number >= 0 or None (read from the file), got "
            f"friction={value!r}"
        )
    return mu


def robot_up(robot: Any) -> tuple[float, float, float]:
    """The tree's `up` direction (opposite to gravity): the ground's normal."""
    tree = robot.tree if isinstance(robot, FloatingTree) else robot
    up = np.asarray(tree.up, float)
    return (float(up[0]), float(up[1]), float(up[2]))


def contact_scene(
    robot: Any,
    params: dict,
    points: Sequence[ContactPoint],
    ground: tuple[Any, float, float | None],
    friction: float | None,
    limits: str | None = None,
) -> tuple[ContactSystem, dict]:
    """`(scene, params)`: `robot.system()` with a sphere per point (by
    [`body_sphere`][lagrax.contact.body_sphere]) on the `ground = (normal, offset,
    its friction or None)`, and `params` plus `"contact_friction"`, one coefficient per
    sphere: `friction` if given, else the point's with the ground's (the larger of the
    two, MuJoCo's rule), else `DEFAULT_FRICTION`; with `limits="contact"`, the robot's
    joint limits as the scene's compliant stops (`contact_limits`)."""
    if not points:
        raise ConfigurationError(
            "contact=: the model has no collision geometry on its moving bodies (or none "
            "of the names given), so nothing can touch the ground"
        )
    floating = isinstance(robot, FloatingTree)
    spheres = [body_sphere(robot, p.body, p.radius, p.offset) for p in points]
    normal, offset, ground_mu = ground
    coefficients = []
    for p in points:
        if friction is not None:
            coefficients.append(friction)
            continue
        found = [m for m in (p.friction, ground_mu) if m is not None]
        coefficients.append(max(found) if found else DEFAULT_FRICTION)
    out = dict(params)
    dtype = params["m"].dtype
    out["contact_friction"] = jnp.asarray(np.asarray(coefficients), dtype)
    scene = ContactSystem(
        robot.system(),
        spheres,
        Plane(normal, offset),
        friction=lambda p: p["contact_friction"],
        limits=contact_limits(robot) if limits == "contact" else None,
        name=f"{robot.base_name if floating else 'robot'} on the ground",
    )
    return scene, out
