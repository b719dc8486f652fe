"""A contact scene in the 3D view: a [`ContactSystem`][lagrax.contact.ContactSystem]'s
spheres (bodies of their own, at their centres), its ground plane (a slab fixed to the
world) and the contact forces as arrows from the contact points, when the solution kept
them (`Solution.contact_force`). A planar scene's `(x, y)` is drawn in the world's x–z
plane, as every planar model is."""

from __future__ import annotations

from typing import Any

import numpy as np

from .._contact.system import ContactSystem
from .poses3d import Poses, Shape, check_width
from .shapes3d import placed

SPHERE_COLOUR, GROUND_COLOUR = 0x30A060, 0xC8C8B4


def _spatial(points: np.ndarray) -> np.ndarray:
    """Planar `(…, 2)` points in the world's x–z plane; spatial ones as they are."""
    if points.shape[-1] == 3:
        return points
    return np.stack([points[..., 0], np.zeros_like(points[..., 0]), points[..., 1]], axis=-1)


def _turning_z_onto(normal: np.ndarray) -> np.ndarray:
    """A rotation whose third column is `normal` (unit)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, normal)
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(normal, x), normal], axis=1)


def contact_poses(
    base: Poses | None,
    times: np.ndarray,
    q: np.ndarray,
    scene: ContactSystem,
    params: Any,
    force: Any,
) -> Poses:
    """`base` (the model's bodies, or `None`) with the scene's spheres, ground and, from
    `force` `(F, S, d)` (or `None`), its contact forces added.

    **Raises:** `ShapeError` when `q` is not the scene's configuration.
    """
    import jax
    import jax.numpy as jnp

    if scene.n_configuration is not None:
        check_width(scene, q, int(scene.n_configuration), "its configuration")
    centres = _spatial(np.asarray(jax.vmap(lambda a: scene.centres(a, params))(jnp.asarray(q))))
    frames, count = centres.shape[:2]
    k0 = 0 if base is None else base.origins.shape[1]
    eye = np.broadcast_to(np.eye(3), (frames, count, 3, 3))
    origins = centres if base is None else np.concatenate([base.origins, centres], axis=1)
    rots = eye if base is None else np.concatenate([base.rotations, eye], axis=1)
    shapes = list(base.shapes) if base is not None else []
    radii = np.array([s.radius for s in scene.spheres])
    size = max(float(np.max(np.ptp(origins.reshape(-1, 3), axis=0))), 4 * float(radii.max()), 0.1)
    for i, r in enumerate(radii):
        shown = r if r > 0 else 0.01 * size  # a point contact as a small dot
        shapes.append(
            Shape(k0 + i, np.eye(4), "sphere", (shown,), colour=SPHERE_COLOUR, name="sphere")
        )
    normal = _spatial(np.asarray(scene.plane.normal))
    flat = origins.reshape(-1, 3)
    middle = 0.5 * (flat.min(axis=0) + flat.max(axis=0))
    on_plane = middle - (middle @ normal - scene.plane.offset) * normal
    thick = 0.01 * size
    rot = _turning_z_onto(normal)
    side = 2.0 * size + 1.0
    shapes.append(
        Shape(
            -1,
            placed(rot, on_plane - 0.5 * thick * normal),
            "box",
            (side, side, thick),
            colour=GROUND_COLOUR,
            name="ground",
        )
    )
    arrows = None
    if force is not None:
        f = _spatial(np.asarray(force, dtype=float))
        feet = centres - radii[None, :, None] * normal
        peak = float(np.max(np.linalg.norm(f, axis=-1), initial=0.0))
        scale = 0.4 * size / peak if peak > 0 else 0.0
        arrows = np.stack([feet, scale * f], axis=2)
    links = () if base is None else base.links
    planar = scene.plane.dim == 2 if base is None else base.planar
    skeleton = base is not None and (base.skeleton or not base.shapes)
    return Poses(times, origins, np.array(rots), links, planar, tuple(shapes), arrows, skeleton)
