r"""Ball joints of a [`Tree`][lagrax.chains.Tree], in Pinocchio's spherical convention:
the configuration holds the joint's unit quaternion `(x, y, z, w)` (4 entries), the
velocity its angular velocity `ω` in the child frame (3 entries).

**Lanes.** Inside the recursions a ball joint is three revolute *lanes* at one origin,
about the child frame's `x`, `y` and `z` axes: lanes `a` and `b` are massless bodies,
lane `c` carries the child. The lanes' angles are always `0`; the rotation comes from the
quaternion instead, as lane `a`'s joint rotation `S R(quat)` (in place of Rodrigues'
`A + sin θ B + (1 − cos θ) C`, whose `B` and `C` terms vanish at `θ = 0`), and lanes `b`
and `c` have the identity rotation and no offset. The lanes' rates are then exactly `ω`,
and the composite-rigid-body algorithm gives the exact `M`.

Only the velocity-product term differs. The lanes at `θ = 0` have `ω = J(θ) θ̇` with
`J(0) = 1`, so `ω̇ = θ̈ + J̇ θ̇` and, for lanes `x`, `y`, `z` in that order,

$$
J̇ θ̇ = δ(ω) = (ω_y ω_z,\; −ω_x ω_z,\; ω_x ω_y).
$$

With `P` placing every ball's `δ` on its lanes: `ω̇ = ABA(q, ω, τ − A P δ) + P δ` and
`τ = RNEA(q, ω, ω̇ − P δ) + A P δ` (`A` the armature, which MuJoCo adds as `A ω̇`).
"""

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from ..algorithms.floating_recursions import quaternion_rate, quaternion_rotation, skew

LANE_AXES = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
"""The axes of a ball joint's three lanes, in the child frame."""


def layout(types: str, balls: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the coordinates sit in the configuration `q` of a tree whose ball joints
    start at the lanes `balls`: `(lanes, slots, quats)`, the lanes that are one-angle
    joints, their slots in `q`, and `(n_balls, 4)` the slots of each ball's quaternion
    (Pinocchio's order: every joint in tree order, a ball taking 4 slots)."""
    starts = set(balls)
    lanes, slots, quats, k, i = [], [], [], 0, 0
    while i < len(types):
        if i in starts:
            quats.append(range(k, k + 4))
            k, i = k + 4, i + 3
        else:
            lanes.append(i)
            slots.append(k)
            k, i = k + 1, i + 1
    return np.asarray(lanes, int), np.asarray(slots, int), np.asarray(quats, int).reshape(-1, 4)


def lane_state(tree: Any, q: Any) -> tuple[jnp.ndarray, jnp.ndarray]:
    """`(θ, A)` of a tree with ball joints at the configuration `q`: every lane's angle
    (zero on a ball's lanes) and the joint constants `A` with each ball's first lane's
    `S R(quat)` (see the module docstring)."""
    balls = tree.balls
    lanes, slots, quats = layout(tree.joint_types, balls)
    theta = jnp.zeros(tree.n_bodies, q.dtype).at[lanes].set(q[slots])
    big_a = jnp.asarray(tree.joint_constants()[0], q.dtype)
    rots = jax.vmap(quaternion_rotation)(q[quats])
    start = np.asarray(balls, int)
    return theta, big_a.at[start].set(big_a[start] @ rots)


def velocity_product(balls: tuple[int, ...], v: Any) -> jnp.ndarray:
    """`P δ(ω)`: every ball's `(ω_y ω_z, −ω_x ω_z, ω_x ω_y)` on its lanes, zero on the
    other joints."""
    a = np.asarray(balls, int)
    wx, wy, wz = v[a], v[a + 1], v[a + 2]
    out = jnp.zeros_like(v)
    return out.at[a].set(wy * wz).at[a + 1].set(-wx * wz).at[a + 2].set(wx * wy)


def velocity_product_jacobian(balls: tuple[int, ...], v: Any) -> jnp.ndarray:
    """`∂(P δ)/∂ω`, shape `(n, n)`."""
    out = jnp.zeros((v.shape[0], v.shape[0]), v.dtype)
    for s in balls:
        wx, wy, wz = v[s], v[s + 1], v[s + 2]
        block = jnp.stack(
            [
                jnp.stack([jnp.zeros_like(wx), wz, wy]),
                jnp.stack([-wz, jnp.zeros_like(wx), -wx]),
                jnp.stack([wy, wx, jnp.zeros_like(wx)]),
            ]
        )
        out = out.at[s : s + 3, s : s + 3].set(block)
    return out


def joint_product(tree: Any, v: Any) -> jnp.ndarray:
    """`P δ` of a floating base's velocity `v = (v_B, joints)`: zero on the base's six
    entries (`FloatingBaseSystem` with ball joints)."""
    return jnp.concatenate([jnp.zeros(6, v.dtype), velocity_product(tree.balls, v[6:])])


def armature_product(params: Any, product: Any) -> Any:
    """`A P δ` of a floating base's `P δ` (`joint_product`), zero on the base; `0.0`
    without armature."""
    rotor = params.get("armature")
    if rotor is None:
        return 0.0
    rotor = jnp.asarray(rotor, product.dtype)
    return jnp.concatenate([jnp.zeros(6, product.dtype), rotor * product[6:]])


def configuration_names(tree: Any) -> tuple[str, ...]:
    """The names of a tree's configuration entries: a one-angle joint's name, a ball's
    `<joint>_qx`, `_qy`, `_qz`, `_qw` (its first lane's name without the `_x`)."""
    names = list(tree.joint_names)
    out: list[str] = []
    i = 0
    while i < len(names):
        if i in tree.balls:
            stem = names[i].removesuffix("_x")
            out += [f"{stem}_q{c}" for c in "xyzw"]
            i += 3
        else:
            out.append(names[i])
            i += 1
    return tuple(out)


def check_quaternions(tree: Any, q: Any, offset: int = 0) -> None:
    """Eagerly, `ShapeError` naming the first ball whose quaternion is zero (`q`: the
    tree's configuration, at `offset` in the system's)."""
    from ..._core.errors import ShapeError

    norms = np.asarray(quaternion_norms(tree, q))
    quats = layout(tree.joint_types, tree.balls)[2]
    for k, lane in enumerate(tree.balls):
        if not norms[k] > 0:
            name = tree.joint_names[lane].removesuffix("_x")
            first = int(quats[k][0]) + offset
            raise ShapeError(
                f"the quaternion of ball joint {name!r}, q[{first}:{first + 4}] = "
                f"{np.asarray(q)[quats[k]]}, is zero: a rotation needs a unit quaternion "
                "(x, y, z, w), e.g. (0, 0, 0, 1)"
            )


def configuration_rate(tree: Any, q: Any, v: Any) -> jnp.ndarray:
    """`q̇ = N(q) v`: a one-angle joint's rate is its velocity, a ball's quaternion
    moves as `½ quat ⊗ (ω, 0)`."""
    lanes, slots, quats = layout(tree.joint_types, tree.balls)
    start = np.asarray(tree.balls, int)
    omega = v[start[:, None] + np.arange(3)]
    rates = jax.vmap(quaternion_rate)(q[quats], omega)
    return jnp.zeros_like(q).at[slots].set(v[lanes]).at[quats].set(rates)


def retract(tree: Any, q: Any, xi: Any) -> jnp.ndarray:
    """`q ⊕ ξ` to first order in `ξ` (the tangent of the configuration, sized like the
    velocity): a one-angle joint moves by `ξ`, a ball's rotation to `R exp([ξ]×)`, its
    quaternion by `½ quat ⊗ (ξ, 0)` (normalized where it is read)."""
    return q + configuration_rate(tree, q, xi)


def normalized(tree: Any, q: Any) -> jnp.ndarray:
    """`q` with every ball's quaternion divided by its norm."""
    quats = layout(tree.joint_types, tree.balls)[2]
    x = q[quats]
    return q.at[quats].set(x / jnp.linalg.norm(x, axis=-1, keepdims=True))


def quaternion_norms(tree: Any, q: Any) -> jnp.ndarray:
    """The norm of every ball's quaternion, shape `(n_balls,)`."""
    return jnp.linalg.norm(q[layout(tree.joint_types, tree.balls)[2]], axis=-1)


def no_scene(tree: Any) -> None:
    """`ConfigurationError` for the scene of a tree with ball joints: its energies are
    not a Lagrangian in `(q, q̇)` (a ball's velocity is not its quaternion's rate)."""
    if tree.balls:
        from ..._core.errors import ConfigurationError

        raise ConfigurationError(
            "a tree with ball joints has no scene of energies in (q, q̇): a ball's velocity "
            "is its angular velocity, not its quaternion's rate; use tree.system() (a "
            "BallTreeSystem, with energy and the recursions)"
        )


def ball_entries(
    balls: Any, types: str, parents: tuple[int, ...], axes: Any, rotations: Any, mimic: Any
) -> tuple[int, ...]:
    """The first lanes of a tree's ball joints, checked: each is followed by its two
    other lanes (`"RRR"` about `x`, `y`, `z`, each the child of the one before, the
    second and third with the identity rotation), no two overlap, and the tree has no
    mimic joints; `ConfigurationError` naming the entry otherwise."""
    from ..._core.errors import ConfigurationError

    out = tuple(sorted(int(b) for b in (balls or ())))
    if out and mimic:
        raise ConfigurationError("a tree with ball joints cannot have mimic joints")
    lanes = [i for b in out for i in range(b, b + 3)]
    if len(set(lanes)) != len(lanes):
        raise ConfigurationError(f"balls {out}: two ball joints share a lane")
    eye = np.eye(3)
    for b in out:
        ok = 0 <= b and b + 2 < len(types) and types[b : b + 3] == "RRR"
        ok = ok and parents[b + 1] == b and parents[b + 2] == b + 1
        ok = ok and all(np.allclose(axes[b + k], LANE_AXES[k]) for k in range(3))
        ok = ok and all(np.allclose(rotations[b + k], eye) for k in (1, 2))
        if not ok:
            raise ConfigurationError(
                f"balls entry {b}: a ball joint is three revolute lanes b, b + 1, b + 2 "
                "about x, y, z, each the child of the one before, the last two with the "
                "identity rotation"
            )
    return out


# `J(θ)` of the lanes, `ω = J(θ) θ̇`: columns `R_zᵀ R_yᵀ e_x`, `R_zᵀ e_y`, `e_z`, i.e.
# `[[c₂c₃, s₃, 0], [−c₂s₃, c₃, 0], [s₂, 0, 1]]`; its derivatives at `θ = 0`:
_DJ = np.zeros((3, 3, 3))  # `∂J/∂θ_k`
_DJ[1, 2, 0] = 1.0
_DJ[2] = [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
_D2J = np.zeros((3, 3, 3, 3))  # `∂²J/∂θ_k∂θ_j` (only `k = j = y` and `k = j = z`)
_D2J[1, 1, 0, 0] = -1.0
_D2J[2, 2] = np.diag([-1.0, -1.0, 0.0])


def tangent_derivatives(balls: tuple[int, ...], tau, dq, dqd, mass, v, vdot, offset: int = 0):
    r"""`(∂τ/∂q, ∂τ/∂v)` along `q ⊕ ξ` at fixed `(ω, ω̇)` from the lanes' analytic
    `(τ_θ, ∂τ_θ/∂θ, ∂τ_θ/∂θ̇, M)` at `θ = 0`, `θ̇ = ω`, `θ̈ = ω̇ − P δ` (no armature).

    Moving a ball's lanes to `θ` with the motion fixed changes their rates and
    accelerations, `θ̇ = J⁻¹ ω` and `θ̈ = J⁻¹ (ω̇ − J̇ θ̇)`, and its generalized force is
    `τ_ω = J⁻ᵀ τ_θ`; with `J(0) = 1` and the constant `∂_k J`, `∂_k ∂_j J` at `0`:

    $$
    \frac{∂τ}{∂ξ_k} = \frac{∂τ_θ}{∂θ_k} + \frac{∂τ_θ}{∂θ̇} u_k + M a_k − (∂_k J)ᵀ τ_θ,
    \quad u_k = −∂_k J\,ω, \quad
    a_k = −∂_k J\,(ω̇ − δ) − \textstyle\sum_j ∂_k ∂_j J\,ω_j\,ω − \frac{∂δ}{∂ω} u_k,
    $$

    the last term on the ball's rows only; and `∂τ/∂ω = ∂τ_θ/∂θ̇ − M ∂(P δ)/∂ω`. `v`,
    `vdot`: the joints' (lanes'); the matrices' joint block starts at `offset` (a
    floating base: 6)."""
    for s in balls:
        w, k0 = v[s : s + 3], offset + s
        lanes_dd = vdot[s : s + 3] - velocity_product((0,), w)
        ddelta = velocity_product_jacobian((0,), w)
        cols = []
        for k in range(3):
            u = -_DJ[k] @ w
            acc = -_DJ[k] @ lanes_dd - (_D2J[k] @ w).T @ w - ddelta @ u
            col = dqd[:, k0 : k0 + 3] @ u + mass[:, k0 : k0 + 3] @ acc
            cols.append(col.at[k0 : k0 + 3].add(-_DJ[k].T @ tau[k0 : k0 + 3]))
        dq = dq.at[:, k0 : k0 + 3].add(jnp.stack(cols, axis=1))
    return dq, dqd.at[:, offset:].add(-mass[:, offset:] @ velocity_product_jacobian(balls, v))


def rotation_blocks(a_mat: Any, balls: tuple[int, ...], v: Any, offset: int = 0) -> jnp.ndarray:
    """`A` of a linearization on the tangent space with every ball's `ξ̇ = ω − ½ ω × ξ +
    O(ξ²)` block `−½ [ω]×` set (`offset`: where the joints' velocities start in `v`)."""
    for lane in balls:
        k = offset + lane
        a_mat = a_mat.at[k : k + 3, k : k + 3].set(-0.5 * skew(v[k : k + 3].astype(a_mat.dtype)))
    return a_mat
