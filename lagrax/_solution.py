"""``Solution``: one simulated trajectory at its saved times."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from ._results import RESULTS


class Solution(eqx.Module):
    """A simulated trajectory at the saved times.

    **Fields:**

    - ``ts``: saved times, shape ``(T,)``.
    - ``q``, ``qd``: coordinates and velocities at ``ts``, shape ``(T, n)``.
    - ``energy``: the Jacobi integral ``h = q̇·∂L/∂q̇ − L`` at ``ts``, shape ``(T,)``
      (:meth:`LagrangianSystem.jacobi_integral`): ``T + V`` when ``T`` is quadratic in
      ``q̇``, and the conserved energy of an autonomous, undamped, unforced system also
      when ``T`` has terms linear in ``q̇`` (a charge in a magnetic field, a rotating
      frame), where ``T + V`` is not conserved.
    - ``result``: result code (``lagrax.RESULTS``: diffrax's codes plus
      ``non_finite_state``); ``ok`` tells success, ``RESULTS[sol.result]`` the message.
    - ``stats``: solver counters (``num_steps``, ``num_accepted_steps``,
      ``num_rejected_steps``, ``max_steps``).
    - ``t_end``, ``q_end``, ``qd_end``: the last state the solver reached: ``t1`` on
      success, the time it stopped at on failure (with a custom ``saveat``, the last save).
    - ``constraint_violation``: for a ``ConstrainedSystem`` with holonomic constraints,
      ``φ(q)`` at ``ts``, shape ``(T, m₁)``; ``None`` otherwise.
    - ``multipliers``: for a ``ConstrainedSystem``, the Lagrange multipliers at ``ts``,
      shape ``(T, m₁ + m₂)``: the holonomic rows' ``λ``, then the velocity rows' ``μ``
      (``J(q)ᵀλ + A(q)ᵀμ`` is the generalized constraint force); ``None`` otherwise.
    - ``work``: for a time-dependent system, the work its explicit time dependence has done
      since the first save, ``W(t) = ∫ −∂L/∂t dt``, shape ``(T,)``, so that
      ``h(t) − h(t0) = W(t)`` on the exact motion without inputs or dissipation;
      ``None`` for an autonomous system. Integrated from the saved states by a
      sixth-order (Hermite) two-point rule, so the saves must resolve the time
      dependence (see :attr:`energy_error`).
    - ``velocity_constraint_violation``: for a ``ConstrainedSystem`` with velocity
      constraints, ``A(q) q̇`` at ``ts``, shape ``(T, m₂)``; ``None`` otherwise.

    After a failed solve with ``throw=False``, entries past the failure time are ``inf``
    (diffrax's fill value), never silently wrong numbers; a fixed-step solve that blew up
    is flagged ``RESULTS.non_finite_state`` (its values past the blow-up are NaN/inf).
    Check ``ok`` first.
    """

    ts: Float[Array, " T"]
    q: Float[Array, "T n"]
    qd: Float[Array, "T n"]
    energy: Float[Array, " T"]
    result: RESULTS
    stats: dict[str, Int[Array, ""]]
    t_end: Float[Array, ""]
    q_end: Float[Array, " n"]
    qd_end: Float[Array, " n"]
    constraint_violation: Float[Array, "T m"] | None = None
    multipliers: Float[Array, "T m"] | None = None
    work: Float[Array, " T"] | None = None
    velocity_constraint_violation: Float[Array, "T m2"] | None = None

    @property
    def ok(self) -> Array:
        """``True`` where the solve succeeded (an array under ``vmap``)."""
        return self.result == RESULTS.successful

    @property
    def energy_change(self) -> Float[Array, " T"]:
        """``h(t) − h(t0)``: the change of :attr:`energy` since the first save (physics,
        not error, for a time-dependent, damped or driven system)."""
        return self.energy - self.energy[..., :1]

    @property
    def energy_error(self) -> Float[Array, " T"]:
        r"""The relative energy balance residual along the path,

        .. math::  \frac{h(t) − h(t_0) − W(t)}{\max(|h(t_0)|, \text{tiny})},

        with ``h`` = :attr:`energy` and ``W`` = :attr:`work` (zero for an autonomous
        system, where this is the relative change of ``h``). It vanishes on the exact
        motion of a system without inputs or dissipation (their work is not subtracted:
        for a damped or driven system it is the change of ``h`` they cause); otherwise it
        measures the integrator's error, plus, for a time-dependent system, the
        quadrature error of ``W`` (sixth order in the save spacing).
        """
        e0 = self.energy[..., :1]
        balance = self.energy - e0
        if self.work is not None:
            balance = balance - self.work
        return balance / jnp.maximum(jnp.abs(e0), jnp.finfo(e0.dtype).tiny)
