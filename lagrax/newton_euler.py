"""Independent Newton–Euler derivations: an oracle for the autodiff Lagrangian.

- [`planar_2r`][lagrax.newton_euler.planar_2r]: the planar 2R arm by the lecture's free-body method.
  Each link is cut free; Newton's law `m a_c = Σ f` and Euler's equation `I α = Σ M` (about the
  centre of mass, or about a fixed point with the parallel-axis inertia) are applied to each, and
  the unknown joint reaction is eliminated.
- [`rnea`][lagrax.newton_euler.rnea]: the recursive Newton–Euler algorithm for any serial chain or
  kinematic tree of [`lagrax.chains`][] (planar, spatial, [`Tree`][lagrax.chains.Tree]): velocities
  and accelerations outward from the base, forces and moments inward from the tips.

No Lagrangian appears anywhere in this module, and `rnea` reads only the chain's
structure (joint types, axes, fixed rotations) and `params`, with its own kinematics.
"""

import functools
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from ._core.custom_types import Params
from ._core.errors import ArgumentTypeError, ShapeError
from ._multibody.articulated.chains import PlanarChain, SpatialChain
from ._multibody.articulated.trees import AbstractTree, Tree
from ._multibody.joint_space import joint_inverse
from ._multibody.joints import revolute

__all__ = ["planar_2r", "planar_2r_free_body", "FreeBody2R", "rnea"]


def _cross_z(a, b):
    """z component of the planar cross product `a × b`."""
    return a[0] * b[1] - a[1] * b[0]


def _z_cross(w, r):
    """`(w ẑ) × r` for a planar vector `r`."""
    return w * jnp.stack([-r[1], r[0]])


class FreeBody2R(NamedTuple):
    """Result of the free-body analysis of the 2R arm (all in the fixed frame)."""

    tau: Float[Array, "2"]
    """Joint torques `(τ1, τ2)`; `τ2` acts on link 2, `−τ2` on link 1."""
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

    1. Kinematics. Link 1 turns at `ω1 = θ̇1`, `α1 = θ̈1`; link 2 at `ω2 = θ̇1 + θ̇2`,
       `α2 = θ̈1 + θ̈2`. For a point at `r` from a pivot of a link,
       `a = a_pivot + α ẑ × r − ω² r`: this gives the elbow and both CoM accelerations.
    2. Link 2, Newton: `m2 a_c2 = f2 + m2 g⃗` gives the reaction `f2` of link 1 on link 2.
    3. Link 2, Euler about its CoM: `I2 α2 = τ2 + (r_elbow − r_c2) × f2` gives `τ2`.
    4. Link 1, Euler about the fixed joint `O` (parallel axis `I1 + m1 r1²`):
       `(I1 + m1 r1²) α1 = τ1 − τ2 + r_c1 × m1 g⃗ + r_elbow × (−f2)` gives `τ1`; the
       ground reaction `f1` has no moment about `O` and drops out.
    5. Link 1, Newton: `m1 a_c1 = f1 − f2 + m1 g⃗` recovers `f1` (not needed for τ).
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
    """Joint torques `(τ1, τ2)` of the planar 2R arm by the free-body Newton–Euler method.

    Same convention and parameter names as [`lagrax.models.planar_2r`][]; see
    [`planar_2r_free_body`][lagrax.newton_euler.planar_2r_free_body] for the steps and the reaction
    forces.
    """
    return planar_2r_free_body(q, qd, qdd, params).tau


# ------------------------------------------------------------------ recursive Newton–Euler
def rnea(
    chain: PlanarChain | SpatialChain | Tree,
    q: Float[Array, " n"],
    qd: Float[Array, " n"],
    qdd: Float[Array, " n"],
    params: Params,
) -> Float[Array, " n"]:
    r"""Joint torques/forces of a serial chain or a kinematic tree by the recursive
    Newton–Euler algorithm.

    **Outward recursion** (base to tip), link `i` from link `i − 1`, all vectors in
    link `i`'s own frame, `E = ⁱ⁻¹R_iᵀ`, joint axis `a`, `p` the joint's offset:

    - revolute: `ω_i = E ω_{i−1} + q̇_i a`, `ω̇_i = E ω̇_{i−1} + (E ω_{i−1}) × q̇_i a + q̈_i a`,
      `a_i = E (a_{i−1} + ω̇_{i−1} × p + ω_{i−1} × (ω_{i−1} × p))` (acceleration of the
      frame origin, which lies on the joint axis);
    - prismatic (`s = q_i a`): `ω_i = E ω_{i−1}`, `ω̇_i = E ω̇_{i−1}`,
      `a_i = E (…as above…) + ω̇_i × s + ω_i × (ω_i × s) + 2 ω_i × q̇_i a + q̈_i a`;
    - centre of mass: `a_ci = a_i + ω̇_i × c_i + ω_i × (ω_i × c_i)`;
    - Newton and Euler: `F_i = m_i a_ci`, `N_i = I_i ω̇_i + ω_i × I_i ω_i`.

    Gravity enters as an upward acceleration `g up` of the base (`a_0 = −g⃗`).

    **Inward recursion** (tip to base), with `f_i`, `n_i` the force and moment (about
    frame `i`'s origin) exerted on link `i` by link `i − 1`:

    - `f_i = ⁱR_{i+1} f_{i+1} + F_i`,
    - `n_i = N_i + ⁱR_{i+1} n_{i+1} + c_i × F_i + ⁱp_{i+1} × ⁱR_{i+1} f_{i+1}`,
    - `τ_i = n_i · a_i` (revolute) or `f_i · a_i` (prismatic).

    For a [`Tree`][lagrax.chains.Tree] "link `i − 1`" is body `i`'s parent and the
    inward sums run over all of body `i`'s children `c`:
    `f_i = F_i + Σ_c ⁱR_c f_c`, `n_i = N_i + c_i × F_i + Σ_c (ⁱR_c n_c + ⁱp_c × ⁱR_c f_c)`.
    (Joint damping, a Rayleigh dissipation of the system, is not part of `τ` here.)
    A tree's joint-space terms, where its params have them (armature `a`, joint springs
    and fixed tendons' springs, `lagrax._multibody.joint_space`), add `a θ̈ + ∂V_s/∂θ`.
    A tree with mimic joints runs the recursion over all its joints at `θ = J q + b`,
    `θ̇ = J q̇`, `θ̈ = J q̈` and returns `Jᵀ τ_θ` (the principle of virtual work).

    For a [`PlanarChain`][lagrax.chains.PlanarChain] the same recursion runs in the plane with
    scalar angular rates and moments (`z` components) in the fixed frame: joint `i + 1`'s
    acceleration `a_{i+1} = a_i + α_i ẑ × l_i u_i − ω_i² l_i u_i`, then
    `f_i = m_i a_ci + f_{i+1}` and ``n_i = I_i α_i + r_i u_i × m_i a_ci + n_{i+1} +
    l_i u_i × f_{i+1}` about joint `i``.

    This is an independent derivation (no energies, no autodiff, its own kinematics): use
    it to check a chain's [`inverse_dynamics`][lagrax.LagrangianSystem.inverse_dynamics].

    **Arguments:**

    - `chain`: a [`PlanarChain`][lagrax.chains.PlanarChain],
      [`SpatialChain`][lagrax.chains.SpatialChain] or [`Tree`][lagrax.chains.Tree].
    - `q`, `qd`, `qdd`: joint positions, rates and accelerations, shape `(n,)`.
    - `params`: the chain's parameters (`chain.params(...)`).

    **Returns:** `τ`, shape `(n,)`: joint torques (revolute) or forces (prismatic).

    **Raises:** `ShapeError` for inputs of the wrong length; `ArgumentTypeError` (a
    `TypeError`) for another kind of chain.
    """
    return _rnea(chain, q, qd, qdd, params)


def _checked(chain, q, qd, qdd):
    q, qd, qdd = (jnp.asarray(x) for x in (q, qd, qdd))
    for name, x in (("q", q), ("qd", qd), ("qdd", qdd)):
        if x.shape != (chain.n,):
            raise ShapeError(f"rnea: {name} has shape {x.shape}, expected ({chain.n},)")
    return q, qd, qdd


# One oracle per kind of chain, registered by type: a new kind registers its own.
@functools.singledispatch
def _rnea(chain, q, qd, qdd, params):
    raise ArgumentTypeError(
        f"rnea needs a PlanarChain, SpatialChain or Tree, got {type(chain).__name__}"
    )


@_rnea.register
def _(chain: PlanarChain, q, qd, qdd, params):
    return _rnea_planar(chain.n, *_checked(chain, q, qd, qdd), params)


@_rnea.register
def _(chain: AbstractTree, q, qd, qdd, params):
    q, qd, qdd = _checked(chain, q, qd, qdd)
    if not chain.mimic:
        return _rnea_spatial(chain, q, qd, qdd, params) + joint_inverse(params, q, qdd)
    # mimic joints: every joint's torque at θ = J q + b, θ̇ = J q̇, θ̈ = J q̈, then Jᵀ τ_θ
    theta = (chain.joint_angles(q), chain.joint_rates(qd), chain.joint_rates(qdd))
    tau = _rnea_spatial(chain, *theta, params) + joint_inverse(params, theta[0], theta[2])
    return jnp.asarray(chain.coupling_matrix(), tau.dtype).T @ tau


def _rnea_planar(n, q, qd, qdd, p):
    m, length, r, inertia = (jnp.asarray(p[k]) for k in ("m", "l", "r", "I"))
    g = jnp.asarray(p["g"])
    # outward: absolute angle, rate and acceleration of each link; joint accelerations
    phi = w = alpha = jnp.zeros((), q.dtype)
    a_joint = jnp.stack([jnp.zeros_like(g), g])  # base accelerates up: gravity
    links = []
    for i in range(n):
        phi, w, alpha = phi + q[i], w + qd[i], alpha + qdd[i]
        u = jnp.stack([jnp.cos(phi), jnp.sin(phi)])
        rc, rl = r[i] * u, length[i] * u
        a_c = a_joint + _z_cross(alpha, rc) - w**2 * rc
        links.append((alpha, rc, rl, a_c))
        a_joint = a_joint + _z_cross(alpha, rl) - w**2 * rl
    # inward: force and moment of link i-1 on link i at joint i
    f_next = jnp.zeros(2, q.dtype)
    n_next = jnp.zeros((), q.dtype)
    tau = [None] * n
    for i in reversed(range(n)):
        alpha, rc, rl, a_c = links[i]
        force = m[i] * a_c
        n_i = inertia[i] * alpha + _cross_z(rc, force) + n_next + _cross_z(rl, f_next)
        f_next, n_next = force + f_next, n_i
        tau[i] = n_i
    return jnp.stack(tau)


def _skew(v):
    z = jnp.zeros_like(v[0])
    return jnp.stack(
        [jnp.stack([z, -v[2], v[1]]), jnp.stack([v[2], z, -v[0]]), jnp.stack([-v[1], v[0], z])]
    )


def _rotation_about(axis, angle):
    """`R = cos θ 1 + sin θ [a]× + (1 − cos θ) a aᵀ` (unit `a`)."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    return c * jnp.eye(3, dtype=axis.dtype) + s * _skew(axis) + (1 - c) * jnp.outer(axis, axis)


def _rnea_spatial(chain, q, qd, qdd, p):
    dtype = q.dtype
    m, com, inertia, offset = (jnp.asarray(p[k]) for k in ("m", "com", "inertia", "offset"))
    g = jnp.asarray(p["g"])
    n = chain.n_bodies
    axes = [jnp.asarray(np.asarray(a), dtype) for a in chain.axes]
    fixed = [jnp.asarray(np.asarray(s), dtype) for s in chain.rotations]
    # ⁱ⁻¹R_i and ⁱ⁻¹p_i (position of origin i in frame i-1)
    rel_rot, rel_pos = [], []
    for i, kind in enumerate(chain.joint_types):
        if revolute(kind):
            rel_rot.append(fixed[i] @ _rotation_about(axes[i], q[i]))
            rel_pos.append(offset[i])
        else:
            rel_rot.append(fixed[i])
            rel_pos.append(offset[i] + fixed[i] @ (axes[i] * q[i]))

    parents = chain.parents
    # outward: each body from its parent (the base: at rest, accelerating up: gravity)
    base = (
        jnp.zeros(3, dtype),
        jnp.zeros(3, dtype),
        g * jnp.asarray(np.asarray(chain.up), dtype),
    )
    motion = []  # (ω_i, ω̇_i, a_i) in frame i
    forces, moments = [], []
    for i, kind in enumerate(chain.joint_types):
        w, wd, acc = base if parents[i] < 0 else motion[parents[i]]
        e = rel_rot[i].T
        a = axes[i]
        pi = offset[i]
        acc = e @ (acc + jnp.cross(wd, pi) + jnp.cross(w, jnp.cross(w, pi)))
        if revolute(kind):
            w_prev = e @ w
            w = w_prev + qd[i] * a
            wd = e @ wd + jnp.cross(w_prev, qd[i] * a) + qdd[i] * a
        else:
            w, wd = e @ w, e @ wd
            s = a * q[i]
            acc = (
                acc
                + jnp.cross(wd, s)
                + jnp.cross(w, jnp.cross(w, s))
                + 2 * jnp.cross(w, qd[i] * a)
                + qdd[i] * a
            )
        motion.append((w, wd, acc))
        a_c = acc + jnp.cross(wd, com[i]) + jnp.cross(w, jnp.cross(w, com[i]))
        forces.append(m[i] * a_c)
        moments.append(inertia[i] @ wd + jnp.cross(w, inertia[i] @ w))

    # inward: f_i, n_i exerted on body i by its parent, summing over its children
    f_on = [None] * n
    n_on = [None] * n
    tau = [None] * n
    for i in reversed(range(n)):
        f_i = forces[i]
        mom = moments[i] + jnp.cross(com[i], forces[i])
        for c in (k for k in range(i + 1, n) if parents[k] == i):
            f_child = rel_rot[c] @ f_on[c]
            f_i = f_i + f_child
            mom = mom + rel_rot[c] @ n_on[c] + jnp.cross(rel_pos[c], f_child)
        f_on[i], n_on[i] = f_i, mom
        tau[i] = jnp.dot(mom if revolute(chain.joint_types[i]) else f_i, axes[i])
    return jnp.stack(tau)
