"""A 3D view of a trajectory: a standalone, offline web page played by meshcat's viewer.

The scene is built here, without meshcat's server: meshcat-python's geometry, material and
animation classes lower it to the commands its browser viewer reads (MessagePack), and the
page inlines the viewer's JavaScript (`meshcat/viewer/dist/main.min.js`, from the installed
package) with those commands. Nothing is fetched from a network or a CDN.
"""

from __future__ import annotations

import base64
import html as html_lib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._core.errors import ArgumentTypeError, ConfigurationError, ShapeError
from .._solve.solution import Solution
from ..chains import AbstractTree, FloatingTree, PlanarChain

_INSTALL_HINT = "the 3D viewer needs meshcat: pip install 'lagrax[viz]'"


@dataclass(frozen=True)
class Poses:
    """What the view draws, at each frame of the recording.

    **Fields:**

    - `times`: the frames' simulation times, shape `(F,)`.
    - `origins`: the body-frame origins in the world frame, shape `(F, k, 3)`.
    - `rotations`: the bodies' rotations (body to world), shape `(F, k, 3, 3)`.
    - `links`: pairs `(a, b)` of origins joined by a rod (parent and child).
    - `planar`: whether the mechanism moves in a plane (drawn in the world x–z plane).
    """

    times: np.ndarray
    origins: np.ndarray
    rotations: np.ndarray
    links: tuple[tuple[int, int], ...]
    planar: bool


def _resampled(sol: Solution, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Times at `fps` over the solve's reached span, and `q` linearly interpolated there."""
    ts, q = np.asarray(sol.ts, dtype=float), np.asarray(sol.q, dtype=float)
    if q.ndim != 2 or ts.ndim != 1 or ts.shape[0] != q.shape[0]:
        raise ShapeError(
            f"show3d draws one trajectory: sol.ts of shape (T,) and sol.q of shape (T, n); got "
            f"{ts.shape} and {q.shape} (for a sweep, pick one member first)"
        )
    keep = np.isfinite(ts) & np.all(np.isfinite(q), axis=-1)
    ts, q = ts[keep], q[keep]
    if ts.size == 0:
        raise ShapeError("the solution holds no finite saved state to draw")
    n_frames = max(int(round((ts[-1] - ts[0]) * fps)) + 1, 1)
    times = np.linspace(ts[0], ts[-1], n_frames) if ts.size > 1 else ts[:1]
    out = np.stack([np.interp(times, ts, q[:, i]) for i in range(q.shape[1])], axis=-1)
    return times, out


def _quaternion_matrix(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices `(..., 3, 3)` of quaternions `(x, y, z, w)`, normalised first."""
    x, y, z, w = np.moveaxis(quat / np.linalg.norm(quat, axis=-1, keepdims=True), -1, 0)
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def _tree_frames(tree: AbstractTree, q: np.ndarray, params: Any):
    """Origins `(F, n, 3)` and rotations `(F, n, 3, 3)` of a fixed-base tree's bodies."""
    import jax
    import jax.numpy as jnp

    origins, rots = jax.vmap(lambda a: tree.frames(a, params))(jnp.asarray(q))
    return np.asarray(origins), np.asarray(rots)


def _tree_links(parents: tuple[int, ...], offset: int) -> tuple[tuple[int, int], ...]:
    """Rods from each body to its parent; index 0 is the base (fixed or floating)."""
    return tuple((p + offset if p >= 0 else 0, i + offset) for i, p in enumerate(parents))


def _check_width(model: Any, q: np.ndarray, expected: int, what: str) -> None:
    """A `ShapeError` when the solution's coordinates are not the model's."""
    if q.shape[1] != expected:
        raise ShapeError(
            f"the solution has {q.shape[1]} coordinates per state but the "
            f"{type(model).__name__} has {expected} ({what}): a solution of another model?"
        )


def _points_poses(pts: np.ndarray, times: np.ndarray, planar: bool) -> Poses:
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


def poses(sol: Solution, model: Any = None, *, params: Any = None, fps: float = 30.0) -> Poses:
    """The bodies' poses along a solution, resampled at `fps` frames per second.

    **Arguments:** as [`show3d`][lagrax.plot.show3d].

    **Returns:** a `Poses`.

    **Raises:** `ShapeError` when the solution's coordinates are not the model's;
    `ConfigurationError` for a chain or tree without `params`; `ArgumentTypeError` for a
    model it cannot draw.
    """
    if not (np.isfinite(fps) and fps > 0):
        raise ConfigurationError(f"fps must be a positive number of frames per second; got {fps}")
    times, q = _resampled(sol, fps)
    needs_params = isinstance(model, AbstractTree | FloatingTree | PlanarChain)
    if needs_params and params is None:
        raise ConfigurationError(f"drawing a {type(model).__name__} needs its parameters: params=")
    if isinstance(model, FloatingTree):
        _check_width(model, q, 7 + model.n, "7 base coordinates and the joints")
        base_rot = _quaternion_matrix(q[:, 3:7])
        origins, rots = _tree_frames(model.tree, q[:, 7:], params)
        origins = q[:, None, :3] + np.einsum("fij,fkj->fki", base_rot, origins)
        rots = np.einsum("fij,fkjl->fkil", base_rot, rots)
        origins = np.concatenate([q[:, None, :3], origins], axis=1)
        rots = np.concatenate([base_rot[:, None], rots], axis=1)
        return Poses(times, origins, rots, _tree_links(model.tree.parents, 1), False)
    if isinstance(model, AbstractTree):
        _check_width(model, q, model.n, "its joint coordinates")
        origins, rots = _tree_frames(model, q, params)
        zeros = np.zeros((q.shape[0], 1, 3))
        origins = np.concatenate([zeros, origins], axis=1)
        rots = np.concatenate([np.broadcast_to(np.eye(3), (q.shape[0], 1, 3, 3)), rots], axis=1)
        return Poses(times, origins, rots, _tree_links(model.parents, 1), False)
    if isinstance(model, PlanarChain):
        _check_width(model, q, model.n, "one angle per link")
        import jax
        import jax.numpy as jnp

        pts = np.asarray(jax.vmap(lambda a: model.joint_positions(a, params))(jnp.asarray(q)))
        return _points_poses(pts, times, True)
    if model is None:
        lengths = _planar_lengths(params, q.shape[1])
        angles = np.cumsum(q, axis=-1)
        steps = np.stack([lengths * np.cos(angles), lengths * np.sin(angles)], axis=-1)
        pts = np.concatenate([np.zeros((q.shape[0], 1, 2)), np.cumsum(steps, axis=1)], axis=1)
        return _points_poses(pts, times, True)
    if callable(model):
        pts = np.stack([np.asarray(model(a), dtype=float) for a in q])
        return _points_poses(pts, times, pts.ndim == 3 and pts.shape[-1] == 2)
    raise ArgumentTypeError(
        f"show3d cannot draw a {type(model).__name__}: pass a lagrax.chains Tree, FloatingTree, "
        "SpatialChain or PlanarChain (with params=), a function q -> (k, 2 or 3) points, or "
        "None for the lecture's planar chain"
    )


def _meshcat() -> Any:
    """meshcat's modules, imported on first use (the `viz` extra)."""
    try:
        import meshcat.animation
        import meshcat.commands
        import meshcat.geometry
        import umsgpack
    except ImportError as err:  # pragma: no cover - exercised without the extra
        raise ImportError(_INSTALL_HINT) from err
    return meshcat, umsgpack


def _quaternion_of(rot: np.ndarray) -> np.ndarray:
    """Quaternions `(x, y, z, w)` of rotation matrices `(..., 3, 3)` (Shepperd's method)."""
    flat = rot.reshape(-1, 3, 3)
    out = np.empty((flat.shape[0], 4))
    for k, m in enumerate(flat):
        tr = np.trace(m)
        i = int(np.argmax([tr, m[0, 0], m[1, 1], m[2, 2]]))
        if i == 0:
            s = 2.0 * np.sqrt(max(1.0 + tr, 1e-300))
            out[k] = [
                (m[2, 1] - m[1, 2]) / s,
                (m[0, 2] - m[2, 0]) / s,
                (m[1, 0] - m[0, 1]) / s,
                s / 4,
            ]
        else:
            a, b, c = (i - 1, i % 3, (i + 1) % 3)
            s = 2.0 * np.sqrt(max(1.0 + m[a, a] - m[b, b] - m[c, c], 1e-300))
            v = np.empty(4)
            v[a], v[b], v[c] = s / 4, (m[b, a] + m[a, b]) / s, (m[c, a] + m[a, c]) / s
            v[3] = (m[c, b] - m[b, c]) / s
            out[k] = v
    return out.reshape(rot.shape[:-2] + (4,))


def _rod_quaternions(direction: np.ndarray) -> np.ndarray:
    """Quaternions `(x, y, z, w)` turning the +y axis (meshcat's cylinders) onto `direction`."""
    u = direction / np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), 1e-12)
    ey = np.array([0.0, 1.0, 0.0])
    quat = np.concatenate([np.cross(ey, u), 1.0 + u[..., 1:2]], axis=-1)
    flipped = quat[..., 3] < 1e-9  # pointing along −y: half a turn about x
    quat[flipped] = [1.0, 0.0, 0.0, 0.0]
    return quat / np.linalg.norm(quat, axis=-1, keepdims=True)


def _extent(points: np.ndarray) -> float:
    """The largest side of the box around `points` `(..., 3)` (1 m when they coincide)."""
    flat = points.reshape(-1, 3)
    extent = float(np.max(flat.max(axis=0) - flat.min(axis=0)))
    return extent if extent > 1e-9 else 1.0


def _robot_size(p: Poses) -> float:
    """The robot's own size, for its shapes: its largest extent in any one frame (a
    floating robot that travels far is not drawn larger for it)."""
    if p.origins.shape[1] < 2:
        return 0.25 * _extent(p.origins)
    return max(_extent(frame) for frame in p.origins)


def _scene_commands(p: Poses, fps: float, play: bool) -> list[dict]:
    """meshcat commands (lowered to dicts) that draw `p` and animate it at `fps`."""
    mc, _ = _meshcat()
    g, anim_mod, cmd = mc.geometry, mc.animation, mc.commands
    size = _robot_size(p)
    out: list[dict] = []
    clips: dict = {}
    quats = _quaternion_of(p.rotations)
    for k in range(p.origins.shape[1]):
        path = mc.path.Path(("lagrax", f"body_{k}"))
        shape = g.Box([0.12 * size] * 3) if k == 0 else g.Sphere(0.035 * size)
        colour = 0x404040 if k == 0 else 0xE07020
        out.append(cmd.SetObject(shape, g.MeshLambertMaterial(color=colour), path).lower())
        clip = clips[path] = anim_mod.AnimationClip(fps=fps)
        for f in range(p.times.size):
            clip.set_property(f, "position", "vector3", p.origins[f, k].tolist())
            clip.set_property(f, "quaternion", "quaternion", quats[f, k].tolist())
    for j, (a, b) in enumerate(p.links):
        path = mc.path.Path(("lagrax", f"link_{j}"))
        rod = g.Cylinder(1.0, 0.015 * size)
        out.append(cmd.SetObject(rod, g.MeshLambertMaterial(color=0x2060C0), path).lower())
        d = p.origins[:, b] - p.origins[:, a]
        mid, length = 0.5 * (p.origins[:, a] + p.origins[:, b]), np.linalg.norm(d, axis=-1)
        q = _rod_quaternions(d)
        clip = clips[path] = anim_mod.AnimationClip(fps=fps)
        for f in range(p.times.size):
            clip.set_property(f, "position", "vector3", mid[f].tolist())
            clip.set_property(f, "quaternion", "quaternion", q[f].tolist())
            clip.set_property(f, "scale", "vector3", [1.0, max(float(length[f]), 1e-9), 1.0])
    animation = anim_mod.Animation(clips=clips, default_framerate=fps)
    out.append(cmd.SetAnimation(animation, play=play, repetitions=1).lower())
    return out + _camera_commands(p)


def _camera_commands(p: Poses) -> list[dict]:
    """The camera aimed at the middle of the motion, from the side (front of a plane)."""
    flat = p.origins.reshape(-1, 3)
    centre = 0.5 * (flat.min(axis=0) + flat.max(axis=0))
    size = _extent(flat)
    target = np.eye(4)
    target[:3, 3] = centre
    # the camera's position in meshcat's y-up frame under /Cameras/default/rotated:
    # world (x, y, z) is (x, z, −y) there
    eye = [0.0, 0.0, 1.6 * size] if p.planar else [0.75 * size, 0.6 * size, 0.75 * size]
    # a plane is drawn upright: the floor grid would cut through it
    grid = [{"type": "set_property", "path": "/Grid", "property": "visible", "value": False}]
    return (grid if p.planar else []) + [
        {"type": "set_transform", "path": "/Cameras/default", "matrix": target.T.ravel().tolist()},
        {
            "type": "set_property",
            "path": "/Cameras/default/rotated/<object>",
            "property": "position",
            "value": eye,
        },
    ]


_PAGE = """<!DOCTYPE html>
<html>
<head><meta charset="utf-8"><title>{title}</title>
<style>body {{ margin: 0; }} #meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
</style></head>
<body>
<div id="meshcat-pane"></div>
<script>{viewer_js}</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
var lagraxCommands = [{commands}];
for (const c of lagraxCommands) {{
  viewer.handle_command_bytearray(Uint8Array.from(atob(c), (ch) => ch.charCodeAt(0)));
}}
if (!viewer.animator.playing) {{  // paused at the start, but the time slider must scrub
  viewer.animator.play();
  viewer.animator.pause();
}}
viewer.gui.open();
window.lagraxDuration = viewer.animator.duration;
window.lagraxReady = true;
</script>
</body>
</html>
"""


def _viewer_js() -> str:
    """meshcat's browser viewer, read from the installed package."""
    mc, _ = _meshcat()
    return (Path(mc.__file__).parent / "viewer" / "dist" / "main.min.js").read_text("utf-8")


class View3D:
    """A recorded 3D view of a trajectory: shows inline in Jupyter and saves as a standalone,
    offline web page (meshcat's viewer, with play, pause, reset, a time slider and a speed,
    `timeScale`, under *Animations* in its control panel).

    Made by [`show3d`][lagrax.plot.show3d]; the fields are what it drew.

    **Fields:**

    - `poses`: the bodies' origins and rotations at each frame (`Poses`).
    - `fps`: frames per second of the recording.
    - `title`: the page's title.
    - `play`: whether the page starts playing when it opens.
    """

    def __init__(self, poses: Poses, *, fps: float, title: str, play: bool = True) -> None:
        self.poses, self.fps, self.title, self.play = poses, fps, title, play

    def html(self) -> str:
        """The standalone page: the viewer's JavaScript and the scene inlined, no network.

        **Returns:** the page's HTML text.
        """
        _, umsgpack = _meshcat()
        commands = _scene_commands(self.poses, self.fps, self.play)
        encoded = ",".join(
            '"' + base64.b64encode(umsgpack.packb(c)).decode("ascii") + '"' for c in commands
        )
        return _PAGE.format(
            title=html_lib.escape(self.title), viewer_js=_viewer_js(), commands=encoded
        )

    def save(self, path: str | Path) -> Path:
        """Write the standalone page (one HTML file that plays offline in a browser).

        **Arguments:** `path`, the file to write (conventionally `….html`).

        **Returns:** the path written.
        """
        path = Path(path)
        path.write_text(self.html(), encoding="utf-8")
        return path

    def _repr_html_(self, height: int = 480) -> str:
        """The page in an `iframe` (`srcdoc`), for Jupyter's inline display."""
        return (
            f'<div style="height: {height}px; width: 100%; resize: both; overflow: hidden">'
            f'<iframe srcdoc="{html_lib.escape(self.html(), quote=True)}" '
            'style="width: 100%; height: 100%; border: none"></iframe></div>'
        )

    def __repr__(self) -> str:
        p = self.poses
        return (
            f"View3D({p.origins.shape[1]} bodies, {len(p.links)} rods, {p.times.size} frames "
            f"at {self.fps:g} fps, t = {p.times[0]:g}…{p.times[-1]:g} s)"
        )


def show3d(
    sol: Solution,
    model: Any = None,
    *,
    params: Any = None,
    fps: float = 30.0,
    play: bool = True,
    title: str = "lagrax",
) -> View3D:
    """A 3D view of a trajectory, played in the browser: inline in Jupyter, or saved as a
    standalone offline page with `.save("run.html")`.

    Bodies are drawn from what the model knows: each body frame's origin as a sphere (a
    floating base as a box, turning with the base), and a rod from each body's parent
    origin to its own. A planar mechanism is drawn upright in the world's x–z plane, seen
    from the front. The solution is resampled at `fps` (its coordinates linearly
    interpolated; a floating base's quaternion renormalised), and plays in real time at
    speed 1. Needs the `viz` extra (`pip install 'lagrax[viz]'`: meshcat).

    **Arguments:**

    - `sol`: a `lagrax.Solution` of one trajectory.
    - `model`: what moves; one of
        - a [`lagrax.chains.Tree`][] or [`SpatialChain`][lagrax.chains.SpatialChain]
          (e.g. from [`lagrax.chains.from_urdf`][]) or a
          [`FloatingTree`][lagrax.chains.FloatingTree] (`q` = position, quaternion
          `(x, y, z, w)`, joints), with `params=`;
        - a [`lagrax.chains.PlanarChain`][] with `params=`;
        - a function `points(q) -> (k, 2)` or `(k, 3)`: a chain of points joined in order;
        - `None` (default): the lecture's planar serial chain, lengths `params["l1"], …`
          when `params` has them, else 1 m (right for `lagrax.models.planar_2r`).
    - `params`: the model's parameters.
    - `fps`: frames per second of the recording.
    - `play`: start playing when the page opens.
    - `title`: the page's title.

    **Returns:** a `View3D`; `.save(path)` writes the page, `.html()` gives it.

    **Raises:** `ShapeError` for a solution whose coordinates are not the model's (a
    solution of another model); `ConfigurationError` for a tree or chain without `params`
    or `fps` not positive; `ArgumentTypeError` for a model it cannot draw.

    **Example:**

    ```python
    tree, params = lagrax.chains.from_urdf(lagrax.models.urdf_path("arm7"))
    sol = lagrax.simulate(tree.system(), q0, qd0, params, t1=2.0)
    lagrax.plot.show3d(sol, tree, params=params).save("arm7.html")
    ```
    """
    _meshcat()
    p = poses(sol, model, params=params, fps=fps)
    return View3D(p, fps=float(fps), title=title, play=play)
