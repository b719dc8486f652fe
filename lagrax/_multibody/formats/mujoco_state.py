"""States between MuJoCo's free joint and lagrax's floating base: MuJoCo's `qpos` holds
the quaternion scalar first and `qvel` the base's linear velocity in the world frame;
lagrax's (Pinocchio's) `q` the quaternion scalar last and `v` both velocities in the base
frame."""

from typing import Any

import jax.numpy as jnp

from ..._core.errors import ArgumentTypeError, ShapeError


def _rotation(quat_xyzw: Any) -> jnp.ndarray:
    from ..algorithms.floating_recursions import quaternion_rotation

    return quaternion_rotation(quat_xyzw)


def from_mujoco_state(qpos: Any, qvel: Any) -> tuple[jnp.ndarray, jnp.ndarray]:
    r"""A floating robot's MuJoCo state (free joint first) as lagrax's `(q, v)`.

    MuJoCo's free joint has `qpos = (x, y, z, q_w, q_x, q_y, q_z)` and `qvel = (v_O,
    ω_b)`, the body origin's velocity in the **world** frame and the angular velocity in
    the body frame; lagrax's floating base (Pinocchio's free-flyer convention, see
    [`FloatingTree`][lagrax.chains.FloatingTree]) has `q = (x, y, z, q_x, q_y, q_z,
    q_w)` and `v = (R^T v_O, ω_b)`, both velocities in the base frame. The joints
    follow unchanged. A generalized force converts like the velocity (`R^T f` for the
    linear part), and MuJoCo's `qacc` is `(R (v̇_b + ω_b × v_b), ω̇_b, q̈)`.

    **Arguments:** `qpos` `(..., 7 + n)`, `qvel` `(..., 6 + n)` (leading batch axes
    allowed).

    **Returns:** `(q, v)`, of the same shapes.

    **Raises:** `ShapeError` for a `qpos` or `qvel` without the free joint's entries, or
    whose joints or batch axes do not match; `ArgumentTypeError` for non-numeric input.
    """
    qpos, qvel = _free_joint_state(qpos, qvel, ("qpos", "qvel"), (7, 6))
    quat = jnp.concatenate([qpos[..., 4:7], qpos[..., 3:4]], axis=-1)
    rot = jnp.vectorize(_rotation, signature="(4)->(3,3)")(quat)
    linear = jnp.einsum("...ji,...j->...i", rot, qvel[..., :3])
    q = jnp.concatenate([qpos[..., :3], quat, qpos[..., 7:]], axis=-1)
    return q, jnp.concatenate([linear, qvel[..., 3:]], axis=-1)


def to_mujoco_state(q: Any, v: Any) -> tuple[jnp.ndarray, jnp.ndarray]:
    r"""lagrax's floating-base `(q, v)` as MuJoCo's `(qpos, qvel)` of a free joint: the
    inverse of [`from_mujoco_state`][lagrax.chains.from_mujoco_state].

    **Arguments:** `q` `(..., 7 + n)`, `v` `(..., 6 + n)`.

    **Returns:** `(qpos, qvel)`, of the same shapes.

    **Raises:** as [`from_mujoco_state`][lagrax.chains.from_mujoco_state], naming `q`
    and `v`.
    """
    q, v = _free_joint_state(q, v, ("q", "v"), (7, 6))
    rot = jnp.vectorize(_rotation, signature="(4)->(3,3)")(q[..., 3:7])
    linear = jnp.einsum("...ij,...j->...i", rot, v[..., :3])
    qpos = jnp.concatenate([q[..., :3], q[..., 6:7], q[..., 3:6], q[..., 7:]], axis=-1)
    return qpos, jnp.concatenate([linear, v[..., 3:]], axis=-1)


def _free_joint_state(pos: Any, vel: Any, names: tuple[str, str], sizes: tuple[int, int]):
    """`(pos, vel)` of a floating base (a free joint first, then the joints; leading
    batch axes allowed) as arrays, or an error naming the caller's arguments: each must
    have at least `sizes` entries on its last axis (the base's), as many joints each,
    and the same batch axes."""
    out = []
    for name, x, size in zip(names, (pos, vel), sizes, strict=True):
        try:
            x = jnp.asarray(x)
        except (TypeError, ValueError) as err:
            raise ArgumentTypeError(
                f"{name} must be an array of real numbers, got {type(x).__name__}: {err}"
            ) from None
        if x.ndim == 0 or x.shape[-1] < size:
            raise ShapeError(
                f"{name} must have {size} + n entries on its last axis (the free joint's "
                f"{size}, then the n joints'), got shape {x.shape}"
            )
        out.append(x)
    (p, v), (np_, nv) = out, sizes
    if p.shape[-1] - np_ != v.shape[-1] - nv or p.shape[:-1] != v.shape[:-1]:
        raise ShapeError(
            f"{names[1]} has shape {v.shape} ({v.shape[-1] - nv} joints) but {names[0]} has "
            f"shape {p.shape} ({p.shape[-1] - np_} joints): {names[1]}'s last axis must have "
            f"{p.shape[-1] - np_ + nv} entries ({nv} + n) and the leading (batch) axes must "
            "match"
        )
    return p, v
