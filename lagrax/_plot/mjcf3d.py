"""A MuJoCo model's geoms as shapes, posed by MuJoCo's own kinematics.

The model is compiled by MuJoCo (a path, MJCF text or a `mujoco.MjModel`, as
[`from_mjcf`][lagrax.chains.from_mjcf] reads it), and each frame's `qpos` is put through
`mj_kinematics`: the bodies' `xpos` and `xmat` are the view's bodies, and each geom hangs
from its body at `geom_pos`, `geom_quat`, with its type, `geom_size` and colour (its
material's where it has one). Geoms of groups 0–2 are drawn (MuJoCo's viewer's default),
transparent ones and height fields are not. A floating robot's lagrax state is converted to
MuJoCo's (`to_mujoco_state`) first.
"""

from __future__ import annotations

import importlib
import os
from typing import Any

import numpy as np

from .._core.errors import MJCFError, ShapeError
from ..chains import AbstractTree, FloatingTree
from .poses3d import Poses, Shape, check_width, quaternion_matrix
from .shapes3d import colour_of, placed

# mujoco.mjtGeom
_PLANE, _SPHERE, _CAPSULE, _ELLIPSOID, _CYLINDER, _BOX, _MESH = 0, 2, 3, 4, 5, 6, 7


def is_mjcf(geometry: Any) -> bool:
    """Whether `geometry` names a MuJoCo model: an `MjModel`, MJCF text or an `.xml` or
    `.mjcf` file."""
    if type(geometry).__name__ == "MjModel":
        return True
    if isinstance(geometry, str) and geometry.lstrip().startswith("<"):
        return "<mujoco" in geometry[:2000]
    return isinstance(geometry, str | os.PathLike) and os.fspath(geometry).lower().endswith(
        (".xml", ".mjcf")
    )


def compiled(source: Any) -> Any:
    """`source` compiled by MuJoCo."""
    try:
        mujoco = importlib.import_module("mujoco")
    except ImportError:
        raise MJCFError("drawing MJCF geoms needs mujoco: pip install mujoco") from None
    if type(source).__name__ == "MjModel":
        return source
    try:
        if isinstance(source, str) and source.lstrip().startswith("<"):
            return mujoco.MjModel.from_xml_string(source)
        return mujoco.MjModel.from_xml_path(os.fspath(source))
    except ValueError as err:
        raise MJCFError(f"MuJoCo cannot compile the model: {err}") from None


def _qpos(model: Any, q: np.ndarray, nq: int) -> np.ndarray:
    """MuJoCo's `qpos` of the resampled lagrax states (a floating base's quaternion moved
    to the front, `(w, x, y, z)`)."""
    if isinstance(model, FloatingTree):
        check_width(model, q, 7 + model.n, "7 base coordinates and the joints")
        q = np.concatenate([q[:, :3], q[:, 6:7], q[:, 3:6], q[:, 7:]], axis=1)
    elif isinstance(model, AbstractTree):
        check_width(model, q, int(model.n), "its joint coordinates")
    if q.shape[1] != nq:
        raise ShapeError(
            f"the solution has {q.shape[1]} coordinates per state but the MuJoCo model's qpos "
            f"has {nq}: a solution of another model?"
        )
    return q


def _shape(m: Any, g: int, size: float) -> Shape | None:
    """Geom `g` of model `m` as a shape on its body (`None`: not drawn)."""
    rgba = m.mat_rgba[m.geom_matid[g]] if m.geom_matid[g] >= 0 else m.geom_rgba[g]
    if rgba[3] <= 0 or m.geom_group[g] > 2:
        return None
    colour, opacity = colour_of(rgba)
    kind, s = int(m.geom_type[g]), np.asarray(m.geom_size[g], float)
    body = int(m.geom_bodyid[g])
    transform = placed(quaternion_matrix(np.roll(m.geom_quat[g], -1)), m.geom_pos[g])
    name = f"geom_{g}"
    common = dict(colour=colour, opacity=opacity, name=name)
    if kind == _SPHERE:
        return Shape(body, transform, "sphere", (s[0],), **common)
    if kind == _ELLIPSOID:
        return Shape(body, transform, "ellipsoid", tuple(s), **common)
    if kind == _CYLINDER:
        return Shape(body, transform, "cylinder", (s[0], 2 * s[1]), **common)
    if kind == _BOX:
        return Shape(body, transform, "box", tuple(2 * s), **common)
    if kind == _PLANE:
        half = [x if x > 0 else 1.5 * size for x in s[:2]]
        transform = transform @ placed(np.eye(3), [0.0, 0.0, -0.005 * size])
        return Shape(body, transform, "box", (2 * half[0], 2 * half[1], 0.01 * size), **common)
    if kind == _CAPSULE:
        import trimesh

        mesh = trimesh.creation.capsule(height=2 * s[1], radius=s[0], count=[16, 16])
        return Shape(body, transform, "mesh", (), mesh.vertices, mesh.faces, **common)
    if kind == _MESH:
        k = int(m.geom_dataid[g])
        v0, nv = int(m.mesh_vertadr[k]), int(m.mesh_vertnum[k])
        f0, nf = int(m.mesh_faceadr[k]), int(m.mesh_facenum[k])
        vertices = np.asarray(m.mesh_vert[v0 : v0 + nv], float)
        return Shape(
            body, transform, "mesh", (), vertices, np.asarray(m.mesh_face[f0 : f0 + nf]), **common
        )
    return None


def mjcf_poses(times: np.ndarray, q: np.ndarray, source: Any, model: Any = None) -> Poses:
    """The MuJoCo model's bodies along the resampled states `q` `(F, n)` (lagrax's: a
    floating base's quaternion last), and its geoms as shapes on them.

    **Raises:** `ShapeError` when `q` is not the model's; `MJCFError` when MuJoCo cannot
    compile it.
    """
    import mujoco

    m = compiled(source)
    qpos = _qpos(model, q, int(m.nq))
    data = mujoco.MjData(m)
    origins = np.empty((len(times), m.nbody, 3))
    rots = np.empty((len(times), m.nbody, 3, 3))
    for f, row in enumerate(qpos):
        data.qpos[:] = row
        mujoco.mj_kinematics(m, data)
        origins[f], rots[f] = data.xpos, data.xmat.reshape(-1, 3, 3)
    size = max(float(np.max(np.ptp(origins.reshape(-1, 3), axis=0))), float(m.stat.extent))
    shapes = tuple(s for g in range(m.ngeom) if (s := _shape(m, g, size)) is not None)
    links = tuple((int(m.body_parentid[b]), b) for b in range(1, m.nbody))
    return Poses(times, origins, rots, links, False, shapes)
