r"""The derivatives of the forward and inverse dynamics at one state, in one call
(in the spirit of Pinocchio's `computeABADerivatives` and `computeRNEADerivatives`).

With the residual `r(t, q, q̇, q̈, p) = M q̈ + C q̇ + G + ∂D/∂q̇ − F` of `implicit`:

- inverse dynamics `τ = r`: `∂τ/∂q`, `∂τ/∂q̇`, `∂τ/∂q̈ = M` and `∂τ/∂p`;
- forward dynamics `q̈ = FD(t, q, q̇, p, τ)`: `∂q̈/∂q = −M⁻¹ ∂r/∂q`,
  `∂q̈/∂q̇ = −M⁻¹ ∂r/∂q̇`, `∂q̈/∂τ = M⁻¹` and `∂q̈/∂p = −M⁻¹ ∂r/∂p`.

`∂r/∂q`, `∂r/∂q̇` and `M` come from the same place as the tangents of the accelerations
(`implicit.residual_jacobians`: analytic recursions for chains and trees), so one call costs
about what one Jacobian-vector product of the accelerations does plus `n³/2` for `M⁻¹`.
"""

from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from .._core.custom_types import Matrix, Params, Vector
from .._core.linalg import cholesky_solve_many, spd_inverse
from . import derivatives as d
from . import implicit


class ForwardDynamicsDerivatives(eqx.Module):
    """The accelerations `q̈ = FD(q, q̇, τ; params)` at one state and their derivatives.

    **Fields:**

    - `qdd`: `q̈`, shape `(n,)`.
    - `dq`: `∂q̈/∂q`, shape `(n, n)` (`dq[i, j] = ∂q̈_i/∂q_j`).
    - `dqd`: `∂q̈/∂q̇`, shape `(n, n)`.
    - `dtau`: `∂q̈/∂τ = M⁻¹`, shape `(n, n)`.
    - `dparams`: `∂q̈/∂params`, a pytree of `params`' structure whose leaves have shape
      `(n, *leaf.shape)`; `None` unless asked for (`wrt_params=True`).
    """

    qdd: Vector
    dq: Matrix
    dqd: Matrix
    dtau: Matrix
    dparams: Any = None


class InverseDynamicsDerivatives(eqx.Module):
    """The inputs `τ = ID(q, q̇, q̈; params)` at one state and their derivatives.

    **Fields:**

    - `tau`: `τ = M q̈ + C q̇ + G + ∂D/∂q̇ − F`, shape `(n,)`.
    - `dq`: `∂τ/∂q`, shape `(n, n)`.
    - `dqd`: `∂τ/∂q̇`, shape `(n, n)`.
    - `dqdd`: `∂τ/∂q̈ = M(q)`, shape `(n, n)`.
    - `dparams`: `∂τ/∂params` (leaves of shape `(n, *leaf.shape)`), or `None` unless
      asked for (`wrt_params=True`). `τ` is linear in the masses and inertias: these are
      the columns of the regressor of identification.
    """

    tau: Vector
    dq: Matrix
    dqd: Matrix
    dqdd: Matrix
    dparams: Any = None


_ONE_STATE_LAPACK_ABOVE = 3  # below, the written-out inverse compiles as fast


def jacobian_wrt_params(fn, params: Params) -> Any:
    """`∂fn/∂params` leaf by leaf (forward mode; leaves that are not inexact arrays get
    `None`), each of shape `(n, *leaf.shape)`."""
    dynamic, static = eqx.partition(params, eqx.is_inexact_array)
    return jax.jacfwd(lambda p: fn(eqx.combine(p, static)))(dynamic)


def forward(
    e: d.Energies,
    scalar: bool | None,
    t,
    q,
    qd,
    params: Params,
    tau,
    wrt_params: bool,
    one_state: bool = False,
):
    """[`ForwardDynamicsDerivatives`][lagrax.ForwardDynamicsDerivatives] of a system given by
    its energies (or structure-aware equations), at checked 1-D arrays; NaN where `M` is
    not positive-definite.

    `one_state=True` (a program for one state, such as `linearize`'s) applies `M⁻¹` by one
    LAPACK factorization and solve for all `3n` columns, which compiles in a fraction of
    the written-out inverse's time (0.35 s for `n = 7`); the written-out inverse is the
    faster of the two under `vmap` over many states.
    """
    if e.equations is not None:  # one evaluation of the structure's kinematics
        qdd, jq, jqd, mass = implicit.primal_and_jacobians(e, t, q, qd, params, tau)
    else:
        qdd = implicit.accelerations(e, scalar, t, q, qd, params, tau)
        jq, jqd, mass = implicit.residual_jacobians(e, scalar, t, q, qd, qdd, params)
    dparams = None
    if wrt_params:
        dparams = jacobian_wrt_params(
            lambda p: implicit.accelerations(e, scalar, t, q, qd, p, tau), params
        )
    n = q.shape[0]
    lapack = one_state and n > _ONE_STATE_LAPACK_ABOVE
    if lapack or (e.equations is None and d.use_scalar(n, scalar)):
        # M⁻¹ [−∂r/∂q, −∂r/∂q̇, I] by solves: one LAPACK call for all 3n columns, or the
        # scalar path's written-out solve with the columns vectorized through it, on `M`'s
        # entries as scalars (as the accelerations' tangents solve; the entries read back
        # out of the stacked `M` ran 15 % slower: 0.30 against 0.26 µs for the 2R arm)
        if lapack:
            return by_solves(qdd, jq, jqd, mass, dparams)

        def scalar_solve(_, rhs):  # `M`'s entries as the scalars they were computed as
            rows, _ = d.eom_small(e, q, qd, params, t)
            return jax.vmap(
                lambda b: jnp.stack(d.solve_spd_unrolled(rows, [b[i] for i in range(n)])),
                in_axes=1,
                out_axes=1,
            )(rhs)

        return by_solves(qdd, jq, jqd, mass, dparams, scalar_solve)
    m_inv = spd_inverse(mass)
    mm = implicit.matmul(e)
    return ForwardDynamicsDerivatives(qdd, -mm(m_inv, jq), -mm(m_inv, jqd), m_inv, dparams)


def by_solves(
    qdd, jq, jqd, mass, dparams: Any = None, solve: Callable = cholesky_solve_many
) -> ForwardDynamicsDerivatives:
    """[`ForwardDynamicsDerivatives`][lagrax.ForwardDynamicsDerivatives] from `q̈`,
    `∂r/∂q`, `∂r/∂q̇` and `M`: `M⁻¹ [−∂r/∂q, −∂r/∂q̇, I]` by one `solve(M, rhs)` of all
    `3n` columns (by default one LAPACK factorization)."""
    n = qdd.shape[0]
    rhs = jnp.concatenate([-jq, -jqd, jnp.eye(n, dtype=mass.dtype)], axis=1)
    cols = solve(mass, rhs)
    return ForwardDynamicsDerivatives(
        qdd, cols[:, :n], cols[:, n : 2 * n], cols[:, 2 * n :], dparams
    )


def forward_by_inverse_jacobians(
    accelerations: Callable, jacobians: Callable, params: Params, wrt_params: bool
) -> ForwardDynamicsDerivatives:
    """The forward dynamics' derivatives of a system whose inverse dynamics has analytic
    derivatives: `v̇ = accelerations(params)`, `(τ, ∂τ/∂q, ∂τ/∂v, M) = jacobians(v̇)` at
    that primal `v̇`, then `by_solves`; `∂v̇/∂params` (with `wrt_params`) by forward mode
    through `accelerations`."""
    vdot = accelerations(params)
    _, jq, jv, mass = jacobians(vdot)
    dparams = jacobian_wrt_params(accelerations, params) if wrt_params else None
    return by_solves(vdot, jq, jv, mass, dparams)


def inverse_by_jacobians(
    inverse: Callable, jacobians: Callable, vdot, params: Params, wrt_params: bool
) -> InverseDynamicsDerivatives:
    """The inverse dynamics' derivatives from `(τ, ∂τ/∂q, ∂τ/∂v, M) = jacobians(v̇)`;
    `∂τ/∂params` (with `wrt_params`) by forward mode through `inverse(params)`."""
    tau, jq, jv, mass = jacobians(vdot)
    dparams = jacobian_wrt_params(inverse, params) if wrt_params else None
    return InverseDynamicsDerivatives(tau, jq, jv, mass, dparams)


def inverse(e: d.Energies, scalar: bool | None, t, q, qd, qdd, params: Params, wrt_params: bool):
    """[`InverseDynamicsDerivatives`][lagrax.InverseDynamicsDerivatives] at checked 1-D
    arrays."""
    tau = implicit.residual(e, t, q, qd, qdd, params)
    jq, jqd, mass = implicit.residual_jacobians(e, scalar, t, q, qd, qdd, params)
    dparams = None
    if wrt_params:
        dparams = jacobian_wrt_params(lambda p: implicit.residual(e, t, q, qd, qdd, p), params)
    return InverseDynamicsDerivatives(tau, jq, jqd, mass, dparams)


def forward_by_jacobian(accelerations, q, qd, tau, params: Params, wrt_params: bool):
    """[`ForwardDynamicsDerivatives`][lagrax.ForwardDynamicsDerivatives] of any
    `accelerations(q, qd, tau, params)` by one `jax.linearize` and the `3n` basis tangents
    (a constrained system's, whose tangents go through its KKT system)."""
    n = q.shape[0]
    qdd, lin = jax.linearize(lambda a, b, c: accelerations(a, b, c, params), q, qd, tau)
    eye = jnp.eye(n, dtype=qdd.dtype)
    zero = jnp.zeros((n, n), qdd.dtype)
    dq = jax.vmap(lin, in_axes=(1, 1, 1), out_axes=1)(eye, zero, zero)
    dqd = jax.vmap(lin, in_axes=(1, 1, 1), out_axes=1)(zero, eye, zero)
    dtau = jax.vmap(lin, in_axes=(1, 1, 1), out_axes=1)(zero, zero, eye)
    dparams = None
    if wrt_params:
        dparams = jacobian_wrt_params(lambda p: accelerations(q, qd, tau, p), params)
    return ForwardDynamicsDerivatives(qdd, dq, dqd, dtau, dparams)
