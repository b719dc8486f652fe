"""The derivative kernels every system kind shares: `M`, the bias force, `∂V/∂q` …

They take the energies (any object with `kinetic`, `potential`, `dissipation` and
`force` attributes, e.g. a `LagrangianSystem`) and `params`, never a system class,
so that every system module can call them without importing another.

With `L = T − V`, generalized inputs `τ`, an applied force `F(t, q, q̇)` and a
Rayleigh dissipation `D(q, q̇)`, the equations of motion are `M(q) q̈ = f` with
`M = ∂²T/∂q̇²` and `f = ∂L/∂q − (∂²L/∂q̇∂q) q̇ + τ + F − ∂D/∂q̇`.

A time-dependent system (`e.time_dependent`) has `T(t, q, q̇)`, `V(t, q)`,
`D(t, q, q̇)`: every kernel then takes the time `t` and `f` gains `−∂²L/∂q̇∂t`.
For an autonomous system `t` is ignored and the kernels trace exactly the code they
traced before time-dependent systems existed.
"""

import abc
from collections.abc import Callable
from typing import Any, Protocol

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.checks import call_energy, call_user, energy_value, force_value
from .._core.clamped_reads import clamped_reads
from .._core.errors import ArgumentTypeError
from .._core.linalg import cholesky_solve, solve_spd_unrolled

# Up to this many coordinates, the equations use scalar forward-over-forward derivatives.
FOF_MAX = 6


class AbstractEquations(eqx.Module):
    """A structure-aware evaluation of the equations of the same `T` and `V` (a chain's
    recursions, a scene's pose maps): `M`, `q̈` for a generalized force, `M q̈ + C q̇ + G`
    and its derivatives, and `(T, V)` where the structure gives them more cheaply than
    the energy functions (see `structured_energies`)."""

    @abc.abstractmethod
    def mass_matrix(self, q: Any, params: Any) -> Any:
        """`M(q)`."""

    @abc.abstractmethod
    def mass_and_bias(self, q: Any, qd: Any, params: Any) -> tuple[Any, Any]:
        """`M` and the bias `C q̇ + G`."""

    @abc.abstractmethod
    def accelerations(self, q: Any, qd: Any, params: Any, force: Any) -> Any:
        """`q̈` solving `M q̈ + C q̇ + G = force` (`None`: zero)."""

    @abc.abstractmethod
    def inverse_dynamics(self, q: Any, qd: Any, qdd: Any, params: Any) -> Any:
        """`M q̈ + C q̇ + G` (`qdd=None`: the bias)."""

    @abc.abstractmethod
    def derivatives(self, q: Any, qd: Any, qdd: Any, params: Any) -> tuple[Any, Any, Any]:
        """`(∂τ/∂q, ∂τ/∂q̇, M)` of `τ = M q̈ + C q̇ + G`."""

    @abc.abstractmethod
    def energies(self, q: Any, qd: Any, params: Any) -> tuple[Any, Any] | None:
        """`(T, V)` from the structure, or `None`: from the energy functions."""

    def accelerations_and_derivatives(
        self, q: Any, qd: Any, params: Any, force: Any
    ) -> tuple[Any, Any, Any, Any]:
        """`(q̈, ∂τ/∂q, ∂τ/∂q̇, M)`: `accelerations`, then `derivatives` at that `q̈` (what
        the custom JVP of the accelerations needs; a chain shares its kinematics)."""
        qdd = self.accelerations(q, qd, params, force)
        return (qdd, *self.derivatives(q, qd, qdd, params))

    def blocks(self) -> tuple[int | None, int | None]:
        """States per block of a large vmapped batch (`lagrax._core.blocking`) for the
        accelerations and for their derivatives; `None`: not blocked."""
        return None, None


class Energies(Protocol):
    """What the kernels read: the user's energy and force functions (or `None`), and
    optionally structure-aware `equations` of the same energies."""

    kinetic: Callable[..., Any]
    potential: Callable[..., Any] | None
    dissipation: Callable[..., Any] | None
    force: Callable[..., Any] | None
    equations: AbstractEquations | None
    time_dependent: bool


def timed(e: Energies) -> bool:
    """Whether the energies take the time first: `T(t, q, q̇)`, `V(t, q)`, `D(t, q, q̇)`."""
    return e.time_dependent


def time_of(t, q):
    """The time as a scalar array of `q`'s dtype (what a time-dependent energy receives)."""
    if t is None:
        raise ArgumentTypeError("internal error: a time-dependent system's kernel needs the time t")
    return jnp.asarray(t, q.dtype)


def _with_time(e: Energies, t, q, *args):
    """The arguments of a user energy before `params`: `(t, q, …)` when time-dependent."""
    return (time_of(t, q), q, *args) if timed(e) else (q, *args)


def use_scalar(n: int, scalar_derivatives: bool | None) -> bool:
    """Scalar forward-over-forward for `n <= FOF_MAX` unless the system says otherwise."""
    return n <= FOF_MAX if scalar_derivatives is None else scalar_derivatives


# What the messages call each user function.
KINETIC = "kinetic energy function T(q, qd, params)"
POTENTIAL = "potential energy function V(q, params)"
DISSIPATION = "dissipation function D(q, qd, params)"
FORCE = "force function F(t, q, qd, params)"
# ... and of a time-dependent system
KINETIC_T = "kinetic energy function T(t, q, qd, params)"
POTENTIAL_T = "potential energy function V(t, q, params)"
DISSIPATION_T = "dissipation function D(t, q, qd, params)"


def kinetic(e: Energies, q, qd, params, t=None):
    """`T(q, q̇)` (`T(t, q, q̇)`), checked (at trace time) to be a real scalar reading
    `q`, `q̇` in range."""
    label = KINETIC_T if timed(e) else KINETIC
    args = _with_time(e, t, q, qd)
    clamped_reads(e.kinetic, label, params, *args)
    return energy_value(call_energy(e.kinetic, "kinetic energy", label, params, *args), label, q)


def potential(e: Energies, q, params, t=None):
    """`V(q)` (`V(t, q)`; zero when the system has no potential)."""
    if e.potential is None:
        return jnp.zeros((), q.dtype)
    label = POTENTIAL_T if timed(e) else POTENTIAL
    args = _with_time(e, t, q)
    clamped_reads(e.potential, label, params, *args)
    return energy_value(
        call_energy(e.potential, "potential energy", label, params, *args), label, q
    )


def lagrangian(e: Energies, q, qd, params, t=None):
    """`L = T − V`."""
    return kinetic(e, q, qd, params, t) - potential(e, q, params, t)


def grad_kinetic(e: Energies, q, qd, params, t=None):
    """`(∂T/∂q, ∂T/∂q̇)` in one reverse pass."""
    return jax.grad(lambda a, b: kinetic(e, a, b, params, t), argnums=(0, 1))(q, qd)


def jacobi(e: Energies, q, qd, params, t=None):
    """The Jacobi integral `h = q̇·∂L/∂q̇ − L = q̇·∂T/∂q̇ − T + V`: one JVP of `T` along
    `q̇` in `q̇` gives `T` and `q̇·∂T/∂q̇` together (`h = T + V` for a `T`
    quadratic in `q̇`, up to round-off)."""
    t_val, t_dot = jax.jvp(lambda b: kinetic(e, q, b, params, t), (qd,), (qd,))
    return t_dot - t_val + potential(e, q, params, t)


def structured_energies(e: Energies, q, qd, params, t=None):
    """`(T, V)` of a system with structure-aware `equations`: from the equations'
    own `energies(q, q̇, params)` where they offer one (a spatial chain's outward pass:
    no derivative of the pose maps), else from the energy functions."""
    out = None if e.equations is None else e.equations.energies(q, qd, params)
    if out is not None:
        return out
    return kinetic(e, q, qd, params, t), potential(e, q, params, t)


def kinetic_and_jacobi(e: Energies, q, qd, params, t, potential):
    """`(T, h)` from one JVP of `T` along `q̇` (see `jacobi`), given `V`."""
    t_val, t_dot = jax.jvp(lambda b: kinetic(e, q, b, params, t), (qd,), (qd,))
    return t_val, t_dot - t_val + potential


def explicit_power(e: Energies, q, qd, params, t):
    """`−∂L/∂t` (`∂V/∂t − ∂T/∂t`): the rate at which an explicit time dependence
    changes the Jacobi integral, `dh/dt = −∂L/∂t + q̇·(τ + F − ∂D/∂q̇)`."""
    t = time_of(t, q)
    return -jax.jvp(lambda s: lagrangian(e, q, qd, params, s), (t,), (jnp.ones_like(t),))[1]


def mass_columns(e: Energies, q, qd, params, extra_q_tangent=None, t=None):
    """Forward-over-reverse: `M = ∂p/∂q̇` column by column, plus optionally
    `(∂p/∂q) v` for a tangent `v` in `q`; returns `(∂T/∂q, p, M, (∂p/∂q) v)`.

    All tangents go through one vmapped JVP of the gradient of `T`. For a time-dependent
    system the extra tangent also moves the time at unit rate: it returns
    `(∂p/∂q) v + ∂p/∂t`.
    """
    n = q.shape[0]
    eye = jnp.eye(n, dtype=q.dtype)
    tq = jnp.zeros((n, n), q.dtype)
    if extra_q_tangent is not None:
        tq = jnp.concatenate([tq, extra_q_tangent[None]], axis=0)
        eye = jnp.concatenate([eye, jnp.zeros((1, n), q.dtype)], axis=0)

    if timed(e):
        s = time_of(t, q)
        tt = jnp.zeros((n,), q.dtype)  # M's columns at fixed t; the extra tangent moves t
        if extra_q_tangent is not None:
            tt = jnp.concatenate([tt, jnp.ones((1,), q.dtype)])

        def along_timed(dq, dqd, dt):
            return jax.jvp(
                lambda a, b, c: grad_kinetic(e, a, b, params, c), (q, qd, s), (dq, dqd, dt)
            )

        (tq_grad, p), (_, dp) = jax.vmap(along_timed)(tq, eye, tt)
    else:

        def along(dq, dqd):
            return jax.jvp(lambda a, b: grad_kinetic(e, a, b, params), (q, qd), (dq, dqd))

        (tq_grad, p), (_, dp) = jax.vmap(along)(tq, eye)
    tq_grad, p = tq_grad[0], p[0]
    mass = dp[:n].T
    extra = dp[n] if extra_q_tangent is not None else None
    return tq_grad, p, mass, extra


def mass_matrix(e: Energies, q, qd, params, t=None):
    """`M(q) = ∂²T/∂q̇²` (`n` JVPs of `∂T/∂q̇`, or the structure-aware `equations`)."""
    if e.equations is not None:
        return e.equations.mass_matrix(q, params)
    return mass_columns(e, q, qd, params, t=t)[2]


def coriolis(e: Energies, q, qd, params, t=None):
    """`C(q, q̇) q̇ = (∂²T/∂q̇∂q) q̇ − ∂T/∂q`: one JVP along `(q̇, 0)`."""
    (t_q, _), (_, dp) = jax.jvp(lambda a: grad_kinetic(e, a, qd, params, t), (q,), (qd,))
    return dp - t_q


def time_rate_of_momentum(e: Energies, q, qd, params, t):
    """`∂²T/∂q̇∂t = ∂p/∂t` at fixed `(q, q̇)` (one JVP along the time)."""
    s = time_of(t, q)
    return jax.jvp(lambda c: grad_kinetic(e, q, qd, params, c)[1], (s,), (jnp.ones_like(s),))[1]


def gravity(e: Energies, q, params, t=None):
    """`G(q) = ∂V/∂q`."""
    if e.potential is None:
        return jnp.zeros_like(q)
    return jax.grad(lambda a: potential(e, a, params, t))(q)


def damping(e: Energies, q, qd, params, t=None):
    """`∂D/∂q̇` (the force acting is its negative)."""
    if e.dissipation is None:
        return jnp.zeros_like(q)
    label = DISSIPATION_T if timed(e) else DISSIPATION
    args = _with_time(e, t, q, qd)
    clamped_reads(e.dissipation, label, params, *args)

    def dissipation(b):
        out = call_energy(e.dissipation, "dissipation", label, params, *args[:-1], b)
        return energy_value(out, label, q)

    return jax.grad(dissipation)(qd)


def applied(e: Energies, t, q, qd, params, tau):
    """Right-hand generalized force `τ + F(t, q, q̇) − ∂D/∂q̇` (without potential)."""
    f = -damping(e, q, qd, params, t)
    if tau is not None:
        f = f + tau
    if e.force is not None:
        clamped_reads(e.force, FORCE, params, t, q, qd)
        out = call_user(e.force, "force", params, t, q, qd)
        f = f + force_value(out, f"the {FORCE}", q)
    return f


def eom_small(e: Energies, q, qd, params, t=None):
    """`M` and `∂L/∂q − (∂²L/∂q̇∂q) q̇` (`− ∂²L/∂q̇∂t` when time-dependent) as lists
    of scalars, by scalar forward-over-forward derivatives.

    For small `n` this beats forward-over-reverse: every derivative is a straight
    line of scalar arithmetic on the primal values, which XLA fuses into one loop with
    each transcendental evaluated once. It costs `n(n+1)/2 + n` second-order and
    `n` first-order directional derivatives of `L`, so it is used for
    `n <= FOF_MAX` only (see `use_scalar`).
    """
    n = q.shape[0]
    basis = [jnp.asarray(np.eye(n)[i], q.dtype) for i in range(n)]
    zero = jnp.zeros_like(q)

    if timed(e):
        s = time_of(t, q)
        one = jnp.ones_like(s)

    def lag(a, b, c=t):
        return lagrangian(e, a, b, params, c)

    def p_i(i):  # q, q̇ (, t) -> ∂L/∂q̇_i
        return lambda a, b, c=t: jax.jvp(lambda x, y: lag(x, y, c), (a, b), (zero, basis[i]))[1]

    rows = [[None] * n for _ in range(n)]
    rhs = []
    for i in range(n):
        for j in range(i, n):
            mij = jax.jvp(lambda b, i=i: p_i(i)(q, b), (qd,), (basis[j],))[1]
            rows[i][j] = rows[j][i] = mij
        l_q = jax.jvp(lag, (q, qd), (basis[i], zero))[1]
        if timed(e):  # (∂²L/∂q̇∂q) q̇ + ∂²L/∂q̇∂t: one JVP along (q̇, 1)
            mixed = jax.jvp(lambda a, c, i=i: p_i(i)(a, qd, c), (q, s), (qd, one))[1]
        else:
            mixed = jax.jvp(lambda a, i=i: p_i(i)(a, qd), (q,), (qd,))[1]
        rhs.append(l_q - mixed)
    return rows, rhs


def has_applied(e: Energies, tau) -> bool:
    return tau is not None or e.force is not None or e.dissipation is not None


def applied_or_none(e: Energies, t, q, qd, params, tau):
    """`applied(...)`, or `None` where nothing is applied (what structure-aware
    equations take as their force)."""
    return applied(e, t, q, qd, params, tau) if has_applied(e, tau) else None


def mass_and_force(e: Energies, scalar: bool | None, t, q, qd, params, tau):
    """`M(q)` and `f = τ + F − C q̇ − G − ∂D/∂q̇`: the equations `M q̈ = f`.

    `scalar` chooses the derivatives as `use_scalar` does; structure-aware
    `equations` take precedence.
    """
    f_applied = applied(e, t, q, qd, params, tau)
    if e.equations is not None:
        mass, bias = e.equations.mass_and_bias(q, qd, params)
        return mass, f_applied - bias
    if use_scalar(q.shape[0], scalar):
        rows, rhs = eom_small(e, q, qd, params, t)
        mass = jnp.stack([jnp.stack(row) for row in rows])
        return mass, jnp.stack(rhs) + f_applied
    t_q, _, mass, dp_q = mass_columns(e, q, qd, params, extra_q_tangent=qd, t=t)
    return mass, t_q - dp_q - gravity(e, q, params, t) + f_applied


def accelerations(e: Energies, scalar: bool | None, t, q, qd, params, tau):
    """`q̈ = M⁻¹ f` without raising: NaN where `M` is not positive-definite.

    The scalar path solves with a Cholesky factorization unrolled over the scalars (no
    matrix is stacked); the vector path with a Cholesky factorization of `M`.
    Structure-aware `equations` (a chain's articulated-body algorithm) take precedence.
    """
    if e.equations is not None:
        return e.equations.accelerations(q, qd, params, applied_or_none(e, t, q, qd, params, tau))
    if use_scalar(q.shape[0], scalar):
        rows, rhs = eom_small(e, q, qd, params, t)
        if has_applied(e, tau):
            f_applied = applied(e, t, q, qd, params, tau)
            rhs = [r + f_applied[i] for i, r in enumerate(rhs)]
        return solve_spd_unrolled(rows, rhs)
    return cholesky_solve(*mass_and_force(e, scalar, t, q, qd, params, tau))
