"""`Solution`: one simulated trajectory at its saved times."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float, Int

from .._core.results import RESULTS


class EventRecord(eqx.Module):
    """The crossings of one [`Event`][lagrax.Event] found along a solve.

    **Fields:** (`K` is the event's `max_events`; under `vmap` or in a sweep every
    field gains the batch axes in front)

    - `times`: the crossing times in order, shape `(K,)`; entries past `count` are
      `inf`.
    - `q`, `qd`: the state at each crossing (before a reset), shape `(K, n)`;
      `inf` past `count`.
    - `count`: how many crossings were recorded (an `int32` scalar).

    `record.times[: record.count]` are the crossings of an eager solve.
    """

    times: Float[Array, " K"]
    q: Float[Array, "K n"]
    qd: Float[Array, "K n"]
    count: Int[Array, ""]

    @property
    def first(self) -> Float[Array, ""]:
        """The first crossing time (`inf` when there was none)."""
        return self.times[..., 0]


class Solution(eqx.Module):
    r"""A simulated trajectory at the saved times.

    **Fields:**

    - `ts`: saved times, shape `(T,)`.
    - `q`, `qd`: coordinates and velocities at `ts`, shape `(T, n)`.
    - `energy`: the Jacobi integral `h = q̇·∂L/∂q̇ − L` at `ts`, shape `(T,)`
      ([`LagrangianSystem.jacobi_integral`][lagrax.LagrangianSystem.jacobi_integral]): `T + V` when
      `T` is quadratic in `q̇`, and the conserved energy of an autonomous, undamped, unforced system
      also when `T` has terms linear in `q̇` (a charge in a magnetic field, a rotating
      frame), where `T + V` is not conserved.
    - `result`: result code (`lagrax.RESULTS`: diffrax's codes plus
      `non_finite_state`, `event_cascade`, ...); `ok` tells success (also true for
      `event_occurred`, a stop at a terminal [`Event`][lagrax.Event]), `RESULTS[sol.result]`
      the message.
    - `stats`: solver counters (`num_steps`, `num_accepted_steps`,
      `num_rejected_steps`, `max_steps`).
    - `t_end`, `q_end`, `qd_end`: the last state the solver reached: `t1` on
      success, the root of a terminal event, the time it stopped at on failure (with a
      custom `saveat`, the last save).
    - `constraint_violation`: for a `ConstrainedSystem` with holonomic constraints,
      `φ(q)` at `ts`, shape `(T, m₁)`; `None` otherwise.
    - `multipliers`: for a `ConstrainedSystem`, the Lagrange multipliers at `ts`,
      shape `(T, m₁ + m₂)`: the holonomic rows' `λ`, then the velocity rows' `μ`
      (`J(q)ᵀλ + A(q)ᵀμ` is the generalized constraint force); `None` otherwise.
    - `work`: the work done on the system since the first save by everything that
      changes `h`, shape `(T,)`:

      $$
      W(t) = ∫_{t_0}^{t} \big(−∂L/∂t + q̇·(τ + F − ∂D/∂q̇)\big)\,dt,
      $$

      the explicit time dependence (a moving support, a reeled-in pendulum), the inputs
      `τ`, the applied force `F` and the dissipation `D` (its share is negative),
      so that `h(t) − h(t_0) = W(t)` on the exact motion. `None` for an autonomous
      system without any of them (then `h` is conserved). Constraint forces do no
      work and are not included. With a Runge–Kutta method and no events, integrated
      with the state on the solve's own steps (read at the saves by quadrature along the
      step's dense output); otherwise from the saved states by a sixth-order (Hermite)
      two-point rule, so the saves must resolve the time dependence and the inputs (see
      [`energy_error`][lagrax.Solution.energy_error]).
    - `velocity_constraint_violation`: for a `ConstrainedSystem` with velocity
      constraints, `A(q) q̇` at `ts`, shape `(T, m₂)`; `None` otherwise.
    - `energy_scale`: the scale of [`energy_error`][lagrax.Solution.energy_error],
      `max(|h(t_0)|, max_t (|T| + |V|))` over the saves, a scalar.
    - `events`: with `simulate(..., events=...)`, one [`EventRecord`][lagrax.EventRecord] per event
      (in the order given): `times` `(K,)`, `q` and `qd` `(K, n)` at each
      crossing (before a reset), padded with `inf` past `count` (`K` is the
      event's `max_events`; fixed shapes, so it works under `jit` and `vmap`);
      `None` without events.
    - `contact_gap`, `contact_force`: for a
      [`lagrax.contact.ContactSystem`][], each sphere's gap to the ground at `ts`
      (negative: penetration), shape `(T, S)`, and the contact force on its contact point
      (normal and friction, world frame), shape `(T, S, d)`; `None` otherwise (and
      without a plane).
    - `pair_gap`, `pair_force`: for a `ContactSystem` with sphere–sphere `pairs`, each
      pair's gap `|c_j − c_i| − r_i − r_j` at `ts`, shape `(T, P)`, and the force on
      sphere `j` of pair `(i, j)` (that on `i` is its opposite), shape `(T, P, d)`;
      `None` otherwise.
    - `limit_gap`, `limit_force`: for a `ContactSystem` with joint `limits`, each stop's
      gap to its bound at `ts` (negative: past the limit), shape `(T, K)`, and its
      generalized force on its joint (positive at a lower stop), shape `(T, K)`; `None`
      otherwise.

    After a failed solve with `throw=False`, entries past the failure time are `inf`
    (diffrax's fill value), never silently wrong numbers; a fixed-step solve that blew up
    is flagged `RESULTS.non_finite_state` (its values past the blow-up are NaN/inf).
    Check `ok` first.
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
    energy_scale: Float[Array, ""] | None = None
    events: tuple[EventRecord, ...] | None = None
    contact_gap: Float[Array, "T S"] | None = None
    contact_force: Float[Array, "T S d"] | None = None
    pair_gap: Float[Array, "T P"] | None = None
    pair_force: Float[Array, "T P d"] | None = None
    limit_gap: Float[Array, "T K"] | None = None
    limit_force: Float[Array, "T K"] | None = None

    @property
    def ok(self) -> Array:
        """`True` where the solve succeeded (an array under `vmap`): it reached
        `t1`, or stopped at a terminal event (`RESULTS.event_occurred`)."""
        if self.events is None:
            return self.result == RESULTS.successful
        return (self.result == RESULTS.successful) | (self.result == RESULTS.event_occurred)

    @property
    def energy_change(self) -> Float[Array, " T"]:
        """`h(t) − h(t0)`: the change of `energy` since the first save (physics,
        not error, for a time-dependent, damped or driven system: it equals
        `work` on the exact motion)."""
        return self.energy - self.energy[..., :1]

    @property
    def energy_balance(self) -> Float[Array, " T"]:
        """The absolute energy balance residual `h(t) − h(t_0) − W(t)` (in energy
        units; `W` = `work`, zero when `None`): zero on the exact motion,
        whatever the inputs, dissipation or time dependence."""
        balance = self.energy_change
        if self.work is not None:
            balance = balance - self.work
        return balance

    @property
    def energy_error(self) -> Float[Array, " T"]:
        r"""The energy balance residual relative to the path's energy scale,

        $$
        \frac{h(t) − h(t_0) − W(t)}
        {\max\big(|h(t_0)|,\ \max_s (|T| + |V|)(s)\big)},
        $$

        with `h` = `energy`, `W` = `work` (the work of the explicit time
        dependence, inputs, applied force and dissipation; zero for a conservative
        system, where this is the change of `h`) and the maximum over the saved
        states (`energy_scale`). The scale cannot vanish on a moving system, so a
        pendulum released from rest at the horizontal (`h = 0`) reads the error
        relative to its kinetic and potential energies, not `inf`; for a system whose
        `T` and `V` never exceed `|h(t_0)|` it is the familiar relative change.
        It vanishes on the exact motion; otherwise it measures the integrator's error,
        plus the quadrature error of `W` (where it is formed from the saves: sixth
        order in the save spacing).
        [`energy_balance`][lagrax.Solution.energy_balance] is the same residual in energy units,
        [`energy_change`][lagrax.Solution.energy_change] the change of `h` itself.
        """
        if self.energy_scale is None:
            scale = jnp.abs(self.energy[..., :1])
        else:
            scale = jnp.asarray(self.energy_scale)[..., None]
        return self.energy_balance / jnp.maximum(scale, jnp.finfo(scale.dtype).tiny)
