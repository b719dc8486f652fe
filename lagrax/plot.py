"""Matplotlib figures for trajectories and sweeps of lagrax systems.

Every function takes the result to draw first (a `Solution`, a sweep's
`xarray.Dataset`, a work–precision study), optional `ax` last, and returns the axes (or
figure, or animation) it drew on, so the result can be restyled:

- one trajectory: `joint_trajectories`, `phase_portrait`, `energy_error`,
  `arm_snapshots`, `summary`, `animate`;
- many: `sweep_heatmap` (a quantity over a 1-D or 2-D `lagrax.sweep` grid);
- methods: `work_precision` (the chart of `lagrax.bench.work_precision`);
- in 3D, in the browser: `show3d` (a `View3D`: inline in Jupyter, `.save("run.html")` a
  standalone offline page; the `viz` extra).

Functions that draw a mechanism take its `geometry`: a function `points(q) -> (k, 2)`
giving the planar points to join (base, joints, tip) at a configuration `q`, in metres.
The default is the planar serial chain of the lecture's 2R arm: `θ1` measured from the
+x axis, each further angle relative to the previous link (`planar_chain_points`).
"""

import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ._core.errors import ArgumentTypeError, ConfigurationError, ShapeError
from ._plot.axes import axes_for
from ._plot.sweep import sweep_heatmap as sweep_heatmap
from ._plot.view3d import View3D as View3D
from ._plot.view3d import show3d as show3d
from ._solve.solution import Solution
from .chains import PlanarChain

Geometry = Callable[[Any], Any] | Sequence[float] | Any
"""What to draw: a function `q -> (k, 2)` points, link lengths, or a chain object."""


def _reached(sol: Solution) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Saved times and states up to where the solve got (a failed solve's tail is inf)."""
    ts, q, qd = np.asarray(sol.ts), np.asarray(sol.q), np.asarray(sol.qd)
    keep = np.isfinite(ts) & np.all(np.isfinite(q), axis=-1) & np.all(np.isfinite(qd), axis=-1)
    return ts[keep], q[keep], qd[keep]


def joint_trajectories(
    sol: Solution, *, labels: Sequence[str] | None = None, unit: str = "rad", ax=None
):
    """Generalized coordinates `q(t)` against time, one line each.

    **Arguments:**

    - `sol`: a `lagrax.Solution`.
    - `labels`: one name per coordinate (default `q1`, `q2`, …).
    - `unit`: the coordinates' unit for the y label (default `rad`; `m` for lengths,
      `""` for mixed coordinates).
    - `ax`: axes to draw on (default: a new figure).

    **Returns:** the axes, one line per coordinate.
    """
    ax = axes_for(ax)
    q = np.asarray(sol.q)
    for i in range(q.shape[1]):
        ax.plot(np.asarray(sol.ts), q[:, i], label=labels[i] if labels else f"q{i + 1}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"q [{unit}]" if unit else "q")
    ax.legend(loc="best")
    return ax


def energy_error(sol: Solution, *, ax=None):
    """The energy error `|h(t) − h(0) − W(t)| / scale` against time, on a log scale.

    `Solution.energy_error`: the balance residual of the Jacobi integral `h` (the work
    `W` of inputs, applied forces, dissipation and explicit time dependence subtracted),
    relative to the path's energy scale `max(|h(0)|, max |T| + |V|)`. Times where the
    error is exactly zero (always `t = 0`, and any step that conserves `h` to the last
    bit) cannot be drawn on a log axis: they are left out (a gap in the line), so the
    axis spans the errors that occur rather than reaching down to 1e-16.

    **Arguments:** `sol`, a `lagrax.Solution`; `ax`, axes to draw on (default: a new
    figure).

    **Returns:** the axes; its one line holds the positive errors.
    """
    ax = axes_for(ax)
    ts = np.asarray(sol.ts)
    err = np.abs(np.asarray(sol.energy_error))
    shown = np.isfinite(err) & (err > 0)
    ax.plot(ts, np.where(shown, err, np.nan))
    ax.set_yscale("log")
    if not shown.any():
        ax.text(0.5, 0.5, "E(t) = E(0) exactly", transform=ax.transAxes, ha="center")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("|h(t) − h(0) − W(t)| / scale")
    return ax


def planar_chain_points(q, lengths) -> np.ndarray:
    """Joint positions of a planar serial chain in the lecture's convention.

    `θ1 = q[0]` is measured from the +x axis, each `θi = q[i − 1]` relative to the
    previous link, counter-clockwise positive; link `i` has length `lengths[i − 1]`.
    Joint `k` is at `Σ_{i ≤ k} l_i (cos φ_i, sin φ_i)` with `φ_i = θ1 + … + θi`.

    **Returns:** an array `(..., n + 1, 2)`: the base at the origin, then each link's end.
    """
    q = np.asarray(q)
    angles = np.cumsum(q, axis=-1)
    lengths = np.asarray(lengths, dtype=float)
    steps = np.stack([lengths * np.cos(angles), lengths * np.sin(angles)], axis=-1)
    base = np.zeros(q.shape[:-1] + (1, 2))
    return np.concatenate([base, np.cumsum(steps, axis=-2)], axis=-2)


def _default_lengths(params: Any, n: int) -> list[float]:
    """Link lengths for the default geometry: `params["l1"], …` when given, else 1 m."""
    if isinstance(params, dict) and all(f"l{i + 1}" in params for i in range(n)):
        return [float(params[f"l{i + 1}"]) for i in range(n)]
    return [1.0] * n


def _chain_points(geometry: Any, q: np.ndarray, params: Any) -> np.ndarray:
    """Points `(T, k, 2)` to draw at each saved state, from the kinds of geometry."""
    if geometry is None:
        pts = planar_chain_points(q, _default_lengths(params, q.shape[-1]))
    elif isinstance(geometry, PlanarChain):
        if params is None:
            raise ConfigurationError(
                f"drawing a {type(geometry).__name__} needs its parameters: pass params="
            )
        import jax
        import jax.numpy as jnp

        pts = np.asarray(jax.vmap(lambda a: geometry.joint_positions(a, params))(jnp.asarray(q)))
    elif callable(geometry):
        pts = np.stack([np.asarray(geometry(a)) for a in q])
    else:
        lengths = np.asarray(geometry, dtype=float)
        if lengths.ndim != 1 or lengths.size != q.shape[-1]:
            raise ShapeError(
                f"link lengths {geometry!r} must be one per coordinate ({q.shape[-1]}); for "
                "another mechanism pass a function geometry(q) -> (k, 2) points"
            )
        pts = planar_chain_points(q, lengths)
    if pts.ndim != 3 or pts.shape[-1] != 2:
        raise ShapeError(
            "the geometry must give k planar points per state, shape (k, 2); got shape "
            f"{pts.shape[1:]} per state"
        )
    return pts


def _square_limits(ax, pts: np.ndarray, margin: float = 0.55) -> None:
    """Equal-aspect limits around every drawn point."""
    flat = pts.reshape(-1, 2)
    flat = flat[np.all(np.isfinite(flat), axis=1)]
    lo, hi = flat.min(axis=0), flat.max(axis=0)
    centre, half = 0.5 * (lo + hi), margin * max(float(np.max(hi - lo)), 1e-9)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")


def arm_snapshots(
    sol: Solution,
    geometry: Geometry = None,
    *,
    params: Any = None,
    n_snapshots: int = 12,
    colorbar: bool = True,
    ax=None,
):
    """Stroboscopic drawing of a planar mechanism: its pose at evenly spaced saved times,
    coloured by time (viridis: dark purple early, yellow late; a colour bar gives the
    time in seconds), and the path of its last point (the tip) in grey.

    **Arguments:**

    - `sol`: a `lagrax.Solution`.
    - `geometry`: the mechanism's points (joints and tip, in metres) at a configuration;
      one of
        - a function `points(q) -> (k, 2)` (any planar mechanism, any angle
          convention: e.g. a pendulum with angles from the downward vertical);
        - link lengths `[l1, …, ln]` of a planar serial chain in the lecture's
          convention (`θ1` from +x, `θi` relative to link `i − 1`, see
          `planar_chain_points`);
        - a [`lagrax.chains.PlanarChain`][] (then pass `params=`);
        - `None` (default): the lecture's chain, with lengths `params["l1"], …` when
          `params` has them, else 1 m per link (right for `lagrax.models.planar_2r`).
    - `params`: parameters for a chain object, or for the default's link lengths.
    - `n_snapshots`: how many poses to draw.
    - `colorbar`: draw the time colour bar next to the axes.
    - `ax`: axes to draw on (default: a new figure).

    **Returns:** the axes; `ax.lines[0]` is the tip's path, `ax.lines[1:]` the poses
    (their data are the geometry's points at the drawn times).
    """
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    ax = axes_for(ax)
    ts, q, _ = _reached(sol)
    pts = _chain_points(geometry, q, params)
    idx = np.unique(np.linspace(0, len(pts) - 1, n_snapshots).round().astype(int))
    cmap = plt.get_cmap("viridis")
    norm = Normalize(float(ts[0]), float(ts[-1]) if ts[-1] > ts[0] else float(ts[0]) + 1.0)
    ax.plot(pts[:, -1, 0], pts[:, -1, 1], color="0.7", lw=0.8, label="tip path")
    for i in idx:
        ax.plot(pts[i, :, 0], pts[i, :, 1], "-o", color=cmap(norm(ts[i])), lw=2, ms=3)
    _square_limits(ax, pts)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper right")
    if colorbar:
        ax.figure.colorbar(ScalarMappable(norm, cmap), ax=ax, label="t [s]")
    return ax


def summary(
    sol: Solution, geometry: Geometry = None, *, params: Any = None, title: str | None = None
):
    """Three panels: joint angles, the mechanism's snapshots, energy error.

    **Arguments:**

    - `sol`: a `lagrax.Solution`.
    - `geometry`, `params`: the mechanism's points at a configuration, as for
      [`arm_snapshots`][lagrax.plot.arm_snapshots]: a function `points(q) -> (k, 2)`
      (any angle convention), link lengths, a chain object with `params=`, or `None`
      (default): the lecture's chain (`θ1` from +x, `θi` relative to link `i − 1`).
    - `title`: a title over the three panels.

    **Returns:** the figure.
    """
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 3, figsize=(15, 4.4), constrained_layout=True)
    joint_trajectories(sol, labels=[f"θ{i + 1}" for i in range(np.shape(sol.q)[1])], ax=axs[0])
    arm_snapshots(sol, geometry, params=params, ax=axs[1])
    energy_error(sol, ax=axs[2])
    axs[0].set_title("joint angles")
    axs[1].set_title("snapshots")
    axs[2].set_title("energy error")
    if title:
        fig.suptitle(title)
    return fig


def phase_portrait(
    sol: Solution,
    *,
    dof: int | Sequence[int] | None = None,
    labels: Sequence[str] | None = None,
    unit: str = "rad",
    ax=None,
):
    """Phase portrait: `q̇_i` against `q_i`, one curve per coordinate.

    Each curve starts at a dot (●, at the first saved time) and ends at a square (■, at
    the last one); the legend's key gives both times. A conservative 1-DOF system
    traces a closed level curve of `E = T + V`; dissipation makes it spiral in.

    **Arguments:**

    - `sol`: a `lagrax.Solution`.
    - `dof`: the coordinate index (or indices) to draw; default all.
    - `labels`: one name per drawn coordinate (default `q1`, `q2`, …).
    - `unit`: the coordinates' unit for the axis labels (default `rad`; velocities are
      in `unit/s`).
    - `ax`: axes to draw on (default: a new figure).

    **Returns:** the axes; `ax.lines` holds one curve per drawn coordinate.
    """
    from matplotlib.lines import Line2D

    ax = axes_for(ax)
    ts, q, qd = _reached(sol)
    dofs = list(range(q.shape[1])) if dof is None else [int(i) for i in np.atleast_1d(dof)]
    for k, i in enumerate(dofs):
        name = labels[k] if labels else f"q{i + 1}"
        (line,) = ax.plot(q[:, i], qd[:, i], lw=1, label=name)
        c = line.get_color()
        ax.scatter(q[:1, i], qd[:1, i], color=c, marker="o", s=22, zorder=3)
        ax.scatter(q[-1:, i], qd[-1:, i], color=c, marker="s", s=22, zorder=3)
    key = [
        Line2D([], [], ls="", marker="o", color="0.3", label=f"start, t = {ts[0]:.3g} s"),
        Line2D([], [], ls="", marker="s", color="0.3", label=f"end, t = {ts[-1]:.3g} s"),
    ]
    handles, _ = ax.get_legend_handles_labels()
    ax.legend(handles=handles + key, loc="best", fontsize=8)
    ax.set_xlabel(f"q [{unit}]" if unit else "q")
    ax.set_ylabel(f"q̇ [{unit}/s]" if unit else "q̇")
    return ax


def animate(
    sol: Solution,
    geometry: Geometry = None,
    *,
    params: Any = None,
    max_frames: int = 150,
    speed: float = 1.0,
    trail: bool = True,
    title: str | None = None,
    ax=None,
):
    """Animate a planar mechanism along a solution (matplotlib `FuncAnimation`).

    Each frame draws the mechanism as a polyline through its points (joints and tip) at
    one saved time, the path of the last point so far, and the time.

    In a notebook show it with `IPython.display.HTML(anim.to_jshtml())` (no extra
    software; call `plt.close()` first so the empty figure is not shown as well), or
    `anim.to_html5_video()` (needs ffmpeg). On disk: `anim.save("arm.gif",
    writer="pillow")` (Pillow ships with matplotlib) or `anim.save("arm.mp4")` (ffmpeg).

    The order before 0.3, `animate(geometry, sol)`, still works with a
    `DeprecationWarning`.

    **Arguments:**

    - `sol`: a `lagrax.Solution` (its saved times are the frames).
    - `geometry`, `params`: the mechanism's points at a configuration, as for
      [`arm_snapshots`][lagrax.plot.arm_snapshots]: a function `points(q) -> (k, 2)`
      (any angle convention), link lengths, a chain object with `params=`, or `None`
      (default): the lecture's chain (`θ1` from +x, `θi` relative to link `i − 1`).
    - `max_frames`: at most this many frames, evenly spaced over the saved times.
    - `speed`: playback speed relative to real time.
    - `trail`: draw the path of the last point.
    - `title`, `ax`: a title; axes to draw on (default: a new figure).

    **Returns:** the `matplotlib.animation.FuncAnimation`.

    **Raises:** `ShapeError` when the geometry's points are not `(k, 2)`, or link
    lengths do not match the coordinates; `ConfigurationError` for a chain object
    without `params=`.
    """
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

    if not isinstance(sol, Solution) and isinstance(geometry, Solution):
        warnings.warn(
            "animate(geometry, sol) is deprecated: pass the solution first, as to every "
            "other plot, animate(sol, geometry); the old order stops working in 0.4",
            DeprecationWarning,
            stacklevel=2,
        )
        sol, geometry = geometry, sol
    if not isinstance(sol, Solution):
        raise ConfigurationError(
            f"animate draws a lagrax.Solution (its first argument), got {type(sol).__name__}"
        )
    ts, q, _ = _reached(sol)  # a failed solve stops early: animate what was reached
    pts = _chain_points(geometry, q, params)
    frames = np.unique(np.linspace(0, len(ts) - 1, min(len(ts), int(max_frames))).round())
    frames = frames.astype(int)
    span = float(ts[frames[-1]] - ts[frames[0]])
    interval = 1000.0 * span / max(len(frames) - 1, 1) / float(speed)  # ms per frame

    if ax is None:
        fig, ax = plt.subplots(figsize=(5, 5))
    else:
        fig = ax.figure
    _square_limits(ax, pts)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if title:
        ax.set_title(title)
    (path,) = ax.plot([], [], color="0.6", lw=0.8)
    (links,) = ax.plot([], [], "-o", color="C0", lw=3, ms=6, mfc="white")
    clock = ax.text(0.03, 0.95, "", transform=ax.transAxes, va="top")

    def draw(k):
        i = frames[k]
        links.set_data(pts[i, :, 0], pts[i, :, 1])
        if trail:
            path.set_data(pts[: i + 1, -1, 0], pts[: i + 1, -1, 1])
        clock.set_text(f"t = {ts[i]:.2f} s")
        return path, links, clock

    draw(0)
    return FuncAnimation(fig, draw, frames=len(frames), interval=interval, blit=False)


def work_precision(
    points: Any,
    reference_error: float | None = None,
    *,
    title: str = "",
    axes=None,
):
    """The work–precision chart: error against wall time, one line per method.

    Two log–log panels (final-state error, and maximum energy error, against the median
    wall time of a compiled solve) of a study by `lagrax.bench.work_precision`;
    this is `lagrax.bench.plot_work_precision` under the name of the other plots.

    **Arguments:**

    - `points`: the study's list of `lagrax.bench.WorkPrecisionPoint`, or the
      `(points, reference_error)` pair that `lagrax.bench.work_precision` returns.
    - `reference_error`: the reference solution's own error (drawn as a dotted line);
      taken from the pair when one is given.
    - `title`, `axes`: a title; two axes to draw on (default: a new figure).

    **Returns:** the figure.
    """
    from .bench import plot_work_precision

    if isinstance(points, tuple) and len(points) == 2 and np.ndim(points[1]) == 0:
        points, reference_error = points
    if reference_error is None:
        raise ArgumentTypeError(
            "work_precision needs reference_error= (or the (points, error) pair)"
        )
    return plot_work_precision(
        points, reference_error=float(reference_error), title=title, axes=axes
    )


__all__ = [
    "joint_trajectories",
    "phase_portrait",
    "energy_error",
    "planar_chain_points",
    "arm_snapshots",
    "summary",
    "animate",
    "sweep_heatmap",
    "work_precision",
    "show3d",
    "View3D",
]
