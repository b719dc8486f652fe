"""Matplotlib figures for trajectories of lagrax systems.

Every function takes optional ``ax`` and returns the axes (or figure) it drew on, so the
result can be restyled.
"""

from collections.abc import Sequence

import numpy as np

from ._simulate import Solution


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
    """Relative energy error ``|E(t) − E(0)| / |E(0)|`` on a log scale."""
    ax = _axes(ax)
    err = np.abs(np.asarray(sol.energy_error))
    # zero error (at t0, or exactly conserved) is drawn at 1/10 of machine epsilon
    floor = 0.1 * np.finfo(err.dtype).eps
    ax.semilogy(np.asarray(sol.ts), np.maximum(err, floor))
    ax.set_xlabel("t [s]")
    ax.set_ylabel("|E(t) − E(0)| / |E(0)|")
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
