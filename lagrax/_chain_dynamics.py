"""Chains' structure-aware equations: their kinematics as a `Chain`,
and `ChainEquations`, which a chain's `LagrangianSystem` evaluates instead of
differentiating its energies (see `lagrax._articulated`)."""

from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from . import _articulated as a
from ._errors import ShapeError
from ._typing import Params


def _check(n: int, q) -> None:
    if q.shape != (n,):
        raise ShapeError(f"q has shape {q.shape}, expected ({n},) for this chain")


# Chains up to these lengths are written out link by link (straight-line code that skips
# structural zeros: fastest to run); longer ones loop over the links with ``lax.scan``,
# whose compile time does not grow with n.
UNROLL_MAX_PLANAR = 3
UNROLL_MAX_SPATIAL = 2
# The energies' pass is short enough to write out for longer chains: `simulate` evaluates
# it under `vmap` over the saved states, where a scan over the links costs ~3x more
# (measured on the 7-DOF arm: 0.28 against 0.97 µs a saved state).
UNROLL_MAX_ENERGIES = 10


def _planar_link(carry, x):
    phi, px, py = carry
    q, m, length, r, inertia = x
    phi = a.add(phi, q)
    c, sn = jnp.cos(phi), jnp.sin(phi)
    s = (1.0, py, -px)
    com = (a.add(px, r * c), a.add(py, r * sn))
    inertia = a.planar_inertia(m, inertia, com)
    return (phi, a.add(px, length * c), a.add(py, length * sn)), (s, inertia)


def planar_chain(n: int, q, params: Params, scan: bool | None = None) -> a.Chain:
    """A planar chain (joint `i` at `p_i`, link angle `φ_i = q_1 + … + q_i`): motion
    subspaces `S_i = (1, p_iy, −p_ix)` and link inertias at the origin."""
    _check(n, q)
    scan = n > UNROLL_MAX_PLANAR if scan is None else scan
    passes = a.Passes(n, scan, q.dtype)
    per_link = (q, *(jnp.asarray(params[k], q.dtype) for k in ("m", "l", "r", "I")))
    _, ys = passes.run(_planar_link, (0.0, 0.0, 0.0), passes.links(per_link))
    s, inertia = passes.split(ys)
    g = jnp.asarray(params["g"], q.dtype)
    return a.Chain(passes, a.PLANAR, s, inertia, (0.0, 0.0, g))


def _spatial_link(carry, x):
    rot, origin = carry
    q, big_a, big_b, big_c, slide, axis, rev, offset, com, inertia, m = x
    origin = a.vadd(origin, a.matvec(rot, a.vadd(offset, a.vscale(slide, q))))
    sn, cs = jnp.sin(q), 1 - jnp.cos(q)
    joint = tuple(
        tuple(
            a.add(big_a[r][k], a.add(a.mul(sn, big_b[r][k]), a.mul(cs, big_c[r][k])))
            for k in range(3)
        )
        for r in range(3)
    )
    cols = tuple(zip(*joint, strict=True))
    rot = tuple(tuple(a.dot(row, col) for col in cols) for row in rot)
    z = a.matvec(rot, axis)
    prismatic = a.sub(1.0, rev)
    s = a.vscale(z, rev) + a.vadd(a.vscale(a.cross(origin, z), rev), a.vscale(z, prismatic))
    centre = a.vadd(origin, a.matvec(rot, com))
    r_bar = [a.matvec(inertia, row) for row in rot]  # rows of R Ī (Ī symmetric)
    world = [[None] * 3 for _ in range(3)]
    for r_ in range(3):
        for k in range(r_, 3):
            world[r_][k] = world[k][r_] = a.dot(r_bar[r_], rot[k])
    return (rot, origin), (s, a.spatial_inertia(m, tuple(map(tuple, world)), centre))


def _transpose_times(m, v):
    """`mᵀ v` for a 3×3 tuple matrix."""
    return tuple(a.dot(tuple(m[r][k] for r in range(3)), v) for k in range(3))


def _spatial_energy_link(carry, x):
    # In link frames: angular velocity w, velocity v of the link origin and the `up`
    # direction, each carried from the parent through the joint rotation J (`Jᵀ`), and
    # the origin's height h. No world rotation is formed.
    w, v, up, h = carry
    q, qd, big_a, big_b, big_c, slide, axis, rev, offset, com, inertia, m, lift = x
    step = a.vadd(offset, a.vscale(slide, q))  # parent origin -> this origin, parent axes
    v = a.vadd(a.vadd(v, a.cross(w, step)), a.vscale(slide, qd))
    h = a.add(h, a.dot(up, step))
    sn, cs = jnp.sin(q), 1 - jnp.cos(q)
    joint = tuple(
        tuple(
            a.add(big_a[r][k], a.add(a.mul(sn, big_b[r][k]), a.mul(cs, big_c[r][k])))
            for k in range(3)
        )
        for r in range(3)
    )
    w = a.vadd(_transpose_times(joint, w), a.vscale(axis, a.mul(rev, qd)))
    v, up = _transpose_times(joint, v), _transpose_times(joint, up)
    v_com = a.vadd(v, a.cross(w, com))
    kinetic = a.mul(0.5, a.add(a.mul(m, a.dot(v_com, v_com)), a.dot(w, a.matvec(inertia, w))))
    potential = a.mul(a.mul(m, lift), a.add(h, a.dot(up, com)))
    return (w, v, up, h), (kinetic, potential)


def spatial_energies(chain: Any, q, qd, params: Params, scan: bool | None = None):
    """`(T, V)` of a spatial chain or tree by one outward pass in link frames:
    `ω_i = J_iᵀ ω_p + a_i q̇_i`, the origin's velocity `v_i = J_iᵀ (v_p + ω_p × d_i +
    s_i q̇_i)` (`d_i` the step from the parent's origin), `T_i = ½ m_i |v_i + ω_i × c_i|²
    + ½ ω_iᵀ Ī_i ω_i` and `V_i = m_i g (h_i + up_i·c_i)` with the height `h_i` of the
    origin and `up` carried into link axes. About half the work of the recursions'
    world-frame kinematics (no `R Ī Rᵀ`, no spatial inertias)."""
    n = chain.n
    _check(n, q)
    scan = n > UNROLL_MAX_ENERGIES if scan is None else scan
    passes = a.Passes(n, scan, q.dtype, getattr(chain, "parents", None))
    big_a, big_b, big_c, slide = chain._joint_constants()
    axes = np.asarray(chain.axes, float)
    rev = np.asarray([1.0 if k == "R" else 0.0 for k in chain.joint_types])
    g = jnp.asarray(params["g"], q.dtype)
    values = [jnp.asarray(params[k], q.dtype) for k in ("offset", "com", "inertia", "m")]
    lift = jnp.broadcast_to(g, (n,))
    per_link = (q, qd.astype(q.dtype), big_a, big_b, big_c, slide, axes, rev, *values, lift)
    zero = (0.0, 0.0, 0.0)
    up = tuple(float(u) for u in chain.up)
    _, ys = passes.run(_spatial_energy_link, (zero, zero, up, 0.0), passes.links(per_link))
    kinetic, potential = passes.split(ys)
    if passes.scan:
        return jnp.sum(kinetic), jnp.sum(potential)
    return _total(kinetic, q.dtype), _total(potential, q.dtype)


def _total(values, dtype):
    out = 0.0
    for v in values:
        out = a.add(out, v)
    return jnp.asarray(out, dtype)


def spatial_chain(chain: Any, q, params: Params, scan: bool | None = None) -> a.Chain:
    """A spatial chain or tree (a [`Tree`][lagrax.chains.Tree]: body `i` hangs from
    body `parents[i]`, and every pass runs over parents): world joint axes
    `z_i = R_i axis_i` through the joint origins `o_i`, `S_i = (z_i, o_i × z_i)`
    (revolute) or `(0, z_i)` (prismatic), and link inertias at the origin,
    `R_i Ī_i R_iᵀ` about the centre of mass `o_i + R_i com_i`."""
    n = chain.n
    _check(n, q)
    scan = n > UNROLL_MAX_SPATIAL if scan is None else scan
    passes = a.Passes(n, scan, q.dtype, getattr(chain, "parents", None))
    big_a, big_b, big_c, slide = chain._joint_constants()
    axes = np.asarray(chain.axes, float)
    rev = np.asarray([1.0 if k == "R" else 0.0 for k in chain.joint_types])
    values = (jnp.asarray(params[k], q.dtype) for k in ("offset", "com", "inertia", "m"))
    per_link = (q, big_a, big_b, big_c, slide, axes, rev, *values)
    eye = tuple(tuple(1.0 if i == j else 0.0 for j in range(3)) for i in range(3))
    _, ys = passes.run(_spatial_link, (eye, (0.0, 0.0, 0.0)), passes.links(per_link))
    s, inertia = passes.split(ys)
    g = jnp.asarray(params["g"], q.dtype)
    a0 = (0.0, 0.0, 0.0) + tuple(a.mul(g, u) for u in chain.up)
    return a.Chain(passes, a.SPATIAL, s, inertia, a0)


class ChainEquations(eqx.Module):
    """The equations of a chain's or a tree's `LagrangianSystem` from Featherstone's recursions:
    `q̈` by the articulated-body algorithm (O(n)), `M` by the composite-rigid-body
    algorithm, `M q̈ + C q̇ + G` by recursive Newton–Euler. They equal the autodiff
    Lagrangian of the chain's energies to round-off (tested against it and against
    [`lagrax.newton_euler.rnea`][])."""

    chain: Any  # PlanarChain | SpatialChain | Tree: structure only (static fields)

    scan: bool | None = eqx.field(default=None, static=True)

    def at(self, q, params: Params) -> a.Chain:
        """The chain's motion subspaces and inertias at `q`."""
        if hasattr(self.chain, "joint_types"):
            return spatial_chain(self.chain, q, params, self.scan)
        return planar_chain(self.chain.n, q, params, self.scan)

    def accelerations(self, q, qd, params: Params, force) -> jnp.ndarray:
        """`q̈` solving `M q̈ + C q̇ + G = force` (`force` `None` means zero); NaN
        where the chain's articulated inertias are not positive."""
        chain = self.at(q, params)
        links = chain.passes.links
        f = None if force is None else links(jnp.asarray(force, q.dtype))
        return a.stack(a.aba(chain, links(qd.astype(q.dtype)), f), q)

    def energies(self, q, qd, params: Params) -> tuple[jnp.ndarray, jnp.ndarray] | None:
        """`(T, V)` of a spatial chain or tree by one outward pass in link frames
        (`spatial_energies`; ~4x faster than the pose maps' JVP under `vmap`), or `None`
        for a planar chain, whose vectorized pose maps are already the cheaper route
        (0.2 against 0.8 µs a state at n = 7)."""
        if hasattr(self.chain, "joint_types"):
            return spatial_energies(self.chain, q, qd, params, self.scan)
        return None

    def mass_matrix(self, q, params: Params) -> jnp.ndarray:
        return a.crba(self.at(q, params))

    def mass_and_bias(self, q, qd, params: Params) -> tuple[jnp.ndarray, jnp.ndarray]:
        """`M` and the bias `C q̇ + G` from one evaluation of the kinematics."""
        chain = self.at(q, params)
        bias = a.rnea(chain, chain.passes.links(qd.astype(q.dtype)), None)
        return a.crba(chain), a.stack(bias, q)

    def inverse_dynamics(self, q, qd, qdd, params: Params) -> jnp.ndarray:
        """`M q̈ + C q̇ + G` (`qdd=None`: the bias `C q̇ + G`)."""
        chain = self.at(q, params)
        links = chain.passes.links
        qdd = None if qdd is None else links(qdd.astype(q.dtype))
        return a.stack(a.rnea(chain, links(qd.astype(q.dtype)), qdd), q)
