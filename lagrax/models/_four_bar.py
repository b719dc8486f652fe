"""A planar four-bar linkage: three links in absolute angles with a loop-closure constraint."""

import jax.numpy as jnp

from .._core.errors import ArgumentTypeError
from .._systems.constrained import ConstrainedSystem
from .._systems.lagrangian import LagrangianSystem

PARAM_NAMES = ("l1", "l2", "l3", "d", "m1", "m2", "m3", "g")


def _unit(angle):
    return jnp.stack([jnp.cos(angle), jnp.sin(angle)])


def joints(q, p):
    """Moving joints `A` (crank–coupler) and `B` (coupler–rocker, reached through the
    crank and coupler), and `B'` (the same joint reached from the rocker's pivot)."""
    a = p["l1"] * _unit(q[0])
    b = a + p["l2"] * _unit(q[1])
    b_rocker = jnp.stack([p["d"], jnp.zeros_like(p["d"])]) + p["l3"] * _unit(q[2])
    return a, b, b_rocker


def _centres(q, p):
    """Centres of mass of the three uniform links, shape `(3, 2)`."""
    a, _, _ = joints(q, p)
    ground_b = jnp.stack([p["d"], jnp.zeros_like(p["d"])])
    return jnp.stack(
        [
            0.5 * p["l1"] * _unit(q[0]),
            a + 0.5 * p["l2"] * _unit(q[1]),
            ground_b + 0.5 * p["l3"] * _unit(q[2]),
        ]
    )


def kinetic(q, qd, p):
    """`T = Σ ½ m_i |v_ci|² + ½ (m_i l_i²/12) θ̇_i²` (uniform rods), with the centre
    velocities `v_c1 = ½ l1 θ̇1 e⊥(θ1)`, `v_c2 = l1 θ̇1 e⊥(θ1) + ½ l2 θ̇2 e⊥(θ2)`,
    `v_c3 = ½ l3 θ̇3 e⊥(θ3)` (`e⊥(θ) = (−sin θ, cos θ)`), written out: a planar link
    needs only its centre velocity and one angular rate."""
    w1, w2, w3 = qd[0], qd[1], qd[2]
    # |v_c2|² = (l1 θ̇1)² + (½ l2 θ̇2)² + l1 l2 θ̇1 θ̇2 cos(θ1 − θ2)
    cross = p["l1"] * p["l2"] * w1 * w2 * jnp.cos(q[0] - q[1])
    v2_sq = (p["l1"] * w1) ** 2 + (0.5 * p["l2"] * w2) ** 2 + cross
    rot = (
        p["m1"] * p["l1"] ** 2 * w1**2
        + p["m2"] * p["l2"] ** 2 * w2**2
        + p["m3"] * p["l3"] ** 2 * w3**2
    ) / 12.0
    return 0.5 * (
        p["m1"] * (0.5 * p["l1"] * w1) ** 2
        + p["m2"] * v2_sq
        + p["m3"] * (0.5 * p["l3"] * w3) ** 2
        + rot
    )


def potential(q, p):
    """`V = g Σ m_i y_ci` (gravity along −y)."""
    masses = jnp.stack([p["m1"], p["m2"], p["m3"]])
    return p["g"] * jnp.sum(masses * _centres(q, p)[:, 1])


def loop_closure(q, p):
    """`φ(q) = B − B' = l1 e(θ1) + l2 e(θ2) − l3 e(θ3) − (d, 0)`, shape `(2,)`."""
    _, b, b_rocker = joints(q, p)
    return b - b_rocker


def four_bar(*, alpha: float = 10.0, beta: float = 10.0, **overrides):
    """A planar four-bar linkage under gravity, as `(system, params)`.

    Three uniform rods — crank (length `l1`, pivot at the origin), coupler (`l2`) and
    rocker (`l3`, pivot at `(d, 0)`); the ground is the fourth bar. Coordinates
    `q = (θ1, θ2, θ3)` are the links' absolute angles from the x axis, gravity along
    −y. Closing the loop (crank tip + coupler = rocker tip) is the holonomic constraint
    `φ(q) = l1 e(θ1) + l2 e(θ2) − l3 e(θ3) − (d, 0) = 0` (2 equations, so 1 degree of
    freedom): a [`ConstrainedSystem`][lagrax.ConstrainedSystem]. Its multipliers `λ` are the force
    (x, y) that the rocker exerts on the coupler at their joint.

    `params`: `l1 l2 l3 d m1 m2 m3 g`. Defaults: a Grashof crank–rocker
    (`l1 = 0.5`, `l2 = 2`, `l3 = 1.5`, `d = 2` m; the crank turns fully) of
    1 kg/m rods, `g = 9.81`; keyword arguments override them. For it, `J = ∂φ/∂q`
    has full rank in every assembled configuration.

    **Example:** the crank up and an approximate assembly, projected by `simulate`:

    ```python
    system, params = lagrax.models.four_bar()
    sol = lagrax.simulate(system, [1.57, 0.35, 1.9], [0.0, 0.0, 0.0], params, t1=10.0)
    abs(sol.constraint_violation).max()
    ```
    """
    unknown = set(overrides) - set(PARAM_NAMES)
    if unknown:
        raise ArgumentTypeError(
            f"four_bar() got unknown parameters {sorted(unknown)}; known: {PARAM_NAMES}"
        )
    params = dict(l1=0.5, l2=2.0, l3=1.5, d=2.0, m1=0.5, m2=2.0, m3=1.5, g=9.81)
    params.update(overrides)
    params = {k: jnp.asarray(v, dtype=float) for k, v in params.items()}
    free = LagrangianSystem(kinetic, potential, n_dof=3, name="three free links")
    system = ConstrainedSystem(free, loop_closure, alpha=alpha, beta=beta, name="four-bar linkage")
    return system, params
