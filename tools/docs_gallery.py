"""mkdocs hook (mkdocs.yml's `hooks`): the robots of the 3D gallery (docs/viewer.md), recorded
into the built site.

Each robot of example-robot-data in `GALLERY` is drawn with its meshes by
`lagrax.plot.show3d` along a short made-up motion (its joints swaying, no simulation) and
saved as `site/recordings/<name>.html`, which the page embeds in an `iframe`. The pages
are written at build time, not committed: about 2 MB each, most of it the meshes and
meshcat's viewer. Without example-robot-data the gallery is left out (the frames stay
empty) and the build says so (as info: `mkdocs build --strict` fails on a warning).
`tests/test_viewer.py` builds the same pages and opens them in Chromium.
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
    for path in write_gallery(Path(config["site_dir"]) / "recordings"):
        log.info("3D gallery: %s (%.1f MB)", path.name, path.stat().st_size / 1e6)
