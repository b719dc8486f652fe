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
hundred flops per body), and the `n × n` matrices are four small products: `O(n²)` in
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
from .recursions import Chain, add, dot, matvec, vadd, vscale

Packed = tuple[Any, ...]  # the upper triangle of a symmetric matrix, row by row


def _pack(m: r.Mat) -> Packed:
    k = len(m)
    return tuple(m[i][j] for i in range(k) for j in range(i, k))


def _packed_index(k: int) -> list[list[int]]:
    index = [[0] * k for _ in range(k)]
    p = 0
    for i in range(k):
        for j in range(i, k):
            index[i][j] = index[j][i] = p
            p += 1
    return index


def _sym_matvec(p: Packed, x: r.Vec, index: list[list[int]]) -> r.Vec:
    k = len(x)
    return tuple(dot(tuple(p[index[i][j]] for j in range(k)), x) for i in range(k))


def _sym_add(a: Packed, b: Packed) -> Packed:
    return tuple(add(x, y) for x, y in zip(a, b, strict=True))


def _coriolis_sym(alg: r.Algebra, v: r.Vec, inertia: r.Mat) -> Packed:
    """The symmetric part `crf(v) I + (crf(v) I)ᵀ` of `B`, packed."""
    k = len(v)
    cols = [alg.crf(v, tuple(inertia[i][j] for i in range(k))) for j in range(k)]
    return tuple(add(cols[j][i], cols[i][j]) for i in range(k) for j in range(i, k))


def rnea_derivatives(chain: Chain, qd: Any, qdd: Any) -> tuple[jax.Array, ...]:
    """`(τ, ∂τ/∂q, ∂τ/∂q̇, M)` of `τ = M(q) q̈ + C(q, q̇) q̇ + G(q)` at `(q, q̇, q̈)`.

    **Arguments:** `chain`, the chain or tree at `q` (its motion subspaces and inertias,
    from the tree's `links`); `qd`, `qdd`, per-body sequences as the recursions take them.

    **Returns:** `τ` of shape `(n,)` and the three `(n, n)` matrices `∂τ/∂q`,
    `∂τ/∂q̇` and the mass matrix `M = ∂τ/∂q̈`.
    """
    alg, passes = chain.algebra, chain.passes
    k = len(chain.a0)
    index = _packed_index(k)
    zero = tuple(0.0 for _ in range(k))

    def outward(carry, x):
        v_parent, a_parent = carry
        s, inertia, qd_i, qdd_i = x
        v = vadd(v_parent, vscale(s, qd_i))
        d = alg.crm(v, s)  # = v_parent × S_i
        psi = vadd(alg.crm(a_parent, s), alg.crm(v_parent, d))
        a = vadd(vadd(a_parent, vscale(d, qd_i)), vscale(s, qdd_i))
        h = matvec(inertia, v)
        f = vadd(matvec(inertia, a), alg.crf(v, h))
        return (v, a), (d, psi, f, h, _coriolis_sym(alg, v, inertia), _pack(inertia))

    xs = passes.zip(chain.s, chain.inertia, qd, qdd)
    _, ys = passes.run(outward, (zero, chain.a0), xs)
    d, psi, f, h, sym, packed = passes.split(ys)

    def inward(carry, x):
        y_c, sym_c, f_c, h_c = carry
        s, inertia, d_i, psi_i, f_i, h_i, sym_i = x
        y, sym_c, f_c, h_c = (
            _sym_add(inertia, y_c),
            _sym_add(sym_i, sym_c),
            vadd(f_i, f_c),
            vadd(h_i, h_c),
        )
        u = _sym_matvec(y, s, index)  # Y S: a column of M
        sym_s = _sym_matvec(sym_c, s, index)
        s_h = alg.crf(s, h_c)  # S ×* h^c
        bt_s = vadd(sym_s, vscale(s_h, -1.0))  # B^cᵀ S (the momentum part is skew)
        b_d = vadd(_sym_matvec(sym_c, d_i, index), alg.crf(d_i, h_c))  # B^c d
        pq = vadd(vadd(_sym_matvec(y, psi_i, index), b_d), alg.crf(s, f_c))
        pv = vadd(vscale(_sym_matvec(y, d_i, index), 2.0), vadd(sym_s, s_h))  # 2 Y d + B^c S
        return (y, sym_c, f_c, h_c), (dot(s, f_c), u, bt_s, pq, pv)

    zp = tuple(0.0 for _ in range(k * (k + 1) // 2))
    xs = passes.zip(chain.s, packed, d, psi, f, h, sym)
    _, outs = passes.run(inward, (zp, zp, zero, zero), xs, reverse=True)
    tau, u, bt_s, pq, pv = passes.split(outs)
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
