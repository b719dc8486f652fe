r"""MuJoCo's equality constraints as holonomic constraints `φ(q) = 0` for
[`lagrax.ConstrainedSystem`][], read by [`lagrax.chains.from_mjcf`][].

Each active equality (`eq_active0`) gives the rows MuJoCo's `mj_instantiateEquality`
gives it, with MuJoCo's residual (its `efc_pos`), so `φ` is zero exactly where MuJoCo's
constraint is satisfied:

- `connect` (3 rows): `p_1 − p_2`, the anchor's world position on body 1 less its
  position on body 2 (`eq_data[0:3]` in body 1's frame, `eq_data[3:6]` in body 2's; the
  sites' positions with the site semantic);
- `weld` (6 rows): the position rows `p_1 − p_2` (the `relpose` position
  `eq_data[3:6]` on body 1, the `anchor` `eq_data[0:3]` on body 2), then the
  orientation rows `torquescale · vec(q̄_2 ⊗ q_1 ⊗ q_rel)` (the axis part of the
  quaternion error, `q_rel` the `relpose` quaternion `eq_data[6:10]`);
- `joint` (1 row): `x_1 − x_1⁰ − a_0 − Σ_{k=1}^4 a_k (x_2 − x_2⁰)^k` with `x` the
  joints' `qpos`, `x⁰` their `qpos0` and `a` the `polycoef` (`x_1 − x_1⁰ − a_0` alone
  without a second joint);
- `tendon` (1 row): the same polynomial in the lengths `L = Σ c_i qpos_i` of two fixed
  tendons, about their `tendon_length0`.

MuJoCo enforces these softly (`solref`, `solimp`: a stiff, damped spring that lets the
constraint give a little); lagrax enforces them exactly, as Lagrange multipliers in a KKT
system with Baumgarte stabilization, so a constrained `q̈` differs from MuJoCo's by the
softness. A `tendon` equality on a spatial tendon, and the `flex` equalities, are refused
by name.
"""

from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._core.custom_types import Params
from ..._core.errors import MJCFError
from ..._systems.constrained import ConstrainedSystem
from ..algorithms.floating_recursions import quaternion_rotation
from ..floating.forest import Forest
from ..floating.system import FloatingTree
from .mjcf_parts import quat_matrix
from .mjcf_tendons import is_fixed

# mujoco.mjtEq
_CONNECT, _WELD, _JOINT, _TENDON = 0, 1, 2, 3
_SITE = 6  # mujoco.mjtObj.mjOBJ_SITE


class Equality(eqx.Module):
    r"""A model's equality constraints, `φ(q, params)` (a function for
    [`ConstrainedSystem`][lagrax.ConstrainedSystem]), with MuJoCo's residuals (see
    `lagrax._multibody.formats.mjcf_equality`).

    `places[b]` locates MuJoCo body `b`: `(part, tree body, R, p)`, its frame in the
    frame of a tree body of a part of the robot (`part` −1: the world, where `R, p` is
    the world pose; tree body −1: the part's base, or the world for a fixed part).
    `rows` holds each row group: `("connect" | "weld", bodies, anchors, frames,
    torquescale)` or `("poly", qpos indices and coefficients of side 1, of side 2,
    references, polycoef)`. `names` names the equalities, one per group.
    """

    robot: Any
    places: tuple = eqx.field(static=True)
    rows: tuple = eqx.field(static=True)
    names: tuple[str, ...] = eqx.field(static=True)

    def _parts(self) -> tuple[Any, ...]:
        return self.robot.parts if isinstance(self.robot, Forest) else (self.robot,)

    def _pose(self, b: int, q: Any, params: Params, frames: dict) -> tuple[Any, Any]:
        """MuJoCo body `b`'s world rotation and origin at `q`."""
        k, tb, rot, pos = self.places[b]
        dtype = q.dtype
        rot, pos = jnp.asarray(rot, dtype), jnp.asarray(pos, dtype)
        if k < 0:
            return rot, pos
        parts = self._parts()
        part, start = parts[k], sum(_nq(p) for p in parts[:k])
        qk = q[start : start + _nq(part)]
        pk = params[k] if isinstance(self.robot, Forest) else params
        if isinstance(part, FloatingTree):
            base_r, base_p = quaternion_rotation(qk[3:7]), qk[:3]
            joints, tree = qk[7:], part.tree
        else:
            base_r, base_p = jnp.eye(3, dtype=dtype), jnp.zeros(3, dtype)
            joints, tree = qk, part
        if tb >= 0:
            if k not in frames:
                frames[k] = tree.frames(joints, pk)
            origins, rots = frames[k]
            base_p, base_r = base_p + base_r @ origins[tb], base_r @ rots[tb]
        return base_r @ rot, base_p + base_r @ pos

    def __call__(self, q: Any, params: Params) -> jnp.ndarray:
        out, frames = [], {}
        for row in self.rows:
            if row[0] == "poly":
                out.append(_poly(q, *row[1:]))
                continue
            kind, bodies, anchors, turns, scale = row
            (r1, o1), (r2, o2) = (self._pose(b, q, params, frames) for b in bodies)
            p1 = o1 + r1 @ jnp.asarray(anchors[0], q.dtype)
            p2 = o2 + r2 @ jnp.asarray(anchors[1], q.dtype)
            out.append(p1 - p2)
            if kind == "weld":
                error = (
                    (r2 @ jnp.asarray(turns[1], q.dtype)).T @ r1 @ jnp.asarray(turns[0], q.dtype)
                )
                out.append(scale * _quaternion_axis(error))
        return jnp.concatenate(out)


def _quaternion_axis(rot: Any) -> jnp.ndarray:
    """The axis part `(x, y, z)` of the unit quaternion (`w ≥ 0`) of a rotation near the
    identity: `axial(R − Rᵀ) / (4 w)`, `w = ½ √(1 + tr R)`."""
    w = 0.5 * jnp.sqrt(jnp.maximum(1.0 + jnp.trace(rot), 1e-300))
    axial = jnp.stack([rot[2, 1] - rot[1, 2], rot[0, 2] - rot[2, 0], rot[1, 0] - rot[0, 1]])
    return axial / (4.0 * w)


def _poly(q: Any, side1: tuple, side2: tuple, refs: tuple, coef: tuple) -> jnp.ndarray:
    """A `joint` or `tendon` row: `x_1 − x_1⁰ − a_0 − Σ a_k (x_2 − x_2⁰)^k`, each `x` a
    sum `Σ c_i q_i` (`side2` empty: without the polynomial)."""

    def length(side):
        return sum(c * q[i] for i, c in side)

    value = length(side1) - refs[0] - coef[0]
    if side2:
        dif = length(side2) - refs[1]
        value = value - sum(coef[k] * dif**k for k in range(1, 5))
    return jnp.reshape(value, (1,))


def _nq(part: Any) -> int:
    return 7 + part.n if isinstance(part, FloatingTree) else part.n


class ConstrainedRobot(eqx.Module):
    r"""A robot ([`Tree`][lagrax.chains.Tree], [`FloatingTree`][lagrax.chains.FloatingTree]
    or [`Forest`][lagrax.chains.Forest]) with holonomic constraints `φ(q) = 0`: what
    [`lagrax.chains.from_mjcf`][] returns for a model with equality constraints.

    Its [`system`][lagrax.chains.ConstrainedRobot.system] is a
    [`ConstrainedSystem`][lagrax.ConstrainedSystem] over the robot's system, which
    solves the constraints exactly (MuJoCo solves them softly); its params are the
    robot's.

    **Arguments:** `robot`, the unconstrained robot; `constraints`, `φ(q, params)`
    (shape `(m,)`); `alpha`, `beta`, the Baumgarte gains of the
    [`ConstrainedSystem`][lagrax.ConstrainedSystem] (default 10 each).
    """

    robot: Any
    constraints: Any
    alpha: float = eqx.field(default=10.0, static=True)
    beta: float = eqx.field(default=10.0, static=True)

    @property
    def n(self) -> int:
        """The robot's number of velocities (joints, and six per floating base)."""
        robot = self.robot
        return robot.n + 6 if isinstance(robot, FloatingTree) else robot.n

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The robot's joint names."""
        return self.robot.joint_names

    @property
    def constraint_names(self) -> tuple[str, ...]:
        """The equality constraints' names, one per row group (MuJoCo's, or
        `equality<i>`)."""
        return getattr(self.constraints, "names", ())

    def system(self) -> ConstrainedSystem:
        """The [`ConstrainedSystem`][lagrax.ConstrainedSystem] of the robot's system under
        `constraints`."""
        return ConstrainedSystem(
            self.robot.system(), self.constraints, alpha=self.alpha, beta=self.beta
        )


def _side(model, kind: int, obj: int, anchor: Any) -> tuple[int, np.ndarray, np.ndarray]:
    """`(body, anchor in the body frame, frame rotation in the body frame)` of one side
    of a connect or weld: a body with `anchor`, or a site."""
    if int(model.eq_objtype[kind]) == _SITE:
        return (
            int(model.site_bodyid[obj]),
            np.asarray(model.site_pos[obj], float),
            quat_matrix(model.site_quat[obj]),
        )
    return obj, np.asarray(anchor, float), np.eye(3)


def _tuple(x: Any) -> tuple:
    """An array as (nested) tuples of Python floats (static, hashable)."""
    x = np.asarray(x, float)
    return tuple(_tuple(row) for row in x) if x.ndim == 2 else tuple(float(v) for v in x)


def _scalar(mujoco, model, names, e: int, obj: int, tendon: bool) -> tuple[tuple, float]:
    """`(((qpos index, coefficient), …), reference)` of a joint's value or a fixed
    tendon's length."""
    if not tendon:
        if int(model.jnt_type[obj]) not in (2, 3):
            raise MJCFError(
                f"equality {names('equality', e)!r} couples joint {names('joint', obj)!r}, "
                "which is not a hinge or slide joint (lagrax couples scalar joints)"
            )
        adr = int(model.jnt_qposadr[obj])
        return ((adr, 1.0),), float(model.qpos0[adr])
    if not is_fixed(model, obj):
        raise MJCFError(
            f"equality {names('equality', e)!r} couples the spatial tendon "
            f"{names('tendon', obj)!r} (a path through sites): lagrax couples fixed tendons"
        )
    first = int(model.tendon_adr[obj])
    side = tuple(
        (int(model.jnt_qposadr[int(model.wrap_objid[w])]), float(model.wrap_prm[w]))
        for w in range(first, first + int(model.tendon_num[obj]))
    )
    return side, float(model.tendon_length0[obj])


def equality_rows(mujoco, model, names) -> tuple[list, list[str]]:
    """The active equalities of `model` as `Equality.rows` and their names.

    **Raises:** `MJCFError` naming an equality lagrax does not model (flex, a spatial
    tendon, a ball or free joint)."""
    rows, kept = [], []
    for e in range(model.neq):
        if not bool(model.eq_active0[e]):
            continue
        kind, data = int(model.eq_type[e]), np.asarray(model.eq_data[e], float)
        o1, o2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
        if kind in (_CONNECT, _WELD):
            weld = kind == _WELD
            a1, a2 = (data[3:6], data[0:3]) if weld else (data[0:3], data[3:6])
            (b1, p1, s1), (b2, p2, s2) = _side(model, e, o1, a1), _side(model, e, o2, a2)
            if weld and int(model.eq_objtype[e]) != _SITE:
                s1 = quat_matrix(data[6:10])
            scale = float(data[10]) if weld else 1.0
            rows.append(
                ("weld" if weld else "connect", (b1, b2), (_tuple(p1), _tuple(p2)),
                 (_tuple(s1), _tuple(s2)), scale)
            )  # fmt: skip
        elif kind in (_JOINT, _TENDON):
            tendon = kind == _TENDON
            side1, ref1 = _scalar(mujoco, model, names, e, o1, tendon)
            side2, ref2 = _scalar(mujoco, model, names, e, o2, tendon) if o2 >= 0 else ((), 0.0)
            rows.append(("poly", side1, side2, (ref1, ref2), tuple(float(x) for x in data[:5])))
        else:
            what = mujoco.mjtEq(kind).name.removeprefix("mjEQ_").lower()
            raise MJCFError(
                f"equality {names('equality', e)!r} is a {what} constraint, which lagrax "
                "does not model (it models connect, weld, joint and tendon equalities)"
            )
        kept.append(names("equality", e))
    return rows, kept


def constrained(model, robot: Any, rows: list, names: list[str], places: dict, world: Any):
    """`robot` under the equalities `rows` (`places`: MuJoCo body → `(part, tree body,
    R, p)` for the bodies of the parts; `world`: every body's world pose `(R, p)` at
    rest, for the bodies welded to the world), or `robot` itself without any."""
    if not rows:
        return robot
    out = []
    for b in range(model.nbody):
        if b in places:
            k, tb, rot, pos = places[b]
            out.append((int(k), int(tb), _tuple(rot), _tuple(pos)))
        else:
            rot, pos = world(b)
            out.append((-1, -1, _tuple(rot), _tuple(pos)))
    equality = Equality(robot, tuple(out), tuple(rows), tuple(names))
    return ConstrainedRobot(robot, equality)
