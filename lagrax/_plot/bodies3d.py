"""A user's own bodies ([`lagrax.bodies`][]) in the 3D view: each a simple shape sized from
its mass and inertia, posed at every frame by the body's own pose map.

- a [`SpatialBody`][lagrax.bodies.SpatialBody]: the uniform box with its principal moments
  (sides `a_i = √(6 (I_j + I_k − I_i) / m)`, along its principal axes), or, when two
  principal moments are equal (an axisymmetric body: a wheel, a rod), the uniform cylinder
  about the third axis (`I_axis = m r²/2`, `I_⊥ = m (3 r² + h²)/12`);
- a [`PlanarBody`][lagrax.bodies.PlanarBody]: the uniform rod of its moment along its own x
  axis (`L = √(12 I/m)`), drawn in the world's x–z plane as every planar model is;
- a [`PointMass`][lagrax.bodies.PointMass]: a small sphere.

Sides are at least 2 % of the largest, so that rods and plates stay visible. A spatial
scene whose gravity is a vector (the bicycle's `+z`, say) is turned so that gravity
points down the screen.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._contact.system import ContactSystem
from .._multibody.common import value
from .._systems.constrained import ConstrainedSystem
from ..bodies import PlanarBody, Scene, SpatialBody, principal_axes
from .drawn3d import Poses, Shape, ShapeKind, check_width
from .shapes3d import placed

PALETTE = (0x3070C0, 0xE07020, 0x30A060, 0xC03040, 0x8060B0, 0xB09030)
MIN_SIDE = 0.02  # of the largest side
_EQUAL = 1e-6  # relative difference of two principal moments taken as equal


def scene_of(model: Any) -> Scene | None:
    """The [`Scene`][lagrax.bodies.Scene] behind `model`: the scene itself, its
    `LagrangianSystem` (`scene.system()`), or a constrained system built on one; `None`
    for anything else."""
    for _ in range(4):
        if isinstance(model, Scene):
            return model if model.bodies else None
        kinetic = getattr(model, "kinetic", None)
        if isinstance(getattr(kinetic, "__self__", None), Scene):
            model = kinetic.__self__
        elif isinstance(model, ConstrainedSystem | ContactSystem):
            model = model.system  # a constrained system (or a contact scene) around a system
        else:
            return None
    return None


def _stacked(x: Any, base_ndim: int) -> np.ndarray:
    """Per-frame values of `k` bodies, `(F, k, …)`, from a vmapped pose output (a list of
    `k` arrays `(F, …)`, or one array `(F, …)` or `(F, k, …)`)."""
    if isinstance(x, list | tuple):
        return np.stack([np.asarray(e, dtype=float) for e in x], axis=1)
    x = np.asarray(x, dtype=float)
    return x[:, None] if x.ndim == base_ndim + 1 else x


def _per_body(x: Any, k: int, base_ndim: int) -> np.ndarray:
    """A body's parameter for each of its `k` bodies (shared, or one per body)."""
    x = np.asarray(x, dtype=float)
    return np.broadcast_to(x, (k,) + x.shape) if x.ndim == base_ndim else x


def _rotation_y(angle: np.ndarray) -> np.ndarray:
    """A planar body's rotation in the world: the plane's `(x, y)` is the world's `(x, z)`,
    so turning by `θ` from x towards y is turning about −y."""
    c, s, zero, one = np.cos(angle), np.sin(angle), np.zeros_like(angle), np.ones_like(angle)
    rows = [[c, zero, -s], [zero, one, zero], [s, zero, c]]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def _in_world(x: np.ndarray) -> np.ndarray:
    """Positions `(…, d)` in the world: 2-D ones in the x–z plane, 1-D ones along z."""
    if x.shape[-1] == 3:
        return x
    zero = np.zeros_like(x[..., 0])
    if x.shape[-1] == 2:
        return np.stack([x[..., 0], zero, x[..., 1]], axis=-1)
    return np.stack([zero, zero, x[..., 0]], axis=-1)


def spatial_shape(
    mass: float, inertia: np.ndarray
) -> tuple[ShapeKind, tuple[float, ...], np.ndarray]:
    """`(kind, size, axes)` of a spatial body's shape: the uniform box of its principal
    moments, or the uniform cylinder about the odd axis when two moments are equal;
    `axes` the shape's frame in the body's (a rotation, its columns principal axes)."""
    moments, axes = (np.asarray(x, dtype=float) for x in principal_axes(inertia))
    moments = np.maximum(moments, 0.0)
    scale = max(float(moments.max()), 1e-300)
    pairs = [(i, j) for i in range(3) for j in range(i + 1, 3)]
    equal = [p for p in pairs if abs(moments[p[0]] - moments[p[1]]) <= _EQUAL * scale]
    if len(equal) == 1:  # axisymmetric: a cylinder about the odd axis
        odd = ({0, 1, 2} - set(equal[0])).pop()
        perp = moments[equal[0][0]]
        radius = np.sqrt(2.0 * moments[odd] / mass)
        height = np.sqrt(max(12.0 * perp / mass - 3.0 * radius**2, 0.0))
        floor = MIN_SIDE * max(2 * radius, height)
        order = [equal[0][0], equal[0][1], odd]
        axes = axes[:, order]
        size = (max(radius, floor / 2), max(height, floor))
        kind = "cylinder"
    else:
        total = moments.sum()
        sides = np.sqrt(np.maximum(6.0 * (total - 2.0 * moments) / mass, 0.0))
        size = tuple(float(s) for s in np.maximum(sides, MIN_SIDE * sides.max()))
        kind = "box"
    if np.linalg.det(axes) < 0:  # the cylinder's reordered axes: right-handed again
        axes = axes * np.array([1.0, 1.0, -1.0])
    return kind, tuple(float(s) for s in size), axes


def _shapes_of(body: Any, params: Any, first: int, k: int, dot: float) -> list[Shape]:
    """The shapes of a body standing for `k` bodies, drawn as bodies `first, …`."""
    masses = _per_body(value(body.mass, params), k, 0)
    out = []
    for i in range(k):
        colour, name = PALETTE[(first + i) % len(PALETTE)], f"{type(body).__name__}_{first + i}"
        if isinstance(body, SpatialBody):
            inertia = _per_body(value(body.inertia, params), k, 2)[i]
            kind, size, axes = spatial_shape(float(masses[i]), inertia)
            out.append(
                Shape(first + i, placed(axes, np.zeros(3)), kind, size, colour=colour, name=name)
            )
            continue
        length = 0.0
        if isinstance(body, PlanarBody):
            inertia = float(_per_body(value(body.inertia, params), k, 0)[i])
            length = float(np.sqrt(max(12.0 * inertia / masses[i], 0.0)))
        if length > 2 * dot:  # the rod of its moment, along the body's x axis
            width = max(0.08 * length, dot)
            size: tuple[float, ...] = (length, width, width)
            out.append(Shape(first + i, np.eye(4), "box", size, colour=colour, name=name))
        else:
            out.append(Shape(first + i, np.eye(4), "sphere", (dot,), colour=colour, name=name))
    return out


def _gravity_turn(scene: Scene, params: Any) -> np.ndarray:
    """The world's turn that makes a spatial scene's gravity vector point along −z
    (the identity for a magnitude, or no gravity)."""
    if scene.gravity is None:
        return np.eye(3)
    g = np.asarray(value(scene.gravity, params), dtype=float)
    if g.shape != (3,) or not np.linalg.norm(g) > 0:
        return np.eye(3)
    u, down = g / np.linalg.norm(g), np.array([0.0, 0.0, -1.0])
    axis, cos = np.cross(u, down), float(u @ down)
    if np.linalg.norm(axis) < 1e-12:
        return np.eye(3) if cos > 0 else np.diag([1.0, -1.0, -1.0])  # half a turn about x
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + cos)


def body_poses(times: np.ndarray, q: np.ndarray, scene: Scene, params: Any) -> Poses:
    """The scene's bodies along the resampled states `q` `(F, n)`, each posed by its pose
    map, with a shape sized from its inertia.

    **Raises:** `ShapeError` when `q` is not the scene's (`n_dof`, when it has one).
    """
    import jax
    import jax.numpy as jnp

    if scene.n_dof is not None:
        check_width(scene, q, int(scene.n_dof), "the scene's n_dof")
    origins, rotations, counts, dims = [], [], [], []
    for body in scene.bodies:
        x, angle = jax.vmap(lambda a, b=body: b.pose(a, params))(jnp.asarray(q))
        x = _stacked(x, 1)  # (F, k, d)
        if isinstance(body, SpatialBody):
            rot = _stacked(angle, 2)
        elif isinstance(body, PlanarBody):
            rot = _rotation_y(_stacked(angle, 0))
        else:
            rot = np.broadcast_to(np.eye(3), x.shape[:2] + (3, 3))
        origins.append(_in_world(x))
        rotations.append(rot)
        counts.append(x.shape[1])
        dims.append(x.shape[-1])
    origins, rotations = np.concatenate(origins, axis=1), np.concatenate(rotations, axis=1)
    planar = max(dims) < 3  # drawn upright in the world's x–z plane
    turn = _gravity_turn(scene, params)
    origins = origins @ turn.T
    rotations = np.einsum("ij,fkjl->fkil", turn, rotations)
    spread = float(np.max(np.ptp(origins.reshape(-1, 3), axis=0)))
    dot = 0.04 * (spread if spread > 1e-9 else 1.0)
    shapes, first = [], 0
    for body, k in zip(scene.bodies, counts, strict=True):
        shapes += _shapes_of(body, params, first, k, dot)
        first += k
    return Poses(times, origins, rotations, (), planar, tuple(shapes))
