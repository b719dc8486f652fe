"""The 3D view's scene lowered to meshcat's commands, and the standalone page that plays it.

The scene is built here, without meshcat's server: meshcat-python's geometry, material and
animation classes lower it to the commands its browser viewer reads (MessagePack), and the
page inlines the viewer's JavaScript (`meshcat/viewer/dist/main.min.js`, from the installed
package) with those commands. Nothing is fetched from a network or a CDN.

Each body is a node (`lagrax/body_k`, or `lagrax/m{i}/body_k` for the members of a
sweep) whose position and rotation are animated; its shapes hang below it at their fixed
placements. Shapes fixed to the world hang from `…/world`, arrows from `…/arrow_a`.
"""

from __future__ import annotations

import base64
import html as html_lib
import warnings
from pathlib import Path
from typing import Any, assert_never

import numpy as np

from .._core.errors import MissingDependencyError
from .poses3d import Poses, Shape

INSTALL_HINT = "the 3D viewer needs meshcat: pip install 'lagrax[viz]'"
GHOST_OPACITY = 0.3
TRAVEL = 5.0  # travel past this many times the model's size: the view follows it
# meshcat's cylinders stand along +y; URDF's and MuJoCo's along +z: a quarter turn about x
_Y_ONTO_Z = np.array(
    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0, 0, 0, 1]]
)


def meshcat_modules() -> Any:
    """meshcat's modules, imported on first use (the `viz` extra)."""
    try:
        with warnings.catch_warnings():
            # meshcat imports pyzmq's deprecated `zmq.eventloop.ioloop` (for its server,
            # which lagrax does not start): not the user's concern
            warnings.simplefilter("ignore", DeprecationWarning)
            import meshcat.animation
            import meshcat.commands
            import meshcat.geometry
            import umsgpack
    except ImportError as err:  # pragma: no cover - exercised without the extra
        raise MissingDependencyError(INSTALL_HINT) from err
    return meshcat, umsgpack


def quaternion_of(rot: np.ndarray) -> np.ndarray:
    """Quaternions `(x, y, z, w)` of rotation matrices `(..., 3, 3)` (Shepperd's method)."""
    m = rot.reshape(-1, 3, 3)
    tr = np.trace(m, axis1=1, axis2=2)
    pick = np.argmax(np.stack([tr, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=1), axis=1)
    out = np.empty((m.shape[0], 4))
    k = pick == 0
    s = 2.0 * np.sqrt(np.maximum(1.0 + tr[k], 1e-300))
    out[k] = np.stack(
        [
            (m[k, 2, 1] - m[k, 1, 2]) / s,
            (m[k, 0, 2] - m[k, 2, 0]) / s,
            (m[k, 1, 0] - m[k, 0, 1]) / s,
            s / 4,
        ],
        axis=1,
    )
    for i in (1, 2, 3):
        k = pick == i
        a, b, c = i - 1, i % 3, (i + 1) % 3
        s = 2.0 * np.sqrt(np.maximum(1.0 + m[k, a, a] - m[k, b, b] - m[k, c, c], 1e-300))
        out[k, a] = s / 4
        out[k, b] = (m[k, b, a] + m[k, a, b]) / s
        out[k, c] = (m[k, c, a] + m[k, a, c]) / s
        out[k, 3] = (m[k, c, b] - m[k, b, c]) / s
    return out.reshape(rot.shape[:-2] + (4,))


def rod_quaternions(direction: np.ndarray) -> np.ndarray:
    """Quaternions `(x, y, z, w)` turning the +y axis (meshcat's cylinders) onto `direction`."""
    u = direction / np.maximum(np.linalg.norm(direction, axis=-1, keepdims=True), 1e-12)
    ey = np.array([0.0, 1.0, 0.0])
    quat = np.concatenate([np.cross(ey, u), 1.0 + u[..., 1:2]], axis=-1)
    flipped = quat[..., 3] < 1e-9  # pointing along −y: half a turn about x
    quat[flipped] = [1.0, 0.0, 0.0, 0.0]
    return quat / np.linalg.norm(quat, axis=-1, keepdims=True)


def extent(points: np.ndarray) -> float:
    """The largest side of the box around `points` `(..., 3)` (1 m when they coincide)."""
    flat = points.reshape(-1, 3)
    flat = flat[np.all(np.isfinite(flat), axis=1)]
    if flat.size == 0:
        return 1.0
    size = float(np.max(flat.max(axis=0) - flat.min(axis=0)))
    return size if size > 1e-9 else 1.0


def robot_size(p: Poses) -> float:
    """The robot's own size, for its shapes: its largest extent in any one frame (a
    floating robot that travels far is not drawn larger for it)."""
    if p.origins.shape[1] < 2:
        return 0.25 * extent(p.origins)
    return max(extent(frame) for frame in p.origins)


class _Track:
    """One member's commands and animation clips, under the node `root`."""

    def __init__(self, mc: Any, root: tuple[str, ...], fps: float, opacity: float) -> None:
        self.mc, self.root, self.fps, self.opacity = mc, root, fps, opacity
        self.commands: list[dict] = []
        self.clips: dict = {}

    def path(self, *names: str) -> Any:
        return self.mc.path.Path(self.root + names)

    def material(self, colour: int, opacity: float = 1.0) -> Any:
        g = self.mc.geometry
        return g.MeshLambertMaterial(color=colour, opacity=opacity * self.opacity)

    def put(self, geometry: Any, material: Any, *names: str, matrix: Any = None) -> None:
        cmd = self.mc.commands
        path = self.path(*names)
        self.commands.append(cmd.SetObject(geometry, material, path).lower())
        if matrix is not None:
            self.commands.append(cmd.SetTransform(np.asarray(matrix), path).lower())

    def animate(self, names: tuple[str, ...], frames: dict[str, tuple[str, np.ndarray]]) -> None:
        clip = self.clips[self.path(*names)] = self.mc.animation.AnimationClip(fps=self.fps)
        for prop, (kind, values) in frames.items():
            for f, v in enumerate(values):
                clip.set_property(f, prop, kind, [float(x) for x in v])


def _compact_mesh(g: Any, vertices: np.ndarray, faces: np.ndarray) -> Any:
    """A triangle mesh lowered as three.js's `BufferGeometry`: float32 positions and
    16-bit indices where the vertices allow (half the bytes of meshcat's 32-bit ones);
    the viewer computes the normals."""
    geometry = g.TriangularMeshGeometry(vertices, faces)
    if len(vertices) >= 2**16:
        return geometry
    index = np.ascontiguousarray(np.asarray(faces, dtype=np.uint16))
    packed = {
        "itemSize": 1,
        "type": "Uint16Array",
        "array": _umsgpack().Ext(0x14, index.tobytes()),
        "normalized": False,
    }
    lower = geometry.lower

    def compact(object_data: Any) -> dict:
        data = lower(object_data)
        data["data"]["index"] = packed
        return data

    geometry.lower = compact
    return geometry


def _umsgpack() -> Any:
    return meshcat_modules()[1]


def _geometry(g: Any, shape: Shape) -> tuple[Any, np.ndarray]:
    """The meshcat geometry of a shape, and its placement (cylinders turned onto z)."""
    if shape.kind == "box":
        return g.Box(list(shape.size)), shape.transform
    if shape.kind == "sphere":
        return g.Sphere(shape.size[0]), shape.transform
    if shape.kind == "ellipsoid":
        return g.Ellipsoid(list(shape.size)), shape.transform
    if shape.kind == "cylinder":
        return g.Cylinder(shape.size[1], shape.size[0]), shape.transform @ _Y_ONTO_Z
    if shape.kind == "mesh":
        return _compact_mesh(g, shape.vertices, shape.faces), shape.transform
    assert_never(shape.kind)


def _skeleton(t: _Track, p: Poses) -> None:
    """Each body as a sphere (the base a box), each link as a rod from parent to child."""
    g = t.mc.geometry
    size = robot_size(p)
    for k in range(p.origins.shape[1]):
        shape = g.Box([0.12 * size] * 3) if k == 0 else g.Sphere(0.035 * size)
        t.put(shape, t.material(0x404040 if k == 0 else 0xE07020), f"body_{k}")
    for j, (a, b) in enumerate(p.links):
        t.put(g.Cylinder(1.0, 0.015 * size), t.material(0x2060C0), f"link_{j}")
        d = p.origins[:, b] - p.origins[:, a]
        length = np.maximum(np.linalg.norm(d, axis=-1), 1e-9)
        scale = np.stack([np.ones_like(length), length, np.ones_like(length)], axis=-1)
        t.animate(
            (f"link_{j}",),
            {
                "position": ("vector3", 0.5 * (p.origins[:, a] + p.origins[:, b])),
                "quaternion": ("quaternion", rod_quaternions(d)),
                "scale": ("vector3", scale),
            },
        )


def _arrows(t: _Track, arrows: np.ndarray, size: float) -> None:
    """Each arrow a shaft (scaled to its length) and a head at its tip."""
    g = t.mc.geometry
    radius = 0.008 * size
    for a in range(arrows.shape[1]):
        foot, vec = arrows[:, a, 0], arrows[:, a, 1]
        length = np.linalg.norm(vec, axis=-1)
        shown = length > 1e-3 * size
        quat = rod_quaternions(np.where(shown[:, None], vec, [0.0, 0.0, 1.0]))
        unit = vec / np.maximum(length, 1e-12)[:, None]
        head = 4 * radius
        t.put(g.Cylinder(1.0, radius), t.material(0xD02020), f"arrow_{a}", "shaft")
        t.put(g.Cylinder(head, 0.0, 0.0, 2.5 * radius), t.material(0xD02020), f"arrow_{a}", "head")
        tiny = np.where(shown, 1.0, 1e-6)
        t.animate(
            (f"arrow_{a}", "shaft"),
            {
                "position": ("vector3", foot + 0.5 * vec),
                "quaternion": ("quaternion", quat),
                "scale": ("vector3", np.stack([tiny, np.maximum(length, 1e-9), tiny], axis=-1)),
            },
        )
        t.animate(
            (f"arrow_{a}", "head"),
            {
                "position": ("vector3", foot + vec + 0.5 * head * unit),
                "quaternion": ("quaternion", quat),
                "scale": ("vector3", np.repeat(tiny[:, None], 3, axis=1)),
            },
        )


def member_commands(t: _Track, p: Poses) -> None:
    """The commands and clips that draw one member's `p` under `t`'s root."""
    g = t.mc.geometry
    quats = quaternion_of(p.rotations)
    moving = sorted({s.body for s in p.shapes if s.body >= 0})
    if p.skeleton or not p.shapes:
        _skeleton(t, p)
        moving = list(range(p.origins.shape[1]))
    for j, shape in enumerate(p.shapes):
        geometry, matrix = _geometry(g, shape)
        node = "world" if shape.body < 0 else f"body_{shape.body}"
        t.put(
            geometry,
            t.material(shape.colour, shape.opacity),
            node,
            f"{shape.name}_{j}",
            matrix=matrix,
        )
    for k in moving:
        t.animate(
            (f"body_{k}",),
            {"position": ("vector3", p.origins[:, k]), "quaternion": ("quaternion", quats[:, k])},
        )
    if p.arrows is not None:
        _arrows(t, p.arrows, robot_size(p))


def scene_commands(
    members: list[Poses], offsets: np.ndarray, ghost: bool, fps: float, play: bool
) -> list[dict]:
    """meshcat commands (lowered to dicts) that draw the members, each shifted by its
    offset (`(M, 3)`), the members after the first ghosted when `ghost`, and animate them
    at `fps`."""
    mc, _ = meshcat_modules()
    out: list[dict] = []
    clips: dict = {}
    follow = following(members)
    for i, p in enumerate(members):
        root = ("lagrax",) if len(members) == 1 else ("lagrax", f"m{i}")
        t = _Track(mc, root, fps, GHOST_OPACITY if ghost and i > 0 else 1.0)
        if len(members) > 1 and np.any(offsets[i]):
            shift = np.eye(4)
            shift[:3, 3] = offsets[i]
            out.append(mc.commands.SetTransform(shift, mc.path.Path(root)).lower())
        member_commands(t, p)
        if follow is not None:  # the member rides on the spot; offsets[i] kept
            t.animate((), {"position": ("vector3", offsets[i] - follow)})
        out += t.commands
        clips.update(t.clips)
    animation = mc.animation.Animation(clips=clips, default_framerate=fps)
    out.append(mc.commands.SetAnimation(animation, play=play, repetitions=1).lower())
    return out + camera_commands(members, offsets, follow is not None)


def following(members: list[Poses]) -> np.ndarray | None:
    """The first member's horizontal travel from its first frame, `(F, 3)` (`z` zero), when
    the motion travels more than `TRAVEL` times the model's own size (a bicycle riding
    on): the scene is shifted back by it, so the model stays in view while the floor's
    grid stands still. `None` otherwise."""
    flat = np.concatenate([p.origins.reshape(-1, 3) for p in members])
    if extent(flat) <= TRAVEL * max(robot_size(p) for p in members):
        return None
    origins = members[0].origins
    centre = 0.5 * (np.nanmin(origins, axis=1) + np.nanmax(origins, axis=1))
    travel = centre - centre[0]
    travel[:, 2] = 0.0
    return travel


def camera_commands(members: list[Poses], offsets: np.ndarray, follow: bool = False) -> list[dict]:
    """The camera aimed at the middle of the motion, from the side (front of a plane);
    aimed at the first frame and sized to the model when it `follow`s."""
    flat = np.concatenate(
        [p.origins.reshape(-1, 3) + o for p, o in zip(members, offsets, strict=True)]
    )
    flat = flat[np.all(np.isfinite(flat), axis=1)]
    centre = 0.5 * (flat.min(axis=0) + flat.max(axis=0))
    size = extent(flat) * (1.5 if any(p.shapes for p in members) else 1.0)
    if follow:
        first = members[0].origins[0] + offsets[0]
        centre = 0.5 * (first.min(axis=0) + first.max(axis=0))
        size = 2.5 * max(robot_size(p) for p in members)
    target = np.eye(4)
    target[:3, 3] = centre
    planar = all(p.planar for p in members)
    # the camera's position in meshcat's y-up frame under /Cameras/default/rotated:
    # world (x, y, z) is (x, z, −y) there
    eye = [0.0, 0.0, 1.6 * size] if planar else [0.75 * size, 0.6 * size, 0.75 * size]
    # a plane is drawn upright: the floor grid would cut through it
    grid = [{"type": "set_property", "path": "/Grid", "property": "visible", "value": False}]
    return (grid if planar else []) + [
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
<style>body {{ margin: 0; overflow: hidden; }}
#meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
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


def viewer_js() -> str:
    """meshcat's browser viewer, read from the installed package."""
    mc, _ = meshcat_modules()
    return (Path(mc.__file__).parent / "viewer" / "dist" / "main.min.js").read_text("utf-8")


def page(commands: list[dict], title: str) -> str:
    """The standalone page: the viewer's JavaScript and the commands inlined."""
    _, umsgpack = meshcat_modules()
    encoded = ",".join(
        '"' + base64.b64encode(umsgpack.packb(c)).decode("ascii") + '"' for c in commands
    )
    return _PAGE.format(title=html_lib.escape(title), viewer_js=viewer_js(), commands=encoded)
