r"""Featherstone's recursions with a free (6-DOF) root joint: a floating base.

The coordinates are Pinocchio's free-flyer convention: `q = (x, y, z, q_x, q_y, q_z, q_w,
joints…)` (the base origin in the world frame and the unit quaternion of the base
rotation `R`, world from base) and `v = (v_b, ω_b, joint rates…)` with `v_b` the velocity
of the base origin and `ω_b` the base's angular velocity, both in the base frame.

The recursions of `lagrax._multibody.algorithms.recursions` work in world coordinates at the world
origin. There the base moves with the spatial velocity `v_B = S_B (v_b, ω_b)`, with the
motion subspace of the root, the identity in the base's own frame, written in world
coordinates:

    S_B = [[0, R], [R, [p]× R]]      (ω = R ω_b, v_O = R v_b + p × R ω_b).

`S_B` moves with the base, so `Ṡ_B v = v_B × v_B = 0`: the base's spatial acceleration is
`S_B v̇`. The bodies below the base are the tree's, placed from the base pose instead of
the world's origin; gravity stays the fictitious base acceleration `a_0 = (0, g up)`.

The recursions run in world axes at the *base origin* (`p = 0` above): in a uniform
gravity field the equations do not depend on where the base is, and spatial inertias
about a far-away origin would lose digits to the parallel-axis terms `m |p|²` (a light
robot 2 m from the world origin: 1e-11 relative in `v̇` instead of 1e-13). The base's
position is kept for what does depend on it (the centre of mass, the momentum about the
world origin, the potential energy).

- ABA: the joints' inward pass hands the base the articulated inertia `I^A_B` and bias
  `p^A_B` of its subtrees; the base, a free body, gets `a'_B = (I^A_B)⁻¹ (S_B⁻ᵀ τ_B −
  p^A_B)` (a 6×6 solve; `a'_B = S_B v̇ + a_0`), and the outward pass starts from it.
- RNEA: the outward pass starts from `a'_B = S_B v̇ + a_0` and `v_B`; the base's
  generalized force is `τ_B = S_Bᵀ (I_B a'_B + v_B ×* I_B v_B + f_children)`, the wrench
  on the base about its origin in the base frame (force, torque).
- CRBA: `M_BB = S_Bᵀ I^c_B S_B` (`I^c_B` the whole robot's inertia), `M_Bj = S_Bᵀ I^c_j S_j`,
  and the joints' block as for a fixed base.

A tree with no joints (a single rigid body: `q` of size 7, `v` of size 6) runs the same
code with passes over no bodies: ABA is the base's 6×6 solve `I_B a'_B = S_B⁻ᵀ τ_B −
v_B ×* I_B v_B` (Newton–Euler for one body), RNEA its wrench, CRBA `M = S_Bᵀ I_B S_B`.
"""

from typing import Any

import jax.numpy as jnp
import numpy as np

from ..._core.checks import param_shapes
from .. import joint_space as js
from ..joints import revolute_flags
from . import recursions as a
from .links import UNROLL_MAX_SPATIAL, joint_trig, spatial_link


def quaternion_rotation(quat: Any) -> jnp.ndarray:
    """The rotation matrix of the quaternion `(x, y, z, w)`, normalized first (so a
    quaternion slightly off the unit sphere still gives a rotation)."""
    x, y, z, w = quat / jnp.linalg.norm(quat)
    return jnp.stack(
        [
            jnp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)]),
            jnp.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)]),
            jnp.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]),
        ]
    )


def quaternion_rate(quat: Any, omega: Any) -> jnp.ndarray:
    """`q̇ = ½ q ⊗ (ω, 0)` for `q = (x, y, z, w)` and a body-frame angular velocity `ω`."""
    vec, w = quat[:3], quat[3]
    return jnp.concatenate([0.5 * (w * omega + jnp.cross(vec, omega)), -0.5 * (vec @ omega)[None]])


def skew(p: Any) -> jnp.ndarray:
    zero = jnp.zeros((), p.dtype)
    return jnp.stack(
        [
            jnp.stack([zero, -p[2], p[1]]),
            jnp.stack([p[2], zero, -p[0]]),
            jnp.stack([-p[1], p[0], zero]),
        ]
    )


def _tuples(x: jnp.ndarray) -> Any:
    """An array as nested tuples of JAX scalars (the recursions' vectors and matrices)."""
    if x.ndim == 0:
        return x
    return tuple(_tuples(x[i]) for i in range(x.shape[0]))


def _array(x: Any, dtype: Any) -> jnp.ndarray:
    """Nested tuples (scalars, some perhaps Python `0.0`) as an array."""
    if isinstance(x, tuple):
        return jnp.stack([_array(v, dtype) for v in x])
    return jnp.asarray(x, dtype)


class FloatingChain:
    """A floating-base tree at one configuration: the joints' `recursions.Chain` (placed
    from the base pose), the base's world inertia at the origin `I_B`, its motion
    subspace `S_B` (6×6), all in world axes at the base origin, and the pose: `position`
    (the base origin in the world frame) and `rot` (`p`, the origin of the spatial
    quantities relative to the base origin, is zero)."""

    def __init__(self, chain: a.Chain, inertia_base: Any, s_base: Any, position: Any, rot: Any):
        self.chain, self.inertia_base, self.s_base, self.position, self.rot = (
            chain,
            inertia_base,
            s_base,
            position,
            rot,
        )
        self.p = jnp.zeros_like(position)
        self.theta: Any = None  # every body's joint angle (`None`: no joints)
        self.params: Any = {}  # the params it was built from (their joint-space terms)

    def base_velocity(self, v_base: Any) -> Any:
        """`v_B = S_B (v_b, ω_b)` as a tuple."""
        return _tuples(self.s_base @ v_base)

    def to_base(self, motion: Any) -> jnp.ndarray:
        """`S_B⁻¹ m`: a world motion vector `(ω, v_O)` as the base's `(v_b, ω_b)`."""
        omega, v_o = motion[:3], motion[3:]
        return jnp.concatenate([self.rot.T @ (v_o - jnp.cross(self.p, omega)), self.rot.T @ omega])

    def force_from_base(self, tau: Any) -> jnp.ndarray:
        """`S_B⁻ᵀ τ`: the base's `(force, torque about its origin)` in its frame as a
        world force `(n_O, f)` at the origin."""
        f = self.rot @ tau[:3]
        return jnp.concatenate([self.rot @ tau[3:] + jnp.cross(self.p, f), f])


def floating_chain(
    tree: Any, q: Any, params: Any, scan: bool | None = None, lanes: Any = None
) -> FloatingChain:
    """The kinematics of a floating tree (`tree` the joints' `Tree`, `params` with
    `base_m`, `base_com`, `base_inertia`) at `q` of size `7 + n`: every body's joint
    angle `θ = J q_joints + b` (the coordinates themselves without mimic joints), so the
    chain has `tree.n_bodies` links. `lanes`: `(θ, A)`, the joint angles and constants
    `A` in their place (a tree with ball joints: `articulated.balls.lane_state`)."""
    n, dtype = tree.n_bodies, q.dtype
    base = {"base_m": (), "base_com": (3,), "base_inertia": (3, 3)}
    param_shapes(params, base, "a floating base")
    if n:
        tree._check_params(params)
    position, rot = q[:3], quaternion_rotation(q[3:7])
    p = jnp.zeros_like(position)  # the recursions' origin: the base origin
    scan = n > UNROLL_MAX_SPATIAL if scan is None else scan
    passes = a.Passes(n, bool(scan) and n > 0, dtype, tree.parents)
    joints = None
    if n == 0:  # a single rigid body: the base alone, its passes over no bodies
        s, inertia = [], []
    else:
        js.check(params, n)
        big_a, big_b, big_c, slide = tree.joint_constants()
        joints = tree.joint_angles(q[7:]) if lanes is None else lanes[0]
        big_a = big_a if lanes is None else lanes[1]
        axes = np.asarray(tree.axes, float)
        rev = revolute_flags(tree.joint_types)
        values = (jnp.asarray(params[k], dtype) for k in ("offset", "com", "inertia", "m"))
        per_link = (joint_trig(joints), big_a, big_b, big_c, slide, axes, rev, *values)
        _, ys = passes.run(spatial_link, (_tuples(rot), _tuples(p)), passes.links(per_link))
        s, inertia = passes.split(ys)
    g = jnp.asarray(params["g"], dtype)
    a0 = (0.0, 0.0, 0.0) + tuple(a.mul(g, u) for u in tree.up)
    rotor = js.armature(params, dtype) if n else None
    chain = a.Chain(
        passes, a.SPATIAL, s, inertia, a0, None if rotor is None else passes.links(rotor)
    )
    m_base = jnp.asarray(params["base_m"], dtype)
    inertia_w = rot @ jnp.asarray(params["base_inertia"], dtype) @ rot.T
    centre = p + rot @ jnp.asarray(params["base_com"], dtype)
    inertia_base = a.spatial_inertia(m_base, _tuples(inertia_w), _tuples(centre))
    zero = jnp.zeros((3, 3), dtype)
    s_base = jnp.block([[zero, rot], [rot, skew(p) @ rot]])
    out = FloatingChain(chain, inertia_base, s_base, position, rot)
    out.theta, out.params = joints, params
    return out


def _velocities(chain: a.Chain, qd: Any, v0: Any) -> Any:
    """`Chain.velocities` from the base velocity `v0` instead of rest."""
    alg = chain.algebra

    def step(v, x):
        s, inertia, qd_i = x
        v = a.vadd(v, a.vscale(s, qd_i))
        return v, (a.vscale(alg.crm(v, s), qd_i), alg.crf(v, a.matvec(inertia, v)))

    return chain.passes.run(step, v0, chain.passes.zip(chain.s, chain.inertia, qd))[1]


def _base_bias(fc: FloatingChain, v_b: Any) -> Any:
    """`v_B ×* I_B v_B`, the base's velocity-product force."""
    return fc.chain.algebra.crf(v_b, a.matvec(fc.inertia_base, v_b))


def aba(fc: FloatingChain, v: Any, force: Any | None) -> jnp.ndarray:
    """`v̇` (size `6 + n`) of `M v̇ + b = force` by the articulated-body algorithm with a
    free root (`force` `None`: zero; else `(τ_B, τ_joints)`)."""
    chain = fc.chain
    passes, dtype = chain.passes, v.dtype
    v_b = fc.base_velocity(v[:6])
    links = passes.links
    vel = _velocities(chain, links(v[6:]), v_b)
    taus = links(jnp.zeros(passes.n, dtype) if force is None else force[6:])

    def inward(carry, x):
        art_child, p_child = carry
        s, inertia, (c, p), tau, *rotor = x
        art = a.madd(inertia, art_child)
        p_art = a.vadd(p, p_child)
        u = a.matvec(art, s)
        d = a.add(a.dot(s, u), rotor[0]) if rotor else a.dot(s, u)  # D_i += armature
        d_inv = 1.0 / jnp.where(d > 0, d, jnp.nan)
        u_sc = a.sub(tau, a.dot(s, p_art))
        child = a.sym_rank1_sub(art, u, d_inv)
        pa = a.vadd(p_art, a.vadd(a.matvec(child, c), a.vscale(u, a.mul(u_sc, d_inv))))
        return (child, pa), (u, d_inv, u_sc)

    xs = chain.zip_armature(chain.s, chain.inertia, vel, taus)
    (art_sub, p_sub), factors = passes.run(
        inward, (chain._zero_matrix(), chain._zero()), xs, reverse=True
    )
    art_base = _array(a.madd(fc.inertia_base, art_sub), dtype)
    p_base = _array(a.vadd(_base_bias(fc, v_b), p_sub), dtype)
    wrench = -p_base if force is None else fc.force_from_base(force[:6]) - p_base
    acc_base = jnp.linalg.solve(art_base, wrench)  # a'_B = S_B v̇_B + a_0
    vdot_base = fc.to_base(acc_base - _array(chain.a0, dtype))

    def outward(acc, x):
        s, (c, _), (u, d_inv, u_sc) = x
        acc = a.vadd(acc, c)
        qdd = a.mul(a.sub(u_sc, a.dot(u, acc)), d_inv)
        return a.vadd(acc, a.vscale(s, qdd)), qdd

    qdd = passes.run(outward, _tuples(acc_base), passes.zip(chain.s, vel, factors))[1]
    return jnp.concatenate([vdot_base, passes.vector(qdd, v)])


def rnea(fc: FloatingChain, v: Any, vdot: Any | None) -> jnp.ndarray:
    """`M v̇ + b` (size `6 + n`; `vdot` `None`: the bias `b`) by recursive Newton–Euler
    with a free root: the first six entries are the wrench on the base about its origin,
    in the base frame (force, torque)."""
    chain = fc.chain
    passes, dtype = chain.passes, v.dtype
    v_b = fc.base_velocity(v[:6])
    links = passes.links
    vel = _velocities(chain, links(v[6:]), v_b)
    acc_base = _array(chain.a0, dtype)
    if vdot is not None:
        acc_base = acc_base + fc.s_base @ vdot[:6]
    qdd = links(jnp.zeros(passes.n, dtype) if vdot is None else vdot[6:])

    def outward(acc, x):
        s, inertia, (c, p), qdd_i = x
        acc = a.vadd(a.vadd(acc, c), a.vscale(s, qdd_i))
        return acc, a.vadd(a.matvec(inertia, acc), p)

    xs = passes.zip(chain.s, chain.inertia, vel, qdd)
    _, forces = passes.run(outward, _tuples(acc_base), xs)

    def inward(f_child, x):
        s, f = x
        f = a.vadd(f, f_child)
        return f, a.dot(s, f)

    f_sub, taus = passes.run(inward, chain._zero(), passes.zip(chain.s, forces), reverse=True)
    f_base = a.vadd(a.matvec(fc.inertia_base, _tuples(acc_base)), _base_bias(fc, v_b))
    f_base = _array(a.vadd(f_base, f_sub), dtype)
    return jnp.concatenate([fc.s_base.T @ f_base, passes.vector(taus, v)])


def crba(fc: FloatingChain) -> tuple[jnp.ndarray, jnp.ndarray]:
    """`(M, I^c_B)`: the `(6 + n) × (6 + n)` mass matrix by the composite-rigid-body
    algorithm with a free root, and the whole robot's spatial inertia in world axes at
    the base origin."""
    chain = fc.chain
    passes, dtype = chain.passes, fc.s_base.dtype

    def inward(comp, x):
        s, inertia = x
        comp = a.madd(inertia, comp)
        return comp, a.matvec(comp, s)

    comp_sub, f = passes.run(
        inward, chain._zero_matrix(), passes.zip(chain.s, chain.inertia), reverse=True
    )
    if passes.n:
        s_arr, f_arr = passes.column(chain.s), passes.column(f)
    else:  # a single rigid body: no joint columns
        s_arr = f_arr = jnp.zeros((0, 6), dtype)
    g = s_arr @ f_arr.T  # g[j, i] = S_j · I^c_i S_i
    above = passes.ancestors()
    if passes.parents is None:
        m_jj = jnp.where(above, g, g.T)
    else:
        m_jj = jnp.where(above, g, jnp.where(above.T, g.T, 0.0))
    total = _array(a.madd(fc.inertia_base, comp_sub), dtype)
    m_bb = fc.s_base.T @ total @ fc.s_base
    m_bj = fc.s_base.T @ f_arr.T.astype(dtype)
    mass = jnp.block([[m_bb, m_bj], [m_bj.T, m_jj.astype(dtype)]])
    return mass, total
