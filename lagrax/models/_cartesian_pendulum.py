"""A pendulum in Cartesian coordinates: a point mass in the plane held by a rigid rod."""

import jax.numpy as jnp

from .._core.errors import ArgumentTypeError
from .._systems.constrained import ConstrainedSystem
from .._systems.lagrangian import LagrangianSystem

PARAM_NAMES = ("m", "l", "g")


def kinetic(q, qd, p):
    """`T = ½ m (ẋ² + ẏ²)`."""
    return 0.5 * p["m"] * jnp.sum(qd**2)


def potential(q, p):
    """`V = m g y` (gravity along −y)."""
    return p["m"] * p["g"] * q[1]


def rod(q, p):
    """`φ = x² + y² − l²`: the bob stays at distance `l` from the pivot (origin)."""
    return jnp.stack([q[0] ** 2 + q[1] ** 2 - p["l"] ** 2])


def cartesian_pendulum(*, alpha: float = 10.0, beta: float = 10.0, **overrides):
    """A simple pendulum in Cartesian coordinates `q = (x, y)`, as `(system, params)`.

    A point mass `m` in the plane (gravity `g` along −y, pivot at the origin) with the
    holonomic constraint `φ(q) = x² + y² − l² = 0`: a
    [`ConstrainedSystem`][lagrax.ConstrainedSystem] with 2 coordinates and 1 constraint (1 degree of
    freedom). In the minimal coordinate `θ` (from the downward vertical, `x = l sin θ`, `y = −l cos
    θ`) it is `m l² θ̈ + m g l sin θ = 0`, and the rod tension is `m (l θ̇² + g cos θ)`; the
    multiplier is `λ = −tension / (2 l)` (the constraint force `Jᵀλ = 2λ (x, y)`
    pulls the bob towards the pivot).

    `params`: `m l g` (default 1 kg, 1 m, 9.81 m/s²); keyword arguments override them.
    `alpha`, `beta`: Baumgarte gains of the [`ConstrainedSystem`][lagrax.ConstrainedSystem].

    **Example:** `system, params = lagrax.models.cartesian_pendulum(l=2.0)`
    """
    unknown = set(overrides) - set(PARAM_NAMES)
    if unknown:
        raise ArgumentTypeError(
            f"cartesian_pendulum() got unknown parameters {sorted(unknown)}; known: {PARAM_NAMES}"
        )
    params = {"m": 1.0, "l": 1.0, "g": 9.81, **overrides}
    params = {k: jnp.asarray(v, dtype=float) for k, v in params.items()}
    free = LagrangianSystem(kinetic, potential, n_dof=2, name="point mass (x, y)")
    system = ConstrainedSystem(free, rod, alpha=alpha, beta=beta, name="Cartesian pendulum")
    return system, params
