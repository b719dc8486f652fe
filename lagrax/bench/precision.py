"""Work–precision study: error against cost, per method and tolerance (or step)."""

import csv
import math
import statistics
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np

from .._solve.methods import METHODS, resolve_solver
from .._solve.simulate import simulate
from .._solve.solution import Solution
from .._systems.lagrangian import LagrangianSystem

# default ladders: tolerances for adaptive methods, steps for fixed-step ones
DEFAULT_LADDERS: dict[str, tuple[str, tuple[float, ...]]] = {
    "tsit5": ("rtol", (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)),
    "dopri5": ("rtol", (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)),
    "dopri8": ("rtol", (1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)),
    "kvaerno5": ("rtol", (1e-4, 1e-6, 1e-8, 1e-10)),
    "rk4": ("dt", (0.02, 0.01, 0.005, 0.0025, 0.00125, 0.000625)),
    "variational": ("dt", (0.01, 0.005, 0.0025, 0.00125, 0.000625)),
    "variational4": ("dt", (0.02, 0.01, 0.005, 0.0025, 0.00125)),
}
QUICK_LADDERS: dict[str, tuple[str, tuple[float, ...]]] = {
    "tsit5": ("rtol", (1e-5, 1e-7, 1e-9)),
    "dopri8": ("rtol", (1e-5, 1e-7, 1e-9)),
    "variational": ("dt", (0.01, 0.005)),
}


@dataclass(frozen=True)
class WorkPrecisionPoint:
    """One run of the study (one method at one tolerance or step)."""

    method: str
    setting: str  # "rtol" (= atol) or "dt"
    value: float
    final_error: float  # max-norm of the state (q, q̇) error at t1 against the reference
    max_energy_error: float  # max_t |Solution.energy_error| (balance residual / scale)
    time_s: float  # median wall time of the compiled solve
    compile_s: float  # first call (trace + compile + run) minus time_s
    steps: int  # accepted + rejected
    rhs_evals: float  # right-hand-side evaluations (explicit RK: exact; else NaN)
    ok: bool


def _rhs_evals(method: str, solver: dfx.AbstractSolver, stats) -> float:
    tableau = getattr(solver, "tableau", None)
    if tableau is None or METHODS[method].implicit:
        return math.nan
    stages = len(tableau.c) + 1
    per_step = stages - (1 if tableau.fsal else 0)
    return float(int(stats["num_steps"]) * per_step + (1 if tableau.fsal else 0))


def _state_error(a: Solution, b: Solution) -> float:
    return float(max(jnp.max(jnp.abs(a.q_end - b.q_end)), jnp.max(jnp.abs(a.qd_end - b.qd_end))))


def reference_solution(system, q0, qd0, params, *, t1: float, n_save: int = 201):
    """Dopri8 at `rtol = atol = 1e-13`, and an estimate of its own error.

    The estimate is the difference from a second, independent run (Dopri8 at 1e-14 with
    a different step-size history); returned as `(solution, error_estimate)`.
    """
    ref = simulate(
        system,
        q0,
        qd0,
        params,
        t1=t1,
        solver="dopri8",
        rtol=1e-13,
        atol=1e-13,
        n_save=n_save,
        max_steps=2_000_000,
    )
    check = simulate(
        system,
        q0,
        qd0,
        params,
        t1=t1,
        solver="dopri8",
        rtol=1e-14,
        atol=1e-14,
        n_save=n_save,
        max_steps=4_000_000,
    )
    return ref, _state_error(ref, check)


def work_precision(
    system: LagrangianSystem,
    q0,
    qd0,
    params,
    *,
    t1: float = 10.0,
    ladders: Mapping[str, tuple[str, Sequence[float]]] | None = None,
    repeats: int = 5,
    n_save: int = 201,
    progress: bool = False,
) -> tuple[list[WorkPrecisionPoint], float]:
    """Run each method over its ladder of tolerances or steps; measure error and cost.

    For every (method, tolerance or step): the state error at `t1` against a reference
    solution ([`reference_solution`][lagrax.bench.reference_solution]), the largest relative energy
    error along the trajectory (`n_save` points), the median wall time of `repeats` runs after
    compilation, the compile time (first call minus a run), the step count and, for
    explicit Runge–Kutta methods, the number of right-hand-side evaluations. Adaptive
    methods use `rtol = atol = value`; fixed-step methods `dt = value`. Failed runs are
    recorded with `ok=False`, not dropped.

    **Returns:** `(points, reference_error)`.
    """
    ladders = DEFAULT_LADDERS if ladders is None else ladders
    ref, ref_err = reference_solution(system, q0, qd0, params, t1=t1, n_save=n_save)
    points = []
    for method, (setting, values) in ladders.items():
        solver, _ = resolve_solver(method)
        for value in values:
            # at a fixed dt, simulate sizes the step budget itself (fixed_step_budget)
            if setting == "rtol":
                kw = {"rtol": value, "atol": value, "max_steps": 1_000_000}
            else:
                kw = {"dt": value}

            def run(kw=kw, method=method):
                sol = simulate(
                    system, q0, qd0, params, t1=t1, solver=method, n_save=n_save, throw=False, **kw
                )
                jax.block_until_ready(sol.q)
                return sol

            t0 = time.perf_counter()
            sol = run()
            first = time.perf_counter() - t0
            times = []
            for _ in range(repeats):
                t0 = time.perf_counter()
                run()
                times.append(time.perf_counter() - t0)
            median = statistics.median(times)
            ok = bool(sol.ok)
            point = WorkPrecisionPoint(
                method=method,
                setting=setting,
                value=float(value),
                final_error=_state_error(sol, ref) if ok else math.inf,
                max_energy_error=float(jnp.max(jnp.abs(sol.energy_error))) if ok else math.inf,
                time_s=median,
                compile_s=max(first - median, 0.0),
                steps=int(sol.stats["num_steps"]),
                rhs_evals=_rhs_evals(method, solver, sol.stats),
                ok=ok,
            )
            points.append(point)
            if progress:
                print(
                    f"  {method:12s} {setting}={value:<8.1e} error {point.final_error:9.2e}  "
                    f"energy {point.max_energy_error:9.2e}  {median * 1e3:8.2f} ms  "
                    f"{point.steps:7d} steps",
                    flush=True,
                )
    return points, ref_err


def write_csv(points: Sequence[WorkPrecisionPoint], path) -> Path:
    """Write the study as CSV (one row per run)."""
    path = Path(path)
    with path.open("w", newline="") as fh:
        fields = list(asdict(points[0]))
        writer = csv.DictWriter(fh, fieldnames=fields)
        writer.writeheader()
        for p in points:
            writer.writerow(asdict(p))
    return path


def _setting_label(setting: str, value: float) -> str:
    """A point's tolerance or step, as printed next to it: `1e-8`, `dt 0.005`."""
    if setting == "dt":
        return f"{value:g}"
    return f"{value:.0e}".replace("e-0", "e-").replace("e+0", "e")


def plot_work_precision(
    points: Sequence[WorkPrecisionPoint], *, reference_error: float, title: str = "", axes=None
):
    """Two log–log panels: final-state error vs time, and max energy error vs time.

    One line per method, a marker at each tolerance or step, labelled with it (adaptive
    methods: `rtol` = `atol`; fixed-step ones: `dt` in seconds), so the tolerance a
    target error needs can be read off. Errors that are exactly zero are not drawn (a
    log axis has no zero). Returns the figure.
    """
    import matplotlib.pyplot as plt

    if axes is None:
        fig, axes = plt.subplots(1, 2, figsize=(13, 5), constrained_layout=True)
    else:
        fig = axes[0].figure
    methods = list(dict.fromkeys(p.method for p in points))
    for k, m in enumerate(methods):
        rows = [p for p in points if p.method == m and p.ok]
        if not rows:
            continue
        fixed = rows[0].setting == "dt"
        style = "--s" if fixed else "-o"
        label = f"{m} ({'fixed step; labels: dt [s]' if fixed else 'adaptive; labels: rtol'})"
        t = np.array([p.time_s for p in rows]) * 1e3
        for ax, errs in (
            (axes[0], np.array([p.final_error for p in rows])),
            (axes[1], np.array([p.max_energy_error for p in rows])),
        ):
            shown = errs > 0
            (line,) = ax.loglog(
                t, np.where(shown, errs, np.nan), style, label=label, ms=4, color=f"C{k}"
            )
            for p, ti, e in zip(rows, t, errs, strict=True):
                if e > 0 and np.isfinite(e):
                    ax.annotate(
                        _setting_label(p.setting, p.value),
                        (ti, e),
                        xytext=(4, 3),
                        textcoords="offset points",
                        fontsize=6.5,
                        color=line.get_color(),
                    )
    axes[0].axhline(reference_error, color="0.5", lw=0.8, ls=":")
    axes[0].text(
        0.01,
        0.02,
        f"reference (Dopri8, tol 1e-13) error ≈ {reference_error:.1e}",
        transform=axes[0].transAxes,
        fontsize=8,
        color="0.3",
    )
    axes[0].set_xlabel("wall time per solve [ms] (after compilation)")
    axes[0].set_ylabel("state error at t1 (max norm over q, q̇)")
    axes[1].set_xlabel("wall time per solve [ms] (after compilation)")
    axes[1].set_ylabel("max |E(t) − E(0)| / |E(0)|")
    axes[0].legend(fontsize=8)
    axes[0].set_title("accuracy vs cost")
    axes[1].set_title("energy error vs cost")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    if title:
        fig.suptitle(title)
    return fig
