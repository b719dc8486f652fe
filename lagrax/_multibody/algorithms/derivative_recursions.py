r"""Analytic derivatives of the inverse dynamics of chains and trees, in `O(n²)`.

The recursive Newton–Euler algorithm ([`recursions.rnea`][]) gives, in world coordinates at
the world origin (Featherstone's fixed-frame form, as every recursion here),

$$
v_i = v_{λ(i)} + S_i q̇_i, \qquad a_i = a_{λ(i)} + (v_i × S_i) q̇_i + S_i q̈_i,
\qquad f_i = I_i a_i + v_i ×^* I_i v_i,
$$

$$
F_i = \sum_{k ∈ \mathrm{sub}(i)} f_k, \qquad τ_i = S_iᵀ F_i,
$$

with `λ(i)` the parent of body `i`, `sub(i)` its subtree (itself included) and the base
accelerating at `a_0 = −g`. This module differentiates `τ` with respect to `q` and `q̇`
at a given `q̈`, the way Carpentier and Mansard do it for Pinocchio (*Analytical
derivatives of rigid body dynamics algorithms*, RSS 2018): by the rules of how each
quantity moves, not by differentiating the code.

**Moving joint `i`.** Turning (or sliding) joint `i` by `δq_i` moves its subtree rigidly
by the twist `S_i δq_i`: a motion vector `X` fixed in a body of the subtree changes by
`S_i × X`, a force by `S_i ×^* X`, an inertia by `S_i ×^* I − I S_i ×`. Measured in the
moving bodies (the derivative `D_i X = ∂X/∂q_i − S_i × X`, under which `S`, `I` and
pairings `Sᵀ F` are constant), the velocities and accelerations of every body `k` of the
subtree change by the same two vectors, whatever `k` is:

$$
D_i v_k = d_i := v_{λ(i)} × S_i, \qquad D_i a_k = ψ_i + d_i × (v_k − v_{λ(i)}),
\qquad ψ_i := a_{λ(i)} × S_i + v_{λ(i)} × d_i .
$$

Then `D_i f_k = I_k ψ_i + B_k d_i` with the Coriolis-like map
`B_k x = v_k ×^* I_k x − I_k (v_k × x) + x ×^* (I_k v_k)`, which is the sum of the
symmetric matrix `Σ_k = crf(v_k) I_k + (crf(v_k) I_k)ᵀ` and the skew-symmetric map
`x ↦ x ×^* h_k` of the momentum `h_k = I_k v_k`. Summed over a subtree these give the
composite inertia `Y_j = Σ I_k`, the composite `Σ^c_j` and the composite momentum `h^c_j`.
`Σ_k = v_k ×^* I_k − I_k v_k×` is the rate `İ_k` of the body's inertia as it moves, so
it is a rigid-body inertia's ten numbers too (with `ṁ = 0`): every inertia here, composite
or not, is carried and applied as those numbers (`Rigid`), not as a `6 × 6` matrix.

**The result.** For `j` on the path from `i` to the base (`j ≼ i`, `i` itself included)
and for `j` in the subtree of `i` (`i ≺ j`):

$$
\frac{∂τ_j}{∂q_i} = \begin{cases}
S_jᵀ (Y_i ψ_i + B^c_i d_i + S_i ×^* F_i) & j ≼ i \\
(Y_j S_j)·ψ_i + (B^{c\,ᵀ}_j S_j)·d_i & i ≺ j
\end{cases}, \qquad
\frac{∂τ_j}{∂q̇_i} = \begin{cases}
S_jᵀ (2 Y_i d_i + B^c_i S_i) & j ≼ i \\
2 (Y_j S_j)·d_i + (B^{c\,ᵀ}_j S_j)·S_i & i ≺ j
\end{cases},
$$

with `B^c = Σ^c + (· ×^* h^c)` and zero for bodies on other branches. `Y_j S_j` are also
the columns of the composite-rigid-body algorithm, so `M_ji = S_jᵀ Y_i S_i` (`j ≼ i`)
comes for free. One outward and one inward pass compute the per-body vectors (a few
hundred flops per body), and the `n × n` matrices are dot products of them: `O(n²)` in
all, with no second derivative and no matrix of the chain factored. The same formulas hold
for planar chains in the planar algebra (3-vectors).

The tests hold this to `jax.jacfwd` of the recursive Newton–Euler algorithm, to the
autodiff Lagrangian and to Pinocchio's `computeRNEADerivatives`.
"""

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from . import recursions as r
from .recursions import Chain, add, dot, mul, vadd, vscale

Rigid = tuple[Any, ...]
"""A rigid-body inertia at the origin as the numbers that define it: spatial
`(m, h_x, h_y, h_z, I_xx, I_xy, I_xz, I_yy, I_yz, I_zz)` (mass, first moment `h = m c`,
rotational inertia about the origin `I_O`, for `I = [[I_O, [h]×], [[h]×ᵀ, m 1]]`),
planar `(m, h_x, h_y, I_O)`. Ten (four) numbers where the matrix has 36 (9) entries."""


def _rigid(inertia: r.Mat) -> Rigid:
    """The numbers of a rigid-body inertia matrix (`recursions.spatial_inertia` or
    `planar_inertia`), read off its entries."""
    i = inertia
    if len(i) == 6:
        h = (r.sub(0.0, i[1][5]), i[0][5], r.sub(0.0, i[0][4]))
        return (i[3][3], *h, i[0][0], i[0][1], i[0][2], i[1][1], i[1][2], i[2][2])
    return (i[1][1], i[0][2], r.sub(0.0, i[0][1]), i[0][0])


def _rigid_mul(p: Rigid, x: r.Vec) -> r.Vec:
    """`I x` of a motion vector `x`: `(I_O ω + h × v_O, m v_O − h × ω)`."""
    if len(x) == 6:
        m, h, io = p[0], p[1:4], p[4:]
        w, u = x[:3], x[3:]
        iw = (dot(io[0:3], w), dot((io[1], io[3], io[4]), w), dot((io[2], io[4], io[5]), w))
        hu, hw = r.cross(h, u), r.cross(h, w)
        return vadd(iw, hu) + tuple(r.sub(mul(m, a), b) for a, b in zip(u, hw, strict=True))
    m, hx, hy, io = p
    w, vx, vy = x
    return (
        add(mul(io, w), r.sub(mul(hx, vy), mul(hy, vx))),
        r.sub(mul(m, vx), mul(hy, w)),
        add(mul(m, vy), mul(hx, w)),
    )


def _rigid_rate(p: Rigid, v: r.Vec) -> Rigid:
    """`İ = v ×* I − I v×`, the rate of change of the inertia of a body moving with
    velocity `v`: the symmetric part `crf(v) I + (crf(v) I)ᵀ` of the Coriolis-like map
    `B` below, itself a rigid inertia's numbers with `ṁ = 0`: `ḣ = m v_O + ω × h`,
    `İ_O = [ω]× I_O − I_O [ω]× − h v_Oᵀ − v_O hᵀ + 2 (h · v_O) 1` (planar:
    `İ_O = 2 h · v_O`)."""
    if len(v) == 6:
        m, h, io = p[0], p[1:4], p[4:]
        w, u = v[:3], v[3:]
        h_dot = vadd(vscale(u, m), r.cross(w, h))
        cols = [r.cross(w, c) for c in (io[0:3], (io[1], io[3], io[4]), (io[2], io[4], io[5]))]
        hu2 = mul(2.0, dot(h, u))
        rate = []
        for i in range(3):
            for j in range(i, 3):
                val = r.sub(add(cols[j][i], cols[i][j]), add(mul(h[i], u[j]), mul(u[i], h[j])))
                rate.append(add(val, hu2) if i == j else val)
        return (0.0, *h_dot, *rate)
    m, hx, hy, _ = p
    w, vx, vy = v
    h_dot = (r.sub(mul(m, vx), mul(w, hy)), add(mul(m, vy), mul(w, hx)))
    return (0.0, *h_dot, mul(2.0, add(mul(hx, vx), mul(hy, vy))))


def _rigid_add(a: Rigid, b: Rigid) -> Rigid:
    return tuple(add(x, y) for x, y in zip(a, b, strict=True))


def rnea_derivatives(chain: Chain, qd: Any, qdd: Any) -> tuple[jax.Array, ...]:
    """`(τ, ∂τ/∂q, ∂τ/∂q̇, M)` of `τ = M(q) q̈ + C(q, q̇) q̇ + G(q)` at `(q, q̇, q̈)`.

    **Arguments:** `chain`, the chain or tree at `q` (its motion subspaces and inertias,
    from the tree's `links`); `qd`, `qdd`, per-body sequences as the recursions take them.

    **Returns:** `τ` of shape `(n,)` and the three `(n, n)` matrices `∂τ/∂q`,
    `∂τ/∂q̇` and the mass matrix `M = ∂τ/∂q̈`.
    """
    per_body, _ = _passes(chain, qd, qdd)
    return _assemble(chain, per_body)


def _passes(chain: Chain, qd: Any, qdd: Any, root: tuple[Any, Any] | None = None):
    """`(per_body, totals)`: the outward and inward passes of `rnea_derivatives`.

    `per_body` is `(τ, u, bt_s, pq, pv, d, ψ)`, per-body sequences (`u = Y S`,
    `bt_s = B^cᵀ S`, `pq` and `pv` the vectors `∂τ_j/∂q_i` and `∂τ_j/∂q̇_i` pair with `S_j`
    for `j ≼ i`); `totals` is `(Y, Σ^c, F, h^c)` summed over the root's subtrees (the
    inertia as its ten numbers less the mass, see `Rigid`). `root`: the velocity and
    acceleration `(v, a)` the root's children start from (a moving base; by default rest
    and `a_0`)."""
    alg, passes = chain.algebra, chain.passes
    k = len(chain.a0)
    zero = tuple(0.0 for _ in range(k))

    def outward(carry, x):
        v_parent, a_parent = carry
        s, inertia, qd_i, qdd_i = x
        v = vadd(v_parent, vscale(s, qd_i))
        d = alg.crm(v, s)  # = v_parent × S_i
        psi = vadd(alg.crm(a_parent, s), alg.crm(v_parent, d))
        a = vadd(vadd(a_parent, vscale(d, qd_i)), vscale(s, qdd_i))
        rigid = _rigid(inertia)
        h = _rigid_mul(rigid, v)
        f = vadd(_rigid_mul(rigid, a), alg.crf(v, h))
        return (v, a), (d, psi, f, h, _rigid_rate(rigid, v)[1:], rigid)

    xs = passes.zip(chain.s, chain.inertia, qd, qdd)
    _, ys = passes.run(outward, (zero, chain.a0) if root is None else root, xs)
    d, psi, f, h, sym, rigid = passes.split(ys)

    def inward(carry, x):
        y_c, sym_c, f_c, h_c = carry
        s, rigid, d_i, psi_i, f_i, h_i, sym_i = x
        y, sym_c, f_c, h_c = (
            _rigid_add(rigid, y_c),
            _rigid_add(sym_i, sym_c),
            vadd(f_i, f_c),
            vadd(h_i, h_c),
        )
        sym = (0.0, *sym_c)
        u = _rigid_mul(y, s)  # Y S: a column of M
        sym_s = _rigid_mul(sym, s)
        s_h = alg.crf(s, h_c)  # S ×* h^c
        bt_s = vadd(sym_s, vscale(s_h, -1.0))  # B^cᵀ S (the momentum part is skew)
        b_d = vadd(_rigid_mul(sym, d_i), alg.crf(d_i, h_c))  # B^c d
        pq = vadd(vadd(_rigid_mul(y, psi_i), b_d), alg.crf(s, f_c))
        pv = vadd(vscale(_rigid_mul(y, d_i), 2.0), vadd(sym_s, s_h))  # 2 Y d + B^c S
        return (y, sym_c, f_c, h_c), (dot(s, f_c), u, bt_s, pq, pv)

    zr = tuple(0.0 for _ in range(10 if k == 6 else 4))
    xs = passes.zip(chain.s, rigid, d, psi, f, h, sym)
    totals, outs = passes.run(inward, (zr, zr[1:], zero, zero), xs, reverse=True)
    return (*passes.split(outs), d, psi), totals


def _assemble(chain: Chain, per_body: tuple) -> tuple[jax.Array, ...]:
    """`(τ, ∂τ/∂q, ∂τ/∂q̇, M)` from `_passes`' per-body vectors: dot products (see the
    module docstring)."""
    passes = chain.passes
    tau, u, bt_s, pq, pv, d, psi = per_body
    s_a, u_a, bt_a, pq_a, pv_a, d_a, psi_a = (
        passes.column(x) for x in (chain.s, u, bt_s, pq, pv, d, psi)
    )
    up = passes.ancestors()  # [j, i]: j on i's path to the base (j ≼ i)
    down = up.T & ~np.eye(passes.n, dtype=bool)  # [j, i]: j in i's subtree, j ≠ i
    dtau_dq = jnp.where(up, r.rows_dot(s_a, pq_a), r.rows_dot(u_a, psi_a) + r.rows_dot(bt_a, d_a))
    dtau_dq = jnp.where(up | down, dtau_dq, 0.0)
    dtau_dqd = jnp.where(
        up, r.rows_dot(s_a, pv_a), 2.0 * r.rows_dot(u_a, d_a) + r.rows_dot(bt_a, s_a)
    )
    dtau_dqd = jnp.where(up | down, dtau_dqd, 0.0)
    g = r.rows_dot(s_a, u_a)  # g[j, i] = S_j · Y_i S_i
    mass = jnp.where(up, g, jnp.where(up.T, g.T, 0.0))
    return passes.vector(tau, s_a), dtau_dq, dtau_dqd, mass


def free_root_derivatives(
    chain: Chain, s_base: jax.Array, inertia_base: Any, qd: Any, qdd: Any, v_base, vdot_base
) -> tuple[jax.Array, ...]:
    r"""`(τ, ∂τ/∂q, ∂τ/∂q̇, M)` of a tree on a free root: the base's six coordinates
    (Pinocchio's free flyer: `(v_b, ω_b)` in the base frame, `δ` along `q ⊕ δ`) first,
    then the joints'.

    The base is a joint of six columns `S_B` (world axes) from the world, which rests and
    accelerates at `a_0`; its columns move with the base (they are the base frame's).
    For the derivatives that makes it the first joint of every path, with `d_k = 0 × S_k
    = 0` and `ψ_k = a_0 × S_k` (only gravity's direction changes relative to a robot
    moved as a whole), and the moving-frame rule (`i ≺ j`) between its own columns:

    $$
    \frac{∂τ_B}{∂q_B} = S_Bᵀ Y_B Ψ, \quad \frac{∂τ_j}{∂q_B} = (Y_j S_j)ᵀ Ψ, \quad
    \frac{∂τ_B}{∂q_i} = S_Bᵀ p^q_i, \qquad
    \frac{∂τ_B}{∂v_B} = S_Bᵀ (Y_B E + B^c_B S_B), \quad
    \frac{∂τ_j}{∂v_B} = (Y_j S_j)ᵀ E + (B^{cᵀ}_j S_j)ᵀ S_B, \quad
    \frac{∂τ_B}{∂q̇_i} = S_Bᵀ p^v_i,
    $$

    with `Ψ = [ψ_1 … ψ_6]` and `E = [v_B × S_1 … v_B × S_6]`: a base rate moves every
    body's acceleration by `S_k × (v_m − v_B)`, where a one-column joint `i` moves it
    by `2 d_i + S_i × v_m` (the base's own acceleration `S_B v̇_b` has no velocity term,
    its columns moving with it: `Ṡ_B v_b = v_B × v_B = 0`). `Y_B` and `B^c_B` are the
    whole robot's composite inertia and
    Coriolis-like map (the base body's own included), `p^q_i`, `p^v_i` the vectors
    `rnea_derivatives` pairs with an ancestor's `S_j`, and the joints' block that of a
    fixed base whose root moves with `v_B = S_B v_b` and accelerates at
    `a_B = a_0 + S_B v̇_b`. `M` is the composite-rigid-body algorithm's, `τ_B = S_Bᵀ F_B`.

    **Arguments:** `chain`, the joints' chain at `q` (world axes at the base origin);
    `s_base`, `inertia_base`, the base's `S_B` and inertia (`floating_recursions`);
    `qd`, `qdd`, the joints' rates as the recursions take them; `v_base`, `vdot_base`,
    the base's `(v_b, ω_b)` and their rates.

    **Returns:** `τ` `(6 + n,)` and the `(6 + n, 6 + n)` matrices `∂τ/∂q`, `∂τ/∂q̇`, `M`.
    """
    alg, passes = chain.algebra, chain.passes
    dtype = s_base.dtype
    columns = [tuple(s_base[i, k] for i in range(6)) for k in range(6)]
    s_rows = [tuple(s_base[i, k] for k in range(6)) for i in range(6)]
    rates, accelerations = tuple(v_base[k] for k in range(6)), tuple(vdot_base[k] for k in range(6))
    v_b = tuple(dot(row, rates) for row in s_rows)  # S_B v_b
    a_b = tuple(
        add(a_i, dot(row, accelerations)) for a_i, row in zip(chain.a0, s_rows, strict=True)
    )
    per_body, (y_sub, sym_sub, f_sub, h_sub) = _passes(chain, qd, qdd, root=(v_b, a_b))
    tau, dq, dqd, mass = _assemble(chain, per_body)
    rigid_b = _rigid(inertia_base)
    h_b = _rigid_mul(rigid_b, v_b)
    f_b = vadd(_rigid_mul(rigid_b, a_b), alg.crf(v_b, h_b))
    y = _rigid_add(rigid_b, y_sub)
    sym = (0.0, *_rigid_add(_rigid_rate(rigid_b, v_b)[1:], sym_sub))
    force, momentum = vadd(f_b, f_sub), vadd(h_b, h_sub)

    def rows(vectors):  # 6-vectors as the rows of a (len, 6) array
        return jnp.stack([jnp.stack([jnp.asarray(x, dtype) for x in v]) for v in vectors])

    # the products as dot products of rows (`rows_dot`: elementwise code under `vmap`)
    psi = [alg.crm(chain.a0, c) for c in columns]
    e = [alg.crm(v_b, c) for c in columns]
    bc_s = [  # Y e + B^c S, with B^c S = Σ^c S + S ×* h^c
        vadd(_rigid_mul(y, e_k), vadd(_rigid_mul(sym, c), alg.crf(c, momentum)))
        for e_k, c in zip(e, columns, strict=True)
    ]
    s_r = s_base.T  # S_B's columns as rows
    psi_r, e_r, bc_r = rows(psi), rows(e), rows(bc_s)
    y_psi_r, y_s_r = (
        rows([_rigid_mul(y, p) for p in psi]),
        rows([_rigid_mul(y, c) for c in columns]),
    )
    u_a, bt_a, pq_a, pv_a = (passes.column(x) for x in per_body[1:5])
    rd = r.rows_dot
    dq = jnp.block([[rd(s_r, y_psi_r), rd(s_r, pq_a)], [rd(u_a, psi_r), dq]])
    dqd = jnp.block([[rd(s_r, bc_r), rd(s_r, pv_a)], [rd(u_a, e_r) + rd(bt_a, s_r), dqd]])
    m_bj = rd(s_r, u_a)
    mass = jnp.block([[rd(s_r, y_s_r), m_bj], [m_bj.T, mass]])
    return jnp.concatenate([rd(s_r, rows([force]))[:, 0], tau]), dq, dqd, mass
