r"""Capsules and boxes, as the exact sets of spheres that touch a plane.

Against a plane, a convex shape touches with its lowest point, and for two shapes that
is a sphere's: a **capsule** (a cylinder of radius `r` capped by hemispheres) touches
with one of its two end spheres (radius `r`, on its axis at `±h`), and a **box** with one
of its corners (spheres of radius 0). So a `Capsule` is its two end spheres and a `Box` its
corners, exactly (not an approximation), and a [`ContactSystem`][lagrax.contact.ContactSystem]
takes them among its spheres. Against another sphere (`pairs=`) they are these spheres
too, which is exact only where the other sphere meets an end or a corner.
"""

import itertools
import math
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core.errors import ArgumentTypeError, ConfigurationError
from .geometry import Sphere, real_number


def _orientation(angle, rotation, dim: int, owner: str) -> Callable:
    """`R(q, params)`: the body's rotation, `(dim, dim)` (the identity with neither)."""
    if angle is not None and rotation is not None:
        raise ConfigurationError(
            f"a {owner} takes its body's orientation as angle= (planar) or rotation= "
            "(spatial), not both"
        )
    for label, fn in (("angle", angle), ("rotation", rotation)):
        if fn is not None and not callable(fn):
            raise ArgumentTypeError(f"{owner}'s {label} must be a function of (q, params) or None")
    if angle is not None:
        if dim != 2:
            raise ConfigurationError(f"a {owner} with angle= is planar: give it 2-D sizes")

        def planar(q, params):
            c, s = jnp.cos(angle(q, params)), jnp.sin(angle(q, params))
            return jnp.stack([jnp.stack([c, -s]), jnp.stack([s, c])])

        return planar
    if rotation is not None:
        if dim != 3:
            raise ConfigurationError(f"a {owner} with rotation= is spatial: give it 3-D sizes")
        return lambda q, params: jnp.asarray(rotation(q, params))
    return lambda q, params: jnp.eye(dim)


def _sphere_at(radius, position, orient, arm, angle, rotation) -> Sphere:
    """A sphere centred at `position + R arm` (`arm` in the body's frame)."""
    arm = tuple(float(x) for x in arm)

    def centre(q, params):
        c = jnp.asarray(position(q, params))
        rot = orient(q, params)
        return c + rot.astype(c.dtype) @ jnp.asarray(arm, c.dtype)

    return Sphere(radius, centre, angle=angle, rotation=rotation)


def _vector(value, owner: str, label: str, positive: bool) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as err:
        raise ArgumentTypeError(f"{owner}'s {label} must be 2 or 3 numbers, got {value!r}") from err
    bad = arr.ndim != 1 or arr.shape[0] not in (2, 3) or not np.all(np.isfinite(arr))
    if bad or (positive and not np.all(arr >= 0)):
        rule = "finite numbers >= 0" if positive else "finite numbers"
        raise ConfigurationError(
            f"{owner}'s {label} must be 2 (planar) or 3 (spatial) {rule}, got {label}={value!r}"
        )
    return arr


class Capsule(eqx.Module):
    r"""A capsule fixed to a body: a cylinder of radius `radius` and half-length
    `half_length` along `axis` (in the body's frame), capped by hemispheres. Against a
    plane it is exactly its two end spheres, centred at `c ± R h a` (`c` the capsule's
    centre, `R` the body's rotation, `h` the half-length, `a` the unit axis), each
    turning with the body (so a capsule rolls).

    **Arguments:**

    - `radius`: the radius, `≥ 0`.
    - `half_length`: half the distance between the end spheres' centres, `≥ 0`.
    - `position`: `position(q, params) -> (d,)`, the capsule's centre in the world frame.
    - `axis`: the capsule's axis in the body's frame (default the body's first axis,
      `(1, 0)` or `(1, 0, 0)`: `d` entries, normalized).
    - `angle`, `rotation`: the body's orientation, as for a
      [`Sphere`][lagrax.contact.Sphere] (neither: the capsule does not turn).

    **Raises:** `ConfigurationError` for a negative or non-finite size, a zero axis,
    both `angle` and `rotation`, or an orientation of the wrong dimension.

    **Example:**

    ```python
    # a planar capsule (x, y, θ), 0.05 m radius, 0.2 m between its end centres
    rod = lagrax.contact.Capsule(0.05, 0.1, lambda q, p: q[:2], angle=lambda q, p: q[2])
    scene = lagrax.contact.ContactSystem(body, rod, lagrax.contact.Plane([0.0, 1.0]))
    ```
    """

    spheres: tuple[Sphere, ...]

    def __init__(
        self,
        radius: float,
        half_length: float,
        position: Callable[[Any, Any], Any],
        *,
        axis: Any = None,
        angle: Callable | None = None,
        rotation: Callable | None = None,
    ):
        h = real_number(half_length, "Capsule's half_length must be a real number >= 0")
        if not (math.isfinite(h) and h >= 0):
            raise ConfigurationError(
                f"Capsule's half_length must be finite and >= 0, got half_length={half_length!r}"
            )
        dim = 2 if angle is not None else 3 if rotation is not None else None
        if axis is None:
            axis = (1.0, 0.0) if dim in (2, None) else (1.0, 0.0, 0.0)
        a = _vector(axis, "Capsule", "axis", positive=False)
        norm = float(np.linalg.norm(a))
        if norm == 0:
            raise ConfigurationError(f"Capsule's axis must be non-zero, got axis={axis!r}")
        orient = _orientation(angle, rotation, a.shape[0], "Capsule")
        ends = (h / norm * a, -h / norm * a)
        self.spheres = tuple(
            _sphere_at(radius, position, orient, arm, angle, rotation) for arm in ends
        )


class Box(eqx.Module):
    r"""A box fixed to a body, of half-extents `half_extents` along the body's axes.
    Against a plane it is exactly its corners, points (spheres of radius 0) at
    `c + R (±a, ±b[, ±c])`: 4 in a planar model, 8 in a spatial one.

    **Arguments:**

    - `half_extents`: the half-sizes along the body's axes, 2 (planar) or 3 (spatial)
      numbers `≥ 0`.
    - `position`: `position(q, params) -> (d,)`, the box's centre in the world frame.
    - `angle`, `rotation`: the body's orientation, as for a
      [`Sphere`][lagrax.contact.Sphere] (neither: the box does not turn).

    **Raises:** `ConfigurationError` for a negative or non-finite half-extent, both
    `angle` and `rotation`, or an orientation of the wrong dimension.

    **Example:**

    ```python
    # a planar box (x, y, θ), 0.2 m × 0.1 m
    crate = lagrax.contact.Box((0.1, 0.05), lambda q, p: q[:2], angle=lambda q, p: q[2])
    scene = lagrax.contact.ContactSystem(body, crate, lagrax.contact.Plane([0.0, 1.0]))
    ```
    """

    spheres: tuple[Sphere, ...]

    def __init__(
        self,
        half_extents: Any,
        position: Callable[[Any, Any], Any],
        *,
        angle: Callable | None = None,
        rotation: Callable | None = None,
    ):
        half = _vector(half_extents, "Box", "half_extents", positive=True)
        orient = _orientation(angle, rotation, half.shape[0], "Box")
        signs = itertools.product((-1.0, 1.0), repeat=half.shape[0])
        # (a corner is a point: its orientation does not move its contact point)
        self.spheres = tuple(
            _sphere_at(0.0, position, orient, np.asarray(s) * half, None, None) for s in signs
        )
