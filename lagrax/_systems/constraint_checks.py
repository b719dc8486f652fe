"""A `ConstrainedSystem`'s checks: the checked KKT solve behind `forward_dynamics`,
`multipliers` and `constraint_forces`, a state's eager validation, and the messages
that name a rank-deficient constraint matrix `K = [J; A]`."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core.checks import eager_only, finite, traced
from .._core.errors import ConstraintError, NonFiniteError
from .._core.linalg import PIVOT_RTOL
from .interfaces import Constrained


def checked_kkt(system: Constrained, q, qd, params, tau, t, what: str):
    """`(q̈, (λ, μ))` of a state, checked: eagerly, the error that names the cause;
    under `jit`, a run-time error."""
    q, qd, tau = system._state(q, qd, tau=tau)
    if not traced(system, q, qd, tau, params, t):
        finite(q, "q")
        finite(qd, "qd")
        if tau is not None:
            finite(tau, "tau")
        qdd, lam = system._kkt(t, q, qd, params, tau)
        if not bool(jnp.all(jnp.isfinite(qdd)) & jnp.all(jnp.isfinite(lam))):
            system.check_state(q, qd, params, project=False, t=t)  # raises: the cause
            raise NonFiniteError(
                f"{what} of {system.name} is not finite at q={np.asarray(q)}, "
                f"qd={np.asarray(qd)} although M(q) is positive-definite and {k_name(system)} has "
                "full rank: check the force, dissipation, tau and the constraint "
                "function's derivatives there"
            )
        return qdd, lam
    qdd, lam = system._kkt(t, q, qd, params, tau)
    bad = ~(jnp.all(jnp.isfinite(qdd)) & jnp.all(jnp.isfinite(lam)))
    return eqx.error_if(
        (qdd, lam),
        bad,
        f"{what} of {system.name} is non-finite: q, qd, tau or params contain NaN/inf, "
        f"M(q) is not positive-definite, or {k_name(system)} is "
        "rank-deficient (redundant constraints or a singular configuration, so the "
        f"KKT matrix [[M, K^T], [K, 0]] with K = {k_symbol(system)} is singular). Outside "
        "jit the message names which.",
    )


def rank_message(system: Constrained, q, params) -> str | None:
    """A description of a rank-deficient `K = [J; A]` at `q` (`None` if it has
    full rank)."""
    jac = np.asarray(system._kmat(jnp.asarray(q), params))
    mass = np.asarray(system.system.mass_matrix(q, params))
    m, n = jac.shape
    sv = np.linalg.svd(jac, compute_uv=False) if jac.size else np.zeros(0)
    schur = jac @ np.linalg.solve(mass, jac.T)
    eigs = np.linalg.eigvalsh(0.5 * (schur + schur.T)) if m else np.zeros(0)
    tol = PIVOT_RTOL * np.finfo(jac.dtype).eps
    if m <= n and (m == 0 or eigs[0] > tol * max(np.max(np.abs(np.diag(schur))), 1e-300)):
        return None
    why = (
        f"there are more constraints (m={m}) than coordinates (n={n})"
        if m > n
        else "the constraints are redundant (remove the dependent ones) or q is a "
        "singular configuration of the mechanism (e.g. a linkage at a change point, "
        "links aligned)"
    )
    if system.velocity_constraints is None:
        return (
            f"the constraint Jacobian J = dphi/dq of {system.name} is rank-deficient at "
            f"q={np.asarray(q)} (shape {jac.shape}, singular values {sv}), so the KKT "
            f"matrix [[M, J^T], [J, 0]] is singular: {why}"
        )
    m1 = int(system._phi(jnp.asarray(q), params).shape[0])
    return (
        f"{k_name(system)} of {system.name} is rank-deficient at q={np.asarray(q)} (shape "
        f"{jac.shape}: {m1} holonomic and {m - m1} velocity rows; singular values "
        f"{sv}), so the KKT matrix [[M, K^T], [K, 0]] is singular: {why}"
    )


def k_symbol(system: Constrained) -> str:
    """How messages write the constraint matrix `K`: `J`, `A` or `[J; A]`."""
    if system.velocity_constraints is None:
        return "J"
    return "A" if system.constraints is None else "[J; A]"


def k_name(system: Constrained) -> str:
    """How messages name the constraint matrix `K`."""
    if system.velocity_constraints is None:
        return "the constraint Jacobian J = dphi/dq"
    if system.constraints is None:
        return "the velocity constraint matrix A(q)"
    return "the constraint matrix K = [J; A] (J = dphi/dq, A the velocity constraints)"


def check_state(system: Constrained, q, qd, params, project, t) -> None:
    """`ConstrainedSystem.check_state` (documented there)."""
    eager_only(f"check_state of {system.name}", system, q, qd, params, t)
    system.system.check_state(q, qd, params, t=t)
    q, qd = system._state(q, qd)
    phi = system._phi(q, params)
    finite(phi, "the constraint values phi(q)")
    if system.velocity_constraints is not None:
        finite(system._amat(q, params), f"the velocity constraint matrix A(q) at q={q}")
    if system.project_initial if project is None else project:
        q, qd = system.project(q, qd, params)
    message = rank_message(system, q, params)
    if message is not None:
        raise ConstraintError(message)
