r"""The rows of a `ConstrainedSystem`'s KKT system, on any configuration manifold.

A system whose configuration `q` is not its velocity's integral (a floating base: `q`
holds a unit quaternion, `v` the angular velocity; `q̇ = N(q) v`) states its constraints
`φ(q) = 0` on `q` and is constrained on `v`: differentiating along the motion,

$$
φ̇ = ∂φ/∂q · N(q) v = J_v v, \qquad
φ̈ = J_v v̇ + \dot J_v v, \quad \dot J_v v = \frac{∂(J_v(q) v)}{∂q} N(q) v,
$$

so the constraint Jacobian on the velocities is `J_v = ∂φ/∂q · N(q)` (its columns `n`
JVPs of `φ` along `N(q) e_i`) and `J̇_v v` one more JVP of `q ↦ J_v(q) v` along `N(q) v`
(`v` held fixed). With `N = 1` (an ordinary system, `q̇ = v`) these are `J = ∂φ/∂q` and
`J̇ q̇`, the formulas of the class docstring, computed the same way. A velocity
constraint `A(q) v = 0` is stated on `v` already; `Ȧ v` is the JVP of `A(q) v` along
`N(q) v`.

The equations of such a system, `M(q) v̇ = f = τ − b(q, v) − ∂D/∂v`, come from its
`mass_matrix` and `inverse_dynamics` (`b + ∂D/∂v = inverse_dynamics(q, v, 0)`).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp

from .._core.checks import call_user, configuration_size, coords
from .._core.errors import ShapeError


def tangent_jacobian(system: Any, phi: Any, q: Any, n: int) -> jnp.ndarray:
    """`J_v = ∂φ/∂q · N(q)`, shape `(m, n)`: `n` JVPs of `φ` along `N(q) e_i`."""
    eye = jnp.eye(n, dtype=q.dtype)

    def column(e):
        return jax.jvp(phi, (q,), (system.configuration_rate(q, e),))[1]

    return jax.vmap(column, out_axes=1)(eye)


def rows(cs: Any, q: Any, qd: Any, params: Any, manifold: bool) -> tuple[Any, Any]:
    """The stacked constraint matrix `K = [J_v; A]` and the right-hand side `γ` of
    `K v̇ = γ`, with Baumgarte's stabilization (`ConstrainedSystem._rows`)."""
    rate = cs.system.configuration_rate
    out, gammas = [], []
    if cs.constraints is not None:

        def phi_and_rate(a):
            return jax.jvp(lambda b: cs._phi(b, params), (a,), (rate(a, qd),))

        (phi, jqd), (_, jdot_qd) = jax.jvp(phi_and_rate, (q,), (rate(q, qd),))
        out.append(cs._jacobian(q, params))
        gammas.append(-jdot_qd - 2.0 * cs.alpha * jqd - cs.beta**2 * phi)
    if cs.velocity_constraints is not None:

        def a_and_rate(a):
            amat = cs._amat(a, params)
            return amat, amat @ qd

        # Ȧ q̇ = (∂(A q̇)/∂q) N(q) q̇: one JVP (the unused tangent of A itself is dropped)
        (amat, aqd), (_, adot_qd) = jax.jvp(a_and_rate, (q,), (rate(q, qd),))
        out.append(amat)
        gammas.append(-adot_qd - cs.beta * aqd)
    dtype = jnp.result_type(*out)
    kmat = jnp.concatenate([r.astype(dtype) for r in out], axis=0)
    gamma = jnp.concatenate([g.astype(dtype) for g in gammas])
    return kmat, gamma


def mass_and_force(system: Any, q: Any, qd: Any, params: Any, tau: Any) -> tuple[Any, Any]:
    """`M(q)` and `f = τ − b − ∂D/∂v` of a system on a manifold (by its `mass_matrix`
    and `inverse_dynamics` at zero acceleration)."""
    mass = system.mass_matrix(q, params)
    force = -system.inverse_dynamics(q, qd, jnp.zeros_like(qd), params)
    if tau is not None:
        force = force + tau
    return mass, force


def manifold_state(cs: Any, q: Any, qd: Any, q_name: str, qd_name: str, others: dict) -> list:
    """`q` (size `n_configuration`) and the velocity-sized arrays (`qd`, `tau`, …:
    size `n_dof`; `None` kept) as 1-D arrays of one dtype, or a `ShapeError` naming the
    caller's arguments."""
    system = cs.system
    size = configuration_size(system.n_configuration, system.n_dof)
    out = [coords(q, q_name, system.n_configuration, cs.name, size=size)]
    named = {qd_name: qd, **others} if qd is not None else dict(others)
    for key, value in named.items():
        out.append(None if value is None else coords(value, key, system.n_dof, cs.name))
    dtype = jnp.result_type(*(x for x in out if x is not None))
    return [None if x is None else x.astype(dtype) for x in out]


def phi(cs: Any, q: Any, params: Any) -> Any:
    """`ConstrainedSystem._phi`: the user's `φ(q, params)` as a 1-D array (a scalar as
    one row), or a `ShapeError`."""
    if cs.constraints is None:
        return jnp.zeros((0,), q.dtype)
    out = jnp.asarray(call_user(cs.constraints, "constraint", params, q))
    if out.ndim == 0:
        out = out[None]
    if out.ndim != 1:
        raise ShapeError(
            f"the constraint function of {cs.name} returned shape {out.shape}; "
            "it must return a 1-D array phi(q) of shape (m,)"
        )
    return out


def amat(cs: Any, q: Any, params: Any) -> Any:
    """`ConstrainedSystem._amat`: the user's `A(q, params)` as an `(m₂, n)` matrix (a
    1-D `(n,)` result as one row), or a `ShapeError`."""
    n = q.shape[0] if cs.n_dof is None else cs.n_dof
    if cs.velocity_constraints is None:
        return jnp.zeros((0, n), q.dtype)
    out = jnp.asarray(call_user(cs.velocity_constraints, "velocity constraint", params, q))
    if out.ndim == 1 and out.shape[0] == n:
        out = out[None]
    if out.ndim != 2 or out.shape[1] != n:
        raise ShapeError(
            f"the velocity constraint function of {cs.name} returned shape "
            f"{out.shape} for q of shape ({n},); it must return the matrix A(q) of "
            f"shape (m, {n}) (one row per constraint A(q) qd = 0)"
        )
    if not jnp.issubdtype(out.dtype, jnp.floating):
        out = out.astype(q.dtype)
    return out
