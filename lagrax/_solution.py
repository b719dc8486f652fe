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
    - ``energy``: ``T + V`` at ``ts``, shape ``(T,)``.
    - ``result``: result code (``lagrax.RESULTS``: diffrax's codes plus
      ``non_finite_state``); ``ok`` tells success, ``RESULTS[sol.result]`` the message.
    - ``stats``: solver counters (``num_steps``, ``num_accepted_steps``,
      ``num_rejected_steps``, ``max_steps``).
    - ``t_end``, ``q_end``, ``qd_end``: the last state the solver reached: ``t1`` on
      success, the time it stopped at on failure (with a custom ``saveat``, the last save).
    - ``constraint_violation``: for a ``ConstrainedSystem``, ``φ(q)`` at ``ts``, shape
      ``(T, m)``; ``None`` otherwise.
    - ``multipliers``: for a ``ConstrainedSystem``, the Lagrange multipliers ``λ`` at
      ``ts``, shape ``(T, m)`` (``J(q)ᵀλ`` is the generalized constraint force); ``None``
      otherwise.

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

    @property
    def ok(self) -> Array:
        """``True`` where the solve succeeded (an array under ``vmap``)."""
        return self.result == RESULTS.successful

    @property
    def energy_error(self) -> Float[Array, " T"]:
        """Relative energy change ``(E(t) − E(t0)) / max(|E(t0)|, tiny)`` along the path."""
        e0 = self.energy[..., :1]
        return (self.energy - e0) / jnp.maximum(jnp.abs(e0), jnp.finfo(e0.dtype).tiny)
