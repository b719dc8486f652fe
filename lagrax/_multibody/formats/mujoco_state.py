"""States and accelerations between MuJoCo's free and ball joints and lagrax's floating
base and ball joints: MuJoCo's `qpos` holds a quaternion scalar first and `qvel` a free
joint's linear velocity in the world frame (`qacc` its time derivative); lagrax's
(Pinocchio's) `q` the quaternion scalar last and `v` both of a base's velocities in the
base frame (`a` their time derivatives); a ball's angular velocity is in the child frame
in both."""

from typing import Any

import jax.numpy as jnp

from ..._contact.system import ContactSystem
from ..._core.errors import ArgumentTypeError, ShapeError
from ..floating.forest import Forest
from ..floating.system import FloatingTree


def _rotation(quat_xyzw: Any) -> jnp.ndarray:
    from ..algorithms.floating_recursions import quaternion_rotation

    return quaternion_rotation(quat_xyzw)


def _robot(robot: Any) -> Any:
    """The robot of a contact scene (`from_mujoco`'s, `from_mjcf(..., contact=True)`'s):
    its system; anything else as it is."""
    return robot.system if isinstance(robot, ContactSystem) else robot


def free_joints(robot: Any) -> list[tuple[int, int]]:
    """The `(qpos, qvel)` addresses of every free joint of `robot` (a
    [`FloatingTree`][lagrax.chains.FloatingTree], a [`Forest`][lagrax.chains.Forest] or a
    [`ConstrainedRobot`][lagrax.chains.ConstrainedRobot] around either; `None`: one free
    joint, first): each floating part's base, in the order of the state."""
    robot = getattr(robot, "robot", robot)  # a ConstrainedRobot: its robot
    if robot is None:
        return [(0, 0)]
    if not isinstance(robot, (Forest, FloatingTree)):
        return []  # a fixed base (a planar root of slides and a hinge, say): no free joint
    parts = robot.parts if isinstance(robot, Forest) else (robot,)
    out, qa, va = [], 0, 0
    for part in parts:
        if isinstance(part, FloatingTree):
            out.append((qa, va))
            qa, va = qa + 7 + part.n, va + 6 + part.n
        else:
            qa, va = qa + part.n, va + part.n
    return out


def from_mujoco_state(qpos: Any, qvel: Any, robot: Any = None) -> tuple[jnp.ndarray, jnp.ndarray]:
    r"""A floating robot's MuJoCo state (free joint first) as lagrax's `(q, v)`; with
    `robot`, a model with several free bodies (every free joint where it is).

    MuJoCo's free joint has `qpos = (x, y, z, q_w, q_x, q_y, q_z)` and `qvel = (v_O,
    ω_b)`, the body origin's velocity in the **world** frame and the angular velocity in
    the body frame; lagrax's floating base (Pinocchio's free-flyer convention, see
    [`FloatingTree`][lagrax.chains.FloatingTree]) has `q = (x, y, z, q_x, q_y, q_z,
    q_w)` and `v = (R^T v_O, ω_b)`, both velocities in the base frame. The joints
    follow unchanged. A generalized force converts like the velocity (`R^T f` for the
    linear part); an acceleration does not (the base frame turns):
    [`from_mujoco_acceleration`][lagrax.chains.from_mujoco_acceleration] converts
    MuJoCo's `qacc`.

    With `robot` ([`from_mjcf`][lagrax.chains.from_mjcf]'s result: a
    [`Forest`][lagrax.chains.Forest] of several free bodies, a
    [`FloatingTree`][lagrax.chains.FloatingTree], or a
    [`ConstrainedRobot`][lagrax.chains.ConstrainedRobot] around either), each floating
    part's free joint converts so at its place in the state (MuJoCo's body order, the
    parts' order), and the joints between them are unchanged.

    **Arguments:** `qpos` `(..., 7 + n)`, `qvel` `(..., 6 + n)` (leading batch axes
    allowed); `robot` (default `None`: one free joint, first), or a contact scene
    ([`from_mujoco`][lagrax.chains.from_mujoco]'s model), read as its robot.

    **Returns:** `(q, v)`, of the same shapes.

    **Raises:** `ShapeError` for a `qpos` or `qvel` without the free joint's entries, or
    whose joints or batch axes do not match; `ArgumentTypeError` for non-numeric input.
    """
    robot = _robot(robot)
    if getattr(robot, "balls", ()):
        return _ball_quaternions(robot, qpos, qvel, ("qpos", "qvel"), (1, 2, 3, 0))
    if _floating_balls(robot):  # the balls' quaternions, then the free joint
        qpos, qvel = _ball_quaternions(robot.tree, qpos, qvel, ("qpos", "qvel"), (1, 2, 3, 0), 7)
        pos, vel = from_mujoco_state(qpos[..., :7], qvel[..., :6])
        return qpos.at[..., :7].set(pos), qvel.at[..., :6].set(vel)
    frees = free_joints(robot)
    qpos, qvel = _free_joint_state(qpos, qvel, ("qpos", "qvel"), (7 * len(frees), 6 * len(frees)))
    for qa, va in frees:
        _sizes_at(qpos, qvel, qa, va, ("qpos", "qvel"))
        quat = jnp.concatenate([qpos[..., qa + 4 : qa + 7], qpos[..., qa + 3 : qa + 4]], axis=-1)
        rot = jnp.vectorize(_rotation, signature="(4)->(3,3)")(quat)
        linear = jnp.einsum("...ji,...j->...i", rot, qvel[..., va : va + 3])
        qpos = qpos.at[..., qa + 3 : qa + 7].set(quat)
        qvel = qvel.at[..., va : va + 3].set(linear)
    return qpos, qvel


def _floating_balls(robot: Any) -> bool:
    """Whether `robot` is a [`FloatingTree`][lagrax.chains.FloatingTree] with ball joints."""
    return isinstance(robot, FloatingTree) and bool(robot.tree.balls)


def _ball_quaternions(
    tree: Any, pos: Any, vel: Any, names: tuple[str, str], order: tuple, base: int = 0
):
    """The state of a [`Tree`][lagrax.chains.Tree] with ball joints (after a floating
    base's `base = 7` entries) with every ball's quaternion's entries taken in `order`
    (MuJoCo's `(w, x, y, z)` from lagrax's `(x, y, z, w)` or back); the velocity is the
    same in both (`ω` in the child frame)."""
    from ..articulated.balls import layout

    sizes = (base + tree.n_configuration, (6 if base else 0) + tree.n)
    pos, vel = _free_joint_state(pos, vel, names, sizes)
    if pos.shape[-1] != sizes[0]:
        raise ShapeError(
            f"{names[0]} has {pos.shape[-1]} entries on its last axis, expected "
            f"{sizes[0]} (a ball joint's quaternion takes 4)"
        )
    quats = base + layout(tree.joint_types, tree.balls)[2]
    return pos.at[..., quats].set(pos[..., quats[:, list(order)]]), vel


def _sizes_at(pos: Any, vel: Any, qa: int, va: int, names: tuple[str, str]) -> None:
    """`ShapeError` where a free joint at `(qa, va)` does not fit `pos`, `vel`."""
    if pos.shape[-1] < qa + 7 or vel.shape[-1] < va + 6:
        raise ShapeError(
            f"{names[0]} {pos.shape} and {names[1]} {vel.shape} have no room for the free "
            f"joint at {names[0]}[{qa}:{qa + 7}], {names[1]}[{va}:{va + 6}]: pass the "
            "state of the robot given"
        )


def to_mujoco_state(q: Any, v: Any, robot: Any = None) -> tuple[jnp.ndarray, jnp.ndarray]:
    r"""lagrax's floating-base `(q, v)` as MuJoCo's `(qpos, qvel)` of a free joint: the
    inverse of [`from_mujoco_state`][lagrax.chains.from_mujoco_state] (with `robot`,
    every free joint of a model with several free bodies).

    **Arguments:** `q` `(..., 7 + n)`, `v` `(..., 6 + n)`; `robot` (default `None`: one
    free joint, first).

    **Returns:** `(qpos, qvel)`, of the same shapes.

    **Raises:** as [`from_mujoco_state`][lagrax.chains.from_mujoco_state], naming `q`
    and `v`.
    """
    robot = _robot(robot)
    if getattr(robot, "balls", ()):
        return _ball_quaternions(robot, q, v, ("q", "v"), (3, 0, 1, 2))
    if _floating_balls(robot):
        q, v = _ball_quaternions(robot.tree, q, v, ("q", "v"), (3, 0, 1, 2), 7)
        pos, vel = to_mujoco_state(q[..., :7], v[..., :6])
        return q.at[..., :7].set(pos), v.at[..., :6].set(vel)
    frees = free_joints(robot)
    q, v = _free_joint_state(q, v, ("q", "v"), (7 * len(frees), 6 * len(frees)))
    for qa, va in frees:
        _sizes_at(q, v, qa, va, ("q", "v"))
        rot = jnp.vectorize(_rotation, signature="(4)->(3,3)")(q[..., qa + 3 : qa + 7])
        linear = jnp.einsum("...ij,...j->...i", rot, v[..., va : va + 3])
        quat = jnp.concatenate([q[..., qa + 6 : qa + 7], q[..., qa + 3 : qa + 6]], axis=-1)
        q = q.at[..., qa + 3 : qa + 7].set(quat)
        v = v.at[..., va : va + 3].set(linear)
    return q, v


def to_mujoco_acceleration(q: Any, v: Any, a: Any, robot: Any = None) -> jnp.ndarray:
    r"""lagrax's floating-base acceleration `a = v̇` at the state `(q, v)` as MuJoCo's
    `qacc` (what `mj_forward` writes): with `robot`, every free joint of a model with
    several free bodies, as [`to_mujoco_state`][lagrax.chains.to_mujoco_state] does.

    lagrax's (Pinocchio's) base velocity is the twist `(v_b, ω_b)` in the base frame and
    `a` its derivative `(v̇_b, ω̇_b)` in that frame; MuJoCo's free joint has `qvel =
    (v_O, ω_b)`, the body origin's velocity in the **world** frame `v_O = R v_b` (`R`:
    the base's rotation, base to world), and `qacc` its time derivative. The base
    frame turns at `ω_b`, so `v̇_O = Ṙ v_b + R v̇_b` with `Ṙ = R [ω_b]_×`:

        qacc_lin = R (v̇_b + ω_b × v_b),    qacc_ang = ω̇_b

    and the joints' entries are the same in both. A ball joint's entries are too (its
    angular velocity is in the child frame in both, and `qacc` its derivative there).
    Unlike a velocity or a force, the linear part depends on the velocity `v`: `a` of
    a state converts only with that state.

    **Arguments:** `q` `(..., 7 + n)`, `v` and `a` `(..., 6 + n)` (leading batch axes
    allowed; `a` of `v`'s shape); `robot` as for
    [`to_mujoco_state`][lagrax.chains.to_mujoco_state] (default `None`: one free
    joint, first).

    **Returns:** `qacc`, of `a`'s shape.

    **Raises:** `ShapeError` for a `q`, `v` or `a` without the free joint's entries, or
    whose joints or batch axes do not match (each named); `ArgumentTypeError` for
    non-numeric input.

    **Example:**

    ```python
    robot, params = lagrax.chains.from_mjcf("humanoid.xml")
    q, v = lagrax.chains.from_mujoco_state(data.qpos, data.qvel, robot)
    a = robot.system().forward_dynamics(q, v, params)
    qacc = lagrax.chains.to_mujoco_acceleration(q, v, a, robot)   # ≈ data.qacc
    ```
    """
    robot = _robot(robot)
    return _accelerations(q, v, a, robot, ("q", "v", "a"), to_mujoco=True)


def from_mujoco_acceleration(qpos: Any, qvel: Any, qacc: Any, robot: Any = None) -> jnp.ndarray:
    r"""MuJoCo's `qacc` at the state `(qpos, qvel)` as lagrax's acceleration `a = v̇`:
    the inverse of [`to_mujoco_acceleration`][lagrax.chains.to_mujoco_acceleration]
    (with `robot`, every free joint where it is).

    With `R` the base's rotation (from `qpos`'s quaternion), `ω_b` the angular part of
    `qvel` and `v_b = R^T v_O` the base-frame linear velocity:

        v̇_b = R^T qacc_lin − ω_b × v_b,    ω̇_b = qacc_ang

    and the joints' (and ball joints') entries unchanged.

    **Arguments:** `qpos` `(..., 7 + n)`, `qvel` and `qacc` `(..., 6 + n)` (leading
    batch axes allowed; `qacc` of `qvel`'s shape); `robot` as for
    [`from_mujoco_state`][lagrax.chains.from_mujoco_state] (default `None`: one free
    joint, first).

    **Returns:** `a`, of `qacc`'s shape.

    **Raises:** as [`to_mujoco_acceleration`][lagrax.chains.to_mujoco_acceleration],
    naming `qpos`, `qvel` and `qacc`.
    """
    robot = _robot(robot)
    return _accelerations(qpos, qvel, qacc, robot, ("qpos", "qvel", "qacc"), to_mujoco=False)


def _accelerations(pos: Any, vel: Any, acc: Any, robot: Any, names: tuple, to_mujoco: bool):
    """`acc` with each free joint's linear part converted (see `to_mujoco_acceleration`
    and `from_mujoco_acceleration`); `pos`'s quaternions lagrax's `(x, y, z, w)` when
    `to_mujoco`, MuJoCo's `(w, x, y, z)` otherwise."""
    order = (3, 0, 1, 2) if to_mujoco else (1, 2, 3, 0)
    if getattr(robot, "balls", ()):  # a fixed tree with balls: the same in both
        _, vel = _ball_quaternions(robot, pos, vel, names[:2], order)
        return _acceleration_like(acc, vel, names[1:])
    if _floating_balls(robot):  # the free joint first, then the balls' lanes
        pos, vel = _ball_quaternions(robot.tree, pos, vel, names[:2], order, 7)
        frees = [(0, 0)]
    else:
        frees = free_joints(robot)
        pos, vel = _free_joint_state(pos, vel, names[:2], (7 * len(frees), 6 * len(frees)))
    acc = _acceleration_like(acc, vel, names[1:])
    for qa, va in frees:
        _sizes_at(pos, vel, qa, va, names[:2])
        quat = pos[..., qa + 3 : qa + 7]
        if not to_mujoco:  # (w, x, y, z) -> (x, y, z, w)
            quat = jnp.concatenate([quat[..., 1:], quat[..., :1]], axis=-1)
        rot = jnp.vectorize(_rotation, signature="(4)->(3,3)")(quat)
        omega, linear = vel[..., va + 3 : va + 6], vel[..., va : va + 3]
        if to_mujoco:  # R (v̇_b + ω_b × v_b)
            out = jnp.einsum("...ij,...j->...i", rot, acc[..., va : va + 3])
            out = out + jnp.einsum("...ij,...j->...i", rot, jnp.cross(omega, linear))
        else:  # R^T qacc_lin − ω_b × R^T v_O
            body = jnp.einsum("...ji,...j->...i", rot, linear)
            out = jnp.einsum("...ji,...j->...i", rot, acc[..., va : va + 3])
            out = out - jnp.cross(omega, body)
        acc = acc.at[..., va : va + 3].set(out)
    return acc


def _real_array(x: Any, name: str) -> jnp.ndarray:
    """`x` as an array, or an `ArgumentTypeError` naming the argument `name`."""
    try:
        return jnp.asarray(x)
    except (TypeError, ValueError) as err:
        raise ArgumentTypeError(
            f"{name} must be an array of real numbers, got {type(x).__name__}: {err}"
        ) from None


def _acceleration_like(acc: Any, vel: jnp.ndarray, names: tuple[str, str]) -> jnp.ndarray:
    """`acc` as an array of `vel`'s shape, or an error naming both."""
    acc = _real_array(acc, names[1])
    if acc.shape != vel.shape:
        raise ShapeError(
            f"{names[1]} has shape {acc.shape} but {names[0]} has shape {vel.shape}: an "
            f"acceleration has one entry per velocity (and the same batch axes)"
        )
    return acc


def _free_joint_state(pos: Any, vel: Any, names: tuple[str, str], sizes: tuple[int, int]):
    """`(pos, vel)` of a floating base (a free joint first, then the joints; leading
    batch axes allowed) as arrays, or an error naming the caller's arguments: each must
    have at least `sizes` entries on its last axis (the base's), as many joints each,
    and the same batch axes."""
    out = []
    for name, x, size in zip(names, (pos, vel), sizes, strict=True):
        x = _real_array(x, name)
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
