"""Matplotlib figures for trajectories of lagrax systems.

Every function takes optional ``ax`` and returns the axes (or figure, or animation) it
drew on, so the result can be restyled:

- one trajectory: :func:`joint_trajectories`, :func:`phase_portrait`,
  :func:`energy_error`, :func:`arm_snapshots`, :func:`summary`, :func:`animate`;
- many: :func:`sweep_heatmap` (a quantity over a 2-D :func:`lagrax.sweep` grid);
- methods: :func:`work_precision` (the chart of :func:`lagrax.bench.work_precision`).
"""

from collections.abc import Sequence
from typing import Any

import numpy as np

from ._solution import Solution


def _axes(ax):
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots()
    return ax


def joint_trajectories(sol: Solution, *, labels: Sequence[str] | None = None, ax=None):
    """Generalized coordinates ``q(t)`` against time, one line each."""
    ax = _axes(ax)
    q = np.asarray(sol.q)
    for i in range(q.shape[1]):
        ax.plot(np.asarray(sol.ts), q[:, i], label=labels[i] if labels else f"q{i + 1}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("q [rad]")
    ax.legend(loc="best")
    return ax


def energy_error(sol: Solution, *, ax=None):
    """The energy error ``|h(t) − h(0) − W(t)| / scale`` (``Solution.energy_error``: the
    balance residual, relative to ``max(|h(0)|, |T| + |V|)``) on a log scale."""
    ax = _axes(ax)
    err = np.abs(np.asarray(sol.energy_error))
    # zero error (at t0, or exactly conserved) is drawn at 1/10 of machine epsilon
    floor = 0.1 * np.finfo(err.dtype).eps
    ax.semilogy(np.asarray(sol.ts), np.maximum(err, floor))
    ax.set_xlabel("t [s]")
    ax.set_ylabel("|h(t) − h(0) − W(t)| / scale")
    ax.set_ylim(bottom=floor)
    return ax


def planar_chain_points(q, lengths) -> np.ndarray:
    """Joint positions of a planar serial chain with relative angles ``q`` (from +x).

    Returns an array ``(..., n + 1, 2)``: the base at the origin, then each link's end.
    """
    q = np.asarray(q)
    angles = np.cumsum(q, axis=-1)
    lengths = np.asarray(lengths, dtype=float)
    steps = np.stack([lengths * np.cos(angles), lengths * np.sin(angles)], axis=-1)
    base = np.zeros(q.shape[:-1] + (1, 2))
    return np.concatenate([base, np.cumsum(steps, axis=-2)], axis=-2)


def arm_snapshots(sol: Solution, lengths, *, n_snapshots: int = 12, ax=None):
    """Stroboscopic drawing of a planar chain: the arm at evenly spaced saved times,
    fading from light (early) to dark (late), and the path of the tip."""
    import matplotlib.pyplot as plt

    ax = _axes(ax)
    pts = planar_chain_points(sol.q, lengths)
    idx = np.linspace(0, len(pts) - 1, n_snapshots).astype(int)
    cmap = plt.get_cmap("viridis")
    ax.plot(pts[:, -1, 0], pts[:, -1, 1], color="0.7", lw=0.8, label="tip path")
    for k, i in enumerate(idx):
        c = cmap(k / max(n_snapshots - 1, 1))
        ax.plot(pts[i, :, 0], pts[i, :, 1], "-o", color=c, lw=2, ms=3)
    reach = float(np.sum(lengths))
    ax.set_xlim(-1.1 * reach, 1.1 * reach)
    ax.set_ylim(-1.1 * reach, 1.1 * reach)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper right")
    return ax


def summary(sol: Solution, lengths, *, title: str | None = None):
    """Three panels: joint angles, arm snapshots, energy error. Returns the figure."""
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 3, figsize=(15, 4.4), constrained_layout=True)
    joint_trajectories(sol, labels=[f"θ{i + 1}" for i in range(np.shape(sol.q)[1])], ax=axs[0])
    arm_snapshots(sol, lengths, ax=axs[1])
    energy_error(sol, ax=axs[2])
    axs[0].set_title("joint angles")
    axs[1].set_title("arm snapshots")
    axs[2].set_title("energy error")
    if title:
        fig.suptitle(title)
    return fig


def phase_portrait(
    sol: Solution,
    *,
    dof: int | Sequence[int] | None = None,
    labels: Sequence[str] | None = None,
    ax=None,
):
    """Phase portrait: ``q̇_i`` against ``q_i``, one curve per coordinate.

    The start of each curve is marked with a dot. A conservative 1-DOF system traces a
    closed level curve of ``E = T + V``; dissipation makes it spiral in.

    **Arguments:**

    - ``sol``: a :class:`lagrax.Solution`.
    - ``dof``: the coordinate index (or indices) to draw; default all.
    - ``labels``: one name per drawn coordinate (default ``q1``, ``q2``, …).
    - ``ax``: axes to draw on (default: a new figure).

    **Returns:** the axes; ``ax.lines`` holds one curve per drawn coordinate.
    """
    ax = _axes(ax)
    q, qd = np.asarray(sol.q), np.asarray(sol.qd)
    dofs = list(range(q.shape[1])) if dof is None else [int(i) for i in np.atleast_1d(dof)]
    for k, i in enumerate(dofs):
        keep = np.isfinite(q[:, i]) & np.isfinite(qd[:, i])  # a failed solve's tail is inf
        name = labels[k] if labels else f"q{i + 1}"
        (line,) = ax.plot(q[keep, i], qd[keep, i], lw=1, label=name)
        ax.scatter(q[keep, i][:1], qd[keep, i][:1], color=line.get_color(), s=18, zorder=3)
    ax.set_xlabel("q [rad]")
    ax.set_ylabel("q̇ [rad/s]")
    ax.legend(loc="best")
    return ax


def _chain_points(geometry: Any, q: np.ndarray, params: Any) -> np.ndarray:
    """Points ``(T, k, 2)`` to draw at each saved state, from the three kinds of geometry."""
    if hasattr(geometry, "joint_positions"):  # e.g. lagrax.chains.PlanarChain
        if params is None:
            raise ValueError(
                f"animating a {type(geometry).__name__} needs its parameters: pass params="
            )
        import jax
        import jax.numpy as jnp

        pts = np.asarray(jax.vmap(lambda a: geometry.joint_positions(a, params))(jnp.asarray(q)))
    elif callable(geometry):
        pts = np.stack([np.asarray(geometry(a)) for a in q])
    else:
        pts = planar_chain_points(q, geometry)
    if pts.ndim != 3 or pts.shape[-1] != 2:
        raise ValueError(
            "the geometry must give k planar points per state, shape (k, 2); got shape "
            f"{pts.shape[1:]} per state"
        )
    return pts


def animate(
    geometry: Any,
    sol: Solution,
    *,
    params: Any = None,
    max_frames: int = 150,
    speed: float = 1.0,
    trail: bool = True,
    title: str | None = None,
    ax=None,
):
    """Animate a planar mechanism along a solution (matplotlib ``FuncAnimation``).

    Each frame draws the mechanism as a polyline through its points (joints and tip) at
    one saved time, the path of the last point so far, and the time.

    In a notebook show it with ``IPython.display.HTML(anim.to_jshtml())`` (no extra
    software; call ``plt.close()`` first so the empty figure is not shown as well), or
    ``anim.to_html5_video()`` (needs ffmpeg). On disk: ``anim.save("arm.gif",
    writer="pillow")`` (Pillow ships with matplotlib) or ``anim.save("arm.mp4")``
    (ffmpeg).

    **Arguments:**

    - ``geometry``: what to draw, one of
        - link lengths ``[l1, …, ln]`` of a planar serial chain with relative joint angles
          (``θ1`` from +x, ``θi`` relative to link ``i − 1``; the 2R arm:
          ``[params["l1"], params["l2"]]``);
        - a chain object with ``joint_positions(q, params)`` (e.g.
          :class:`lagrax.chains.PlanarChain`; then pass ``params=``);
        - a function ``points(q) -> (k, 2)`` for any other planar mechanism.
    - ``sol``: a :class:`lagrax.Solution` (its saved times are the frames).
    - ``params``: parameters for a chain object.
    - ``max_frames``: at most this many frames, evenly spaced over the saved times.
    - ``speed``: playback speed relative to real time.
    - ``trail``: draw the path of the last point.
    - ``title``, ``ax``: a title; axes to draw on (default: a new figure).

    **Returns:** the ``matplotlib.animation.FuncAnimation``.
    """
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

    ts = np.asarray(sol.ts)
    reached = np.isfinite(ts)  # a failed solve stops early: animate what was reached
    ts, q = ts[reached], np.asarray(sol.q)[reached]
    pts = _chain_points(geometry, q, params)
    frames = np.unique(np.linspace(0, len(ts) - 1, min(len(ts), int(max_frames))).round())
    frames = frames.astype(int)
    span = float(ts[frames[-1]] - ts[frames[0]])
    interval = 1000.0 * span / max(len(frames) - 1, 1) / float(speed)  # ms per frame

    if ax is None:
        fig, ax = plt.subplots(figsize=(5, 5))
    else:
        fig = ax.figure
    lo, hi = pts.reshape(-1, 2).min(axis=0), pts.reshape(-1, 2).max(axis=0)
    centre, half = 0.5 * (lo + hi), 0.55 * max(float(np.max(hi - lo)), 1e-9)
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")
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


def _edges(centres: np.ndarray) -> tuple[np.ndarray, bool]:
    """Cell edges around grid values (geometric midpoints for log-spaced values)."""
    c = np.asarray(centres, dtype=float)
    if c.size == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5]), False
    log = bool(np.all(c > 0) and c.size > 2)
    if log:
        d = np.diff(np.log(c))
        log = bool(np.allclose(d, d[0], rtol=1e-6)) and not np.allclose(
            np.diff(c), c[1] - c[0], rtol=1e-6
        )
    x = np.log(c) if log else c
    mid = 0.5 * (x[1:] + x[:-1])
    e = np.concatenate([[x[0] - (mid[0] - x[0])], mid, [x[-1] + (x[-1] - mid[-1])]])
    return (np.exp(e) if log else e), log


def sweep_heatmap(
    ds: Any,
    var: Any,
    *,
    dof: int | None = None,
    x: str | None = None,
    y: str | None = None,
    log: bool = False,
    cmap: str = "viridis",
    label: str | None = None,
    ax=None,
):
    """A per-member quantity over a 2-D parameter grid from :func:`lagrax.sweep`.

    Cells are centred on the swept values (log-spaced values get a log axis). Members
    that failed (``ds.ok`` False) or whose value is not finite are drawn grey and
    hatched, and counted in the legend, so a failure never looks like a number.

    **Arguments:**

    - ``ds``: the ``xarray.Dataset`` of a sweep over a 2-D :func:`lagrax.grid`.
    - ``var``: a variable name of ``ds`` (``"energy_error"``, ``"num_steps"``, ``"q"``, a
      ``keep=`` function's output, …) or an ``xarray.DataArray`` over the two sweep
      dimensions (e.g. ``abs(ds.q.sel(dof=1) - ref)``).
    - ``dof``: the coordinate to show when ``var`` has a ``"dof"`` dimension.
    - ``x``, ``y``: which sweep dimension goes on which axis (default: the grid's second
      dimension on x, its first on y, as ``xarray``'s own ``.plot()``).
    - ``log``: logarithmic colour scale (non-positive values are then marked as failed).
    - ``cmap``, ``label``: colour map; colour-bar label (default: the variable's name).
    - ``ax``: axes to draw on (default: a new figure).

    **Returns:** the axes; its first collection is the ``QuadMesh`` whose array has the
    grid's shape ``(len(y), len(x))``.
    """
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm
    from matplotlib.patches import Patch, Rectangle

    da = ds[var] if isinstance(var, str) else var
    name = var if isinstance(var, str) else (da.name or "value")
    if "dof" in da.dims:
        if dof is None:
            raise ValueError(f"{name!r} has a 'dof' dimension: choose a coordinate with dof=")
        da = da.sel(dof=dof)
        name = f"{name}[{dof}]"
    if da.ndim != 2:
        raise ValueError(
            f"sweep_heatmap draws a 2-D grid; {name!r} has dimensions {da.dims} (select "
            "a time or reduce the others first, e.g. ds.q.isel(time=-1))"
        )
    if x is None and y is None:
        y, x = da.dims
    elif x is None or y is None:
        x = x if x is not None else next(d for d in da.dims if d != y)
        y = y if y is not None else next(d for d in da.dims if d != x)
    da = da.transpose(y, x)
    values = np.asarray(da.values, dtype=float)
    bad = ~np.isfinite(values)
    if "ok" in getattr(ds, "data_vars", {}) and set(ds["ok"].dims) == {x, y}:
        bad |= ~np.asarray(ds["ok"].transpose(y, x).values, dtype=bool)
    if log:
        with np.errstate(invalid="ignore"):
            bad |= ~(values > 0)
    data = np.ma.masked_array(values, bad)

    ax = _axes(ax)
    coords = []
    for d in (x, y):
        c = np.asarray(da[d].values) if d in da.coords else np.arange(da.sizes[d])
        if not np.issubdtype(c.dtype, np.number):
            c = np.arange(c.size)
        coords.append(c)
    (xe, xlog), (ye, ylog) = _edges(coords[0]), _edges(coords[1])
    colours = plt.get_cmap(cmap).with_extremes(bad="0.8")
    norm = LogNorm() if log and not bad.all() else None
    mesh = ax.pcolormesh(xe, ye, data, cmap=colours, norm=norm, shading="flat")
    ax.figure.colorbar(mesh, ax=ax, label=label or name)
    if xlog:
        ax.set_xscale("log")
    if ylog:
        ax.set_yscale("log")
    hatch = dict(facecolor="0.8", edgecolor="0.35", hatch="///", lw=0)
    for j, i in zip(*np.nonzero(bad), strict=True):
        ax.add_patch(Rectangle((xe[i], ye[j]), xe[i + 1] - xe[i], ye[j + 1] - ye[j], **hatch))
    if bad.any():
        ax.legend(
            handles=[Patch(**hatch, label=f"failed ({int(bad.sum())} of {bad.size})")],
            loc="upper right",
            fontsize=8,
        )
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    return ax


def work_precision(
    points: Any,
    reference_error: float | None = None,
    *,
    title: str = "",
    axes=None,
):
    """The work–precision chart: error against wall time, one line per method.

    Two log–log panels (final-state error, and maximum energy error, against the median
    wall time of a compiled solve) of a study by :func:`lagrax.bench.work_precision`;
    this is :func:`lagrax.bench.plot_work_precision` under the name of the other plots.

    **Arguments:**

    - ``points``: the study's list of :class:`lagrax.bench.WorkPrecisionPoint`, or the
      ``(points, reference_error)`` pair that ``lagrax.bench.work_precision`` returns.
    - ``reference_error``: the reference solution's own error (drawn as a dotted line);
      taken from the pair when one is given.
    - ``title``, ``axes``: a title; two axes to draw on (default: a new figure).

    **Returns:** the figure.
    """
    from .bench import plot_work_precision

    if isinstance(points, tuple) and len(points) == 2 and np.ndim(points[1]) == 0:
        points, reference_error = points
    if reference_error is None:
        raise TypeError("work_precision needs reference_error= (or the (points, error) pair)")
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
]
