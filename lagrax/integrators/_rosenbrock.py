"""Rodas4, a linearly implicit (Rosenbrock) method, as a diffrax solver.

An implicit Runge–Kutta method (diffrax's `Kvaerno5`) solves a nonlinear system at each
stage by Newton's method: for a contact scene that is one Jacobian of the vector field
per Newton iteration, about sixteen a step. A Rosenbrock method takes one Jacobian `J`
a step and replaces each stage's Newton solve by one linear solve with the same matrix
`W = I/(h γ) − J`:

    W Uᵢ = f(t₀ + cᵢ h, y₀ + Σⱼ aᵢⱼ Uⱼ) + Σⱼ (Cᵢⱼ / h) Uⱼ + h dᵢ ∂f/∂t,
    y₁ = y₀ + Σᵢ mᵢ Uᵢ,

with the error estimate `U₆` (the method is stiffly accurate: `y₁` is the last stage's
argument plus `U₆`) and a third-order dense output from two more combinations of the
`Uᵢ`. Rodas4 is L-stable, of order 4(3), with six stages; coefficients from Hairer &
Wanner, *Solving Ordinary Differential Equations II*, 2nd ed., Springer 1996, §IV.7
(their code RODAS). The stages run in one loop, so the vector field is traced once for
them and once (as a batched JVP) for `J` and `∂f/∂t`.
"""

from collections.abc import Callable
from typing import Any, ClassVar

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
from jax.flatten_util import ravel_pytree

PyTree = Any

# Hairer & Wanner's RODAS4 (their code's METH = 1): the stages' arguments `a`, the
# couplings `C` (both strictly lower triangular), the nodes `c`, the time-derivative
# weights `d`, and the dense output's two rows `H`.
_GAMMA = 0.25
_A = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [1.544, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.9466785280815826, 0.2557011698983284, 0.0, 0.0, 0.0, 0.0],
        [3.314825187068521, 2.896124015972201, 0.9986419139977817, 0.0, 0.0, 0.0],
        [1.221224509226641, 6.019134481288629, 12.53708332932087, -0.687886036105895, 0, 0],
        [1.221224509226641, 6.019134481288629, 12.53708332932087, -0.687886036105895, 1, 0],
    ]
)
_C = np.array(
    [
        [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [-5.6688, 0.0, 0.0, 0.0, 0.0, 0.0],
        [-2.430093356833875, -0.2063599157091915, 0.0, 0.0, 0.0, 0.0],
        [-0.1073529058151375, -9.594562251023355, -20.47028614809616, 0.0, 0.0, 0.0],
        [7.496443313967647, -10.24680431464352, -33.99990352819905, 11.7089089320616, 0, 0],
        [
            8.083246795921522,
            -7.981132988064893,
            -31.52159432874371,
            16.31930543123136,
            -6.058818238834054,
            0.0,
        ],
    ]
)
_NODES = np.array([0.0, 0.386, 0.21, 0.63, 1.0, 1.0])
_D = np.array([0.25, -0.1043, 0.1035, -0.0362, 0.0, 0.0])
_H = np.array(
    [
        [10.12623508344586, -7.487995877610167, -34.80091861555747, -7.992771707568823,
         1.025137723295662, 0.0],
        [-0.6762803392801253, 6.087714651680015, 16.43084320892478, 24.76722511418386,
         -6.594389125716872, 0.0],
    ]
)  # fmt: skip
# the solution's weights: the last stage's argument plus the last increment
_M = _A[5] + np.eye(6)[5]


class TangentLinearField(eqx.Module):
    """A vector field of a state `(y, s)` whose second part is the first's linearization,
    `F(t, (y, s)) = (f(t, y), ∂f/∂y s + g(t, y))`, so that its Jacobian is block lower
    triangular, `[[J, 0], [H(s), J]]` (`J = ∂f/∂y`, `H(s) = ∂(J s + g)/∂y`), with one
    diagonal block per tangent where `tangents` (then `s` carries `k` tangents on a
    leading axis, each of `y`'s structure). `Rodas4` forms and factorizes only `J` for
    such a field (`_tangent_step`)."""

    tangents: eqx.AbstractVar[bool]


class RodasInterpolation(dfx.AbstractLocalInterpolation):
    """Rodas4's dense output on one step: with `s = (t − t₀)/(t₁ − t₀)`,
    `y(s) = y₀ + s (y₁ − y₀) + s (1 − s) (k₁ + s k₂)`, third order in the step."""

    t0: jax.Array
    t1: jax.Array
    y0: PyTree  # pytrees of the state's structure
    y1: PyTree
    k1: PyTree
    k2: PyTree

    def evaluate(self, t0, t1=None, left=True):
        del left
        if t1 is not None:
            return jax.tree_util.tree_map(lambda a, b: a - b, self.evaluate(t1), self.evaluate(t0))
        s = (t0 - self.t0) / (self.t1 - self.t0)
        return jax.tree_util.tree_map(
            lambda y0, y1, k1, k2: y0 + s * (y1 - y0) + s * (1 - s) * (k1 + s * k2),
            self.y0,
            self.y1,
            self.k1,
            self.k2,
        )


class Rodas4(dfx.AbstractAdaptiveSolver):
    """Rodas4: a linearly implicit Rosenbrock method, L-stable, order 4(3), six stages.

    One Jacobian of the vector field and one LU factorization a step (by forward-mode
    autodiff: a batched JVP over the state and the time), then six linear solves: where
    an implicit Runge–Kutta method iterates Newton's method at every stage. The right
    method for stiff contact and joint limits: each step costs a few vector fields and
    a Jacobian, whatever the stiffness. Reference: E. Hairer, G. Wanner, *Solving
    Ordinary Differential Equations II*, 2nd ed., Springer 1996, §IV.7 (RODAS).

    The state may be any pytree of floating arrays of one dtype (it is flattened for
    the linear algebra). Dense output: third order (`RodasInterpolation`).
    """

    term_structure: ClassVar = dfx.AbstractTerm
    interpolation_cls: ClassVar[Callable[..., RodasInterpolation]] = RodasInterpolation

    def order(self, terms):
        del terms
        return 4

    def init(self, terms, t0, t1, y0, args):
        del terms, t0, t1, y0, args
        return None

    def func(self, terms, t0, y0, args):
        return terms.vf(t0, y0, args)

    def step(self, terms, t0, t1, y0, args, solver_state, made_jump):
        del solver_state, made_jump
        field = terms.vector_field if isinstance(terms, dfx.ODETerm) else None
        if isinstance(field, TangentLinearField):
            return _tangent_step(terms, field.tangents, t0, t1, y0, args)
        y0f, unravel = ravel_pytree(y0)

        def flat(t, y, s):
            del s
            return ravel_pytree(terms.vf(t, unravel(y), args))[0], None

        (y1f, k, error), _ = _step(flat, y0f, None, t0, t1)
        y1 = unravel(y1f)
        dense = dict(y0=y0, y1=y1, k1=unravel(k[0]), k2=unravel(k[1]))
        return y1, unravel(error), dense, None, dfx.RESULTS.successful


def _tangent_step(terms, tangents: bool, t0, t1, y0, args):
    """`Rodas4.step` for a `TangentLinearField`: the same numbers as the step on the full
    state (its Jacobian is that field's, exactly), with the Jacobian's columns taken along
    `y` only (`n + 1` directions, where the full state has `n (1 + k) + 1`) and one LU of
    `I/(h γ) − J` (`_step`)."""
    y0_, s0_ = y0
    y0f, unravel = ravel_pytree(y0_)
    one = s0_ if tangents else jax.tree_util.tree_map(lambda x: x[None], s0_)
    s0f = jax.vmap(lambda x: ravel_pytree(x)[0])(one)  # (k, n)

    def pack(sf):
        tree = jax.vmap(unravel)(sf)
        return tree if tangents else jax.tree_util.tree_map(lambda x: x[0], tree)

    def unpack(tree):
        one = tree if tangents else jax.tree_util.tree_map(lambda x: x[None], tree)
        return jax.vmap(lambda x: ravel_pytree(x)[0])(one)

    def flat(t, y, sf):
        dy, ds = terms.vf(t, (unravel(y), pack(sf)), args)
        return ravel_pytree(dy)[0], unpack(ds)

    (y1f, k, error), (s1f, ks, s_error) = _step(flat, y0f, s0f, t0, t1)

    def both(y, s):
        return unravel(y), pack(s)

    y1 = both(y1f, s1f)
    dense = dict(y0=y0, y1=y1, k1=both(k[0], ks[0]), k2=both(k[1], ks[1]))
    return y1, both(error, s_error), dense, None, dfx.RESULTS.successful


def _step(field, y0f, s0f, t0, t1):
    """One Rodas4 step on flat arrays: `((y₁, dense rows, error), tangents' alike)`.

    `field(t, y, s) -> (f, g)` is the vector field of a state `y` of `n` entries and, for
    a `TangentLinearField`, of its `k` tangents `s` (`(k, n)`; `None` and `g = None`
    otherwise, then the tangents' part of the result is `None`). `J = ∂f/∂y`, `∂f/∂t`
    (and for tangents `Hᵢ = ∂gᵢ/∂y`, `∂g/∂t`) come from one batched JVP along `y` and
    `t`, `n + 1` directions; `W = I/(h γ) − [[J, 0], [H, J]]` is block lower triangular,
    so each stage's `W (x, ξ) = (r, ρ)` is `x = W₀⁻¹ r`, `ξᵢ = W₀⁻¹ (ρᵢ + Hᵢ x)` with
    the one LU of `W₀ = I/(h γ) − J`."""
    dtype = y0f.dtype
    t0 = jnp.asarray(t0, dtype)
    h = jnp.asarray(t1, dtype) - t0
    n = y0f.size
    z0 = jnp.concatenate([y0f, t0[None]])

    def along(e):  # the derivatives along z = (y, t)'s direction e
        return jax.jvp(lambda z: field(z[n], z[:n], s0f), (z0,), (e,))[1]

    col_y, col_s = jax.vmap(along)(jnp.eye(n + 1, dtype=dtype))  # (n + 1, n), (n + 1, k, n)
    jac, f_t = col_y[:n].T, col_y[n]
    lu = jsl.lu_factor(jnp.eye(n, dtype=dtype) / (h * _GAMMA) - jac)
    a, c_over_h = jnp.asarray(_A, dtype), jnp.asarray(_C, dtype) / h
    nodes, d = jnp.asarray(_NODES, dtype), jnp.asarray(_D, dtype)
    if s0f is not None:
        coupling, g_t = jnp.transpose(col_s[:n], (1, 2, 0)), col_s[n]  # Hᵢ: (k, n, n); (k, n)

    def stage(i, carry):
        stages, tangent_stages = carry
        s_i = None if s0f is None else s0f + jnp.einsum("j,jkn->kn", a[i], tangent_stages)
        f_i, g_i = field(t0 + nodes[i] * h, y0f + a[i] @ stages, s_i)
        x = jsl.lu_solve(lu, f_i + c_over_h[i] @ stages + h * d[i] * f_t)
        if s0f is None:
            return stages.at[i].set(x), None
        rho = g_i + jnp.einsum("j,jkn->kn", c_over_h[i], tangent_stages) + h * d[i] * g_t
        xi = jsl.lu_solve(lu, (rho + coupling @ x).T).T
        return stages.at[i].set(x), tangent_stages.at[i].set(xi)

    zeros = None if s0f is None else jnp.zeros((6, *s0f.shape), dtype)
    stages, tangent_stages = jax.lax.fori_loop(0, 6, stage, (jnp.zeros((6, n), dtype), zeros))
    m, hh = jnp.asarray(_M, dtype), jnp.asarray(_H, dtype)
    primal = (y0f + m @ stages, hh @ stages, stages[5])
    if s0f is None:
        return primal, None
    s1f = s0f + jnp.einsum("j,jkn->kn", m, tangent_stages)
    ks = jnp.einsum("rj,jkn->rkn", hh, tangent_stages)
    return primal, (s1f, ks, tangent_stages[5])
