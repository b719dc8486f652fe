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

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from . import forces, laws
from . import limits as joint_limits


def rate(contact, q, v, params):
    """`max λ` (1/s) over the touching contacts at `(q, v)` (0 with none touching)."""
    dtype = jnp.result_type(q, v, float)
    fastest = jnp.zeros((), dtype)
    # (the joint limits' stops are left out: the bound held them out before they
    # existed, and their rate needs M⁻¹'s diagonal in the loop)
    for _, lam_n, lam_t in rates(contact, q, v, params, limits=False).values():
        fastest = jnp.maximum(fastest, jnp.max(jnp.maximum(lam_n, lam_t), initial=0.0))
    return fastest


def _normal_rate(k_eff, damping, inv_m):
    """The fastest eigenvalue's magnitude of a spring `k_eff` and damper `damping` on
    the mass `1/inv_m`."""
    omega2 = k_eff * inv_m
    half = 0.5 * damping * inv_m  # ζ ω
    over = half * half - omega2
    root = jnp.sqrt(jnp.where(over > 0, over, 0.0))
    return jnp.where(over > 0, half + root, jnp.sqrt(jnp.maximum(omega2, 0.0)))


def _stiffness(contact, delta, approach, k, c):
    """`(k_eff, b)`: the normal law's `∂f_n/∂δ` and its damping at penetration `delta`
    and approach speed `approach` (zero where not touching)."""
    p = contact.exponent
    k_eff = p * k * laws.positive_power(delta, p - 1.0) * jnp.maximum(0.0, 1.0 + 1.5 * c * approach)
    k_eff = jnp.where(delta > 0, k_eff, 0.0)
    return k_eff, 1.5 * c * k * laws.positive_power(delta, p)


def rates(contact, q, v, params, *, limits=True):
    """Each contact's rates at `(q, v)`: `{kind: (what, λ_n, λ_t)}` for the plane's
    contacts (`"plane"`, one per sphere), the pairs (`"pair"`) and the joint limits'
    stops (`"limit"`, `λ_t = 0`), each `(K,)`, with `what` the coefficients they come
    from, `(stiffness, dissipation, stiction_velocity)` (the limits': theirs, per
    stop), `0` for a contact not touching."""
    dtype = jnp.result_type(q, v, float)
    st = contact.contact_state(q, v, params)
    co = st["coefficients"]
    velocities = forces.velocity_map(contact, q, params, dtype)
    jac = jax.jacfwd(lambda b: velocities(b)[0])(v)  # {key: (K, d, n)}
    mass = contact.system.mass_matrix(q, params)
    out = {}
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
        velocity = st[prefix + "velocity"]
        approach = -jnp.sum(velocity * normal, axis=-1)
        k_eff, damping = _stiffness(
            contact, -st[prefix + "gap"], approach, co.stiffness, co.dissipation
        )
        lam_n = _normal_rate(k_eff, damping, inv_n)
        v_t = velocity + approach[:, None] * normal
        s = laws.safe_norm(v_t) / co.stiction_velocity
        ratio = laws.friction_ratio(s, co.friction, co.static_friction)
        lam_t = st[prefix + "normal_force"] * ratio / co.stiction_velocity * inv_t
        what = (co.stiffness, co.dissipation, co.stiction_velocity)
        out[key] = (what, lam_n, lam_t)
    if limits and "limit_gap" in st:
        stops = joint_limits.stops(contact.limits)
        n_stops = len(stops.q)
        inv_m = jnp.diagonal(jnp.linalg.inv(mass))[stops.v]
        k = jnp.broadcast_to(co.limit_stiffness, (len(contact.limits),))[stops.joint]
        c = jnp.broadcast_to(co.limit_dissipation, (len(contact.limits),))[stops.joint]
        k_eff, damping = _stiffness(contact, -st["limit_gap"], -st["limit_rate"], k, c)
        what = (k, c, jnp.zeros((n_stops,), dtype))
        out["limit"] = (what, _normal_rate(k_eff, damping, inv_m), jnp.zeros((n_stops,), dtype))
    return out


def account(contact, q, v, params):
    """`(sentence, λ)` for the contact with the fastest rate at `(q, v)`, or `None`
    with none touching (see `ContactSystem.stiff_account`). Eager."""
    found = eqx.filter_jit(rates)(contact, jnp.asarray(q), jnp.asarray(v), params)
    best = None
    for kind, (what, lam_n, lam_t) in found.items():
        lam_n, lam_t = np.asarray(lam_n), np.asarray(lam_t)
        for i in range(lam_n.shape[0]):
            for lam, part in ((lam_n[i], "normal"), (lam_t[i], "friction")):
                if np.isfinite(lam) and lam > 0 and (best is None or lam > best[0]):
                    best = (float(lam), kind, i, part, [np.asarray(x) for x in what])
    if best is None:
        return None
    lam, kind, i, part, (k, c, v_s) = best
    k, c, v_s = (float(np.broadcast_to(x, np.shape(lam_n))[i]) for x in (k, c, v_s))
    if kind == "plane":
        where = f"sphere {i}'s contact with the plane"
    elif kind == "pair":
        a, b = contact.pairs[i]
        where = f"the contact between spheres {a} and {b}"
    else:
        st = joint_limits.stops(contact.limits)
        limit = contact.limits[int(st.joint[i])]
        side = "lower" if st.sign[i] > 0 else "upper"
        name = limit.name or f"coordinate {limit.index}"
        where = f"the {side} limit of joint {name!r}"
    if part == "normal":
        what = (
            f"{where}, its normal spring (stiffness={k:.4g}, dissipation={c:.4g}; "
            "lambda = sqrt(k_eff/m), or its overdamped rate)"
        )
    else:
        what = (
            f"{where}, its friction holding it (stiction_velocity={v_s:.4g}; lambda = "
            "mu_s f_n/(v_s m) while it sticks)"
        )
    return what, lam
