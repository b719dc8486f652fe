"""mkdocs hook (mkdocs.yml's `hooks`): the robots of the 3D gallery (docs/viewer.md) and two
simulations, recorded into the built site.

Each robot of example-robot-data in `GALLERY` is drawn with its meshes by
`lagrax.plot.show3d` along a short made-up motion (its joints swaying, no simulation) and
saved as `site/recordings/<name>.html`, which the page embeds in an `iframe`. The pages
are written at build time, not committed: about 2 MB each, most of it the meshes and
meshcat's viewer. Without example-robot-data the gallery is left out (the frames stay
empty) and the build says so (as info: `mkdocs build --strict` fails on a warning).
`tests/test_viewer.py` builds the same pages and opens them in Chromium.

Two recordings are simulated at build time (`SIMULATED`): the contact notebook's solo12
dropped on the floor under joint PD (`solo12_drop`, 1 s; about a minute to compile on a
loaded 2-core machine) on docs/contact.md, and the benchmark bicycle's self-stable run at
5 m/s after a sideways push (`bicycle_run`, 6 s; about half a minute) on docs/viewer.md.
A check build with `LAGRAX_DOCS_EXECUTE=false` (CI's) leaves them out, as it leaves the
notebooks unexecuted. Each is split in a simulation and its drawing (`*_view`), so that
the test draws a made-up motion through the same drawing cheaply.
"""

from __future__ import annotations

import importlib.metadata
import logging
import os
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np

# name: (URDF under example-robot-data's robots folder, floating base)
GALLERY = {
    "solo12": ("solo_description/robots/solo12.urdf", True),
    "panda": ("panda_description/urdf/panda.urdf", False),
}
SECONDS, FPS = 2.0, 15.0
G = 9.81
FEET = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]
STANCE = [0.1, 0.8, -1.6, -0.1, 0.8, -1.6, 0.1, -0.8, 1.6, -0.1, -0.8, 1.6]
SOLO12 = GALLERY["solo12"][0]
# name: the page it is embedded in
SIMULATED = {"solo12_drop": "contact.md", "bicycle": "viewer.md"}

log = logging.getLogger("mkdocs.hooks.gallery")


def robots_folder() -> Path | None:
    """example-robot-data's `robots` folder, or `None` when it is not installed."""
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in dist.files or ():
        if f.name == "package.xml" and "example-robot-data" in f.parts:
            return Path(os.path.dirname(str(dist.locate_file(f)))) / "robots"
    return None


def recording(name: str, robots: Path):
    """The `View3D` of one gallery robot: its joints swaying by ±0.4 rad, a floating base
    standing 0.4 m up."""
    import lagrax as lx

    relative, floating = GALLERY[name]
    path = robots / relative
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # inertias some URDFs get slightly wrong
        model, params = lx.chains.from_urdf(path, floating_base=floating)
    ts = np.linspace(0.0, SECONDS, int(SECONDS * FPS) + 1)
    n = model.n
    sway = 0.4 * np.sin(2 * np.pi * ts / SECONDS)[:, None] * np.cos(np.arange(n))[None, :]
    if floating:
        base = np.tile([0.0, 0.0, 0.4, 0.0, 0.0, 0.0, 1.0], (ts.size, 1))
        q = np.concatenate([base, sway], axis=1)
    else:
        q = sway
    sol = SimpleNamespace(ts=ts, q=q)
    return lx.plot.show3d(
        sol, model, params=params, geometry=path, fps=FPS, title=f"lagrax: {name}"
    )


def solo12_scene(robots: Path):
    """`(robot, contact scene, params)` of the contact notebook's solo12: its four feet on
    the floor, the stiffness of a 0.5 mm static penetration under each foot's share of the
    weight, critically damped (docs/notebooks/09_contact.ipynb)."""
    import lagrax as lx
    from lagrax.contact import ContactSystem

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        robot, _ = lx.chains.from_urdf(robots / SOLO12, floating_base=True)
        feet, params = lx.chains.from_urdf(robots / SOLO12, floating_base=True, contact=FEET)
    weight = G * float(params["base_m"] + np.sum(params["m"]))
    depth = 5e-4
    scene = ContactSystem(
        feet.system, feet.spheres, feet.plane, friction=feet.friction,
        stiffness=(weight / 4) / depth**1.5, dissipation=4 / 3 * np.sqrt(1.5 / (G * depth)),
        stiction_velocity=0.01,
    )  # fmt: skip
    return robot, scene, params


def solo12_drop(robots: Path, seconds: float = 1.0, fps: float = 30.0):
    """The notebook's drop: solo12 released 0.3 m up in its stance, its joints held by PD,
    saved at `fps` (with the contact forces)."""
    import jax.numpy as jnp

    import lagrax as lx

    _, scene, params = solo12_scene(robots)
    stance = jnp.asarray(STANCE)

    def pd(t, q, v):
        return jnp.concatenate([jnp.zeros(6), 10.0 * (stance - q[7:]) - 0.3 * v[6:]])

    q0 = jnp.concatenate([jnp.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 1.0]), stance])
    ts = np.linspace(0.0, seconds, int(round(seconds * fps)) + 1)
    run = dict(t1=seconds, ts=ts, tau=pd, rtol=1e-5, atol=1e-5, solver="tsit5")  # chosen for it
    return lx.simulate(scene, q0, jnp.zeros(18), params, **run)


def solo12_drop_view(sol, robots: Path, fps: float = 30.0):
    """The drop drawn: solo12's meshes, its feet's spheres, the floor and the contact
    forces."""
    import lagrax as lx

    robot, scene, params = solo12_scene(robots)
    return lx.plot.show3d(
        sol, robot, params=params, geometry=robots / SOLO12, contact=scene, fps=fps,
        title="lagrax: solo12 dropped on the floor",
    )  # fmt: skip


def bicycle_run(seconds: float = 6.0, fps: float = 30.0, speed: float = 5.0):
    """The bicycle notebook's self-stable run: the benchmark bicycle upright at `speed`
    (inside its stable range, 4.3–6.0 m/s) pushed sideways (lean rate 0.5 rad/s)."""
    import jax.numpy as jnp

    import lagrax as lx

    bike, params = lx.models.benchmark_bicycle()
    qd = jnp.zeros(8).at[0].set(speed).at[3].set(0.5)
    qd = qd.at[6].set(-speed / params["rR"]).at[7].set(-speed / params["rF"])
    n_save = int(round(seconds * fps)) + 1
    sol = lx.simulate(
        bike, jnp.zeros(8), qd, params, t1=seconds, n_save=n_save, rtol=1e-8, atol=1e-10
    )
    return sol


def bicycle_view(sol, fps: float = 30.0):
    """The run drawn: the bicycle's four bodies (rear frame and rider, front frame, the
    wheels) as the uniform solids of their inertias, on their pose maps."""
    import lagrax as lx

    bike, params = lx.models.benchmark_bicycle()
    title = "lagrax: the benchmark bicycle's self-stable run"
    return lx.plot.show3d(sol, bike, params=params, fps=fps, title=title)


def write_simulated(folder: Path) -> list[Path]:
    """The simulated recordings' pages in `folder` (the drop only with example-robot-data)."""
    folder.mkdir(parents=True, exist_ok=True)
    out = [bicycle_view(bicycle_run()).save(folder / "bicycle.html")]
    robots = robots_folder()
    if robots is not None:
        out.append(solo12_drop_view(solo12_drop(robots), robots).save(folder / "solo12_drop.html"))
    return out


def write_gallery(folder: Path) -> list[Path]:
    """Every gallery robot's page in `folder` (none without example-robot-data)."""
    robots = robots_folder()
    if robots is None:
        log.info("example-robot-data is not installed: the 3D gallery is left out")
        return []
    folder.mkdir(parents=True, exist_ok=True)
    return [recording(name, robots).save(folder / f"{name}.html") for name in GALLERY]


def on_post_build(config, **kwargs) -> None:
    """mkdocs' hook after the build: the gallery's pages into `site/recordings/`."""
    folder = Path(config["site_dir"]) / "recordings"
    pages = write_gallery(folder)
    if os.environ.get("LAGRAX_DOCS_EXECUTE", "true").lower() in ("false", "0", "no", "off"):
        # a check build (CI's): the simulations are left out, as the notebooks' outputs
        # are; tests/test_viewer.py draws them on made-up motions
        log.info("LAGRAX_DOCS_EXECUTE=false: the simulated recordings are left out")
    else:
        pages += write_simulated(folder)
    for path in pages:
        log.info("3D gallery: %s (%.1f MB)", path.name, path.stat().st_size / 1e6)
