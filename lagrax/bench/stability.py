"""Stability atlas: scenes where integration methods fail, and how lagrax reports it."""

import functools
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from .._core.errors import LagraxError
from .._solve.simulate import simulate
from .._systems.lagrangian import LagrangianSystem
from ..models import planar_2r

CHAOTIC_START = (-math.pi / 2 + 1.4, 0.8)


@dataclass(frozen=True)
class AtlasRow:
    """One (scene, method) outcome of the atlas."""

    case: str
    method: str
    outcome: str  # "ok" or "failed"
    detail: str  # what happened, in numbers
    detected_by: str  # how lagrax reports it ("" when nothing failed)
    time_s: float


def _run(case, method, fn, detect_note=""):
    t0 = time.perf_counter()
    try:
        detail = fn()
        return AtlasRow(case, method, "ok", detail, detect_note, time.perf_counter() - t0)
    except LagraxError as err:
        first = str(err).splitlines()[0]
        return AtlasRow(case, method, "failed", first, type(err).__name__, time.perf_counter() - t0)


# ---------------------------------------------------------------- long horizon
def energy_trend(ts, energy_error) -> tuple[float, float]:
    """Least-squares slope of the relative energy error (per unit time) and its max |·|."""
    ts = np.asarray(ts)
    err = np.asarray(energy_error)
    slope = np.polyfit(ts, err, 1)[0]
    return float(slope), float(np.max(np.abs(err)))


def long_horizon(periods: float = 1e4, *, n_save: int = 2001):
    """Torque-free 2R arm over `periods` of its slowest natural period (≈ 2.34 s).

    Tsit5 at a practical tolerance (1e-8) drifts secularly in energy; the midpoint
    variational integrator keeps a bounded, oscillating energy error. Returns the atlas
    rows and the two solutions (for plotting).
    """
    system, params = planar_2r()
    q0 = jnp.array([-math.pi / 2 + 0.6, 0.4])  # regular (quasi-periodic) motion
    qd0 = jnp.zeros(2)
    t1 = periods * 2.3444
    sols, rows = {}, []
    for method, kw in (
        ("tsit5", dict(rtol=1e-8, atol=1e-8)),
        ("variational", dict(dt=0.025)),
    ):
        t0 = time.perf_counter()
        sol = simulate(
            system, q0, qd0, params, t1=t1, solver=method, n_save=n_save, max_steps=50_000_000, **kw
        )
        jax.block_until_ready(sol.q)
        elapsed = time.perf_counter() - t0
        slope, emax = energy_trend(sol.ts, sol.energy_error)
        drift = slope * 1000.0
        sols[method] = sol
        bounded = abs(slope) * t1 < 0.2 * emax
        rows.append(
            AtlasRow(
                f"long horizon ({periods:.0f} periods, {t1:.0f} s)",
                f"{method} {kw}",
                "ok" if bounded else "failed",
                f"energy trend {drift:+.1e} per 1000 s, max |ΔE/E| {emax:.1e}, "
                f"{int(sol.stats['num_steps'])} steps",
                "" if bounded else "secular drift: Solution.energy_error (a trend, no error)",
                elapsed,
            )
        )
    return rows, sols


# ---------------------------------------------------------------- stiff joint
@functools.cache
def _arm() -> LagrangianSystem:
    """The 2R arm, whose kinetic and potential energies the stiff arm reuses."""
    return planar_2r()[0]


def _stiff_potential(q, p):
    return _arm().potential(q, p) + 0.5 * p["k"] * (q[1] - p["q2_rest"]) ** 2


def _stiff_dissipation(q, qd, p):
    return 0.5 * p["c"] * qd[1] ** 2


def stiff_arm(stiffness_ratio: float = 1e6):
    """The 2R arm with a joint-2 spring/damper, `k = ratio · m g l` (gravity scale)."""
    system = LagrangianSystem(
        _arm().kinetic,
        _stiff_potential,
        dissipation=_stiff_dissipation,
        n_dof=2,
        name="2R arm with a stiff joint spring",
    )
    _, params = planar_2r()
    k = stiffness_ratio * float(params["m2"] * params["g"] * params["l2"])
    params = {**params, "k": jnp.asarray(k), "c": jnp.asarray(0.03 * k), "q2_rest": 0.3}
    return system, params


def stiff(stiffness_ratio: float = 1e6, t1: float = 2.0):
    """Explicit methods against a stiff joint: step explosion / blow-up; implicit copes."""
    system, params = stiff_arm(stiffness_ratio)
    q0, qd0 = jnp.array([-math.pi / 2 + 1.0, 0.5]), jnp.zeros(2)
    case = f"stiff joint spring (k = {stiffness_ratio:.0e}·m g l, t1 = {t1:g} s)"

    def go(**kw):
        def fn():
            sol = simulate(system, q0, qd0, params, t1=t1, n_save=201, **kw)
            jax.block_until_ready(sol.q)
            return (
                f"completed: {int(sol.stats['num_steps'])} steps, q(t1) = "
                f"{np.array2string(np.asarray(sol.q[-1]), precision=4)}"
            )

        return fn

    return [
        _run(
            case,
            "tsit5, rtol 1e-6, max_steps 20,000",
            go(solver="tsit5", rtol=1e-6, atol=1e-6, max_steps=20_000),
        ),
        _run(case, "kvaerno5, rtol 1e-6", go(solver="kvaerno5", rtol=1e-6, atol=1e-6)),
        _run(case, "rk4, dt = 1e-3 (past its stability limit)", go(solver="rk4", dt=1e-3)),
        _run(case, "variational, dt = 1e-3", go(solver="variational", dt=1e-3)),
    ]


# ---------------------------------------------------------------- chaos
def chaos(t1: float = 30.0, tolerances=(1e-6, 1e-8, 1e-10, 1e-12), threshold: float = 0.1):
    """Predictability horizon of the chaotic 2R arm against the solver tolerance.

    Each solution is compared with Dopri8 at 1e-13; the horizon is the first time the
    joint angles differ by more than `threshold` rad. Returns rows and the divergence
    curves `{tol: (ts, |Δq|)}`.
    """
    system, params = planar_2r()
    q0, qd0 = jnp.array(CHAOTIC_START), jnp.zeros(2)
    kw = dict(t1=t1, n_save=3001, max_steps=2_000_000)
    ref = simulate(system, q0, qd0, params, solver="dopri8", rtol=1e-13, atol=1e-13, **kw)
    curves, rows = {}, []
    for tol in tolerances:
        t0 = time.perf_counter()
        sol = simulate(system, q0, qd0, params, solver="tsit5", rtol=tol, atol=tol, **kw)
        dq = np.max(np.abs(np.asarray(sol.q) - np.asarray(ref.q)), axis=1)
        ts = np.asarray(sol.ts)
        over = np.nonzero(dq > threshold)[0]
        horizon = float(ts[over[0]]) if over.size else math.inf
        curves[tol] = (ts, dq)
        rows.append(
            AtlasRow(
                f"chaos (2R arm from θ = (−π/2 + 1.4, 0.8), {t1:g} s)",
                f"tsit5, rtol = atol = {tol:.0e}",
                "ok",
                f"predictability horizon (|Δθ| > {threshold} rad vs Dopri8 1e-13): "
                + (f"{horizon:.1f} s" if math.isfinite(horizon) else f"> {t1:g} s"),
                "not a failure: chaos amplifies any error; the horizon grows ~ log(1/tol)",
                time.perf_counter() - t0,
            )
        )
    return rows, curves


# ---------------------------------------------------------------- singular coordinates
def _sph_kinetic(q, qd, p):  # θ from the downward vertical, φ azimuth
    return 0.5 * p["m"] * p["l"] ** 2 * (qd[0] ** 2 + jnp.sin(q[0]) ** 2 * qd[1] ** 2)


def _sph_potential(q, p):
    return -p["m"] * p["g"] * p["l"] * jnp.cos(q[0])


def _bob_position(q, p):
    """Bob position from the horizontal coordinates (x, y); regular at the bottom."""
    z = -jnp.sqrt(p["l"] ** 2 - q[0] ** 2 - q[1] ** 2)
    return jnp.stack([q[0], q[1], z])


def _xy_kinetic(q, qd, p):
    v = jax.jvp(lambda a: _bob_position(a, p), (q,), (qd,))[1]
    return 0.5 * p["m"] * jnp.sum(v**2)


def _xy_potential(q, p):
    return p["m"] * p["g"] * _bob_position(q, p)[2]


def spherical_pendulum(coordinates: str = "spherical"):
    """A spherical pendulum in spherical angles (singular at the bottom) or in the
    horizontal bob coordinates `(x, y)` (regular there)."""
    params = {"m": jnp.asarray(1.0), "l": jnp.asarray(1.0), "g": jnp.asarray(9.81)}
    if coordinates == "spherical":
        return LagrangianSystem(
            _sph_kinetic, _sph_potential, n_dof=2, name="spherical pendulum (θ, φ)"
        ), params
    return LagrangianSystem(
        _xy_kinetic, _xy_potential, n_dof=2, name="spherical pendulum (x, y)"
    ), params


def singular(t1: float = 5.0):
    """Spherical coordinates lose rank at the pole: detected, and the remedy shown."""
    sph, p = spherical_pendulum("spherical")
    xy, _ = spherical_pendulum("xy")
    case = "singular coordinates (spherical pendulum, θ = 0 is the pole)"

    def start_at_pole():
        sph.check_state(jnp.array([0.0, 0.0]), jnp.array([0.5, 0.0]), p)
        return "no error (unexpected)"

    def near_pole(p_phi):
        def fn():
            theta0 = 0.3
            phid = p_phi / math.sin(theta0) ** 2
            sol = simulate(
                sph, [theta0, 0.0], [-2.0, phid], p, t1=t1, max_steps=100_000, rtol=1e-8, atol=1e-8
            )
            return (
                f"p_φ = {p_phi:.0e}: {int(sol.stats['num_steps'])} steps, "
                f"min θ {float(jnp.min(sol.q[:, 0])):.1e}, max |ΔE/E| "
                f"{float(jnp.max(jnp.abs(sol.energy_error))):.1e}"
            )

        return fn

    def remedy():
        x0 = math.sin(0.3)
        sol = simulate(xy, [x0, 0.0], [-2.0 * math.cos(0.3), 1e-3], p, t1=t1, rtol=1e-8, atol=1e-8)
        return (
            f"completed through the bottom: {int(sol.stats['num_steps'])} steps, max |ΔE/E| "
            f"{float(jnp.max(jnp.abs(sol.energy_error))):.1e}"
        )

    rows = [_run(case, "check_state / simulate starting at θ = 0", start_at_pole)]
    for p_phi in (1e-2, 1e-4, 1e-6):
        rows.append(
            _run(
                case,
                "tsit5 near the pole (spherical)",
                near_pole(p_phi),
                "step count grows as p_φ → 0 (M nearly singular)",
            )
        )
    rows.append(_run(case, "remedy: bob coordinates (x, y), tsit5", remedy))
    return rows


def _figure(title, ylabel):
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    return fig, ax


def power_trend(ts, energy_error, *, start_fraction: float = 0.01) -> tuple[float, float]:
    """Fit `max_{s ≤ t} |ΔE/E|(s) ≈ C t^p` by least squares in log–log, over saved times
    `t ≥ start_fraction · t1` (the running maximum, so oscillation does not hide a trend).

    A secular drift gives `p ≈ 1`; a bounded, oscillating error `p ≈ 0`. Returns `(C, p)`.
    """
    ts = np.asarray(ts, dtype=float)
    err = np.maximum.accumulate(np.abs(np.asarray(energy_error, dtype=float)))
    use = (ts >= start_fraction * ts[-1]) & (ts > 0) & (err > 0) & np.isfinite(err)
    p, log_c = np.polyfit(np.log(ts[use]), np.log(err[use]), 1)
    return float(np.exp(log_c)), float(p)


def plot_long_horizon(sols):
    """Relative energy error against time on log–log axes, with fitted power-law trends.

    Each solution's `|E(t) − E(0)| / |E(0)|` (thin; the exact zero at `t = 0` is left
    out) and the trend `C t^p` fitted to its running maximum (see `power_trend`), drawn
    on to where two trends cross when that lies within 10⁴ horizons (dashed beyond the
    simulated horizon), so a drift that has not yet overtaken a bounded error shows
    when it would. The title states what the fits show.
    """
    fig, ax = _figure("", "|E(t) − E(0)| / |E(0)|")
    trends = {}
    t1 = 0.0
    for k, (name, sol) in enumerate(sols.items()):
        ts, err = np.asarray(sol.ts), np.abs(np.asarray(sol.energy_error))
        shown = (ts > 0) & (err > 0) & np.isfinite(err)
        ax.loglog(ts[shown], err[shown], lw=0.6, alpha=0.45, color=f"C{k}")
        trends[name] = power_trend(ts, err)
        t1 = max(t1, float(ts[-1]))
    crossing = None
    if len(trends) == 2:
        (c1, p1), (c2, p2) = trends.values()
        if abs(p1 - p2) > 0.2:
            t_x = (c2 / c1) ** (1.0 / (p1 - p2))
            if t1 < t_x < 1e4 * t1:
                crossing = t_x
    t_end = crossing * 3 if crossing is not None else t1
    for k, (name, (c, p)) in enumerate(trends.items()):
        t_fit = np.geomspace(0.01 * t1, t1, 50)
        ax.loglog(t_fit, c * t_fit**p, color=f"C{k}", lw=2, label=f"{name}: trend ∝ t^{p:.2f}")
        if t_end > t1:
            t_ext = np.geomspace(t1, t_end, 50)
            ax.loglog(t_ext, c * t_ext**p, color=f"C{k}", lw=1.2, ls="--")
    if t_end > t1:
        ax.axvline(t1, color="0.5", lw=0.8, ls=":")
        ax.text(t1, 0.02, " simulated horizon", transform=ax.get_xaxis_transform(), fontsize=8)
    if crossing is not None:
        ax.axvline(crossing, color="k", lw=0.8, ls="-.")
        ax.text(
            crossing,
            0.95,
            f"trends cross\nt ≈ {crossing:.1e} s ",
            transform=ax.get_xaxis_transform(),
            ha="right",
            va="top",
            fontsize=8,
        )
    drift = [n for n, (_, p) in trends.items() if p > 0.5]
    bounded = [n for n, (_, p) in trends.items() if abs(p) < 0.2]
    if drift and bounded:
        title = (
            f"long horizon: {', '.join(drift)}'s energy error grows like t (drift); "
            f"{', '.join(bounded)}'s stays bounded"
        )
    else:
        title = "long horizon: energy error with fitted trends C t^p"
    ax.set_title(title, fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(True, which="major", alpha=0.3)
    return fig


def plot_chaos(curves, threshold: float = 0.1):
    """Divergence from the reference against time, one line per tolerance (log scale;
    exact agreement, as at `t = 0`, is left out)."""
    fig, ax = _figure(
        "chaos: the predictability horizon grows like log(1/tol)",
        "max |Δθ| vs Dopri8 1e-13 [rad]",
    )
    for tol, (ts, dq) in curves.items():
        dq = np.asarray(dq, dtype=float)
        ax.semilogy(ts, np.where(dq > 0, dq, np.nan), label=f"tsit5 tol {tol:.0e}", lw=0.8)
    ax.axhline(threshold, color="0.5", ls=":")
    ax.legend()
    return fig


def write_table(rows, path_md, path_csv):
    """Markdown and CSV tables of the atlas."""
    import csv

    with Path(path_csv).open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(asdict(rows[0])))
        writer.writeheader()
        for r in rows:
            writer.writerow(asdict(r))
    lines = [
        "| case | method | outcome | what happened | how lagrax reports it | time [s] |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        detail = r.detail.replace("|", "/")
        lines.append(
            f"| {r.case} | {r.method} | {r.outcome} | {detail} | {r.detected_by} | {r.time_s:.2f} |"
        )
    Path(path_md).write_text("\n".join(lines) + "\n")


__all__ = [
    "AtlasRow",
    "long_horizon",
    "stiff",
    "chaos",
    "singular",
    "write_table",
    "plot_long_horizon",
    "plot_chaos",
]
