"""The shapes of contact: a ground `Plane` and the `Sphere`s fixed to a system's bodies."""

import abc
import math
from collections.abc import Callable
from typing import Any

import equinox as eqx
import numpy as np

from .._core.errors import ArgumentTypeError, ConfigurationError

PositionFn = Callable[[Any, Any], Any]


def real_number(value: Any, requirement: str) -> float:
    """`value` as a Python float, or an `ArgumentTypeError` that states the
    `requirement` and the value (a contact coefficient or a shape's size)."""
    try:
        return float(value)
    except (TypeError, ValueError) as err:
        raise ArgumentTypeError(f"{requirement}, got {value!r}") from err


class Plane(eqx.Module):
    r"""The ground: the half-space `n·x ≥ offset` is free, its boundary `n·x = offset` is
    the surface, with the unit normal `n` pointing out of the ground.

    In 2-D (`normal` of length 2: a planar model in its `(x, y)` plane) or 3-D. Any
    normal: an incline of angle `θ` under gravity along `−y`, descending towards `+x`,
    has `normal = (sin θ, cos θ)`.

    **Arguments:**

    - `normal`: the normal, length 2 or 3, any non-zero length (it is divided by its
      norm).
    - `offset`: the signed distance of the surface from the origin along `n` (default
      `0`: the surface passes through the origin).

    **Raises:** `ConfigurationError` for a normal that is zero, non-finite or not of
    length 2 or 3, or an offset that is not finite.

    **Example:**

    ```python
    floor = lagrax.contact.Plane([0.0, 0.0, 1.0])                  # z = 0
    slope = lagrax.contact.Plane([np.sin(0.3), np.cos(0.3)])       # planar incline
    ```
    """

    normal: tuple[float, ...] = eqx.field(static=True)
    offset: float = eqx.field(static=True)

    def __init__(self, normal: Any, offset: float = 0.0):
        try:
            arr = np.asarray(normal, dtype=float)
        except (TypeError, ValueError) as err:
            raise ArgumentTypeError(
                f"Plane's normal must be an array of 2 or 3 real numbers, got {normal!r}"
            ) from err
        if arr.ndim != 1 or arr.shape[0] not in (2, 3):
            raise ConfigurationError(
                f"Plane's normal must have 2 (planar) or 3 (spatial) entries, got shape "
                f"{arr.shape}: {normal!r}"
            )
        norm = float(np.linalg.norm(arr))
        if not (np.all(np.isfinite(arr)) and norm > 0):
            raise ConfigurationError(
                f"Plane's normal must be finite and non-zero (it gives the direction out of "
                f"the ground), got normal={arr.tolist()}"
            )
        offset = real_number(offset, "Plane's offset must be a real number")
        if not math.isfinite(offset):
            raise ConfigurationError(f"Plane's offset must be finite, got offset={offset!r}")
        self.normal = tuple(float(x) for x in arr / norm)
        self.offset = offset

    @property
    def dim(self) -> int:
        """The dimension of the space, 2 or 3."""
        return len(self.normal)


class AbstractSphereSource(eqx.Module):
    r"""What places many spheres at once: the centres and rotations of spheres fixed to
    the bodies of one model, computed from one pass of its kinematics (a tree's forward
    kinematics once for all its spheres, not once per sphere).

    A [`ContactSystem`][lagrax.contact.ContactSystem] evaluates the spheres that share a
    source (equal `key`) as one batch: their centres `(K, 3)`, their rotations
    `(K, 3, 3)`, their velocities by one JVP and their generalized force `Σ J_iᵀ F_i` by
    one VJP, so that its program grows with the model's bodies, not with bodies ×
    spheres. [`body_sphere`][lagrax.contact.body_sphere] gives its spheres a source.
    """

    @property
    @abc.abstractmethod
    def key(self) -> int:
        """What the poses are computed from (a model, by identity): spheres whose
        sources have equal keys are placed together, by any one of those sources."""

    @abc.abstractmethod
    def poses(self, q: Any, params: Any, bodies: np.ndarray, offsets: np.ndarray) -> Any:
        """`(centres, rotations)`, `(K, 3)` and `(K, 3, 3)` in the world frame, of `K`
        spheres fixed to the bodies `bodies` `(K,)` at the offsets `offsets` `(K, 3)` in
        the bodies' frames, at the configuration `q`."""


class Sphere(eqx.Module):
    r"""A sphere (a disk in a planar model) fixed to a body of the system.

    Its centre is `position(q, params)`; the point that touches the ground is the
    centre less `radius` along the plane's normal. The body's orientation gives that
    point's velocity, `v_c + ω × (−r n)`, so friction turns the body and a rolling
    sphere has zero slip there:

    - `angle(q, params) -> scalar`: the body's angle in a planar model (`ω = θ̇`,
      counter-clockwise);
    - `rotation(q, params) -> (3, 3)`: the body's rotation matrix in a spatial model
      (`ω` from `Ṙ Rᵀ`);
    - neither: the sphere does not turn (a point mass, a sphere on a body whose
      rotation does not matter); with `radius > 0` it then slides on its lowest point.

    `radius=0` is a point (a box's corner, a foot's tip).

    **Arguments:**

    - `radius`: the radius, `≥ 0`.
    - `position`: `position(q, params) -> (d,)`, the centre in the world frame (`d` is
      the plane's dimension).
    - `angle`, `rotation`: the body's orientation (at most one of them; see above).
    - `source`, `body`, `offset`: for spheres placed in batches (see
      [`AbstractSphereSource`][lagrax.contact.AbstractSphereSource]): the source, the
      body and the centre's offset in its frame. `position` and `rotation` must then
      give the same centre and rotation, one sphere at a time.

    **Raises:** `ConfigurationError` for a negative or non-finite radius, or both
    `angle` and `rotation`; `ArgumentTypeError` when `position`, `angle` or
    `rotation` is not callable.

    **Example:**

    ```python
    # a disk of radius 0.1 in (x, y, θ) coordinates
    wheel = lagrax.contact.Sphere(0.1, lambda q, p: q[:2], angle=lambda q, p: q[2])
    ```
    """

    radius: float = eqx.field(static=True)
    position: PositionFn
    angle: PositionFn | None = None
    rotation: PositionFn | None = None
    source: AbstractSphereSource | None = None
    body: int = eqx.field(static=True, default=0)
    offset: tuple[float, ...] = eqx.field(static=True, default=(0.0, 0.0, 0.0))

    def __init__(
        self,
        radius: float,
        position: PositionFn,
        angle: PositionFn | None = None,
        rotation: PositionFn | None = None,
        *,
        source: AbstractSphereSource | None = None,
        body: int = 0,
        offset: Any = (0.0, 0.0, 0.0),
    ):
        r = real_number(radius, "Sphere's radius must be a real number >= 0")
        if not (math.isfinite(r) and r >= 0):
            raise ConfigurationError(
                f"Sphere's radius must be finite and >= 0 (0 is a point), got radius={radius!r}"
            )
        if not callable(position):
            raise ArgumentTypeError(
                f"Sphere's position must be a function position(q, params) -> centre, got "
                f"{position!r}"
            )
        for label, fn in (("angle", angle), ("rotation", rotation)):
            if fn is not None and not callable(fn):
                raise ArgumentTypeError(
                    f"Sphere's {label} must be a function of (q, params) or None, got {fn!r}"
                )
        if angle is not None and rotation is not None:
            raise ConfigurationError(
                "a Sphere takes its body's orientation as angle= (planar) or rotation= "
                "(spatial), not both"
            )
        if source is not None and not isinstance(source, AbstractSphereSource):
            raise ArgumentTypeError(
                f"Sphere's source must be a lagrax.contact.AbstractSphereSource or None, got "
                f"{source!r}"
            )
        arm = np.asarray(offset, dtype=float)
        if arm.shape != (3,) or not np.all(np.isfinite(arm)):
            raise ConfigurationError(
                f"Sphere's offset must be three finite numbers, got {offset!r}"
            )
        self.radius = r
        self.position = position
        self.angle = angle
        self.rotation = rotation
        self.source = source
        self.body = int(body)
        self.offset = tuple(float(x) for x in arm)


def placement_groups(spheres: tuple[Sphere, ...]) -> tuple[tuple[int, ...], ...]:
    """The indices of the spheres placed together: those whose sources share a key (a
    sphere without a source is placed alone, by its own functions)."""
    keyed: dict[int, list[int]] = {}
    for i, s in enumerate(spheres):
        if s.source is not None and s.angle is None:
            keyed.setdefault(s.source.key, []).append(i)
    return tuple(tuple(ix) for ix in keyed.values())
