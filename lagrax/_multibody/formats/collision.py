r"""Collision geometry from model files, as contact spheres on a robot's bodies.

Every shape becomes spheres fixed to a body of the tree (`radius = 0`: a point), the sets
a plane contact needs, exactly or (curved shapes) approximately:

- a sphere: itself (exact);
- a box: its 8 corners, radius 0 (exact: a box touches a plane at corners, edges or
  faces);
- a capsule: its 2 end spheres (exact: a capsule's lowest point is on an end sphere);
- a cylinder: 8 points on each end's rim, radius 0 (standing or tilted: the rim's
  octagon; rolling on its side it bumps on the octagon: use a capsule or spheres);
- an ellipsoid (MJCF): its bounding sphere;
- a mesh: its bounding sphere (default), or its convex hull's vertices (radius 0,
  `meshes="vertices"`: exact, at the cost of many points).

The bounding sphere is the smallest sphere around the mesh's vertices (URDF: read with
`trimesh`; MJCF: MuJoCo's `geom_rbound` about the geom's origin). Use `meshes="vertices"` for
a mesh that rests on a face (a foot sole, a chassis), or `contact=[link names]` to keep
only the links that should touch the ground (a quadruped's feet: the bounding sphere of a
whole leg reaches below its foot).
"""

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal, assert_never

import numpy as np

from ..._core.errors import ConfigurationError, MJCFError, URDFError
from .mjcf_parts import quat_matrix
from .urdf_elements import rpy_matrix

MESHES = ("bounding_sphere", "vertices")
RIM_POINTS = 8  # points on each end of a cylinder
# the primitives `shape_points` turns into spheres: the readers pass only these (a mesh
# and an ellipsoid become bounding spheres before), so the type checker holds the set
Primitive = Literal["sphere", "box", "capsule", "cylinder"]


@dataclass(frozen=True)
class ContactPoint:
    """One contact sphere read from a model file: fixed to tree body `body` (−1: the
    floating base), its centre `offset` in that body's frame, its `radius`, the link or
    geom `source` it came from, and its friction coefficient (`None`: the file gives
    none)."""

    body: int
    offset: tuple[float, float, float]
    radius: float
    source: str
    friction: float | None = None


def placed(
    body: int,
    frame: tuple[np.ndarray, np.ndarray],
    centres: np.ndarray,
    radius: float,
    source: str,
    friction: float | None,
) -> list[ContactPoint]:
    """A shape's sphere `centres` (in its own frame) as contact points of tree body
    `body`, the shape's frame `(p, R)` given in the body's frame: offsets `p + R c`."""
    pos, rot = frame
    return [
        ContactPoint(body, tuple(float(x) for x in pos + rot @ c), radius, source, friction)
        for c in centres
    ]


def shape_points(kind: Primitive, size: Sequence[float]) -> tuple[np.ndarray, float]:
    """`(centres (k, 3), radius)`: a primitive's spheres in its own frame (the shape's
    axis along `z`). `size`: sphere `(r,)`, box the half-sizes `(a, b, c)`, capsule and
    cylinder `(r, half-length)`."""
    if kind == "sphere":
        return np.zeros((1, 3)), float(size[0])
    if kind == "box":
        signs = np.array([(i, j, k) for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
        return signs * np.asarray(size[:3], float), 0.0
    if kind == "capsule":
        return np.array([[0.0, 0.0, -size[1]], [0.0, 0.0, size[1]]]), float(size[0])
    if kind == "cylinder":
        angles = 2.0 * math.pi * np.arange(RIM_POINTS) / RIM_POINTS
        ring = np.stack([size[0] * np.cos(angles), size[0] * np.sin(angles)], axis=1)
        ends = [np.column_stack([ring, np.full(RIM_POINTS, z)]) for z in (-size[1], size[1])]
        return np.concatenate(ends), 0.0
    assert_never(kind)


def check_meshes(meshes: str) -> None:
    """A `ConfigurationError` unless `meshes` is one of `MESHES`."""
    if meshes not in MESHES:
        raise ConfigurationError(f"meshes must be one of {MESHES}, got meshes={meshes!r}")


def selected(contact: Any, names: Sequence[str], what: str) -> set[str]:
    """The links (geoms, bodies) whose geometry `contact` asks for: all of `names` for
    `True`, else the given names, each checked to be one of them."""
    if contact is True:
        return set(names)
    chosen = [contact] if isinstance(contact, str) else list(contact)
    unknown = [c for c in chosen if c not in names]
    if unknown:
        raise ConfigurationError(
            f"contact names {unknown} that are not {what}s with collision geometry; those "
            f"are {sorted(names)}"
        )
    return set(chosen)


# --------------------------------------------------------------------------- URDF
def _mesh_file(filename: str, base_dir: str | None, package_dirs: Sequence[str]) -> str:
    """The path of a `<mesh filename>`: `package://pkg/rest` looked up in `package_dirs`
    (each a folder holding `pkg`, or `pkg` itself) and then in the folders above the URDF
    file; `file://path`; or a path relative to the URDF file."""
    if filename.startswith("file://"):
        return filename[len("file://") :]
    if not filename.startswith("package://"):
        return filename if os.path.isabs(filename) else os.path.join(base_dir or ".", filename)
    package, _, rest = filename[len("package://") :].partition("/")
    roots = list(package_dirs)
    folder = base_dir
    while folder:  # the folders above the URDF file
        roots.append(folder)
        up = os.path.dirname(folder)
        folder = None if up == folder else up
    for root in roots:
        candidates = [os.path.join(root, package, rest)]
        if os.path.basename(os.path.normpath(root)) == package:
            candidates.append(os.path.join(root, rest))
        for candidate in candidates:
            if os.path.exists(candidate):
                return candidate
    return filename


def _mesh_points(path: str, scale: np.ndarray, meshes: str, where: str):
    """`(centres (k, 3), radius)` of a mesh file in its own frame (scaled)."""
    try:
        import trimesh
    except ImportError:
        raise URDFError(
            f"{where}: reading a mesh's contact geometry needs trimesh (pip install trimesh, "
            "or lagrax[contact])"
        ) from None
    if not os.path.exists(path):
        raise URDFError(
            f"{where}: mesh file {path!r} not found; pass package_dirs= with the folder "
            "holding its package, or contact=[link names] without this link"
        )
    mesh = trimesh.load(path, force="mesh")
    vertices = np.asarray(mesh.vertices, float) * scale
    if meshes == "vertices":
        hull = trimesh.Trimesh(vertices).convex_hull
        return np.asarray(hull.vertices, float), 0.0
    centre, radius = trimesh.nsphere.minimum_nsphere(vertices)
    return np.asarray(centre, float)[None], float(radius)


def _geometry(geometry: ET.Element, where: str, mesh_info: tuple):
    """A `<geometry>` element's spheres in its frame."""
    shape = next(iter(geometry), None)
    if shape is None:
        raise URDFError(f"{where}: <geometry> has no shape")

    def floats(attr: str, n: int, default: Any = None) -> list[float]:
        text = shape.get(attr)
        if text is None and default is not None:
            return default
        try:
            values = [float(v) for v in (text or "").split()]
        except ValueError:
            values = []
        if len(values) != n or not all(math.isfinite(v) and v >= 0 for v in values):
            raise URDFError(
                f"{where}: <{shape.tag} {attr}={text!r}> must be {n} finite number(s) >= 0"
            )
        return values

    if shape.tag == "sphere":
        return shape_points("sphere", floats("radius", 1))
    if shape.tag == "box":
        return shape_points("box", [0.5 * s for s in floats("size", 3)])
    if shape.tag in ("capsule", "cylinder"):
        radius, length = floats("radius", 1)[0], floats("length", 1)[0]
        kind: Primitive = "capsule" if shape.tag == "capsule" else "cylinder"
        return shape_points(kind, (radius, 0.5 * length))
    if shape.tag == "mesh":
        base_dir, package_dirs, meshes = mesh_info
        scale = np.asarray(floats("scale", 3, [1.0, 1.0, 1.0]))
        path = _mesh_file(shape.get("filename", ""), base_dir, package_dirs)
        return _mesh_points(path, scale, meshes, where)
    raise URDFError(f"{where}: unknown collision shape <{shape.tag}>")


def urdf_points(
    links: dict,
    order: Sequence[str],
    place: dict,
    contact: Any,
    floating: bool,
    mesh_info: tuple,
) -> list[ContactPoint]:
    """The contact spheres of the URDF's `<collision>` elements on the kept links
    (`order`), each placed in its body by `place` (`link -> (body, R, p)`, body −1 the
    root: the floating base, or the world, whose links do not move and are skipped).
    `mesh_info = (URDF folder, package_dirs, meshes)`."""
    with_geometry = [k for k in order if links[k].find("collision") is not None]
    chosen = selected(contact, with_geometry, "link")
    friction = _bullet_friction
    points = []
    for link in order:
        if link not in chosen:
            continue
        body, rot, pos = place[link]
        if body < 0 and not floating:
            continue  # fixed to the world
        for k, element in enumerate(links[link].findall("collision")):
            where = f"link {link!r} <collision> {k}"
            geometry = element.find("geometry")
            if geometry is None:
                raise URDFError(f"{where} has no <geometry>")
            origin = element.find("origin")
            xyz = _attr(origin, "xyz", where)
            rpy = _attr(origin, "rpy", where)
            centres, radius = _geometry(geometry, where, mesh_info)
            frame = (pos + rot @ xyz, rot @ rpy_matrix(rpy))
            points += placed(body, frame, centres, radius, link, friction(links[link]))
    return points


def _attr(origin: ET.Element | None, name: str, where: str) -> np.ndarray:
    text = None if origin is None else origin.get(name)
    if text is None:
        return np.zeros(3)
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        values = np.zeros(0)
    if values.shape != (3,) or not np.all(np.isfinite(values)):
        raise URDFError(f"{where}: <origin {name}={text!r}> must be 3 finite numbers")
    return values


def _bullet_friction(link: ET.Element) -> float | None:
    """Bullet's `<contact><lateral_friction value>` of a link, if it has one."""
    element = link.find("contact/lateral_friction")
    if element is None or element.get("value") is None:
        return None
    try:
        value = float(element.get("value", ""))
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise URDFError(
            f"link {link.get('name')!r}: <lateral_friction value={element.get('value')!r}> "
            "must be a finite number >= 0"
        )
    return value


# --------------------------------------------------------------------------- MJCF


_PLANE, _SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER, _BOX, _MESH = 0, 2, 3, 4, 5, 6, 7


def mjcf_ground(model) -> tuple[tuple[float, float, float], float, float | None]:
    """`(normal, offset, friction)` of the model's ground: its first plane geom on the
    world body (its `z` axis the normal), else `z = 0` with no friction of its own."""
    for g in range(model.ngeom):
        if int(model.geom_bodyid[g]) == 0 and int(model.geom_type[g]) == _PLANE:
            rot = quat_matrix(model.geom_quat[g])
            normal = rot[:, 2]
            offset = float(normal @ np.asarray(model.geom_pos[g], float))
            return tuple(float(x) for x in normal), offset, float(model.geom_friction[g, 0])
    return (0.0, 0.0, 1.0), 0.0, None


def ground_margin(model) -> float:
    """The contact margin of the model's ground (`mjcf_ground`'s plane; 0 without)."""
    for g in range(model.ngeom):
        if int(model.geom_bodyid[g]) == 0 and int(model.geom_type[g]) == _PLANE:
            return float(model.geom_margin[g])
    return 0.0


def mjcf_points(
    model,
    names: Any,
    place: dict,
    contact: Any,
    meshes: str,
    floating: bool,
    margin: bool = False,
) -> list[ContactPoint]:
    """The contact spheres of the model's colliding geoms (`contype` or `conaffinity`
    nonzero) on moving bodies, each placed in its tree body by `place` (MuJoCo body ->
    `(tree body, R, p)`; tree body −1 the floating base if `floating`, else the world;
    −2 the world beside a floating base); with `margin`, each sphere's radius grown by
    MuJoCo's margin of its geom against the ground (the two geoms' `margin`s added, as
    MuJoCo adds them)."""
    extra = ground_margin(model) if margin else 0.0
    lowest = -1 if floating else 0
    colliding = [
        g
        for g in range(model.ngeom)
        if (int(model.geom_contype[g]) or int(model.geom_conaffinity[g]))
        # a body outside `place` has no joint above it: welded to the world, not moving
        and place.get(int(model.geom_bodyid[g]), (lowest - 1,))[0] >= lowest
    ]
    chosen = selected(contact, [names("geom", g) for g in colliding], "colliding geom")
    points = []
    for g in colliding:
        name = names("geom", g)
        if name not in chosen:
            continue
        body, rot, pos = place[int(model.geom_bodyid[g])]
        kind, size = int(model.geom_type[g]), np.asarray(model.geom_size[g], float)
        if kind == _SPHERE:
            centres, radius = shape_points("sphere", size)
        elif kind == _BOX:
            centres, radius = shape_points("box", size)
        elif kind in (_CAPSULE, _CYLINDER):
            centres, radius = shape_points("capsule" if kind == _CAPSULE else "cylinder", size)
        elif kind == _MESH and meshes == "vertices":
            mesh = int(model.geom_dataid[g])
            start, count = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
            centres, radius = np.asarray(model.mesh_vert[start : start + count], float), 0.0
        elif kind in (_ELLIPSOID, _MESH):
            centres, radius = np.zeros((1, 3)), float(model.geom_rbound[g])
        else:
            raise MJCFError(
                f"geom {name!r} is of a type lagrax's contact does not read (type "
                f"{kind}: a plane or height field on a moving body); leave it out with "
                "contact=[geom names]"
            )
        frame = (
            pos + rot @ np.asarray(model.geom_pos[g], float),
            rot @ quat_matrix(model.geom_quat[g]),
        )
        if margin:
            radius = radius + extra + float(model.geom_margin[g])
        points += placed(body, frame, centres, radius, name, float(model.geom_friction[g, 0]))
    return points
