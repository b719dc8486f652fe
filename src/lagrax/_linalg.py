"""Small dense linear algebra for the equations of motion.

Mass matrices of mechanisms are small (n ≲ 10) and are solved once per right-hand-side
evaluation, usually under ``vmap``.  A LAPACK call per solve is slow at that size, so for
``n <= _UNROLL_MAX`` the Cholesky factorization and the two triangular solves are unrolled
into scalar arithmetic that XLA fuses into a single loop over the batch.  Larger systems use
``jax.scipy.linalg.cho_factor``/``cho_solve``.  No inverse is ever formed.
"""

import jax.numpy as jnp
import jax.scipy.linalg as jsl
from jaxtyping import Array, Float

_UNROLL_MAX = 8


def cholesky_solve(
    m: Float[Array, "n n"], b: Float[Array, " n"]
) -> tuple[Float[Array, " n"], Float[Array, ""]]:
    """Solve ``m x = b`` for symmetric positive-definite ``m``.

    Returns ``(x, pivot_ratio)`` where ``pivot_ratio = min_i d_i / max_j m_jj`` and ``d_i``
    are the Cholesky pivots (the squared diagonal of the factor).  ``pivot_ratio <= 0``
    (or NaN) means ``m`` is not positive-definite; a ratio near machine epsilon means it
    is numerically singular.
    """
    n = m.shape[-1]
    scale = jnp.max(jnp.abs(jnp.diagonal(m)))
    if n > _UNROLL_MAX:
        factor, lower = jsl.cho_factor(m, lower=True)
        x = jsl.cho_solve((factor, lower), b)
        pivots = jnp.diagonal(factor) ** 2
        return x, jnp.min(pivots) / scale
    # Unrolled LDLᵀ-free Cholesky (L Lᵀ = m), row by row, on scalars.
    low = [[None] * n for _ in range(n)]
    pivots = []
    for j in range(n):
        d = m[j, j] - sum((low[j][k] * low[j][k] for k in range(j)), start=0.0)
        pivots.append(d)
        ljj = jnp.sqrt(d)
        low[j][j] = ljj
        inv = 1.0 / ljj
        for i in range(j + 1, n):
            s = m[i, j] - sum((low[i][k] * low[j][k] for k in range(j)), start=0.0)
            low[i][j] = s * inv
    # forward substitution  L y = b
    y = []
    for i in range(n):
        s = b[i] - sum((low[i][k] * y[k] for k in range(i)), start=0.0)
        y.append(s / low[i][i])
    # back substitution  Lᵀ x = y
    x = [None] * n
    for i in reversed(range(n)):
        s = y[i] - sum((low[k][i] * x[k] for k in range(i + 1, n)), start=0.0)
        x[i] = s / low[i][i]
    ratio = pivots[0]
    for d in pivots[1:]:
        ratio = jnp.minimum(ratio, d)
    return jnp.stack(x), ratio / scale
