"""Meshes for the 3D view: a mesh file (`.stl`, `.obj`, `.dae`, …) read with trimesh, its
parts grouped by colour and, past a budget of triangles, simplified by vertex clustering so
that a page stays small; and the shapes a missing mesh is drawn as."""

from __future__ import annotations

import os
from functools import lru_cache
from typing import Any

import numpy as np

from .drawn3d import Shape

# triangles of one mesh file past which it is simplified (vertex clustering): the pages
# carry every vertex, and a robot's CAD meshes reach 10⁵ triangles a link (the Panda's
# 13,000 a link made a 7.5 MB page before, 10,000 and 16-bit indices about half of it)
MAX_FACES = 10_000
DEFAULT_COLOUR = 0xB4B4B4


class MeshReadError(Exception):
    """A mesh file that cannot be drawn: missing, unreadable, or without triangles."""


def colour_of(rgba: Any) -> tuple[int, float]:
    """`(0xRRGGBB, opacity)` of an RGBA colour with channels in `[0, 1]`."""
    r, g, b, a = (float(x) for x in rgba)
    rgb = [int(round(255 * min(max(c, 0.0), 1.0))) for c in (r, g, b)]
    return (rgb[0] << 16) | (rgb[1] << 8) | rgb[2], min(max(a, 0.05), 1.0)


def _trimesh() -> Any:
    try:
        import trimesh
    except ImportError as err:  # pragma: no cover - exercised without the extra
        raise MeshReadError("reading meshes needs trimesh: pip install 'lagrax[viz]'") from err
    return trimesh


def _part_colour(mesh: Any) -> int | None:
    """A trimesh part's own colour (a COLLADA or OBJ material's), `None` when it has none."""
    visual = getattr(mesh, "visual", None)
    material = getattr(visual, "material", None)
    colour = getattr(material, "main_color", None)
    if colour is None and getattr(visual, "kind", None) == "face":
        colour = np.asarray(visual.face_colors).mean(axis=0)
    elif colour is None and getattr(visual, "kind", None) == "vertex":
        colour = np.asarray(visual.vertex_colors).mean(axis=0)
    if colour is None:
        return None
    c = np.asarray(colour, dtype=float)[:3]
    return (int(c[0]) << 16) | (int(c[1]) << 8) | int(c[2])


@lru_cache(maxsize=64)
def _read(path: str, mtime: float) -> tuple[tuple[np.ndarray, np.ndarray, int | None], ...]:
    """A mesh file's parts `(vertices, faces, colour)`, one per colour (cached by path and
    modification time)."""
    trimesh = _trimesh()
    try:
        loaded = trimesh.load(path)
    except Exception as err:  # noqa: BLE001 - any reader's failure is an unreadable file
        raise MeshReadError(f"{type(err).__name__}: {err}") from None
    parts = loaded.dump(concatenate=False) if isinstance(loaded, trimesh.Scene) else [loaded]
    by_colour: dict[int | None, list[Any]] = {}
    for part in parts:
        if getattr(part, "faces", None) is not None and len(part.faces):
            by_colour.setdefault(_part_colour(part), []).append(part)
    if not by_colour:
        raise MeshReadError("no triangles in it")
    out = []
    for colour, group in by_colour.items():
        vertices, faces, base = [], [], 0
        for part in group:
            vertices.append(np.asarray(part.vertices, dtype=float))
            faces.append(np.asarray(part.faces, dtype=np.int64) + base)
            base += len(part.vertices)
        out.append((np.concatenate(vertices), np.concatenate(faces), colour))
    return tuple(out)


def read_mesh(path: str | os.PathLike) -> tuple[tuple[np.ndarray, np.ndarray, int | None], ...]:
    """The parts of a mesh file, `(vertices (V, 3), faces (F, 3), colour or None)` each
    (its materials' colours; `None`: the file has none), simplified to about `MAX_FACES`
    triangles in all.

    **Raises:** `MeshReadError` saying why it cannot be read.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise MeshReadError("no such file")
    parts = _read(path, os.path.getmtime(path))
    total = sum(len(f) for _, f, _ in parts)
    if total <= MAX_FACES:
        return parts
    return tuple(
        (*simplified(v, f, max(int(MAX_FACES * len(f) / total), 12)), c) for v, f, c in parts
    )


def simplified(
    vertices: np.ndarray, faces: np.ndarray, max_faces: int
) -> tuple[np.ndarray, np.ndarray]:
    """A mesh with at most about `max_faces` triangles, by vertex clustering: vertices in
    one cell of a grid merge into their mean, and triangles that collapse are dropped
    (the outline stays within a cell of the original)."""
    if len(faces) <= max_faces:
        return vertices, faces
    low = vertices.min(axis=0)
    span = float(np.max(vertices.max(axis=0) - low)) or 1.0
    cells = 256
    while True:
        keys = np.floor((vertices - low) / (span / cells)).astype(np.int64)
        _, inverse = np.unique(keys, axis=0, return_inverse=True)
        inverse = inverse.ravel()
        merged = inverse[faces]
        keep = (
            (merged[:, 0] != merged[:, 1])
            & (merged[:, 1] != merged[:, 2])
            & (merged[:, 0] != merged[:, 2])
        )
        merged = merged[keep]
        _, first = np.unique(np.sort(merged, axis=1), axis=0, return_index=True)
        merged = merged[np.sort(first)]
        if len(merged) <= max_faces or cells <= 4:
            break
        cells = max(int(cells * np.sqrt(max_faces / len(merged)) * 0.9), 4)
    count = np.bincount(inverse).astype(float)
    out = np.zeros((count.size, 3))
    np.add.at(out, inverse, vertices)
    return out / count[:, None], merged


def box_of(points: np.ndarray, pad: float) -> tuple[np.ndarray, np.ndarray]:
    """The centre and sides of the box around `points` `(k, 3)`, each side at least
    `pad`."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    low, high = points.min(axis=0), points.max(axis=0)
    return 0.5 * (low + high), np.maximum(high - low, pad)


def placed(rotation: np.ndarray, position: np.ndarray) -> np.ndarray:
    """The `4×4` transform of a rotation and a position."""
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = rotation, position
    return out


def mesh_shapes(
    path: str, body: int, transform: np.ndarray, scale: np.ndarray, colour: int | None, name: str
) -> list[Shape]:
    """The shapes of one mesh file: one per colour of its parts (the given `colour` for
    parts without one of their own).

    **Raises:** `MeshReadError`.
    """
    out = []
    for k, (vertices, faces, own) in enumerate(read_mesh(path)):
        out.append(
            Shape(
                body,
                transform,
                "mesh",
                vertices=vertices * scale,
                faces=faces,
                colour=own if own is not None else (colour or DEFAULT_COLOUR),
                name=f"{name}_{k}",
            )
        )
    return out
