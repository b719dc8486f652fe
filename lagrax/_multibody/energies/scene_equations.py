"""The equations of a [`lagrax.bodies.Scene`][] from its bodies' pose maps.

A scene knows what its kinetic energy is made of: each body's pose `P(q)` (a centre of
mass `x_c`, and an angle `θ` or a rotation `R`), its mass and its inertia. With
the Jacobians `J_v = ∂x_c/∂q` and `J_ω` (`∂θ/∂q` in the plane; in space the
columns `ω_j = vee(Rᵀ ∂R/∂q_j)`, the body-frame angular velocity per unit `q̇_j`),

$$
M(q) = Σ_b m_b J_{v,b}ᵀ J_{v,b} + J_{ω,b}ᵀ I_b J_{ω,b},
$$

$$
C(q, q̇) q̇ = Σ_b m_b J_{v,b}ᵀ a_b + J_{ω,b}ᵀ (I_b α_b + ω_b × I_b ω_b),
$$

where `a_b = ∂²x_c/∂q² [q̇, q̇]` and `α_b = vee(Rᵀ ∂²R/∂q² [q̇, q̇])` are the body's
accelerations when `q̈ = 0` (Newton's and Euler's equations projected on the
coordinates: Kane's method, or d'Alembert's principle). One forward-mode Jacobian of the
pose maps gives `M`, and one second-order forward derivative along `q̇` the velocity
products: no second derivatives of `T`, and none of the nine entries of each rotation
matrix. The gravity and spring forces `G = ∂V/∂q` are one reverse-mode gradient of
`V`. These equal the autodiff Lagrangian of the same energies to round-off (tested).
"""

from collections.abc import Sequence
from typing import Any, Protocol

import jax
import jax.numpy as jnp

from ..._core.custom_types import Params
from ..._core.errors import ConfigurationError, ShapeError
from ..._core.linalg import cholesky_solve
from ..._systems.derivatives import AbstractEquations
from ..common import batch, per_item, value
from .bodies import AbstractBody


def _body_terms(body: AbstractBody, q, qd, params: Params, with_bias: bool):
    """One body's (possibly `k` bodies') contributions to `M` and to `C q̇`."""

    def pose(a):
        return body.pose(a, params)

    (j_x, j_o) = jax.jacfwd(pose)(q)  # every leaf gains a trailing axis of length n
    if with_bias:

        def velocity(a):
            return jax.jvp(pose, (a,), (qd,))

        (prim, vel), (_, acc) = jax.jvp(velocity, (q,), (qd,))
    else:
        prim, vel, acc = pose(q), (None, None), (None, None)
    body.check_pose(prim)

    # translation: Σ m J_vᵀ J_v and Σ m J_vᵀ a
    jv = batch(j_x, 2)  # (k, d, n)
    m = per_item(value(body.mass, params), jv.shape[0], 0, q.dtype)
    mass = jnp.einsum("k,kdi,kdj->ij", m, jv, jv)
    bias = jnp.zeros_like(q)
    if with_bias:
        bias = jnp.einsum("k,kdi,kd->i", m, jv, batch(acc[0], 1))
    # rotation: Σ J_ωᵀ I J_ω and Σ J_ωᵀ (I α + ω × I ω), by the kind of body
    return body.rotation_terms(mass, bias, (prim[1], j_o, vel[1], acc[1]), params, q.dtype)


class PoseScene(Protocol):
    """What [`SceneEquations`][] reads of a scene (a [`lagrax.bodies.Scene`][]): its
    bodies, its potential energy, and that it has no hand-written kinetic energy."""

    @property
    def bodies(self) -> Sequence[AbstractBody]: ...

    @property
    def kinetic(self) -> Any: ...

    def potential_energy(self, q, params: Params) -> Any: ...


class SceneEquations(AbstractEquations):
    """The equations of a scene's `LagrangianSystem` from its bodies' pose maps (see the
    module docstring): `M` from one forward-mode Jacobian of the poses, the velocity
    products from one second-order forward derivative along `q̇`, `G = ∂V/∂q`."""

    scene: PoseScene

    def __check_init__(self):
        if self.scene.kinetic is not None:
            raise ConfigurationError(
                "SceneEquations needs a scene without a hand-written kinetic energy"
            )

    def _mass_and_velocity_products(self, q, qd, params, with_bias: bool):
        n = q.shape[0]
        mass = jnp.zeros((n, n), q.dtype)
        bias = jnp.zeros((n,), q.dtype)
        for body in self.scene.bodies:
            m_b, c_b = _body_terms(body, q, qd, params, with_bias)
            mass, bias = mass + m_b, bias + c_b
        if mass.shape != (n, n):
            raise ShapeError(f"the scene's bodies give a mass matrix of shape {mass.shape}")
        return mass, bias

    def _gravity(self, q, params):
        return jax.grad(lambda a: self.scene.potential_energy(a, params))(q)

    def energies(self, q, qd, params: Params) -> None:
        """`None`: a scene's `(T, V)` come from its energy functions."""
        return None

    def mass_matrix(self, q, params: Params) -> Any:
        """`M(q)` from one forward-mode Jacobian of the poses."""
        return self._mass_and_velocity_products(q, jnp.zeros_like(q), params, False)[0]

    def mass_and_bias(self, q, qd, params: Params) -> tuple[Any, Any]:
        """`M` and the bias `C q̇ + G`."""
        qd = qd.astype(q.dtype)
        mass, cqd = self._mass_and_velocity_products(q, qd, params, True)
        return mass, cqd + self._gravity(q, params)

    def accelerations(self, q, qd, params: Params, force) -> Any:
        """`q̈` solving `M q̈ + C q̇ + G = force` (`None`: zero); NaN where `M` is
        not positive-definite."""
        mass, bias = self.mass_and_bias(q, qd, params)
        rhs = -bias if force is None else jnp.asarray(force, q.dtype) - bias
        return cholesky_solve(mass, rhs)

    def inverse_dynamics(self, q, qd, qdd, params: Params) -> Any:
        """`M q̈ + C q̇ + G` (`qdd=None`: the bias `C q̇ + G`)."""
        mass, bias = self.mass_and_bias(q, qd, params)
        return bias if qdd is None else mass @ qdd.astype(q.dtype) + bias

    def derivatives(self, q, qd, qdd, params: Params) -> tuple[Any, Any, Any]:
        """`(∂τ/∂q, ∂τ/∂q̇, M)` of `τ = M q̈ + C q̇ + G` at `(q, q̇, q̈)`: forward-mode
        Jacobians of [`inverse_dynamics`][] at the fixed `q̈`, and `M`."""
        qd, qdd = qd.astype(q.dtype), qdd.astype(q.dtype)
        dq, dqd = jax.jacfwd(lambda a, b: self.inverse_dynamics(a, b, qdd, params), argnums=(0, 1))(
            q, qd
        )
        return dq, dqd, self.mass_matrix(q, params)
