r"""Structure-aware equations of motion for chains of rigid bodies: O(n) recursions.

A chain knows more than its energies: every link is a rigid body whose velocity is its
parent's plus one joint's motion. Featherstone's recursions use that to form the
Euler–Lagrange equations `M q̈ + C q̇ + G = f` without differentiating `T` twice:

- the **articulated-body algorithm** (ABA) gives `q̈` in O(n), with no matrix to factor;
- the **composite-rigid-body algorithm** (CRBA) gives `M` in O(n²);
- the **recursive Newton–Euler algorithm** (RNEA) gives `M q̈ + C q̇ + G` in O(n).

All spatial quantities are written in world coordinates at the world origin
(Featherstone, *Rigid Body Dynamics Algorithms*, 2008, §2 and §7 with a fixed frame): a
motion vector is `(ω, v_O)` with `v_O` the velocity of the body point now at the origin,
a force vector is `(n_O, f)`, and a joint's motion subspace `S_i` (a revolute joint of
world axis `z` through `p`: `S = (z, p × z)`; a prismatic one: `(0, z)`) moves with
its link, so `Ṡ_i = v_i × S_i`. Nothing is transformed between link frames. Planar
chains use the planar restriction: 3-vectors `(ω, v_x, v_y)`.

Every vector and matrix is a tuple of JAX scalars, and structural zeros stay Python
`0.0` so no work is spent on them. Under `vmap` each scalar becomes a batch array; in a
solver loop the whole recursion is straight-line elementwise code that XLA fuses, with no
LAPACK call (a `q̈` costs a few hundred flops per link). These recursions are fast paths:
the energies remain the definition, and the tests hold every path to the generic
autodiff Lagrangian and to the independent Newton–Euler oracle of
[`lagrax.newton_euler`][].
"""

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ..._core.one_shot import one_shot_on
from .lanes import MAX_PHASES, Lanes, as_arrays, lane_scan, scalars

Vec = tuple[Any, ...]
Mat = tuple[tuple[Any, ...], ...]


# ------------------------------------------------------------------ scalar algebra
def _zero(x: Any) -> bool:
    return isinstance(x, float) and x == 0.0


def mul(a: Any, b: Any) -> Any:
    """`a b`, skipping structural zeros and ones."""
    if _zero(a) or _zero(b):
        return 0.0
    if isinstance(a, float) and a == 1.0:
        return b
    if isinstance(b, float) and b == 1.0:
        return a
    return a * b


def add(a: Any, b: Any) -> Any:
    if _zero(a):
        return b
    if _zero(b):
        return a
    return a + b


def sub(a: Any, b: Any) -> Any:
    if _zero(b):
        return a
    if _zero(a):
        return -b
    return a - b


def dot(a: Vec, b: Vec) -> Any:
    out: Any = 0.0
    for x, y in zip(a, b, strict=True):
        out = add(out, mul(x, y))
    return out


def vadd(a: Vec, b: Vec) -> Vec:
    return tuple(add(x, y) for x, y in zip(a, b, strict=True))


def vscale(a: Vec, s: Any) -> Vec:
    return tuple(mul(x, s) for x in a)


def matvec(m: Mat, x: Vec) -> Vec:
    return tuple(dot(row, x) for row in m)


def madd(a: Mat, b: Mat) -> Mat:
    return tuple(vadd(r, s) for r, s in zip(a, b, strict=True))


def cross(a: Vec, b: Vec) -> Vec:
    return (
        sub(mul(a[1], b[2]), mul(a[2], b[1])),
        sub(mul(a[2], b[0]), mul(a[0], b[2])),
        sub(mul(a[0], b[1]), mul(a[1], b[0])),
    )


def sym_rank1_sub(m: Mat, u: Vec, s: Any) -> Mat:
    """`m − s u uᵀ` for symmetric `m` (the upper triangle is computed once)."""
    k = len(u)
    su = vscale(u, s)
    rows = [[None] * k for _ in range(k)]
    for i in range(k):
        for j in range(i, k):
            rows[i][j] = rows[j][i] = sub(m[i][j], mul(su[i], u[j]))
    return tuple(tuple(r) for r in rows)


# ------------------------------------------------------------------ spatial algebra
class Algebra:
    """Cross products of motion/force vectors of one dimension (3 planar, 6 spatial)."""

    def __init__(self, crm: Callable[[Vec, Vec], Vec], crf: Callable[[Vec, Vec], Vec]):
        self.crm, self.crf = crm, crf


def _crm_planar(v: Vec, m: Vec) -> Vec:
    # (ω, vx, vy) × (ω', mx, my) = (0, −ω my + ω' vy, ω mx − ω' vx)
    return (0.0, add(-mul(v[0], m[2]), mul(m[0], v[2])), sub(mul(v[0], m[1]), mul(m[0], v[1])))


def _crf_planar(v: Vec, f: Vec) -> Vec:
    # (ω, vx, vy) ×* (n, fx, fy) = (vx fy − vy fx, −ω fy, ω fx)
    return (sub(mul(v[1], f[2]), mul(v[2], f[1])), -mul(v[0], f[2]), mul(v[0], f[1]))


def _crm_spatial(v: Vec, m: Vec) -> Vec:
    w, u, w2, u2 = v[:3], v[3:], m[:3], m[3:]
    return cross(w, w2) + vadd(cross(w, u2), cross(u, w2))


def _crf_spatial(v: Vec, f: Vec) -> Vec:
    w, u, n, g = v[:3], v[3:], f[:3], f[3:]
    return vadd(cross(w, n), cross(u, g)) + cross(w, g)


PLANAR = Algebra(_crm_planar, _crf_planar)
SPATIAL = Algebra(_crm_spatial, _crf_spatial)


def planar_inertia(m: Any, inertia: Any, c: Vec) -> Mat:
    """A planar body's inertia at the origin, `(ω, v_x, v_y)` ordering, from its mass,
    its inertia about the centre of mass and the centre of mass `c = (c_x, c_y)`."""
    mx, my = mul(m, c[0]), mul(m, c[1])
    return (
        (add(inertia, add(mul(mx, c[0]), mul(my, c[1]))), -my, mx),
        (-my, m, 0.0),
        (mx, 0.0, m),
    )


def spatial_inertia(m: Any, inertia_w: Mat, c: Vec) -> Mat:
    """A rigid body's spatial inertia at the origin: ``[[Ī + m(|c|²1 − c cᵀ), m[c]×],
    [m[c]×ᵀ, m 1]]` with `Ī`` its inertia about the centre of mass in world axes."""
    mc = vscale(c, m)
    cc = [[mul(mc[i], c[j]) for j in range(3)] for i in range(3)]
    trace = add(add(cc[0][0], cc[1][1]), cc[2][2])
    top = [[None] * 3 for _ in range(3)]
    for i in range(3):
        for j in range(i, 3):
            val = sub(add(inertia_w[i][j], trace if i == j else 0.0), cc[i][j])
            top[i][j] = top[j][i] = val
    cx = (  # m [c]×
        (0.0, -mc[2], mc[1]),
        (mc[2], 0.0, -mc[0]),
        (-mc[1], mc[0], 0.0),
    )
    rows = []
    for i in range(3):
        rows.append(tuple(top[i]) + cx[i])
    for i in range(3):  # m [c]×ᵀ and m 1
        rows.append(
            tuple(cx[j][i] for j in range(3)) + tuple(m if j == i else 0.0 for j in range(3))
        )
    return tuple(rows)


# ------------------------------------------------------------------ the recursions
ONE_SHOT_MAX_PHASES = 1
"""The most phases of a tree's [`Lanes`][] in a one-shot program (`one_shot_on()`): a tree
of more (a humanoid's arms after its legs and torso) runs its passes as one scan over its
bodies. That form compiles in about half the time (dm_control's humanoid_CMU, five phases:
its accelerations 8,417 → 3,288 lines, `simulate`'s first result from the import about
23 → 13 s) and runs several times slower per state (11 → 93 µs): the trade a program
that runs once wants, and a batch (`vmap`, `sweep`) does not."""


class Passes:
    """How a recursion runs over the `n` bodies of a chain or a tree: written out body
    by body (`scan=False`: straight-line code, structural zeros skipped, fastest to run
    for short chains) or as `lax.scan` over the tree's [`Lanes`][] (`scan=True`: one
    scan step per depth of each group of branches, every scalar of a body's code a
    `(W,)` array over the branches; compile time independent of the branches' lengths;
    a tree of more than `MAX_PHASES` phases: one scan over the bodies, their carries in
    a buffer indexed by parent).

    `parents` gives each body's parent (`−1`: the base), with `parents[i] < i`;
    `None` is a chain (`parents[i] = i − 1`). An outward pass hands body `i` its
    parent's carry (the initial carry for a body on the base); an inward pass hands it the
    initial carry plus the sum of its children's carries (every inward recursion sums over
    children: composite and articulated inertias, bias forces, joint forces).

    A pass is `step(carry, x) -> (carry, y)`; per-body inputs `xs` are a list of
    per-body pytrees (unrolled), one pytree of stacked arrays (one scan over the bodies)
    or, over lanes, per group a list of per-phase pytrees with leaves `(depth, …, W)`
    (from `links`), and `run` returns the per-body outputs in the same form (over lanes:
    leaves `(depth, W)`, or Python floats for values equal over a phase). `column` and
    `vector` give them in body order.
    """

    def __init__(self, n: int, scan: bool, dtype: Any, parents: tuple[int, ...] | None = None):
        self.n, self.scan, self.dtype = n, scan, dtype
        if parents is not None and tuple(parents) == tuple(range(-1, n - 1)):
            parents = None  # a chain: the plain carry-passing loops
        self.parents = None if parents is None else tuple(int(p) for p in parents)
        chain = tuple(range(-1, n - 1))
        self.lanes = Lanes(chain if self.parents is None else self.parents) if scan else None
        limit = ONE_SHOT_MAX_PHASES if one_shot_on() else MAX_PHASES
        if self.lanes is not None and sum(map(len, self.lanes.phases)) > limit:
            self.lanes = None  # compile time grows with the phases: one scan, buffers

    def ancestors(self) -> np.ndarray:
        """`(n, n)` booleans: `[j, i]` is true where body `j` is body `i` or on its
        path to the base (upper-triangular for a chain)."""
        if self.parents is None:
            return np.triu(np.ones((self.n, self.n), bool))
        out = np.zeros((self.n, self.n), bool)
        for i in range(self.n):
            j = i
            while j >= 0:
                out[j, i] = True
                j = self.parents[j]
        return out

    def links(self, per_link: Any) -> Any:
        """Per-body data given as a pytree of arrays with a leading axis `n`."""
        if self.scan and self.lanes is None:
            return per_link
        if self.lanes is None:
            return [
                scalars(jax.tree_util.tree_map(lambda v, i=i: v[i], per_link))
                for i in range(self.n)
            ]

        def lay(v: Any, index: np.ndarray) -> Any:
            if isinstance(v, np.ndarray):  # constants stay NumPy (see `components`)
                return np.moveaxis(v[index], 1, -1)  # (depth, W, …) -> (depth, …, W)
            return jnp.moveaxis(jnp.asarray(v)[index], 1, -1)

        return [
            [jax.tree_util.tree_map(lambda v, i=index: lay(v, i), per_link) for *_, index in p]
            for p in self.lanes.phases
        ]

    def zip(self, *seqs: Any) -> Any:
        """Several per-body sequences as one (tuples per body)."""
        if self.scan and self.lanes is None:
            return tuple(seqs)
        if self.lanes is None:
            return list(zip(*seqs, strict=True))
        return [
            [tuple(seq[g][k] for seq in seqs) for k in range(len(p))]
            for g, p in enumerate(self.lanes.phases)
        ]

    def run(self, step: Callable, carry: Any, xs: Any, reverse: bool = False) -> tuple[Any, Any]:
        if self.lanes is not None:
            return self._run_lanes(step, carry, xs, reverse)
        if self.parents is not None:
            if self.scan:
                return self._run_tree_scan(step, carry, xs, reverse)
            return self._run_tree(step, carry, xs, reverse)
        ys: list = [None] * self.n
        for i in reversed(range(self.n)) if reverse else range(self.n):
            carry, ys[i] = step(carry, xs[i])
        return carry, ys

    def _run_tree(self, step: Callable, init: Any, xs: Any, reverse: bool) -> tuple[Any, Any]:
        parents = self.parents
        assert parents is not None
        ys: list = [None] * self.n
        if not reverse:
            outs: list = [None] * self.n
            for i in range(self.n):
                outs[i], ys[i] = step(init if parents[i] < 0 else outs[parents[i]], xs[i])
            return init, ys
        acc: list = [init] * self.n
        total = init
        for i in reversed(range(self.n)):
            out, ys[i] = step(acc[i], xs[i])
            p = parents[i]
            if p >= 0:
                acc[p] = jax.tree_util.tree_map(add, acc[p], out)
            else:
                total = jax.tree_util.tree_map(add, total, out)
        return total, ys

    def _run_tree_scan(self, step: Callable, init: Any, xs: Any, reverse: bool):
        """`run` as one `lax.scan` over the bodies, every body's carry in a buffer (one
        more slot for the base) read (outward) and accumulated (inward) by parent index:
        for trees of more than `MAX_PHASES` phases."""
        parents = self.parents
        assert parents is not None
        n, dtype = self.n, self.dtype
        index = jnp.arange(n)
        parent = jnp.asarray([p if p >= 0 else n for p in parents])  # slot n: the base
        init = as_arrays(init, dtype)
        slots = jax.tree_util.tree_map(lambda v: jnp.broadcast_to(v, (n + 1, *v.shape)), init)

        def take(buf, k):
            return jax.tree_util.tree_map(lambda b: b[k], buf)

        if not reverse:

            def outward(buf, x):
                (i, p), xi = x
                out, y = step(scalars(take(buf, p)), scalars(xi))
                out = as_arrays(out, dtype)
                buf = jax.tree_util.tree_map(lambda b, o: b.at[i].set(o), buf, out)
                return buf, as_arrays(y, dtype)

            _, ys = jax.lax.scan(outward, slots, ((index, parent), xs))
            return init, ys

        def inward(buf, x):
            (i, p), xi = x
            out, y = step(scalars(take(buf, i)), scalars(xi))
            out = as_arrays(out, dtype)
            buf = jax.tree_util.tree_map(lambda b, o: b.at[p].add(o), buf, out)
            return buf, as_arrays(y, dtype)

        buf, ys = jax.lax.scan(inward, slots, ((index, parent), xs), reverse=True)
        return take(buf, n), ys

    def _run_lanes(self, step: Callable, init: Any, xs: Any, reverse: bool) -> tuple[Any, Any]:
        """`run` as scans over the phases of `self.lanes` (an outward pass returns its
        initial carry, an inward one the initial carry plus the base's children's)."""
        lanes = self.lanes
        assert lanes is not None
        dtype, tree_map = self.dtype, jax.tree_util.tree_map
        init = as_arrays(init, dtype)

        def lane_arrays(x: Any, width: int) -> Any:
            return tree_map(lambda v: jnp.broadcast_to(v, (width,)), x)

        def run_group(g: int, carry: Any, phases: Any) -> Any:
            """The group's phases from its lanes' carries; their final carries."""
            for k in phases:
                width = lanes.phases[g][k][1]
                head = tree_map(lambda v, w=width: v[:w], carry)
                head, ys[g][k] = lane_scan(step, head, xs[g][k], reverse, dtype)
                carry = tree_map(lambda h, v, w=width: jnp.concatenate([h, v[w:]]), head, carry)
            return carry

        ys: list = [[None] * len(p) for p in lanes.phases]
        groups = range(len(lanes.widths))
        final: Any = None
        if not reverse:
            for g in groups:
                parent = lanes.parent_lane[g]
                if parent is None:
                    carry = lane_arrays(init, lanes.widths[g])
                else:
                    carry = tree_map(lambda v, i=parent: v[i], final)
                final = run_group(g, carry, range(len(lanes.phases[g])))
            return init, ys
        for g in reversed(groups):
            carry = lane_arrays(init, lanes.widths[g])
            if final is not None:  # the children lanes' final carries, summed
                ids, width = lanes.parent_lane[g + 1], lanes.widths[g]
                assert ids is not None
                sums = tree_map(lambda v, i=ids, w=width: jax.ops.segment_sum(v, i, w), final)
                carry = tree_map(jnp.add, carry, sums)
            final = run_group(g, carry, reversed(range(len(lanes.phases[g]))))
        return tree_map(lambda i, v: i + jnp.sum(v, axis=0), init, final), ys

    def split(self, ys: Any) -> tuple:
        """Per-body outputs that are tuples, as a tuple of per-body sequences."""
        if self.scan and self.lanes is None:
            return tuple(ys)
        if self.lanes is None:
            return tuple(list(c) for c in zip(*ys, strict=True))
        k = len(ys[0][0])
        return tuple([[y[j] for y in group] for group in ys] for j in range(k))

    def _bodies(self, ys: Any) -> jnp.ndarray:
        """A scan's per-phase outputs (`(depth, W, …)` arrays, or Python floats for
        `(depth, W)`) in body order, `(n, …)`."""
        lanes = self.lanes
        assert lanes is not None
        flat = []
        for group, phases in zip(ys, lanes.phases, strict=True):
            for y, (*_, index) in zip(group, phases, strict=True):
                if isinstance(y, float):
                    y = jnp.full(index.shape, y, self.dtype)
                flat.append(y.reshape(-1, *y.shape[2:]))
        return jnp.concatenate(flat)[lanes.order]

    def column(self, ys: Any) -> Any:
        """Per-body vector outputs as an `(n, k)` array."""
        if self.scan and self.lanes is None:
            return jnp.stack(jax.tree_util.tree_leaves(ys), axis=-1).reshape(self.n, -1)
        if self.lanes is None:
            return jnp.stack([jnp.stack([jnp.asarray(v, self.dtype) for v in y]) for y in ys])
        dtype = self.dtype
        stacked = [
            [
                jnp.stack([jnp.broadcast_to(jnp.asarray(v, dtype), index.shape) for v in y], -1)
                for y, (*_, index) in zip(group, phases, strict=True)
            ]
            for group, phases in zip(ys, self.lanes.phases, strict=True)
        ]
        return self._bodies(stacked)

    def vector(self, values: Any, like: Any) -> Any:
        """Per-body scalar outputs (a list of scalars, some perhaps Python `0.0`, or a
        scan's per-phase outputs) as an `(n,)` array of `like`'s dtype."""
        if self.scan and self.lanes is None:
            return values.astype(like.dtype)
        if self.lanes is None:
            return stack(values, like)
        return self._bodies(values).astype(like.dtype)


class Chain:
    """A chain at one configuration: its `Passes`, algebra, per-link motion
    subspaces `S_i` and inertias `I_i` at the origin, and base acceleration `a_0 = −g`;
    `armature`, per-link rotor inertias added to the joints' diagonal of `M` (as
    `Passes.links` lays them out), or `None`."""

    def __init__(
        self, passes: Passes, algebra: Algebra, s: Any, inertia: Any, a0: Vec, armature=None
    ):
        self.passes, self.algebra, self.s, self.inertia, self.a0 = passes, algebra, s, inertia, a0
        self.armature = armature

    def zip_armature(self, *seqs: Any) -> Any:
        """`passes.zip(*seqs)`, with the armature last where the chain has one."""
        if self.armature is None:
            return self.passes.zip(*seqs)
        return self.passes.zip(*seqs, self.armature)

    def _zero(self) -> Vec:
        return tuple(0.0 for _ in self.a0)

    def _zero_matrix(self) -> Mat:
        return tuple(self._zero() for _ in self.a0)

    def velocities(self, qd: Any) -> Any:
        """Outward: `v_i = v_{i−1} + S_i q̇_i`, the velocity-product acceleration
        `c_i = (v_i × S_i) q̇_i` and the bias force `p_i = v_i ×* I_i v_i`."""
        alg = self.algebra

        def step(v, x):
            s, inertia, qd_i = x
            v = vadd(v, vscale(s, qd_i))
            return v, (vscale(alg.crm(v, s), qd_i), alg.crf(v, matvec(inertia, v)))

        xs = self.passes.zip(self.s, self.inertia, qd)
        return self.passes.run(step, self._zero(), xs)[1]


def aba(chain: Chain, qd: Any, force: Any) -> Any:
    """Featherstone's articulated-body algorithm: `q̈` of `M q̈ + C q̇ + G = force`.

    Three passes: velocities and bias forces outward; articulated inertias
    `I^A_i = I_i + (I^A_{i+1} − U Uᵀ/D)` and bias forces inward (`U = I^A S`,
    `D = Sᵀ U`, `u = τ − Sᵀ p^A`); accelerations outward, `q̈_i = (u_i − Uᵀ a') / D_i`.
    A non-positive `D_i` (a massless tip, a singular chain) gives NaN, never a finite
    wrong answer. `qd` and `force` are per-link sequences (`force` may be `None`).
    """
    passes = chain.passes
    vel = chain.velocities(qd)

    def inward(carry, x):
        art_child, p_child = carry
        s, inertia, (c, p), tau, *rotor = x
        art = madd(inertia, art_child)
        p_art = vadd(p, p_child)
        u = matvec(art, s)
        d = add(dot(s, u), rotor[0]) if rotor else dot(s, u)  # D_i = S_iᵀ I^A_i S_i + a_i
        d_inv = 1.0 / jnp.where(d > 0, d, jnp.nan)
        u_sc = sub(tau, dot(s, p_art))
        child = sym_rank1_sub(art, u, d_inv)
        pa = vadd(p_art, vadd(matvec(child, c), vscale(u, mul(u_sc, d_inv))))
        return (child, pa), (u, d_inv, u_sc)

    taus = force if force is not None else passes.links(jnp.zeros(passes.n, passes.dtype))
    xs = chain.zip_armature(chain.s, chain.inertia, vel, taus)
    _, factors = passes.run(inward, (chain._zero_matrix(), chain._zero()), xs, reverse=True)

    def outward(a, x):
        s, (c, _), (u, d_inv, u_sc) = x
        a = vadd(a, c)
        qdd = mul(sub(u_sc, dot(u, a)), d_inv)
        return vadd(a, vscale(s, qdd)), qdd

    xs = passes.zip(chain.s, vel, factors)
    return passes.run(outward, chain.a0, xs)[1]


def crba(chain: Chain) -> jax.Array:
    """The composite-rigid-body algorithm: `M_ji = S_jᵀ I^c_i S_i` for `j ≤ i`, with
    `I^c_i` the inertia of links `i…n` together (an inward sum)."""
    passes = chain.passes

    def inward(comp, x):
        s, inertia = x
        comp = madd(inertia, comp)
        return comp, matvec(comp, s)

    xs = passes.zip(chain.s, chain.inertia)
    _, f = passes.run(inward, chain._zero_matrix(), xs, reverse=True)
    s_arr, f_arr = passes.column(chain.s), passes.column(f)
    g = s_arr @ f_arr.T  # g[j, i] = S_j · I^c_i S_i
    above = passes.ancestors()  # j on i's path to the base: M_ji = S_j · I^c_i S_i
    if passes.parents is None:
        return jnp.where(above, g, g.T)
    return jnp.where(above, g, jnp.where(above.T, g.T, 0.0))


def rnea(chain: Chain, qd: Any, qdd: Any) -> Any:
    """The recursive Newton–Euler algorithm: `τ = M q̈ + C q̇ + G` (`qdd=None`: the
    bias `C q̇ + G`). Outward `a_i = a_{i−1} + S_i q̈_i + c_i`, `f_i = I_i a_i + p_i`;
    inward `τ_i = S_iᵀ f_i`, `f_{i−1} += f_i`."""
    passes = chain.passes
    vel = chain.velocities(qd)
    if qdd is None:
        qdd = passes.links(jnp.zeros(passes.n, passes.dtype))

    def outward(a, x):
        s, inertia, (c, p), qdd_i = x
        a = vadd(vadd(a, c), vscale(s, qdd_i))
        return a, vadd(matvec(inertia, a), p)

    _, forces = passes.run(outward, chain.a0, passes.zip(chain.s, chain.inertia, vel, qdd))

    def inward(f_child, x):
        s, f = x
        f = vadd(f, f_child)
        return f, dot(s, f)

    return passes.run(inward, chain._zero(), passes.zip(chain.s, forces), reverse=True)[1]


def rows_dot(a: jax.Array, b: jax.Array) -> jax.Array:
    """`a @ bᵀ` (`[j, i] = a_j · b_i`) for per-body vectors `(n, k)` with `k` of 3 or 6,
    as a sum of `k` outer products: elementwise code. Under `vmap` over many states,
    XLA:CPU runs the matrix product as a loop of tiny matrix calls, several times slower."""
    out = a[:, 0, None] * b[None, :, 0]
    for c in range(1, a.shape[1]):
        out = out + a[:, c, None] * b[None, :, c]
    return out


def stack(values: Any, like: Any) -> Any:
    """Per-link scalars of an unrolled pass (a list, some perhaps Python `0.0`) as one
    array of `like`'s dtype (a scan's: `Passes.vector`)."""
    # Not ``jnp.stack``: XLA:CPU fuses the whole recursion into the concatenation and
    # recomputes it for every output element (measured 20-40x slower from n = 6 on).
    out = jnp.zeros(len(values), like.dtype)
    for i, v in enumerate(values):
        out = out.at[i].set(jnp.asarray(v, like.dtype))
    return out
