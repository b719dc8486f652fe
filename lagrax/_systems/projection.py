"""Projecting a state of a `ConstrainedSystem` onto its constraints: Newton's method
on `φ(q) = 0` in the kinetic metric, then the `M`-orthogonal projection of `q̇` onto
`K q̇ = 0` (`K = [J; A]`), with the message that says why a projection failed."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.checks import finite, traced
from .._core.errors import ConstraintError
from . import derivatives as d
from .constraint_checks import rank_message
from .interfaces import Constrained
from .kkt import solve_kkt

# Newton iterations to project a state onto φ(q) = 0 (quadratic convergence: a start
# within the basin needs a handful).
PROJECTION_ITERS = 30


def project_state(system: Constrained, q, qd, params):
    """Project `(q, q̇)` onto `φ = 0`, `J q̇ = 0`, `A q̇ = 0` without raising.

    Returns `(q, q̇, ok)`; when `ok` is false, the returned state is the
    input state unchanged (finite, so a solve from it still runs and is flagged).
    """
    q0, qd0 = q, qd
    dtype = q.dtype
    eps = float(jnp.finfo(dtype).eps)
    zero = jnp.zeros_like(qd)
    # M(q0): a fixed SPD metric (the projection has no time: a time-dependent system's
    # M(t, q) is taken at t = 0, which changes the metric, not the manifold)
    t0 = jnp.zeros((), dtype)
    metric = _mass(system, q0, zero, params, t0)

    def newton_step(a):
        phi = system._phi(a, params)
        jac = system._jacobian(a, params)
        # minimal-norm step in the metric M(q0): Δq = −M⁻¹Jᵀ (J M⁻¹ Jᵀ)⁻¹ φ
        return solve_kkt(metric, jac, zero, -phi)[0]

    def body(_, carry):
        # a step Δv on the velocities moves q along N(q) Δv, then back on its manifold
        # (a floating base's quaternion; q + Δv for an ordinary system)
        a, _ = carry
        step = newton_step(a)
        moved = system.project_configuration(a + system.configuration_rate(a, step))
        return moved, step

    if system.constraints is None:  # velocity constraints only: q is admissible as is
        q1, q_ok = q0, jnp.asarray(True)
    else:
        # a fixed number of iterations (a scan, so reverse-mode differentiable); after
        # convergence the steps are round-off sized and change nothing
        init = (q0, zero)
        q1, step = jax.lax.fori_loop(0, PROJECTION_ITERS, body, init)
        scale = 1.0 + jnp.max(jnp.abs(q1))
        q_ok = jnp.all(jnp.isfinite(q1)) & (jnp.max(jnp.abs(step)) <= eps**0.5 * scale)
    # velocities: the M(q)-orthogonal projection onto K q̇ = 0, K = [J; A] (what an
    # impulsive constraint would do: the admissible velocity of least kinetic-energy
    # change)
    q1_safe = jnp.where(q_ok, q1, q0)
    mass = _mass(system, q1_safe, zero, params, t0)
    kmat = system._kmat(q1_safe, params)
    qd1 = qd0 + solve_kkt(mass, kmat, zero, -(kmat @ qd0))[0]
    ok = q_ok & jnp.all(jnp.isfinite(qd1))
    return jnp.where(ok, q1, q0), jnp.where(ok, qd1, qd0), ok


def _mass(system: Constrained, q, zero, params, t0):
    """`M(q)` of the constrained system's system (at `t = 0`)."""
    if system._manifold:  # a floating base, a forest: its own mass matrix
        return system.system.mass_matrix(q, params)
    return d.mass_matrix(system.system, q, zero, params, t0)


def project(system: Constrained, q, qd, params):
    """`ConstrainedSystem.project` of checked 1-D arrays (documented there)."""
    q, qd = system._state(q, qd)
    if traced(system, q, qd, params):
        q1, qd1, ok = project_state(system, q, qd, params)
        return eqx.error_if(
            (q1, qd1),
            ~ok,
            f"could not project the state of {system.name} onto its constraints "
            "phi(q) = 0 (no convergence, or a rank-deficient constraint Jacobian); "
            "call project outside jit for a diagnosis",
        )
    finite(q, "q")
    finite(qd, "qd")
    q1, qd1, ok = _project_jit(system, q, qd, params)
    if not bool(ok):
        raise ConstraintError(projection_message(system, q, params))
    return q1, qd1


def projection_message(system: Constrained, q, params) -> str:
    """Why a state could not be projected: a rank-deficient `K`, else no convergence."""
    head = f"could not project the state of {system.name} onto its constraints"
    rank = rank_message(system, q, params)
    if rank is not None:
        return f"{head}: at the initial q, {rank}"
    phi = np.asarray(system._phi(q, params))
    return (
        f"{head}: Newton's method did not converge in {PROJECTION_ITERS} iterations from "
        f"q={np.asarray(q)} (|phi(q)| = {np.max(np.abs(phi)):.3g} there; phi = {phi}), "
        "or met a configuration where J = dphi/dq is rank-deficient. The constraints "
        "may have no solution near this q (check the lengths/parameters and the "
        "constraint function) or the start is too far from one: start from an "
        "(approximately) consistent configuration."
    )


@eqx.filter_jit
def _project_jit(system: Constrained, q, qd, params):
    return project_state(system, q, qd, params)
