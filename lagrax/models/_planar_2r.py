"""The lecture's planar 2R arm (double pendulum) from its energies."""

import jax.numpy as jnp

from .._core.checks import physical
from .._core.errors import ArgumentTypeError
from .._systems.lagrangian import LagrangianSystem

PARAM_NAMES = ("m1", "m2", "l1", "l2", "r1", "r2", "I1", "I2", "g")


def kinetic(q, qd, p):
    """`T = ½ m1 |v_c1|² + ½ I1 θ̇1² + ½ m2 |v_c2|² + ½ I2 (θ̇1 + θ̇2)²`.

    CoM velocities by the chain rule on the CoM positions (written out, since a planar
    link needs only its CoM velocity and one angular rate).
    """
    th1, th12 = q[0], q[0] + q[1]
    w1, w12 = qd[0], qd[0] + qd[1]
    v1_sq = (p["r1"] * w1) ** 2
    # v_c2 = l1 θ̇1 (−s1, c1) + r2 (θ̇1+θ̇2)(−s12, c12)
    v2x = -p["l1"] * jnp.sin(th1) * w1 - p["r2"] * jnp.sin(th12) * w12
    v2y = p["l1"] * jnp.cos(th1) * w1 + p["r2"] * jnp.cos(th12) * w12
    return 0.5 * (
        p["m1"] * v1_sq + p["I1"] * w1**2 + p["m2"] * (v2x**2 + v2y**2) + p["I2"] * w12**2
    )


def potential(q, p):
    """`V = g (m1 y_c1 + m2 y_c2)` with gravity along −y."""
    s1, s12 = jnp.sin(q[0]), jnp.sin(q[0] + q[1])
    return p["g"] * (p["m1"] * p["r1"] * s1 + p["m2"] * (p["l1"] * s1 + p["r2"] * s12))


def default_params(dtype=None) -> dict:
    """Two uniform 1 kg, 1 m rods (CoM at mid-length, I = m l²/12), g = 9.81 m/s²."""
    vals = dict(m1=1.0, m2=1.0, l1=1.0, l2=1.0, r1=0.5, r2=0.5, I1=1 / 12, I2=1 / 12, g=9.81)
    return {k: jnp.asarray(v, dtype=dtype) for k, v in vals.items()}


def planar_2r(**overrides):
    """The planar 2R arm of the lecture, as `(system, params)`.

    Convention: `θ1` measured from the x axis, `θ2` relative to link 1, gravity along
    −y. Link `i` has mass `m_i`, length `l_i`, its centre of mass on the link at
    distance `r_i` from its joint and z-inertia `I_i` about that centre of mass.
    `params` is a dict with keys `m1 m2 l1 l2 r1 r2 I1 I2 g` (SI units); keyword
    arguments override the defaults (two uniform 1 kg, 1 m rods).

    Its equations of motion (lecture, eq. of the 2R arm):

        τ1 = (I1 + I2 + m1 r1² + m2 (l1² + r2² + 2 l1 r2 c2)) θ̈1 + (I2 + m2 (r2² + l1 r2 c2)) θ̈2
             − m2 l1 r2 s2 (2 θ̇1 + θ̇2) θ̇2 + m1 g r1 c1 + m2 g (l1 c1 + r2 c12)
        τ2 = (I2 + m2 (r2² + l1 r2 c2)) θ̈1 + (I2 + m2 r2²) θ̈2 + m2 l1 r2 s2 θ̇1² + m2 g r2 c12

    **Example:** `system, params = lagrax.models.planar_2r(m2=2.0)`
    """
    params = default_params()
    unknown = set(overrides) - set(PARAM_NAMES)
    if unknown:
        raise ArgumentTypeError(
            f"planar_2r() got unknown parameters {sorted(unknown)}; known: {PARAM_NAMES}"
        )
    params.update({k: jnp.asarray(v, dtype=float) for k, v in overrides.items()})
    for key, what in (("m1", "mass"), ("m2", "mass"), ("I1", "inertia"), ("I2", "inertia")):
        physical(params[key], f"planar_2r {key}", what=what)
    system = LagrangianSystem(kinetic, potential, n_dof=2, name="planar 2R arm")
    return system, params
