"""Small dense SPD solves for the equations of motion.

Mass matrices of mechanisms are small (n ≲ 10) and are solved once per right-hand-side
evaluation, usually under `vmap`. A LAPACK call per solve is slow at that size, so for
`n <= _UNROLL_MAX` the factorization is unrolled into scalar arithmetic that XLA fuses
with the derivative computation into one loop over the batch. Larger systems use
`jax.scipy.linalg.cho_factor`/`cho_solve`. No inverse is ever formed.

Every solve returns NaN (rather than a finite wrong answer) when the matrix is not
positive-definite or is singular to working precision: a Cholesky pivot
`d_j <= tol · max_i |m_ii|` with `tol = 64 ε` is replaced by NaN, so the failure
propagates to the accelerations, where callers detect it.

A note on speed: in XLA:CPU an intermediate with several consumers becomes a fusion
boundary, and every fusion re-evaluates the transcendental functions of the model that
feed it (sin/cos dominate a small model's cost). So the pivot test is folded into the
pivots themselves rather than computed as a separate output.
"""

import jax.numpy as jnp
import jax.scipy.linalg as jsl
from jaxtyping import Array, Float

_UNROLL_MAX = 8
PIVOT_RTOL = 64.0  # in units of machine epsilon


def _tol(x) -> float:
    return PIVOT_RTOL * float(jnp.finfo(jnp.result_type(x)).eps)


def _checked(d, bound):
    """The pivot `d` if it exceeds `bound`, else NaN."""
    return jnp.where(d > bound, d, jnp.nan)


def solve_spd_unrolled(rows: list, rhs: list) -> Float[Array, " n"]:
    """Solve `m x = b` for a small SPD `m` given as nested lists of scalars.

    `n = 1, 2` use the Cholesky pivots directly: for `n = 2`, `d1 = m11` and
    `d2 = det/m11`, and the solve is `x = adj(m) b / det` with `det = d1 d2` (one
    division). `n >= 3` is an unrolled Cholesky factorization `m = L Lᵀ` and two
    triangular solves. NaN where `m` is not positive-definite (see module docstring).
    """
    n = len(rhs)
    scale = jnp.abs(rows[0][0])
    for i in range(1, n):
        scale = jnp.maximum(scale, jnp.abs(rows[i][i]))
    bound = _tol(rows[0][0]) * scale
    if n == 1:
        return jnp.stack([rhs[0] / _checked(rows[0][0], bound)])
    if n == 2:
        m11, m12, m22 = rows[0][0], rows[0][1], rows[1][1]
        # det = d1 d2 > bound·d1 with d1 = m11 > bound  <=>  both pivots exceed bound
        det = m11 * m22 - m12 * m12
        det = jnp.where((m11 > bound) & (det > bound * m11), det, jnp.nan)
        return jnp.stack([(m22 * rhs[0] - m12 * rhs[1]) / det, (m11 * rhs[1] - m12 * rhs[0]) / det])
    low = [[None] * n for _ in range(n)]
    for j in range(n):
        d = rows[j][j] - sum((low[j][k] * low[j][k] for k in range(j)), start=0.0)
        low[j][j] = jnp.sqrt(_checked(d, bound))
        for i in range(j + 1, n):
            s = rows[i][j] - sum((low[i][k] * low[j][k] for k in range(j)), start=0.0)
            low[i][j] = s / low[j][j]
    y = []  # forward substitution  L y = b
    for i in range(n):
        s = rhs[i] - sum((low[i][k] * y[k] for k in range(i)), start=0.0)
        y.append(s / low[i][i])
    x = [None] * n  # back substitution  Lᵀ x = y
    for i in reversed(range(n)):
        s = y[i] - sum((low[k][i] * x[k] for k in range(i + 1, n)), start=0.0)
        x[i] = s / low[i][i]
    return jnp.stack(x)


def cholesky_solve(m: Float[Array, "n n"], b: Float[Array, " n"]) -> Float[Array, " n"]:
    """Solve `m x = b` for symmetric positive-definite `m` (NaN if it is not).

    Unrolled for `n <= _UNROLL_MAX` (see `solve_spd_unrolled`), LAPACK
    (`cho_factor`/`cho_solve`) above.
    """
    n = m.shape[-1]
    if n <= _UNROLL_MAX:
        rows = [[m[i, j] for j in range(n)] for i in range(n)]
        return solve_spd_unrolled(rows, [b[i] for i in range(n)])
    factor, lower = jsl.cho_factor(m, lower=True)
    x = jsl.cho_solve((factor, lower), b)
    pivots = jnp.diagonal(factor) ** 2
    bound = _tol(m) * jnp.max(jnp.abs(jnp.diagonal(m)))
    return jnp.where(jnp.min(pivots) > bound, x, jnp.nan)


def lu_factor_small(a: Float[Array, "n n"]):
    """LU factorization with partial pivoting of a small general matrix: `P a = L U`.

    Unrolled over the columns for `n <= _UNROLL_MAX` (no LAPACK call, so it fuses into
    the surrounding solver loop); `jax.scipy.linalg.lu_factor` above. Returns an opaque
    factorization for `lu_solve_small`. A singular `a` gives non-finite solutions.
    """
    n = a.shape[-1]
    if n > _UNROLL_MAX:
        return jsl.lu_factor(a)
    pivots = []
    for k in range(n):
        p = k + jnp.argmax(jnp.abs(a[k:, k]))
        pivots.append(p)
        row_k, row_p = a[k], a[p]
        a = a.at[p].set(row_k).at[k].set(row_p)
        if k + 1 < n:
            low = a[k + 1 :, k] / a[k, k]
            a = a.at[k + 1 :, k].set(low)
            a = a.at[k + 1 :, k + 1 :].add(-low[:, None] * a[k, k + 1 :][None, :])
    return a, pivots


def lu_solve_small(factors, b: Float[Array, " n"]) -> Float[Array, " n"]:
    """Solve `a x = b` from `lu_factor_small`'s factorization of `a`."""
    lu, pivots = factors
    n = b.shape[0]
    if n > _UNROLL_MAX:
        return jsl.lu_solve((lu, pivots), b)
    for k, p in enumerate(pivots):  # the row swaps, in order
        b_k, b_p = b[k], b[p]
        b = b.at[p].set(b_k).at[k].set(b_p)
    y = []  # L y = P b, unit lower triangular
    for i in range(n):
        y.append(b[i] - sum((lu[i, j] * y[j] for j in range(i)), start=0.0))
    x = [None] * n  # U x = y
    for i in reversed(range(n)):
        s = y[i] - sum((lu[i, j] * x[j] for j in range(i + 1, n)), start=0.0)
        x[i] = s / lu[i, i]
    return jnp.stack(x)


def spd_inverse(m: Float[Array, "n n"]) -> Float[Array, "n n"]:
    """`m⁻¹` of a symmetric positive-definite `m` (NaN where it is not), for applying
    `M⁻¹` to many right-hand sides at once: the tangents of the accelerations.

    Unrolled for `n <= _UNROLL_MAX`: `m = L Lᵀ` (the pivot test of
    `solve_spd_unrolled`), `L⁻¹` by forward substitution and `m⁻¹ = L⁻ᵀ L⁻¹`, about
    `n³/2` scalar operations that XLA fuses into the surrounding computation. Above, LAPACK
    (`cho_factor` and `cho_solve` on the identity).
    """
    n = m.shape[-1]
    if n > _UNROLL_MAX:
        eye = jnp.eye(n, dtype=m.dtype)
        return cholesky_solve_many(m, eye)
    rows = [[m[i, j] for j in range(n)] for i in range(n)]
    scale = jnp.abs(rows[0][0])
    for i in range(1, n):
        scale = jnp.maximum(scale, jnp.abs(rows[i][i]))
    bound = _tol(m) * scale
    low = [[None] * n for _ in range(n)]
    for j in range(n):
        d = rows[j][j] - sum((low[j][k] * low[j][k] for k in range(j)), start=0.0)
        low[j][j] = jnp.sqrt(_checked(d, bound))
        for i in range(j + 1, n):
            s = rows[i][j] - sum((low[i][k] * low[j][k] for k in range(j)), start=0.0)
            low[i][j] = s / low[j][j]
    inv_low = [[None] * n for _ in range(n)]  # L⁻¹, lower triangular
    for i in range(n):
        for j in range(i + 1):
            s = (1.0 if i == j else 0.0) - sum(
                (low[i][k] * inv_low[k][j] for k in range(j, i)), start=0.0
            )
            inv_low[i][j] = s / low[i][i]
    out = [[None] * n for _ in range(n)]
    for i in range(n):
        for j in range(i, n):
            out[i][j] = out[j][i] = sum(
                (inv_low[k][i] * inv_low[k][j] for k in range(j, n)), start=0.0
            )
    return jnp.stack([jnp.stack(row) for row in out])


def cholesky_solve_many(m: Float[Array, "n n"], b: Float[Array, "n k"]) -> Float[Array, "n k"]:
    """Solve `m x = b` for a symmetric positive-definite `m` and `k` right-hand sides
    (NaN if `m` is not positive-definite): one LAPACK factorization for all of them."""
    factor, lower = jsl.cho_factor(m, lower=True)
    x = jsl.cho_solve((factor, lower), b)
    pivots = jnp.diagonal(factor) ** 2
    bound = _tol(m) * jnp.max(jnp.abs(jnp.diagonal(m)))
    return jnp.where(jnp.min(pivots) > bound, x, jnp.nan)


def small_matmul(a: Float[Array, "n k"], b: Float[Array, "k ..."]) -> Float[Array, "n ..."]:
    """`a @ b` for a matrix `a` and a vector or matrix `b`, written out row by row
    (`row_i = Σ_c a[i, c] b[c]`) where `k <= _UNROLL_MAX`, else `a @ b`.

    Under `vmap` over many states XLA:CPU runs a batched product of small matrices as a
    loop of tiny matrix calls (0.27 µs for `7 × 7` on the development CPU); the
    written-out products are elementwise over the batch and fuse with the code around them
    (0.06-0.08 µs). (As a sum of `k` outer products of whole columns, the form that
    `recursions.rows_dot` uses, XLA re-evaluated the inputs' producers: 1.8× slower
    derivatives of the URDF arm.)
    """
    n, k = a.shape
    if k > _UNROLL_MAX or b.ndim not in (1, 2):
        return a @ b
    cols = [b[c] for c in range(k)]
    return jnp.stack([sum((a[i, c] * cols[c] for c in range(k)), start=0.0) for i in range(n)])
