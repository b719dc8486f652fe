"""Hand-written closed-form 2R arm (the lecture's equations), the baseline for benchmarks."""

import jax.numpy as jnp


def forward_dynamics_2r(q, qd, p, tau=None):
    """θ̈ of the 2R arm from the lecture's closed-form M, C q̇, G and an explicit 2×2 solve."""
    s2, c2 = jnp.sin(q[1]), jnp.cos(q[1])
    c1, c12 = jnp.cos(q[0]), jnp.cos(q[0] + q[1])
    m1, m2, l1, r1, r2 = p["m1"], p["m2"], p["l1"], p["r1"], p["r2"]
    i1, i2, g = p["I1"], p["I2"], p["g"]
    h = m2 * l1 * r2
    m11 = i1 + i2 + m1 * r1**2 + m2 * (l1**2 + r2**2) + 2 * h * c2
    m12 = i2 + m2 * r2**2 + h * c2
    m22 = i2 + m2 * r2**2
    b1 = h * s2 * (2 * qd[0] + qd[1]) * qd[1] - m1 * g * r1 * c1 - m2 * g * (l1 * c1 + r2 * c12)
    b2 = -h * s2 * qd[0] ** 2 - m2 * g * r2 * c12
    if tau is not None:
        b1, b2 = b1 + tau[0], b2 + tau[1]
    det = m11 * m22 - m12 * m12
    return jnp.stack([(m22 * b1 - m12 * b2) / det, (m11 * b2 - m12 * b1) / det])
