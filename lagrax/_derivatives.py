"""The derivative kernels every system kind shares: ``M``, the bias force, ``∂V/∂q`` …

They take the energies (any object with ``kinetic``, ``potential``, ``dissipation`` and
``force`` attributes, e.g. a ``LagrangianSystem``) and ``params``, never a system class,
so that every system module can call them without importing another.

With ``L = T − V``, generalized inputs ``τ``, an applied force ``F(t, q, q̇)`` and a
Rayleigh dissipation ``D(q, q̇)``, the equations of motion are ``M(q) q̈ = f`` with
``M = ∂²T/∂q̇²`` and ``f = ∂L/∂q − (∂²L/∂q̇∂q) q̇ + τ + F − ∂D/∂q̇``.
"""

from collections.abc import Callable
from typing import Any, Protocol

import jax
import jax.numpy as jnp
import numpy as np

from ._checks import call_user, clamped_reads, energy_value, force_value
from ._linalg import cholesky_solve, solve_spd_unrolled

# Up to this many coordinates, the equations use scalar forward-over-forward derivatives.
FOF_MAX = 6


class Equations(Protocol):
    """A structure-aware evaluation of the equations of the same ``T`` and ``V`` (a chain's
    recursions): ``M``, ``q̈`` for a generalized force, and ``M q̈ + C q̇ + G``."""

    def mass_matrix(self, q: Any, params: Any) -> Any: ...
    def mass_and_bias(self, q: Any, qd: Any, params: Any) -> tuple[Any, Any]: ...
    def accelerations(self, q: Any, qd: Any, params: Any, force: Any) -> Any: ...
    def inverse_dynamics(self, q: Any, qd: Any, qdd: Any, params: Any) -> Any: ...


class Energies(Protocol):
    """What the kernels read: the user's energy and force functions (or ``None``), and
    optionally structure-aware ``equations`` of the same energies."""

    kinetic: Callable[..., Any]
    potential: Callable[..., Any] | None
    dissipation: Callable[..., Any] | None
    force: Callable[..., Any] | None
    equations: Equations | None


def use_scalar(n: int, scalar_derivatives: bool | None) -> bool:
    """Scalar forward-over-forward for ``n <= FOF_MAX`` unless the system says otherwise."""
    return n <= FOF_MAX if scalar_derivatives is None else scalar_derivatives


# What the messages call each user function.
KINETIC = "kinetic energy function T(q, qd, params)"
POTENTIAL = "potential energy function V(q, params)"
DISSIPATION = "dissipation function D(q, qd, params)"
FORCE = "force function F(t, q, qd, params)"


def kinetic(e: Energies, q, qd, params):
    """``T(q, q̇)``, checked (at trace time) to be a real scalar reading ``q``, ``q̇`` in
    range."""
    clamped_reads(e.kinetic, KINETIC, params, q, qd)
    return energy_value(call_user(e.kinetic, "kinetic energy", params, q, qd), KINETIC, q)


def potential(e: Energies, q, params):
    """``V(q)`` (zero when the system has no potential)."""
    if e.potential is None:
        return jnp.zeros((), q.dtype)
    clamped_reads(e.potential, POTENTIAL, params, q)
    return energy_value(call_user(e.potential, "potential energy", params, q), POTENTIAL, q)


def lagrangian(e: Energies, q, qd, params):
    """``L = T − V``."""
    return kinetic(e, q, qd, params) - potential(e, q, params)


def grad_kinetic(e: Energies, q, qd, params):
    """``(∂T/∂q, ∂T/∂q̇)`` in one reverse pass."""
    return jax.grad(lambda a, b: kinetic(e, a, b, params), argnums=(0, 1))(q, qd)


def mass_columns(e: Energies, q, qd, params, extra_q_tangent=None):
    """Forward-over-reverse: ``M = ∂p/∂q̇`` column by column, plus optionally
    ``(∂p/∂q) v`` for a tangent ``v`` in ``q``; returns ``(∂T/∂q, p, M, (∂p/∂q) v)``.

    All tangents go through one vmapped JVP of the gradient of ``T``.
    """
    n = q.shape[0]
    eye = jnp.eye(n, dtype=q.dtype)
    tq = jnp.zeros((n, n), q.dtype)
    if extra_q_tangent is not None:
        tq = jnp.concatenate([tq, extra_q_tangent[None]], axis=0)
        eye = jnp.concatenate([eye, jnp.zeros((1, n), q.dtype)], axis=0)

    def along(dq, dqd):
        return jax.jvp(lambda a, b: grad_kinetic(e, a, b, params), (q, qd), (dq, dqd))

    (tq_grad, p), (_, dp) = jax.vmap(along)(tq, eye)
    tq_grad, p = tq_grad[0], p[0]
    mass = dp[:n].T
    extra = dp[n] if extra_q_tangent is not None else None
    return tq_grad, p, mass, extra


def mass_matrix(e: Energies, q, qd, params):
    """``M(q) = ∂²T/∂q̇²`` (``n`` JVPs of ``∂T/∂q̇``, or the structure-aware ``equations``)."""
    if e.equations is not None:
        return e.equations.mass_matrix(q, params)
    return mass_columns(e, q, qd, params)[2]


def coriolis(e: Energies, q, qd, params):
    """``C(q, q̇) q̇ = (∂²T/∂q̇∂q) q̇ − ∂T/∂q``: one JVP along ``(q̇, 0)``."""
    (t_q, _), (_, dp) = jax.jvp(lambda a: grad_kinetic(e, a, qd, params), (q,), (qd,))
    return dp - t_q


def gravity(e: Energies, q, params):
    """``G(q) = ∂V/∂q``."""
    if e.potential is None:
        return jnp.zeros_like(q)
    return jax.grad(lambda a: potential(e, a, params))(q)


def damping(e: Energies, q, qd, params):
    """``∂D/∂q̇`` (the force acting is its negative)."""
    if e.dissipation is None:
        return jnp.zeros_like(q)
    clamped_reads(e.dissipation, DISSIPATION, params, q, qd)

    def dissipation(b):
        return energy_value(call_user(e.dissipation, "dissipation", params, q, b), DISSIPATION, q)

    return jax.grad(dissipation)(qd)


def applied(e: Energies, t, q, qd, params, tau):
    """Right-hand generalized force ``τ + F(t, q, q̇) − ∂D/∂q̇`` (without potential)."""
    f = -damping(e, q, qd, params)
    if tau is not None:
        f = f + tau
    if e.force is not None:
        clamped_reads(e.force, FORCE, params, t, q, qd)
        out = call_user(e.force, "force", params, t, q, qd)
        f = f + force_value(out, f"the {FORCE}", q)
    return f


def eom_small(e: Energies, q, qd, params):
    """``M`` and ``∂L/∂q − (∂²L/∂q̇∂q) q̇`` as lists of scalars, by scalar
    forward-over-forward derivatives.

    For small ``n`` this beats forward-over-reverse: every derivative is a straight
    line of scalar arithmetic on the primal values, which XLA fuses into one loop with
    each transcendental evaluated once. It costs ``n(n+1)/2 + n`` second-order and
    ``n`` first-order directional derivatives of ``L``, so it is used for
    ``n <= FOF_MAX`` only (see :func:`use_scalar`).
    """
    n = q.shape[0]
    basis = [jnp.asarray(np.eye(n)[i], q.dtype) for i in range(n)]
    zero = jnp.zeros_like(q)

    def lag(a, b):
        return lagrangian(e, a, b, params)

    def p_i(i):  # q, q̇ -> ∂L/∂q̇_i
        return lambda a, b: jax.jvp(lag, (a, b), (zero, basis[i]))[1]

    rows = [[None] * n for _ in range(n)]
    rhs = []
    for i in range(n):
        for j in range(i, n):
            mij = jax.jvp(lambda b, i=i: p_i(i)(q, b), (qd,), (basis[j],))[1]
            rows[i][j] = rows[j][i] = mij
        l_q = jax.jvp(lag, (q, qd), (basis[i], zero))[1]
        mixed = jax.jvp(lambda a, i=i: p_i(i)(a, qd), (q,), (qd,))[1]
        rhs.append(l_q - mixed)
    return rows, rhs


def _has_applied(e: Energies, tau) -> bool:
    return tau is not None or e.force is not None or e.dissipation is not None


def mass_and_force(e: Energies, scalar: bool | None, t, q, qd, params, tau):
    """``M(q)`` and ``f = τ + F − C q̇ − G − ∂D/∂q̇``: the equations ``M q̈ = f``.

    ``scalar`` chooses the derivatives as :func:`use_scalar` does; structure-aware
    ``equations`` take precedence.
    """
    f_applied = applied(e, t, q, qd, params, tau)
    if e.equations is not None:
        mass, bias = e.equations.mass_and_bias(q, qd, params)
        return mass, f_applied - bias
    if use_scalar(q.shape[0], scalar):
        rows, rhs = eom_small(e, q, qd, params)
        mass = jnp.stack([jnp.stack(row) for row in rows])
        return mass, jnp.stack(rhs) + f_applied
    t_q, _, mass, dp_q = mass_columns(e, q, qd, params, extra_q_tangent=qd)
    return mass, t_q - dp_q - gravity(e, q, params) + f_applied


def accelerations(e: Energies, scalar: bool | None, t, q, qd, params, tau):
    """``q̈ = M⁻¹ f`` without raising: NaN where ``M`` is not positive-definite.

    The scalar path solves with a Cholesky factorization unrolled over the scalars (no
    matrix is stacked); the vector path with a Cholesky factorization of ``M``.
    Structure-aware ``equations`` (a chain's articulated-body algorithm) take precedence.
    """
    if e.equations is not None:
        f = applied(e, t, q, qd, params, tau) if _has_applied(e, tau) else None
        return e.equations.accelerations(q, qd, params, f)
    if use_scalar(q.shape[0], scalar):
        rows, rhs = eom_small(e, q, qd, params)
        if _has_applied(e, tau):
            f_applied = applied(e, t, q, qd, params, tau)
            rhs = [r + f_applied[i] for i, r in enumerate(rhs)]
        return solve_spd_unrolled(rows, rhs)
    return cholesky_solve(*mass_and_force(e, scalar, t, q, qd, params, tau))
