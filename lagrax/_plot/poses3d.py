"""The bodies' poses along a trajectory, for the models `lagrax.plot.show3d` knows: trees,
chains, a user's bodies (`bodies3d`) and chains of points, as `Poses` (`drawn3d`), before
any viewer sees them."""

from __future__ import annotations

from typing import Any

import numpy as np

from .._core.errors import ArgumentTypeError, ConfigurationError, ShapeError
from ..chains import AbstractTree, FloatingTree, PlanarChain
from .bodies3d import body_poses, scene_of
from .drawn3d import Poses as Poses
from .drawn3d import Shape as Shape
from .drawn3d import check_width as check_width


def quaternion_matrix(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices `(..., 3, 3)` of quaternions `(x, y, z, w)`, normalised first."""
    x, y, z, w = np.moveaxis(quat / np.linalg.norm(quat, axis=-1, keepdims=True), -1, 0)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def resampled(ts: np.ndarray, q: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Times at `fps` over the reached span of one trajectory (`ts` `(T,)`, `q`
    `(T, n)`), and `q` linearly interpolated there."""
    keep = np.isfinite(ts) & np.all(np.isfinite(q), axis=-1)
    ts, q = ts[keep], q[keep]
    if ts.size == 0:
        raise ShapeError("the solution holds no finite saved state to draw")
    n_frames = max(int(round((ts[-1] - ts[0]) * fps)) + 1, 1)
    times = np.linspace(ts[0], ts[-1], n_frames) if ts.size > 1 else ts[:1]
    out = np.stack([np.interp(times, ts, q[:, i]) for i in range(q.shape[1])], axis=-1)
    return times, out


def trajectories(sol: Any) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """The trajectories in `sol`, each `(ts (T,), q (T, n), label)`: one for a
    `Solution`; one per member for a batched one (`q` of shape `(B, T, n)`: `vmap`ped
    `simulate`) or a sweep's `xarray.Dataset` kept with `keep="trajectory"` (its grid
    flattened in order, labelled by the swept values)."""
    import xarray as xr  # loaded already when a sweep made `sol`

    if isinstance(sol, xr.Dataset) and "q" in sol.data_vars:
        return _dataset_members(sol)
    ts, q = np.asarray(sol.ts, dtype=float), np.asarray(sol.q, dtype=float)
    if q.ndim == 2 and ts.ndim == 1 and ts.shape[0] == q.shape[0]:
        return [(ts, q, "")]
    if q.ndim == 3 and ts.ndim in (1, 2) and ts.shape[-1] == q.shape[1]:
        ts = np.broadcast_to(ts, q.shape[:2])
        return [(ts[b], q[b], f"member {b}") for b in range(q.shape[0])]
    raise ShapeError(
        f"show3d draws trajectories: sol.ts of shape (T,) and sol.q of shape (T, n) (or a "
        f"batch of them, (B, T) and (B, T, n)); got {ts.shape} and {q.shape}"
    )


def _dataset_members(ds: Any) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """A sweep's members, from its `xarray.Dataset` (`q` over the grid, `time`, dof)."""
    q = ds["q"]
    if "time" not in q.dims:
        raise ShapeError(
            "the sweep kept no trajectory (q has no 'time' dimension): run it with "
            'keep="trajectory" to draw its members'
        )
    grid = [d for d in q.dims if d not in ("time", "dof", "q_dof")]
    coord = ds["time"]
    stacked = q.stack(_member=grid) if grid else q.expand_dims(_member=[0])
    values = np.asarray(stacked.transpose("_member", "time", ...).values, dtype=float)
    times = np.asarray(coord.values, dtype=float)
    out = []
    for b in range(values.shape[0]):
        label = ""
        if grid:
            index = stacked["_member"].values[b]
            index = index if isinstance(index, tuple) else (index,)
            label = ", ".join(f"{d} = {_fmt(v)}" for d, v in zip(grid, index, strict=True))
        out.append((times, values[b], label))
    return out


def _fmt(value: Any) -> str:
    try:
        return f"{float(value):g}"
    except (TypeError, ValueError):
        return str(value)


def _frames_program(tree: AbstractTree, q: Any, params: Any):
    import jax

    return jax.vmap(lambda a: tree.frames(a, params))(q)


_FRAMES: list = []  # the compiled program, made on first use (jax imported lazily)


def _tree_frames(tree: AbstractTree, q: np.ndarray, params: Any):
    """Origins `(F, n, 3)` and rotations `(F, n, 3, 3)` of a fixed-base tree's bodies
    (one compiled program per tree and number of frames, reused by later views)."""
    import equinox as eqx
    import jax.numpy as jnp

    if not _FRAMES:
        _FRAMES.append(eqx.filter_jit(_frames_program))
    origins, rots = _FRAMES[0](tree, jnp.asarray(q), params)
    return np.asarray(origins), np.asarray(rots)


def _tree_links(parents: tuple[int, ...], offset: int) -> tuple[tuple[int, int], ...]:
    """Rods from each body to its parent; index 0 is the base (fixed or floating)."""
    return tuple((p + offset if p >= 0 else 0, i + offset) for i, p in enumerate(parents))


def points_poses(pts: np.ndarray, times: np.ndarray, planar: bool) -> Poses:
    """Poses of a chain of points `(F, k, 2 or 3)`: identity rotations, consecutive rods."""
    if pts.ndim != 3 or pts.shape[-1] not in (2, 3):
        raise ShapeError(
            f"the geometry must give k points of 2 or 3 coordinates per state; got shape "
            f"{pts.shape[1:]} per state"
        )
    if pts.shape[-1] == 2:  # the plane (x, y) drawn upright, as the world's x–z plane
        pts = np.stack([pts[..., 0], np.zeros_like(pts[..., 0]), pts[..., 1]], axis=-1)
    k = pts.shape[1]
    rots = np.broadcast_to(np.eye(3), pts.shape[:2] + (3, 3))
    links = tuple((i, i + 1) for i in range(k - 1))
    return Poses(times, pts, np.array(rots), links, planar or pts.shape[-1] == 2)


def _planar_lengths(params: Any, n: int) -> np.ndarray:
    """Link lengths of the default planar chain: `params["l1"], …` when given, else 1 m."""
    if isinstance(params, dict) and all(f"l{i + 1}" in params for i in range(n)):
        return np.array([float(params[f"l{i + 1}"]) for i in range(n)])
    return np.ones(n)


def model_poses(times: np.ndarray, q: np.ndarray, model: Any, params: Any) -> Poses:
    """The bodies' poses of `model` at the resampled states `q` `(F, n)`.

    **Raises:** `ShapeError` when the solution's coordinates are not the model's;
    `ConfigurationError` for a chain or tree without `params`; `ArgumentTypeError` for a
    model it cannot draw.
    """
    needs_params = isinstance(model, AbstractTree | FloatingTree | PlanarChain)
    if needs_params and params is None:
        raise ConfigurationError(f"drawing a {type(model).__name__} needs its parameters: params=")
    if isinstance(model, FloatingTree):
        check_width(model, q, 7 + model.n, "7 base coordinates and the joints")
        base_rot = quaternion_matrix(q[:, 3:7])
        origins, rots = _tree_frames(model.tree, q[:, 7:], params)
        origins = q[:, None, :3] + np.einsum("fij,fkj->fki", base_rot, origins)
        rots = np.einsum("fij,fkjl->fkil", base_rot, rots)
        origins = np.concatenate([q[:, None, :3], origins], axis=1)
        rots = np.concatenate([base_rot[:, None], rots], axis=1)
        return Poses(times, origins, rots, _tree_links(model.tree.parents, 1), False)
    if isinstance(model, AbstractTree):
        check_width(model, q, model.n, "its joint coordinates")
        origins, rots = _tree_frames(model, q, params)
        zeros = np.zeros((q.shape[0], 1, 3))
        origins = np.concatenate([zeros, origins], axis=1)
        rots = np.concatenate([np.broadcast_to(np.eye(3), (q.shape[0], 1, 3, 3)), rots], axis=1)
        return Poses(times, origins, rots, _tree_links(model.parents, 1), False)
    if isinstance(model, PlanarChain):
        check_width(model, q, model.n, "one angle per link")
        import jax
        import jax.numpy as jnp

        pts = np.asarray(jax.vmap(lambda a: model.joint_positions(a, params))(jnp.asarray(q)))
        return points_poses(pts, times, True)
    scene = scene_of(model)
    if scene is not None:
        return body_poses(times, q, scene, params)
    if model is None:
        lengths = _planar_lengths(params, q.shape[1])
        angles = np.cumsum(q, axis=-1)
        steps = np.stack([lengths * np.cos(angles), lengths * np.sin(angles)], axis=-1)
        pts = np.concatenate([np.zeros((q.shape[0], 1, 2)), np.cumsum(steps, axis=1)], axis=1)
        return points_poses(pts, times, True)
    if callable(model):
        pts = np.stack([np.asarray(model(a), dtype=float) for a in q])
        return points_poses(pts, times, pts.ndim == 3 and pts.shape[-1] == 2)
    raise ArgumentTypeError(
        f"show3d cannot draw a {type(model).__name__}: pass a lagrax.chains Tree, FloatingTree, "
        "SpatialChain or PlanarChain (with params=), a lagrax.bodies.Scene of bodies (or its "
        "system), a lagrax.contact.ContactSystem, a function "
        "q -> (k, 2 or 3) points, or None for the lecture's planar chain"
    )
