r"""Regularized Coulomb friction with stiction: the one friction law of lagrax, shared by
contacts (`lagrax._contact.laws`: a contact point's tangential slip) and joints
(`lagrax._multibody.joint_space`: MuJoCo's joint friction loss).

At the slip speed `s = |v|/v_s` (`v_s` the stiction velocity) the friction coefficient
`μ(s)` rises from 0 as `μ_s s (2 − s)` to the static `μ_s` at `s = 1`, falls smoothly to
the kinetic `μ` at `s = 3` and stays there; the force opposes the slip, `−μ(s) f_n v/|v|`.
A load `F < μ_s f_n` is held by a creep `|v| = v_s (1 − √(1 − F/(μ_s f_n)))`, below
`v_s`; above `3 v_s` the force is exactly kinetic Coulomb friction `μ f_n`.

Along one coordinate (a joint) the law derives from the dissipation function
`D(v) = f_n v_s Φ(|v|/v_s)`, `Φ(s) = ∫₀^s μ`: `∂D/∂v = f_n μ(s) sign(v)`, so that it
enters a system as its Rayleigh damping does, and its power `−v ∂D/∂v ≤ 0` is part of
`Solution.work`. `joint_friction` has its analytic derivative (`μ'(s)/v_s`) as its JVP.
"""

import jax
import jax.numpy as jnp


def friction_coefficient(s, kinetic, static):
    r"""`μ(s)`, the regularized friction coefficient at the slip speed `s = |v_t|/v_s`:

    $$
    μ(s) = \begin{cases} μ_s\, s(2 − s) & s ≤ 1 \\
    μ_s − (μ_s − μ)\,x^2(3 − 2x),\ x = (s − 1)/2 & 1 < s < 3 \\
    μ & s ≥ 3 \end{cases}
    $$

    continuous with its first derivative, `μ(0) = 0`, `μ'(0) = 2 μ_s`."""
    low = static * s * (2.0 - s)
    x = jnp.clip((s - 1.0) / 2.0, 0.0, 1.0)
    high = static - (static - kinetic) * x * x * (3.0 - 2.0 * x)
    return jnp.where(s <= 1.0, low, high)


def friction_slope(s, kinetic, static):
    """`μ'(s)`: `2 μ_s (1 − s)` for `s ≤ 1`, `−3 (μ_s − μ) x (1 − x)` with
    `x = (s − 1)/2` up to `s = 3`, zero beyond."""
    x = jnp.clip((s - 1.0) / 2.0, 0.0, 1.0)
    return jnp.where(s <= 1.0, 2.0 * static * (1.0 - s), -3.0 * (static - kinetic) * x * (1.0 - x))


def friction_ratio(s, kinetic, static):
    """`μ(s)/s` (finite at `s = 0`, where it is `2 μ_s`)."""
    low = static * (2.0 - s)
    safe = jnp.maximum(s, 1.0)
    return jnp.where(s <= 1.0, low, friction_coefficient(safe, kinetic, static) / safe)


def _force(v, kinetic, static, vs):
    return friction_ratio(jnp.abs(v) / vs, kinetic, static) * v / vs


@jax.custom_jvp
def joint_friction(v, kinetic, static, stiction_velocity):
    """`∂D/∂v = μ(|v|/v_s) sign(v)` elementwise: the friction force opposing a rate `v`
    is its negative (`kinetic`, `static`: the forces `μ f_n`, `μ_s f_n` of the slip;
    MuJoCo's friction loss for a joint). Its JVP in `v` is the analytic `μ'(s)/v_s`."""
    return _force(v, kinetic, static, stiction_velocity)


@joint_friction.defjvp
def _joint_friction_jvp(primals, tangents):
    v, kinetic, static, vs = primals
    # the coefficients' tangents by differentiating the formula with `v` held (smooth in
    # them); `v`'s by the slope, which `|v|` would lose at `v = 0` (`sign(0)² = 0`)
    out, coefficients = jax.jvp(_force, primals, (jnp.zeros_like(tangents[0]), *tangents[1:]))
    slope = friction_slope(jnp.abs(v) / vs, kinetic, static) / vs
    return out, coefficients + slope * tangents[0]


def _phi(v, kinetic, static, vs):
    s = jnp.abs(v) / vs
    low = static * (s * s - s * s * s / 3.0)
    x = jnp.clip((s - 1.0) / 2.0, 0.0, 1.0)
    delta = static - kinetic
    mid = 2.0 * static / 3.0 + 2.0 * static * x - 2.0 * delta * (x**3 - x**4 / 2.0)
    high = mid + kinetic * jnp.maximum(s - 3.0, 0.0)
    return vs * jnp.where(s <= 1.0, low, high)


@jax.custom_jvp
def joint_friction_dissipation(v, kinetic, static, stiction_velocity):
    r"""`D = v_s Φ(|v|/v_s)` elementwise, the dissipation function of `joint_friction`
    (`∂D/∂v = joint_friction(v)`, its JVP), with `Φ(s) = ∫₀^s μ`:

    $$
    Φ(s) = \begin{cases} μ_s (s^2 − s^3/3) & s ≤ 1 \\
    \tfrac23 μ_s + 2 μ_s x − 2(μ_s − μ)(x^3 − x^4/2),\ x = (s − 1)/2 & 1 < s < 3 \\
    \tfrac83 μ_s − (μ_s − μ) + μ (s − 3) & s ≥ 3 \end{cases}
    $$
    """
    return _phi(v, kinetic, static, stiction_velocity)


@joint_friction_dissipation.defjvp
def _dissipation_jvp(primals, tangents):
    out, coefficients = jax.jvp(_phi, primals, (jnp.zeros_like(tangents[0]), *tangents[1:]))
    return out, coefficients + joint_friction(*primals) * tangents[0]
