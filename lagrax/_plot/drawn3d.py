"""What a 3D view draws, frame by frame: `Poses` (the bodies' poses along a trajectory)
and the `Shape`s fixed to them; the viewer's modules build on these."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from .._core.errors import ShapeError

# what a `Shape` can be: the viewer draws each (`scene3d._geometry`), and the type checker
# holds every `Shape(...)` to the set
ShapeKind = Literal["box", "sphere", "cylinder", "ellipsoid", "mesh"]


@dataclass(frozen=True)
class Shape:
    """A shape fixed to a body (or to the world).

    **Fields:**

    - `body`: the index of the body it moves with in `Poses` (`-1`: the world, still).
    - `transform`: its `4×4` placement in that body's frame.
    - `kind`: `"box"` (`size` the three sides), `"sphere"` (`size = (r,)`),
      `"cylinder"` (`size = (r, length)`, along its z axis), `"ellipsoid"` (the three
      radii) or `"mesh"` (`vertices` `(V, 3)` and `faces` `(F, 3)`, scaled already).
    - `colour`: `0xRRGGBB`; `opacity` in `(0, 1]`.
    - `name`: what it came from (a link, a geom, a sphere), for the scene's tree.
    """

    body: int
    transform: np.ndarray
    kind: ShapeKind
    size: tuple[float, ...] = ()
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    colour: int = 0xB0B0B0
    opacity: float = 1.0
    name: str = "shape"


@dataclass(frozen=True)
class Poses:
    """What the view draws, at each frame of the recording.

    **Fields:**

    - `times`: the frames' simulation times, shape `(F,)`.
    - `origins`: the body-frame origins in the world frame, shape `(F, k, 3)`.
    - `rotations`: the bodies' rotations (body to world), shape `(F, k, 3, 3)`.
    - `links`: pairs `(a, b)` of origins joined by a rod (parent and child).
    - `planar`: whether the mechanism moves in a plane (drawn in the world x–z plane).
    - `shapes`: the shapes fixed to the bodies (`Shape`s); with none, each body is drawn
      as a sphere (the first as a box) and each link as a rod.
    - `arrows`: forces to draw as arrows, `(F, A, 2, 3)`: each arrow's foot and its
      vector (in metres, scaled already), or `None`.
    - `skeleton`: draw the spheres and rods even though there are shapes (a model
      without geometry of its own, with a contact scene's spheres added).
    """

    times: np.ndarray
    origins: np.ndarray
    rotations: np.ndarray
    links: tuple[tuple[int, int], ...]
    planar: bool
    shapes: tuple[Shape, ...] = field(default=())
    arrows: np.ndarray | None = None
    skeleton: bool = False


def check_width(model: Any, q: np.ndarray, expected: int, what: str) -> None:
    """A `ShapeError` when the solution's coordinates are not the model's."""
    if q.shape[1] != expected:
        raise ShapeError(
            f"the solution has {q.shape[1]} coordinates per state but the "
            f"{type(model).__name__} has {expected} ({what}): a solution of another model?"
        )
