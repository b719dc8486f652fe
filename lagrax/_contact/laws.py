r"""The contact laws, as pure functions of one contact's gap and velocities.

- **Normal**: Hunt–Crossley, `f_n = k δ^p max(0, 1 + (3/2) c δ̇)` for a penetration
  `δ = −gap > 0` (zero outside contact), never pulling. Its elastic part `k δ^p` derives
  from the potential `k δ^{p+1}/(p+1)` (`elastic_energy`); the rest, `f_n − k δ^p`, is
  the dissipation.
- **Tangential**: regularized Coulomb friction with stiction, `F_t = −μ(s) f_n v_t/|v_t|`
  with `s = |v_t|/v_s`; `μ(s)` rises from 0 as `μ_s s (2 − s)` to `μ_s` at `s = 1`,
  falls smoothly to `μ` at `s = 3` and stays there (`friction_ratio` is `μ(s)/s`): the
  law of `lagrax._core.friction`, which joints' friction loss shares.

Every function is smooth where its value is (the positive part and the norm are taken
by the double-`where` pattern, so their derivatives are finite at zero: `jax.grad` of a
solve through a contact onset is not NaN).
"""

import jax.numpy as jnp

from .._core.friction import friction_ratio


def positive_power(x, p):
    """`x₊^p` (zero for `x ≤ 0`), with finite derivatives at `x = 0` for `p ≥ 1`."""
    pos = x > 0
    return jnp.where(pos, jnp.where(pos, x, 1.0) ** p, 0.0)


def normal_force(delta, delta_rate, stiffness, dissipation, exponent):
    r"""`(f_n, f_el)`: the Hunt–Crossley normal force and its elastic part.

    $$
    f_{el} = k\,δ_+^p, \qquad f_n = f_{el}\,\max\big(0,\ 1 + \tfrac32\,c\,δ̇\big),
    $$

    with `δ` the penetration, `δ̇` its rate (positive while approaching), `k` the
    stiffness, `c` the Hunt–Crossley dissipation (time per length) and `p` the exponent.
    The clip makes the force never pull: a contact separating faster than `2/(3c)`
    pushes with nothing."""
    elastic = stiffness * positive_power(delta, exponent)
    return elastic * jnp.maximum(0.0, 1.0 + 1.5 * dissipation * delta_rate), elastic


def elastic_energy(delta, stiffness, exponent):
    """`k δ₊^{p+1}/(p+1)`: the potential of the elastic part of `normal_force`."""
    return stiffness * positive_power(delta, exponent + 1.0) / (exponent + 1.0)


def safe_norm(x):
    """`|x|` over the last axis, with a zero (not NaN) derivative at `x = 0`."""
    squared = jnp.sum(x * x, axis=-1)
    pos = squared > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, squared, 1.0)), 0.0)


def friction_force(v_t, f_n, kinetic, static, stiction_velocity):
    """The friction force `−μ(s) f_n v_t/|v_t|` on a contact point slipping at the
    tangential velocity `v_t` (last axis: the components), `s = |v_t|/v_s`."""
    s = safe_norm(v_t) / stiction_velocity
    scale = f_n * friction_ratio(s, kinetic, static) / stiction_velocity
    return -scale[..., None] * v_t
