"""A 3D view of a trajectory: a standalone, offline web page played by meshcat's viewer.

`show3d` gathers what to draw (`poses3d`: the bodies' poses; `urdf3d`, `mjcf3d`,
`contact3d`: the shapes of a URDF's visuals, of MuJoCo's geoms, of a contact scene), and
`View3D` lowers it to a page (`scene3d`).
"""

from __future__ import annotations

import html as html_lib
import os
from pathlib import Path
from typing import Any

import numpy as np

from .._contact.system import ContactSystem
from .._core.errors import ArgumentTypeError, ConfigurationError, ShapeError
from .._solve.solution import Solution
from ..chains import FloatingTree, Tree
from .contact3d import contact_poses
from .mjcf3d import compiled, is_mjcf, mjcf_poses
from .poses3d import Poses, model_poses, resampled, trajectories
from .scene3d import meshcat_modules, page, robot_size, scene_commands
from .urdf3d import urdf_shapes

__all__ = ["Poses", "View3D", "poses", "show3d"]


def poses(sol: Solution, model: Any = None, *, params: Any = None, fps: float = 30.0) -> Poses:
    """The bodies' poses along one solution, resampled at `fps` frames per second.

    **Arguments:** as [`show3d`][lagrax.plot.show3d].

    **Returns:** a `Poses`.

    **Raises:** as [`show3d`][lagrax.plot.show3d].
    """
    _check_fps(fps)
    found = trajectories(sol)
    if len(found) != 1:
        raise ShapeError(f"poses draws one trajectory; sol holds {len(found)}: pick one")
    ts, q, _ = found[0]
    times, q = resampled(ts, q, fps)
    return model_poses(times, q, model, params)


def _check_fps(fps: float) -> None:
    if not (np.isfinite(fps) and fps > 0):
        raise ConfigurationError(f"fps must be a positive number of frames per second; got {fps}")


def _is_urdf(geometry: Any) -> bool:
    if isinstance(geometry, str) and geometry.lstrip().startswith("<"):
        return "<robot" in geometry[:2000]
    return isinstance(geometry, str | os.PathLike) and os.fspath(geometry).lower().endswith(".urdf")


def _geometry_of(model: Any, geometry: Any, package_dirs: Any) -> Any:
    """What `geometry` gives, read once for every member: MuJoCo's compiled model, a URDF's
    shapes (on the tree's bodies), or `None`."""
    if geometry is None:
        return None
    if is_mjcf(geometry):
        return compiled(geometry)
    if not _is_urdf(geometry):
        raise ArgumentTypeError(
            f"geometry= is a URDF (a .urdf path or its XML) or a MuJoCo model (a .xml "
            f"path, MJCF text or an MjModel); got {geometry!r}"
        )
    tree = model.tree if isinstance(model, FloatingTree) else model
    if not isinstance(tree, Tree):
        raise ArgumentTypeError(
            "a URDF's visuals are drawn on the tree loaded from it: pass the Tree or "
            f"FloatingTree of lagrax.chains.from_urdf as the model, got {type(model).__name__}"
        )
    return urdf_shapes(geometry, tuple(tree.body_names), package_dirs)


def _member_poses(times, q, force, model, params, geometry, contact) -> Poses:
    """One member's `Poses`: the model's bodies (or MuJoCo's, for MJCF geometry), the
    geometry's shapes on them (`_geometry_of`) and the contact scene's spheres, ground
    and forces."""
    if isinstance(model, ContactSystem) and contact is None:
        contact, model = model, None
    base = None
    if isinstance(geometry, tuple):  # a URDF's shapes
        base = model_poses(times, q, model, params)
        if geometry:
            base = Poses(base.times, base.origins, base.rotations, base.links, False, geometry)
    elif geometry is not None:  # MuJoCo's model
        base = mjcf_poses(times, q, geometry, model)
    elif contact is None or model is not None:
        base = model_poses(times, q, model, params)
    if contact is None:
        return base  # type: ignore[return-value]
    return contact_poses(base, times, q, contact, params, force)


def _offsets(found: list[Poses], layout: str) -> tuple[np.ndarray, bool]:
    """Each member's shift, and whether the later members are ghosted."""
    count = len(found)
    if layout == "overlay":
        return np.zeros((count, 3)), True
    if layout != "side":
        raise ConfigurationError(f"layout is 'overlay' or 'side'; got {layout!r}")
    spacing = 1.4 * max(robot_size(p) for p in found)
    axis = np.array([1.0, 0.0, 0.0]) if all(p.planar for p in found) else np.array([0.0, 1.0, 0.0])
    return np.arange(count)[:, None] * spacing * axis, False


def _params_for(params: Any, count: int) -> list[Any]:
    if isinstance(params, list | tuple):
        if len(params) != count:
            raise ShapeError(
                f"params is a list of {len(params)} (one per drawn member) but {count} members "
                "are drawn"
            )
        return list(params)
    return [params] * count


class View3D:
    """A recorded 3D view of a trajectory: shows inline in Jupyter and saves as a standalone,
    offline web page (meshcat's viewer, with play, pause, reset, a time slider and a speed,
    `timeScale`, under *Animations* in its control panel).

    Made by [`show3d`][lagrax.plot.show3d]; the fields are what it drew.

    **Fields:**

    - `poses`: the (first) member's bodies, shapes and arrows at each frame (`Poses`).
    - `members`: every drawn member's `Poses` (one for a single solution).
    - `offsets`: each member's shift in the scene, `(M, 3)` (side by side), zeros when
      overlaid.
    - `labels`: each member's label (a sweep's values).
    - `fps`: frames per second of the recording.
    - `title`: the page's title.
    - `play`: whether the page starts playing when it opens.
    """

    def __init__(
        self,
        poses: Poses | list[Poses],
        *,
        fps: float,
        title: str,
        play: bool = True,
        offsets: Any = None,
        ghost: bool = True,
        labels: Any = None,
    ) -> None:
        found = [poses] if isinstance(poses, Poses) else list(poses)
        self.members, self.poses = found, found[0]
        self.offsets = np.zeros((len(found), 3)) if offsets is None else np.asarray(offsets)
        self.ghost = ghost
        self.labels = list(labels) if labels is not None else [""] * len(found)
        self.fps, self.title, self.play = fps, title, play

    def html(self) -> str:
        """The standalone page: the viewer's JavaScript and the scene inlined, no network.

        **Returns:** the page's HTML text.
        """
        commands = scene_commands(self.members, self.offsets, self.ghost, self.fps, self.play)
        return page(commands, self.title)

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
        what = f"{len(p.shapes)} shapes" if p.shapes else f"{len(p.links)} rods"
        many = f", {len(self.members)} members" if len(self.members) > 1 else ""
        return (
            f"View3D({p.origins.shape[1]} bodies, {what}{many}, {p.times.size} frames "
            f"at {self.fps:g} fps, t = {p.times[0]:g}…{p.times[-1]:g} s)"
        )


def show3d(
    sol: Any,
    model: Any = None,
    *,
    params: Any = None,
    geometry: Any = None,
    contact: ContactSystem | None = None,
    members: Any = None,
    layout: str = "overlay",
    package_dirs: Any = (),
    fps: float = 30.0,
    play: bool = True,
    title: str = "lagrax",
) -> View3D:
    """A 3D view of a trajectory, played in the browser: inline in Jupyter, or saved as a
    standalone offline page with `.save("run.html")`.

    Bodies are drawn from what the model knows. Without `geometry`, each body frame's
    origin is a sphere (a floating base a box, turning with the base), with a rod from
    each body's parent origin to its own. With `geometry`, the robot's own shapes:

    - a **URDF** (a `.urdf` path or its XML, the file the tree was loaded from): each
      link's `<visual>` meshes (`.stl`, `.obj`, `.dae`, …, read with trimesh; `package://`
      paths looked up in `package_dirs` and the folders above the file) and primitives,
      in their `<material>` colours, moving with the tree's bodies. A mesh that is
      missing or unreadable is named in a [`lagrax.URDFWarning`][] and drawn as its
      link's bounding box. Meshes past 10,000 triangles are simplified.
    - a **MuJoCo model** (an `.xml` path, MJCF text or a `mujoco.MjModel`, as for
      [`from_mjcf`][lagrax.chains.from_mjcf]): its geoms (planes, spheres, capsules,
      ellipsoids, cylinders, boxes and meshes of groups 0–2), posed by MuJoCo's own
      kinematics at each frame.

    A [`ContactSystem`][lagrax.contact.ContactSystem] (as the model, or as `contact=`
    beside a model) adds its spheres and its ground plane, and the contact forces as red
    arrows from the contact points when the solution kept them (`sol.contact_force`;
    one scale for the whole recording, the largest force 0.4 of the scene's size).

    A **sweep** (its `xarray.Dataset` kept with `keep="trajectory"`, or a batched
    solution of `vmap`ped `simulate`) draws its `members` (default all) overlaid, the
    first solid and the others ghosted (`layout="overlay"`), or side by side
    (`layout="side"`); `params` may then be a list, one per drawn member.

    A planar mechanism is drawn upright in the world's x–z plane, seen from the front. The
    solution is resampled at `fps` (its coordinates linearly interpolated; a floating
    base's quaternion renormalised), and plays in real time at speed 1. A model that
    travels more than five times its own size is followed (the scene shifted back by
    its horizontal travel). Needs the `viz`
    extra (`pip install 'lagrax[viz]'`: meshcat, trimesh).

    **Arguments:**

    - `sol`: a `lagrax.Solution`, a batch of them, or a sweep's dataset (see above).
    - `model`: what moves; one of
        - a [`lagrax.chains.Tree`][] or [`SpatialChain`][lagrax.chains.SpatialChain]
          (e.g. from [`lagrax.chains.from_urdf`][]) or a
          [`FloatingTree`][lagrax.chains.FloatingTree] (`q` = position, quaternion
          `(x, y, z, w)`, joints), with `params=`;
        - a [`lagrax.chains.PlanarChain`][] with `params=`;
        - a [`lagrax.contact.ContactSystem`][] (its spheres and ground), with `params=`;
        - a [`lagrax.bodies.Scene`][] of a user's bodies, its `system()` or a system
          built on one (a `ConstrainedSystem`, e.g. the benchmark bicycle), with
          `params=`: each body the uniform solid of its mass and inertia (a box on its
          principal axes, a cylinder when two principal moments are equal; a planar
          body the rod of its moment along its x axis; a point mass a sphere), posed by
          its own pose map, a spatial scene turned so that a gravity vector points down;
        - a function `points(q) -> (k, 2)` or `(k, 3)`: a chain of points joined in order;
        - `None` (default): the lecture's planar serial chain, lengths `params["l1"], …`
          when `params` has them, else 1 m (right for `lagrax.models.planar_2r`); with
          MJCF `geometry`, `q` is MuJoCo's `qpos`.
    - `params`: the model's parameters (a list: one per drawn member of a sweep).
    - `geometry`: the robot's shapes: a URDF or a MuJoCo model (see above).
    - `contact`: a `ContactSystem` whose spheres and ground to add.
    - `members`: which members of a sweep to draw (indices into its flattened grid).
    - `layout`: `"overlay"` (ghosted) or `"side"` (side by side).
    - `package_dirs`: folders to look up a URDF's `package://` meshes in.
    - `fps`: frames per second of the recording.
    - `play`: start playing when the page opens.
    - `title`: the page's title.

    **Returns:** a `View3D`; `.save(path)` writes the page, `.html()` gives it.

    **Raises:** `ShapeError` for a solution whose coordinates are not the model's (a
    solution of another model); `ConfigurationError` for a tree or chain without `params`,
    `fps` not positive or an unknown `layout`; `ArgumentTypeError` for a model or
    geometry it cannot draw; [`lagrax.MissingDependencyError`][] (an `ImportError`)
    without meshcat.

    **Example:**

    ```python
    path = lagrax.models.urdf_path("arm7")
    tree, params = lagrax.chains.from_urdf(path)
    sol = lagrax.simulate(tree.system(), q0, qd0, params, t1=2.0)
    lagrax.plot.show3d(sol, tree, params=params, geometry=path).save("arm7.html")
    ```
    """
    meshcat_modules()
    _check_fps(fps)
    found = trajectories(sol)
    chosen = list(range(len(found))) if members is None else [int(i) for i in np.ravel(members)]
    if not chosen or not all(-len(found) <= i < len(found) for i in chosen):
        raise ConfigurationError(
            f"members must pick among the {len(found)} members; got {members!r}"
        )
    force = getattr(sol, "contact_force", None)
    shapes = _geometry_of(model, geometry, package_dirs)
    drawn, labels = [], []
    for i, member_params in zip(chosen, _params_for(params, len(chosen)), strict=True):
        ts, q, label = found[i]
        member_force = None
        if force is not None and len(found) == 1:
            member_force = np.asarray(force, dtype=float)
        columns = (
            q
            if member_force is None
            else np.concatenate([q, member_force.reshape(len(ts), -1)], axis=1)
        )
        times, columns = resampled(ts, columns, fps)
        q = columns[:, : found[i][1].shape[1]]
        if member_force is not None:
            member_force = columns[:, q.shape[1] :].reshape((len(times),) + member_force.shape[1:])
        drawn.append(_member_poses(times, q, member_force, model, member_params, shapes, contact))
        labels.append(label)
    offsets, ghost = _offsets(drawn, layout)
    return View3D(
        drawn, fps=float(fps), title=title, play=play, offsets=offsets, ghost=ghost, labels=labels
    )
