"""Independent Newton–Euler derivations: an oracle for the autodiff Lagrangian.

The planar 2R arm by the lecture's free-body method. Each link is cut free; Newton's law
``m a_c = Σ f`` and Euler's equation ``I α = Σ M`` (about the centre of mass, or about a
fixed point with the parallel-axis inertia) are applied to each, and the unknown joint
reaction is eliminated. No Lagrangian appears anywhere in this module.
"""

from typing import NamedTuple

import jax.numpy as jnp
from jaxtyping import Array, Float

from ._typing import Params


def _cross_z(a, b):
    """z component of the planar cross product ``a × b``."""
    return a[0] * b[1] - a[1] * b[0]


def _z_cross(w, r):
    """``(w ẑ) × r`` for a planar vector ``r``."""
    return w * jnp.stack([-r[1], r[0]])


class FreeBody2R(NamedTuple):
    """Result of the free-body analysis of the 2R arm (all in the fixed frame)."""

    tau: Float[Array, "2"]
    """Joint torques ``(τ1, τ2)``; ``τ2`` acts on link 2, ``−τ2`` on link 1."""
    f_joint1: Float[Array, "2"]
    """Force of the ground on link 1 at joint 1."""
    f_joint2: Float[Array, "2"]
    """Force of link 1 on link 2 at joint 2 (link 2 pushes back with its negative)."""
    a_c1: Float[Array, "2"]
    """Acceleration of the centre of mass of link 1."""
    a_c2: Float[Array, "2"]
    """Acceleration of the centre of mass of link 2."""


def planar_2r_free_body(q, qd, qdd, params: Params) -> FreeBody2R:
    """Free-body Newton–Euler analysis of the planar 2R arm (lecture convention).

    Steps:

    1. Kinematics. Link 1 turns at ``ω1 = θ̇1``, ``α1 = θ̈1``; link 2 at ``ω2 = θ̇1 + θ̇2``,
       ``α2 = θ̈1 + θ̈2``. For a point at ``r`` from a pivot of a link,
       ``a = a_pivot + α ẑ × r − ω² r``: this gives the elbow and both CoM accelerations.
    2. Link 2, Newton: ``m2 a_c2 = f2 + m2 g⃗`` gives the reaction ``f2`` of link 1 on link 2.
    3. Link 2, Euler about its CoM: ``I2 α2 = τ2 + (r_elbow − r_c2) × f2`` gives ``τ2``.
    4. Link 1, Euler about the fixed joint ``O`` (parallel axis ``I1 + m1 r1²``):
       ``(I1 + m1 r1²) α1 = τ1 − τ2 + r_c1 × m1 g⃗ + r_elbow × (−f2)`` gives ``τ1``; the
       ground reaction ``f1`` has no moment about ``O`` and drops out.
    5. Link 1, Newton: ``m1 a_c1 = f1 − f2 + m1 g⃗`` recovers ``f1`` (not needed for τ).
    """
    p = params
    th1, th12 = q[0], q[0] + q[1]
    w1, w2 = qd[0], qd[0] + qd[1]
    a1, a2 = qdd[0], qdd[0] + qdd[1]
    u1 = jnp.stack([jnp.cos(th1), jnp.sin(th1)])
    u12 = jnp.stack([jnp.cos(th12), jnp.sin(th12)])
    g_vec = jnp.stack([jnp.zeros_like(p["g"]), -p["g"]])

    # 1. kinematics (joint 1 is fixed)
    r_c1 = p["r1"] * u1
    r_elbow = p["l1"] * u1
    a_c1 = _z_cross(a1, r_c1) - w1**2 * r_c1
    a_elbow = _z_cross(a1, r_elbow) - w1**2 * r_elbow
    r_2 = p["r2"] * u12  # elbow -> CoM 2
    r_c2 = r_elbow + r_2
    a_c2 = a_elbow + _z_cross(a2, r_2) - w2**2 * r_2

    # 2. Newton, link 2
    f2 = p["m2"] * (a_c2 - g_vec)
    # 3. Euler about CoM 2
    tau2 = p["I2"] * a2 - _cross_z(r_elbow - r_c2, f2)
    # 4. Euler for link 1 about the fixed joint, reaction f1 eliminated
    i1_o = p["I1"] + p["m1"] * p["r1"] ** 2
    tau1 = i1_o * a1 + tau2 - _cross_z(r_c1, p["m1"] * g_vec) + _cross_z(r_elbow, f2)
    # 5. Newton, link 1
    f1 = p["m1"] * (a_c1 - g_vec) + f2
    return FreeBody2R(jnp.stack([tau1, tau2]), f1, f2, a_c1, a_c2)


def planar_2r(q, qd, qdd, params: Params) -> Float[Array, "2"]:
    """Joint torques ``(τ1, τ2)`` of the planar 2R arm by the free-body Newton–Euler method.

    Same convention and parameter names as :func:`lagrax.models.planar_2r`; see
    :func:`planar_2r_free_body` for the steps and the reaction forces.
    """
    return planar_2r_free_body(q, qd, qdd, params).tau
