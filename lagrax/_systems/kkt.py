"""The KKT system of a constrained solve, `[[M, Kᵀ], [K, 0]] (q̈, −λ) = (f, γ)`: its
Schur-complement solve and the tangent rule that differentiates through it at the
primal solution."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from .._core.custom_types import ConstraintJacobian, ConstraintValues, Matrix, Vector
from .._core.linalg import cholesky_solve, spd_inverse
from . import derivatives as d
from . import implicit
from .interfaces import Constrained


def solve_kkt(mass: Matrix, jac: ConstraintJacobian, force: Vector, gamma: ConstraintValues):
    r"""Solve `[[M, Jᵀ], [J, 0]] [x; −λ] = [f; γ]` for `(x, λ)` by the Schur complement.

    `M x = f + Jᵀ λ` and `J x = γ` give `λ = S⁻¹(γ − J M⁻¹ f)` with the Schur
    complement `S = J M⁻¹ Jᵀ` and `x = M⁻¹(f + Jᵀ λ)`: one Cholesky factorization of
    `M` (shared by the `1 + m` right-hand sides) and one of `S`. `S` is
    positive-definite exactly when `M` is and `J` has full row rank; otherwise (a
    Cholesky pivot below `64 ε` relative to the largest diagonal entry) the result is
    NaN, never a finite wrong answer.
    """
    cols = jnp.concatenate([force[:, None], jac.T], axis=1)
    sol = jax.vmap(lambda b: cholesky_solve(mass, b), in_axes=1, out_axes=1)(cols)
    x_free, m_inv_jt = sol[:, 0], sol[:, 1:]
    schur = jac @ m_inv_jt
    schur = 0.5 * (schur + schur.T)
    lam = cholesky_solve(schur, gamma - jac @ x_free)
    return x_free + m_inv_jt @ lam, lam


@eqx.filter_custom_jvp
def kkt_with_rule(system: Constrained, t, q, qd, params, tau):
    return system._kkt_raw(t, q, qd, params, tau)


@kkt_with_rule.def_jvp
def _kkt_tangent(primals, tangents):
    r"""The tangent of `(q̈, λ)` through the KKT system: with the residual
    `R = (r(q̈) − τ − Kᵀλ, K q̈ − γ)` (`r` the system's inverse dynamics less its applied
    forces), `[[M, −Kᵀ], [K, 0]] (δq̈, δλ) = −∂R/∂(t, q, q̇, p, τ) δ(t, q, q̇, p, τ)`, solved
    as the primal is (`solve_kkt`) at the primal `(q̈, λ)`."""
    system, t, q, qd, params, tau = primals
    _, dt, dq, dqd, dparams, dtau = tangents
    qdd, lam = system._kkt_raw(t, q, qd, params, tau)
    inner = system.system
    mass = d.mass_matrix(inner, q, qd, params, t)
    kmat, _ = system._rows(q, qd, params)

    def constrained_residual(s, a, b, p):
        k_a, gamma = system._rows(a, b, p)
        top = implicit.residual(inner, s, a, b, qdd, p) - k_a.T @ lam
        return top, k_a @ qdd - gamma

    dres = implicit.jvp_of_given(constrained_residual, (t, q, qd, params), (dt, dq, dqd, dparams))
    top = jnp.zeros_like(qdd) if dtau is None else dtau.astype(qdd.dtype)
    bottom = jnp.zeros_like(lam)
    if dres is not None:
        top, bottom = top - dres[0], bottom - dres[1]
    # linear in (top, bottom): every matrix below is formed from the primal values only
    m_inv = spd_inverse(mass)
    m_inv_kt = m_inv @ kmat.T.astype(m_inv.dtype)
    s_inv = spd_inverse(0.5 * (kmat @ m_inv_kt + (kmat @ m_inv_kt).T))
    free = m_inv @ top
    dlam = s_inv @ (bottom - kmat @ free)
    return (qdd, lam), (free + m_inv_kt @ dlam, dlam)
