"""The account of a failed solve that ``simulate`` raises."""

import numpy as np

from ._abstract_system import AbstractSystem
from ._checks import pivot_threshold
from ._results import RESULTS
from ._solution import Solution


def diagnose(system: AbstractSystem, sol: Solution, params, max_steps, rtol, atol) -> str:
    """A readable account of why a solve failed, from the state where it stopped."""
    t_end = float(sol.t_end)
    q_end, qd_end = np.asarray(sol.q_end), np.asarray(sol.qd_end)
    steps = int(sol.stats["num_steps"])
    reason = RESULTS[sol.result] if not bool(sol.ok) else "non-finite values"
    lines = [
        f"simulate failed for {system.name}: {reason}",
        f"  the solver stopped at t={t_end:.6g} with q={q_end}, qd={qd_end}",
    ]
    finite_state = np.all(np.isfinite(q_end)) and np.all(np.isfinite(qd_end))
    if not finite_state:
        saved = np.all(np.isfinite(np.asarray(sol.q)), axis=1)
        ts = np.asarray(sol.ts)
        bad = np.nonzero(~saved & ~np.isinf(ts))[0]
        if bad.size and bad[0] > 0:
            lines.append(
                f"  the state blew up (became non-finite) between the saves at "
                f"t={ts[bad[0] - 1]:.6g} and t={ts[bad[0]]:.6g}; if the step is fixed, it is "
                "likely past the method's stability limit: use a smaller dt, an adaptive "
                "step, or an implicit method for stiff scenes"
            )
        else:
            lines.append("  the state itself is non-finite there (it blew up)")
    else:
        qdd = np.asarray(system.accelerations(sol.t_end, sol.q_end, sol.qd_end, params, None))
        eigs = np.linalg.eigvalsh(np.asarray(system.mass_matrix(q_end, params, qd_end)))
        q0, qd0 = np.asarray(sol.q[0]), np.asarray(sol.qd[0])
        eigs0 = np.linalg.eigvalsh(np.asarray(system.mass_matrix(q0, params, qd0)))
        tiny = 1e3 * pivot_threshold(eigs.dtype)
        # singular relative to its own largest eigenvalue, or collapsed since the start
        if not (eigs[0] > tiny * max(abs(eigs[-1]), 1e-300) and eigs[0] > 1e-6 * eigs0[0]):
            lines.append(
                f"  the mass matrix is (nearly) singular there (eigenvalues {eigs}): the "
                "coordinates are singular at this configuration, or a mass/inertia is zero. "
                "Use coordinates without this singularity."
            )
        elif not np.all(np.isfinite(qdd)):
            rank = system.failure_hint(sol.q_end, params)
            lines.append(
                f"  {rank}"
                if rank is not None
                else "  the accelerations are non-finite there: check the force/tau "
                "functions and the energies for divisions by zero or overflow"
            )
    if sol.result == RESULTS.max_steps_reached:
        lines.append(
            f"  all {steps} steps of max_steps={max_steps} were used (rtol={rtol}, "
            f"atol={atol}). Try: a larger max_steps; looser tolerances; or, if the scene "
            "is stiff (stiff springs or dampers), an implicit solver such as "
            "solver=diffrax.Kvaerno5()."
        )
    lines.append("  Pass throw=False to get the partial Solution (entries never reached are inf).")
    return "\n".join(lines)
