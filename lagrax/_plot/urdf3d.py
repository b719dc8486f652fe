"""A URDF's `<visual>` elements as shapes on a tree's bodies: meshes (read with trimesh)
and the primitives `<box>`, `<sphere>`, `<cylinder>`, with their `<material>` colours.

Each link is placed in the frame of the tree body it moves with (the child link of its
nearest moving joint above it, through the fixed joints between, as `from_urdf` merges
them) or of the root (the world, or a floating base). A mesh that is missing or unreadable
is named in a [`lagrax.URDFWarning`][] and drawn as the link's bounding box: the box around
its frame's origin, its centre of mass and its child joints.
"""

from __future__ import annotations

import os
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np

from .._core.errors import URDFWarning
from .._multibody.formats.urdf_elements import parse, rpy_matrix
from .poses3d import Shape
from .shapes3d import MeshReadError, box_of, colour_of, mesh_shapes, placed


def _floats(element: ET.Element | None, attr: str, default: list[float]) -> np.ndarray:
    if element is None or element.get(attr) is None:
        return np.asarray(default, dtype=float)
    try:
        return np.asarray([float(x) for x in element.get(attr, "").split()], dtype=float)
    except ValueError:
        return np.asarray(default, dtype=float)


def _origin(element: ET.Element) -> np.ndarray:
    origin = element.find("origin")
    xyz = _floats(origin, "xyz", [0.0, 0.0, 0.0])
    rpy = _floats(origin, "rpy", [0.0, 0.0, 0.0])
    return placed(rpy_matrix(rpy), xyz)


def resolve(filename: str, base: Path, package_dirs: tuple[Path, ...]) -> Path:
    """A mesh's file: `package://name/rest` looked up in `package_dirs` (a folder named
    `name`, or holding one), then in the folders above the URDF and those of
    `ROS_PACKAGE_PATH`; `file://` and relative paths (to the URDF's folder) as they are."""
    if filename.startswith("file://"):
        return Path(filename[len("file://") :])
    if not filename.startswith("package://"):
        path = Path(filename)
        return path if path.is_absolute() else base / path
    package, _, rest = filename[len("package://") :].partition("/")
    ros = [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    candidates = []
    for folder in (*package_dirs, base, *base.parents, *ros):
        candidates += [folder / rest] if folder.name == package else []
        candidates.append(folder / package / rest)
    for path in candidates:
        if path.is_file():
            return path
    return candidates[0]


def _materials(robot: ET.Element) -> dict[str, tuple[int, float]]:
    """The robot's named `<material>`s with a `<color rgba>`."""
    out = {}
    for m in robot.findall("material"):
        colour = m.find("color")
        if m.get("name") and colour is not None:
            out[m.get("name", "")] = colour_of(_floats(colour, "rgba", [0.7, 0.7, 0.7, 1.0]))
    return out


def _colour(visual: ET.Element, named: dict) -> tuple[int | None, float]:
    material = visual.find("material")
    if material is None:
        return None, 1.0
    colour = material.find("color")
    if colour is not None:
        return colour_of(_floats(colour, "rgba", [0.7, 0.7, 0.7, 1.0]))
    return named.get(material.get("name", ""), (None, 1.0))


def _placements(links: dict, joints: list, body_names: tuple[str, ...]) -> dict:
    """Each link's `(body, 4×4 in the body's frame)`: body `i + 1` for tree body `i`
    (its child link), `0` for the root (the world, or a floating base); moving joints
    that are not the tree's (locked) at zero."""
    parent_of = {j.child: j for j in joints}
    body_of = {name: i + 1 for i, name in enumerate(body_names)}
    out = {}
    for name in links:
        transform, link = np.eye(4), name
        while link not in body_of and link in parent_of:
            j = parent_of[link]
            transform = placed(j.rot, j.xyz) @ transform
            link = j.parent
        out[name] = (body_of.get(link, 0), transform)
    return out


def _link_box(link: ET.Element, joints: list, at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The centre and sides of a link's box (its frame's origin, centre of mass and child
    joints), in its body's frame (`at`: the link's placement there)."""
    name = link.get("name")
    points = [np.zeros(3)] + [j.xyz for j in joints if j.parent == name]
    inertial = link.find("inertial")
    if inertial is not None:
        points.append(_origin(inertial)[:3, 3])
    points = np.asarray(points)
    span = float(np.max(np.ptp(points, axis=0)))
    centre, sides = box_of(points, max(0.3 * span, 0.03))
    return at[:3, :3] @ centre + at[:3, 3], sides


def _visual_shapes(
    visual: ET.Element, body: int, transform: np.ndarray, colour: Any, where: str, ctx: dict
) -> list[Shape]:
    """The shapes of one `<visual>` (raises `MeshReadError` for a mesh)."""
    geometry = visual.find("geometry")
    if geometry is None or len(geometry) == 0:
        return []
    element = geometry[0]
    rgb, opacity = colour
    if element.tag == "mesh":
        filename = element.get("filename", "")
        path = resolve(filename, ctx["base"], ctx["package_dirs"])
        scale = _floats(element, "scale", [1.0, 1.0, 1.0])
        scale = np.broadcast_to(scale if scale.size in (1, 3) else np.ones(3), (3,))
        shapes = mesh_shapes(str(path), body, transform, scale, rgb, where)
        return [
            Shape(s.body, s.transform, s.kind, (), s.vertices, s.faces, s.colour, opacity, s.name)
            for s in shapes
        ]
    rgb = rgb if rgb is not None else 0xB4B4B4
    if element.tag == "box":
        size = tuple(_floats(element, "size", [0.1, 0.1, 0.1]))
        return [Shape(body, transform, "box", size, colour=rgb, opacity=opacity, name=where)]
    if element.tag == "sphere":
        radius = float(_floats(element, "radius", [0.05])[0])
        return [
            Shape(body, transform, "sphere", (radius,), colour=rgb, opacity=opacity, name=where)
        ]
    if element.tag == "cylinder":
        r = float(_floats(element, "radius", [0.05])[0])
        length = float(_floats(element, "length", [0.1])[0])
        return [
            Shape(body, transform, "cylinder", (r, length), colour=rgb, opacity=opacity, name=where)
        ]
    return []


def urdf_shapes(
    source: str | os.PathLike, body_names: tuple[str, ...], package_dirs: Any = ()
) -> tuple[Shape, ...]:
    """The `<visual>` shapes of a URDF (a path, or its XML text) on the bodies of the tree
    loaded from it (`body_names`: the tree's, its bodies' child links).

    **Warns:** [`lagrax.URDFWarning`][] naming each mesh that is missing or unreadable
    (drawn as its link's box).

    **Raises:** [`lagrax.URDFError`][] for malformed XML (as `from_urdf`).
    """
    text = os.fspath(source)
    base = Path.cwd()
    if not text.lstrip().startswith("<"):
        base = Path(text).resolve().parent
        with open(text, encoding="utf-8") as f:
            text = f.read()
    links, joints = parse(text)
    robot = ET.fromstring(text)
    named = _materials(robot)
    dirs = tuple(
        Path(p) for p in ([package_dirs] if isinstance(package_dirs, str) else package_dirs)
    )
    ctx = {"base": base, "package_dirs": dirs}
    out: list[Shape] = []
    for name, (body, at) in _placements(links, joints, tuple(body_names)).items():
        for k, visual in enumerate(links[name].findall("visual")):
            transform = at @ _origin(visual)
            where = f"{name}_{k}"
            colour = _colour(visual, named)
            try:
                out += _visual_shapes(visual, body, transform, colour, where, ctx)
            except MeshReadError as err:
                mesh = visual.find("geometry/mesh")
                filename = mesh.get("filename", "") if mesh is not None else "?"
                warnings.warn(
                    f"the mesh {filename!r} of link {name!r} cannot be drawn ({err}): drawn as "
                    "the link's bounding box",
                    URDFWarning,
                    stacklevel=4,
                )
                centre, sides = _link_box(links[name], joints, at)
                box = placed(at[:3, :3], centre)
                out.append(Shape(body, box, "box", tuple(sides), colour=0xC04040, name=where))
    return tuple(out)


__all__ = ["urdf_shapes", "resolve"]
