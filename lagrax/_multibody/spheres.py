"""Spheres fixed to a tree's bodies, by name, from the kinematics the recursions use."""

import weakref
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._contact.geometry import AbstractSphereSource, Sphere
from .._core.errors import ArgumentTypeError, ConfigurationError
from .algorithms.floating_recursions import quaternion_rotation
from .articulated.trees import AbstractTree, Tree
from .floating.system import FloatingTree


def _index(names: tuple[str, ...], body: Any, base: str | None) -> int:
    """The body's index in the tree (`−1`: the floating base)."""
    if isinstance(body, str):
        if base is not None and body == base:
            return -1
        if body in names:
            return names.index(body)
        known = ([base] if base is not None else []) + list(names)
        raise ConfigurationError(f"no body named {body!r} in this tree; its bodies are {known}")
    if isinstance(body, (int, np.integer)) and not isinstance(body, bool):
        low = -1 if base is not None else 0
        if low <= int(body) < len(names):
            return int(body)
        raise ConfigurationError(
            f"body index {body} is out of range: this tree has bodies {low} … {len(names) - 1}"
        )
    raise ArgumentTypeError(f"body must be a body's name or index, got {body!r}")


_LAST: list = [None]  # the last (tree (weakly), q, params, frames) that _frames computed


def _frames(tree: AbstractTree, q: Any, params: Any, floating: bool):
    """`tree.frames` at the joints of `q` (a floating base's: `q[7:]`), computed once for
    the same traced `q` and `params` (the spheres of one robot at one state: a
    `ContactSystem` passes each sphere the same tracers), so that `S` spheres trace the
    tree's kinematics once, not `S` times. Objects compared by identity: a
    new state, a new trace or other params compute anew (the tree is held weakly, so the
    cache keeps no model alive)."""
    if not isinstance(q, jax.core.Tracer):  # eager: params may change between calls
        return tree.frames(q[7:] if floating else q, params)
    last = _LAST[0]
    if last is not None and last[0]() is tree and last[1] is q and last[2] is params:
        return last[3]
    out = tree.frames(q[7:] if floating else q, params)
    _LAST[0] = (weakref.ref(tree), q, params, out)
    return out


class TreeSpheres(AbstractSphereSource):
    """The poses of spheres fixed to a tree's bodies: the tree's forward kinematics
    (`frames`) once, then every sphere's centre and rotation as one gather and one
    batched product (a floating base's pose applied to all at once)."""

    tree: AbstractTree
    floating: bool = eqx.field(static=True)
    identity: int = eqx.field(static=True)

    def __init__(self, tree: AbstractTree, floating: bool):
        self.tree = tree
        self.floating = floating
        self.identity = id(tree)

    @property
    def key(self) -> int:
        """The tree's identity when the source was made."""
        return self.identity

    def poses(self, q, params, bodies, offsets):
        """`(centres (K, 3), rotations (K, 3, 3))` of the spheres on `bodies` (`−1`: the
        floating base) at `offsets` in the bodies' frames."""
        q = jnp.asarray(q)
        if self.tree.n_bodies == 0:  # a lone free body: its spheres all on the base
            dtype = jnp.result_type(q.dtype, float)
            origins, rots = jnp.zeros((0, 3), dtype), jnp.zeros((0, 3, 3), dtype)
        else:
            origins, rots = self.tree.frames(q[7:] if self.floating else q, params)
        dtype = rots.dtype
        bodies = np.asarray(bodies, int)
        if np.any(bodies < 0):  # the floating base itself: origin 0, no rotation
            origins = jnp.concatenate([jnp.zeros((1, 3), dtype), origins])
            rots = jnp.concatenate([jnp.eye(3, dtype=dtype)[None], rots])
            bodies = bodies + 1
        if np.array_equal(bodies, np.arange(rots.shape[0])):
            o, r = origins, rots
        else:
            o, r = origins[bodies], rots[bodies]
        centres = o + jnp.einsum("kij,kj->ki", r, jnp.asarray(offsets, dtype))
        if not self.floating:
            return centres, r
        base = quaternion_rotation(q[3:7]).astype(dtype)
        return q[None, :3].astype(dtype) + centres @ base.T, jnp.einsum("ij,kjl->kil", base, r)


def body_sphere(robot: Any, body: Any, radius: float, offset: Any = (0.0, 0.0, 0.0)) -> Sphere:
    r"""A [`Sphere`][lagrax.contact.Sphere] fixed to a body of a tree (a URDF robot's
    link, a foot), its centre at `offset` in the body's frame.

    The centre and the body's rotation come from the tree's own forward kinematics
    (`frames`, the recursions' joint transforms; computed once for all the spheres of
    a tree that a [`ContactSystem`][lagrax.contact.ContactSystem] evaluates at one
    state): for a fixed-base tree (a
    [`Tree`][lagrax.chains.Tree] or [`SpatialChain`][lagrax.chains.SpatialChain], `q` its
    coordinates) `c = o_i + R_i offset`; for a
    [`FloatingTree`][lagrax.chains.FloatingTree] (`q = (p, quaternion (x, y, z, w),
    joints)`) `c = p + R_b (o_i + R_i offset)`, with the rotation `R_b R_i` (the base
    itself: its name, or index `−1`). A link that `from_urdf` merged into its parent body
    (a foot on a fixed joint) is its parent body with the fixed joint's origin as `offset`.

    **Arguments:**

    - `robot`: a `FloatingTree`, `Tree` or `SpatialChain`.
    - `body`: the body's name (`robot.body_names`, or a floating base's `base_name`) or
      index.
    - `radius`: the sphere's radius, `≥ 0`.
    - `offset`: the centre in the body's frame, `(3,)` (default the body's origin).

    **Returns:** a `Sphere` with `position` and `rotation`, for a
    [`ContactSystem`][lagrax.contact.ContactSystem] of `robot.system()` on a 3-D plane.

    **Raises:** `ConfigurationError` for an unknown body or an offset that is not three
    finite numbers; `ArgumentTypeError` for a robot that is not a tree.
    """
    floating = isinstance(robot, FloatingTree)
    tree = robot.tree if floating else robot
    if not isinstance(tree, AbstractTree):
        raise ArgumentTypeError(
            f"body_sphere takes a FloatingTree, Tree or SpatialChain, got {type(robot).__name__}"
        )
    if isinstance(tree, Tree):
        names = tree.body_names
    else:  # a spatial chain's bodies are unnamed
        names = tuple(f"body{k}" for k in range(tree.n_bodies))
    i = _index(tuple(names), body, robot.base_name if floating else None)
    arm = np.asarray(offset, dtype=float)
    if arm.shape != (3,) or not np.all(np.isfinite(arm)):
        raise ConfigurationError(f"offset must be three finite numbers, got offset={offset!r}")
    arm_t = tuple(float(x) for x in arm)

    def local(joints, params):
        """The body's origin and rotation in the base (fixed tree: world) frame
        (`joints`: the whole `q`)."""
        if i < 0:
            return jnp.zeros(3, joints.dtype), jnp.eye(3, dtype=joints.dtype)
        origins, rots = _frames(tree, joints, params, floating)
        return origins[i], rots[i]

    def pose(q, params):
        q = q if isinstance(q, jax.Array) else jnp.asarray(q)  # (keeps a tracer's identity)
        if not floating:
            o, rot = local(q, params)
            return o + rot @ jnp.asarray(arm_t, rot.dtype), rot
        o, rot = local(q, params)
        base = quaternion_rotation(q[3:7])
        centre = q[:3] + base @ (o + rot @ jnp.asarray(arm_t, rot.dtype))
        return centre, base @ rot

    return Sphere(
        radius,
        lambda q, params: pose(q, params)[0],
        rotation=lambda q, params: pose(q, params)[1],
        source=TreeSpheres(tree, floating),
        body=i,
        offset=arm_t,
    )
