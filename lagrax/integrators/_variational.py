"""Variational integrators: discrete Euler–Lagrange equations as a diffrax solver."""

from collections.abc import Callable
from typing import ClassVar

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
from jax import lax

from .._core.errors import ConfigurationError
from .._core.linalg import cholesky_solve, lu_factor_small, lu_solve_small
from .._systems import derivatives
from .._systems.lagrangian import LagrangianSystem
from .._systems.vector_field import lagrangian_field_of

# Yoshida's triple jump: composing a symmetric order-2 map with these step fractions
# gives order 4 (H. Yoshida, Phys. Lett. A 150, 262 (1990)).
_CBRT2 = 2.0 ** (1.0 / 3.0)
_COMPOSITIONS: dict[int, tuple[float, ...]] = {
    2: (1.0,),
    4: (1.0 / (2.0 - _CBRT2), -_CBRT2 / (2.0 - _CBRT2), 1.0 / (2.0 - _CBRT2)),
}


def _newton(residual, x0, rtol, atol, max_steps):
    """Solve `residual(x) = 0` by a chord (simplified Newton) iteration from `x0`.

    The exact Jacobian (`n` JVPs) is formed and factored once, at `x0`; each iteration
    then costs one residual. From the third-order predictor of `Variational` the start
    is within `O(h³)` of the root, so the contraction factor `‖J(x0)⁻¹(J(x*) − J(x0))‖`
    is tiny and two or three iterations reach round-off — cheaper than full Newton, whose
    every iteration re-forms the Jacobian.

    Stops when the update is below `atol + rtol·|x|`. Returns `(x, aux, result)` with
    `aux` the residual's auxiliary output at the returned `x`; the result is
    `nonlinear_max_steps_reached` if it did not converge and `nonlinear_divergence`
    if the iterate became non-finite.
    """
    r0, aux0 = residual(x0)
    jac = jax.jacfwd(lambda x: residual(x)[0])(x0)
    lu = lu_factor_small(jac)

    def body(carry):
        x, r, _, _, k = carry
        dx = lu_solve_small(lu, r)
        x_new = x - dx
        r_new, aux_new = residual(x_new)
        small = jnp.all(jnp.abs(dx) <= atol + rtol * jnp.abs(x_new))
        return x_new, r_new, aux_new, small, k + 1

    def cond(carry):
        x, _, _, done, k = carry
        return (~done) & (k < max_steps) & jnp.all(jnp.isfinite(x))

    init = (x0, r0, aux0, jnp.asarray(False), jnp.asarray(0))
    x, _, aux, done, _ = lax.while_loop(cond, body, init)
    result = dfx.RESULTS.where(
        done, dfx.RESULTS.successful, dfx.RESULTS.nonlinear_max_steps_reached
    )
    result = dfx.RESULTS.where(jnp.all(jnp.isfinite(x)), result, dfx.RESULTS.nonlinear_divergence)
    return x, aux, result


class Variational(dfx.AbstractSolver):
    r"""Midpoint variational integrator (and its order-4 composition), for any `T`.

    The discrete Lagrangian of the midpoint rule

        `L_d(q_k, q_{k+1}) = h L((q_k + q_{k+1})/2, (q_{k+1} − q_k)/h)`

    and the discrete Lagrange–d'Alembert principle (forces `F = τ + F_applied − ∂D/∂q̇`
    at the midpoint, split equally between the two ends: `f^± = (h/2) F`) give the
    position–momentum map `(q_k, p_k) ↦ (q_{k+1}, p_{k+1})`:

        `p_k + (h/2)(∂L/∂q + F) − ∂L/∂q̇ = 0`     (solved for `q_{k+1}` by Newton)
        `p_{k+1} = p_k + h (∂L/∂q + F)`

    with `∂L/∂q`, `∂L/∂q̇` and `F` evaluated at the midpoint
    `((q_k + q_{k+1})/2, (q_{k+1} − q_k)/h)` (and, for a time-dependent system, at the
    midpoint time `t_k + h/2`). It does not need `L` to be separable,
    so it applies to configuration-dependent mass matrices (diffrax's
    `SemiImplicitEuler` does not). Without forcing the map is symplectic and conserves
    the discrete momentum map of every symmetry of `L_d` (e.g. `p_i` for a cyclic
    coordinate `q_i`) to solver precision; the energy error stays bounded over
    exponentially long times instead of drifting. The midpoint map is symmetric, so
    `order=4` composes it with Yoshida's triple-jump step fractions.

    The state handed to diffrax is `(q, q̇)`; the momentum `p` is carried in the
    solver state, and `q̇_{k+1}` is recovered from `p_{k+1} = ∂T/∂q̇(q_{k+1}, q̇_{k+1})`
    (`M(q) q̇ = p − ∂T/∂q̇(q, 0)` for `T` quadratic in `q̇`).

    **Fixed step only.** This solver provides no error estimate and must not be paired
    with an error-controlled adaptive step: changing `h` from step to step according to
    the state destroys symplecticity, and with it the bounded energy error. Use it with
    `diffrax.ConstantStepSize()` (`lagrax.simulate(..., dt=h)`).

    **Arguments:**

    - `order`: 2 (midpoint) or 4 (triple-jump composition, three Newton solves a step).
    - `rtol`, `atol`: tolerances of the Newton iteration on `q_{k+1}` (on the change
      between iterates; Newton converges quadratically, so the accepted iterate is
      accurate to round-off). Tighter values can stall on round-off in long runs.
    - `max_newton_steps`: Newton iterations allowed per (sub)step; failure to converge
      is reported as a failed solve.

    **Raises:** `ConfigurationError` for an `order` other than 2 or 4.

    References: J. E. Marsden and M. West, *Discrete mechanics and variational
    integrators*, Acta Numerica 10 (2001) 357–514; E. Hairer, C. Lubich, G. Wanner,
    *Geometric Numerical Integration*, 2nd ed., Springer (2006), ch. VI.6 and II.4.
    """

    order_: int = eqx.field(default=2, static=True)
    rtol: float = 1e-10
    atol: float = 1e-10
    max_newton_steps: int = eqx.field(default=20, static=True)

    term_structure: ClassVar = dfx.AbstractTerm
    interpolation_cls: ClassVar[Callable[..., dfx.LocalLinearInterpolation]] = (
        dfx.LocalLinearInterpolation
    )

    def __check_init__(self):
        if self.order_ not in _COMPOSITIONS:
            raise ConfigurationError(
                f"Variational(order_={self.order_}) is not available; use one of "
                f"{sorted(_COMPOSITIONS)}"
            )

    def order(self, terms):
        return self.order_

    def init(self, terms, t0, t1, y0, args):
        field = lagrangian_field_of(terms)
        q0, qd0 = y0
        # solver state: the momentum p_k, and an estimate of q̈_k for the predictor
        # (zero to start)
        momentum = _lagrangian_system(field).momentum(q0, qd0, args[0], t=t0)
        return momentum, jnp.zeros_like(qd0)

    def _substep(self, field, args, t0, h, q0, qd0, p0, acc):
        system = _lagrangian_system(field)
        params, tau_const = args

        tm = t0 + 0.5 * h  # the discrete Lagrangian h L(t_m, q_m, v), at the midpoint time

        def grads(qm, v):
            return jax.grad(
                lambda a, b: derivatives.lagrangian(system, a, b, params, tm), argnums=(0, 1)
            )(qm, v)

        def residual(q1):
            qm, v = 0.5 * (q0 + q1), (q1 - q0) / h
            l_q, l_v = grads(qm, v)
            lq_f = l_q + derivatives.applied(
                system, tm, qm, v, params, field.tau(tm, qm, v, tau_const)
            )
            return p0 + 0.5 * h * lq_f - l_v, lq_f

        # Taylor predictor: within O(h³) of q_{k+1} (O(h²) on the first step)
        q_guess = q0 + h * qd0 + (0.5 * h * h) * acc
        q1, lq_f, result = _newton(residual, q_guess, self.rtol, self.atol, self.max_newton_steps)
        p1 = p0 + h * lq_f
        # velocity from the momentum: M(q1) q̇1 = p1 − ∂T/∂q̇(q1, 0)
        zero = jnp.zeros_like(q1)
        p_offset = system.momentum(q1, zero, params, t=t0 + h)
        mass = system.mass_matrix(q1, params, t=t0 + h)
        qd1 = cholesky_solve(mass, p1 - p_offset)
        # the step's mean velocity (q1 − q0)/h ≈ q̇1 − (h/2) q̈1 gives the next q̈ estimate
        acc1 = 2.0 * (qd1 - (q1 - q0) / h) / h
        return q1, qd1, p1, acc1, result

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        del made_jump
        field = lagrangian_field_of(terms)
        q, qd = y0
        p, acc = solver_state
        h = t1 - t0
        result = dfx.RESULTS.successful
        t = t0
        for frac in _COMPOSITIONS[self.order_]:
            q, qd, p, acc, res = self._substep(field, args, t, frac * h, q, qd, p, acc)
            t = t + frac * h
            result = dfx.RESULTS.where(result == dfx.RESULTS.successful, res, result)
        y1 = (q, qd)
        # a non-finite state is a failure (step past the Newton iteration's reach)
        finite = jnp.all(jnp.isfinite(q)) & jnp.all(jnp.isfinite(qd))
        result = dfx.RESULTS.where(finite, result, dfx.RESULTS.nonlinear_divergence)
        return y1, None, dict(y0=y0, y1=y1), (p, acc), result

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)


def _lagrangian_system(field) -> LagrangianSystem:
    """The unconstrained `LagrangianSystem` a variational integrator needs, or an error."""
    system = field.system
    if not isinstance(system, LagrangianSystem):
        raise ConfigurationError(
            "the variational integrators work on the Lagrangian of an unconstrained system "
            f"and would ignore the constraints of {system.name}: use an ODE method such "
            "as 'tsit5' (or 'rk4' at a fixed step)"
        )
    return system
