r"""The fastest rate of a contact scene: what limits an explicit method's fixed step.

Linearized about a state, each touching contact is a spring–damper on its effective
mass `m_n` along its normal, `1/m_n = nᵀ J M⁻¹ Jᵀ n` (`J` the contact point's velocity
Jacobian: a sphere on a body of mass `m` has `m_n = m`; a pair's relative motion
`m_i m_j/(m_i + m_j)`), with the stiffness `k_eff = ∂f_n/∂δ = p k δ^{p−1}(1 + (3/2) c
δ̇)₊` and the damping `b = (3/2) c k δ^p`. Its fastest eigenvalue has the magnitude

$$
λ_n = ω \big(ζ + \sqrt{ζ^2 − 1}\big)\ (ζ > 1), \qquad λ_n = ω\ (ζ ≤ 1), \qquad
ω = \sqrt{k_{eff}/m_n},\ ζ = b/(2 m_n ω).
$$

Its friction, at the slip speed `s = |v_t|/v_s`, is a damper of rate
`λ_t = f_n (μ(s)/s)/(v_s m_t)` on the tangential effective mass (`1/m_t ≤ tr(J M⁻¹
Jᵀ) − 1/m_n`), `2 μ_s f_n/(v_s m_t)` while it sticks: stiffer than the spring by far at
the default stiction velocity. An explicit method at a fixed step `h` is stable on these
modes for `h λ ≲ 2` (forward Euler and Heun on a damper: `h λ < 2`; RK4: 2.79 on a damper,
2.83 on an undamped spring), which is the bound `simulate` holds a fixed-step solve to
(`rate` is `max λ` over the contacts).
"""

import jax
import jax.numpy as jnp

from . import forces, laws


def rate(contact, q, v, params):
    """`max λ` (1/s) over the touching contacts at `(q, v)` (0 with none touching)."""
    dtype = jnp.result_type(q, v, float)
    st = contact.contact_state(q, v, params)
    co = st["coefficients"]
    velocities = forces.velocity_map(contact, q, params, dtype)
    jac = jax.jacfwd(lambda b: velocities(b)[0])(v)  # {key: (K, d, n)}
    mass = contact.system.mass_matrix(q, params)
    fastest = jnp.zeros((), dtype)
    for key, prefix in (("plane", ""), ("pair", "pair_")):
        if key not in jac:
            continue
        j = jac[key]
        k_, d_, n_ = j.shape
        solved = jnp.linalg.solve(mass, j.reshape(k_ * d_, n_).T)  # M⁻¹ Jᵀ, (n, K d)
        compliance = jnp.einsum("kdn,nke->kde", j, solved.reshape(n_, k_, d_))
        normal = st[prefix + "normal"]
        inv_n = jnp.einsum("kd,kde,ke->k", normal, compliance, normal)
        inv_t = jnp.maximum(jnp.trace(compliance, axis1=1, axis2=2) - inv_n, 0.0)
        delta = -st[prefix + "gap"]
        velocity = st[prefix + "velocity"]
        approach = -jnp.sum(velocity * normal, axis=-1)
        p = contact.exponent
        k_eff = (
            p
            * co.stiffness
            * laws.positive_power(delta, p - 1.0)
            * jnp.maximum(0.0, 1.0 + 1.5 * co.dissipation * approach)
        )
        k_eff = jnp.where(delta > 0, k_eff, 0.0)
        damping = 1.5 * co.dissipation * co.stiffness * laws.positive_power(delta, p)
        omega2 = k_eff * inv_n
        half = 0.5 * damping * inv_n  # ζ ω
        over = half * half - omega2
        root = jnp.sqrt(jnp.where(over > 0, over, 0.0))
        lam_n = jnp.where(over > 0, half + root, jnp.sqrt(jnp.maximum(omega2, 0.0)))
        v_t = velocity + approach[:, None] * normal
        s = laws.safe_norm(v_t) / co.stiction_velocity
        ratio = laws.friction_ratio(s, co.friction, co.static_friction)
        lam_t = st[prefix + "normal_force"] * ratio / co.stiction_velocity * inv_t
        fastest = jnp.maximum(fastest, jnp.max(jnp.maximum(lam_n, lam_t)))
    return fastest
