"""MJCF import through MuJoCo's own compiler: a `mujoco.MjModel` as a
[`Tree`][lagrax.chains.Tree] and its params.

The tree is built from the compiled model's arrays (`body_parentid`, `body_pos`,
`body_quat`, `body_mass`, `body_ipos`, `body_iquat`, `body_inertia`, `jnt_type`,
`jnt_axis`, `jnt_pos`, `qpos0`, `dof_damping`, `jnt_limited`, `jnt_range`,
`opt.gravity`), never from the XML: defaults classes, `<frame>`, `<include>`,
`<compiler angle=... eulerseq=...>`, `fromto`, inertias from geometry and every other
convenience of the format are resolved by MuJoCo exactly as it resolves them for its own
simulation, and a file MuJoCo reads in another format (URDF) is read the same way.

MuJoCo moves a body by its joints in order, each about (hinge) or along (slide) its axis
in the body frame as moved by the joints before it, by `qpos − qpos0` (`qpos0`: the
joint's `ref`). Joint `j` of body `b` becomes a body of the tree whose frame sits at the
joint's anchor `jnt_pos`, with the body's orientation; the MuJoCo body frame is then that
frame shifted by `−jnt_pos`, and the joint's `ref` is folded into the tree's fixed
rotation (hinge: `S Rot(a, −ref)`) or offset (slide: `−ref a`), so that the tree's
coordinates are MuJoCo's `qpos` unchanged. A body with several joints becomes a chain of
massless tree bodies, the body's inertia on the last; a body without joints is merged into
the body it is welded to (as a URDF fixed joint), and bodies welded to the world are
dropped (their children are placed through them).
"""

import importlib
import math
import os
import warnings
from collections.abc import Sequence
from typing import Any

import jax.numpy as jnp
import numpy as np

from ..._core.errors import MissingFileError, MJCFError
from ..articulated.trees import Tree
from ..common import about_centres, float_dtype, steiner
from ..floating.forest import Forest
from ..joint_space import FRICTION_VELOCITY
from ..limits import with_limits
from .collision import check_meshes, mjcf_ground, mjcf_points
from .contact_scene import contact_friction, contact_scene, limits_need_contact
from .mjcf_balls import ball_lanes, balls_supported
from .mjcf_equality import constrained, equality_rows
from .mjcf_parts import TreeBody, quat_matrix, split_parts
from .mjcf_support import unsupported
from .mjcf_tendons import fixed_tendons

# mujoco.mjtJoint: free, ball, slide, hinge
_FREE, _BALL, _SLIDE, _HINGE = 0, 1, 2, 3


def _mujoco():
    """The `mujoco` module, or an `MJCFError` saying how to install it."""
    try:
        return importlib.import_module("mujoco")
    except ImportError:
        raise MJCFError(
            "lagrax.chains.from_mjcf reads MJCF through MuJoCo's own compiler, and the "
            "mujoco package is not installed: pip install mujoco (or lagrax[dev])"
        ) from None


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues: the rotation by `angle` about the unit vector `axis`."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def _load(mujoco, source: Any):
    """`source` as a compiled `mujoco.MjModel` (a model, XML text, or a file path)."""
    if isinstance(source, mujoco.MjModel):
        return source
    if isinstance(source, str) and source.lstrip().startswith("<"):
        what, load = "the MJCF text", lambda: mujoco.MjModel.from_xml_string(source)
    else:
        path = os.fspath(source)
        if not os.path.exists(path):
            raise MissingFileError(f"no MJCF file at {path!r}")
        what, load = f"{path!r}", lambda: mujoco.MjModel.from_xml_path(path)
    try:
        return load()
    except ValueError as err:
        raise MJCFError(f"MuJoCo cannot compile {what}: {err}".strip()) from None


def load_model(source: Any):
    """`(mujoco, model)`: the `mujoco` module and `source` compiled (a model, XML text or
    a path; `MJCFError` as `from_mjcf` raises it)."""
    mujoco = _mujoco()
    return mujoco, _load(mujoco, source)


class Names:
    """Names of a model's objects (`kind` plus the index where unnamed)."""

    def __init__(self, mujoco, model):
        self._mujoco, self._model = mujoco, model

    def __call__(self, obj: str, i: int) -> str:
        kind = getattr(self._mujoco.mjtObj, f"mjOBJ_{obj.upper()}")
        name = self._mujoco.mj_id2name(self._model, kind, i)
        return name if name else f"{obj}{i}"


def from_mjcf(
    source: Any,
    *,
    limits: str | None = None,
    restitution: Any = 0.0,
    ignore_unsupported: bool = False,
    friction_velocity: float = FRICTION_VELOCITY,
    dtype: Any = None,
    contact: bool | Sequence[str] = False,
    meshes: str = "bounding_sphere",
    friction: float | None = None,
    margin: bool = False,
) -> tuple[Any, dict]:
    r"""A MuJoCo model (MJCF, or any file MuJoCo reads) as a [`Tree`][lagrax.chains.Tree]
    and its params, built from MuJoCo's compiled model.

    The file is compiled by MuJoCo (`mujoco.MjModel.from_xml_path` /
    `from_xml_string`) and the tree is read from the model's arrays, so every MJCF MuJoCo
    reads is read as MuJoCo reads it (defaults, frames, `fromto`, inertias computed from
    geoms, angles in degrees, URDF files). Each hinge joint becomes a revolute body of the
    tree and each slide joint a prismatic one, in MuJoCo's order, so **`q` is MuJoCo's
    `qpos` and `q̇` its `qvel`**, with the joint's `ref` (`qpos0`) folded into the
    tree's fixed rotation or offset.

    A **ball joint** is Pinocchio's spherical joint: 4 entries of `q`, the unit
    quaternion `(x, y, z, w)` of the body's rotation in the joint frame (MuJoCo's
    `qpos` holds it as `(w, x, y, z)`: [`from_mujoco_state`][lagrax.chains.from_mujoco_state]
    with the tree reorders it), and 3 of `q̇`, the body's angular velocity in its own
    frame (MuJoCo's `qvel`). The tree gets three revolute lanes for it (`tree.balls`;
    see [`BallTreeSystem`][lagrax.chains.BallTreeSystem], the tree's system), each with
    its dof's damping, armature and friction loss. A spring or a limit on a ball is not
    modelled (refused, or dropped under `ignore_unsupported`).

    A **free joint** (`<freejoint/>`, on a body hanging from the world, with every other
    joint below it) makes that body a floating base: the result is a
    [`FloatingTree`][lagrax.chains.FloatingTree], whose state is Pinocchio's free-flyer
    `(q, v)`, not MuJoCo's `(qpos, qvel)`: the quaternion's order and the frame of the
    base's linear velocity differ ([`from_mujoco_state`][lagrax.chains.from_mujoco_state]
    and [`to_mujoco_state`][lagrax.chains.to_mujoco_state] convert). The bodies welded
    to the free body are merged into the base; bodies welded to the world are dropped. A
    model whose only joint is the free joint (a single rigid body) is the base alone: a
    `FloatingTree` with no joints, `q` of size 7 and `v` of size 6.

    **Several free bodies** (a dog and its ball, boxes to stack) make a
    [`Forest`][lagrax.chains.Forest]: each free body with the bodies below it a
    `FloatingTree`, the robots fixed to the world between them a `Tree`, in MuJoCo's
    body order (the state is the parts' states one after the other, MuJoCo's joint
    order; `from_mujoco_state(qpos, qvel, forest)` converts every free joint), and the
    params a tuple of the parts'.

    **Equality constraints** (`connect`, `weld`, `joint`, `tendon` on fixed tendons,
    active at `qpos0`) make a [`ConstrainedRobot`][lagrax.chains.ConstrainedRobot]
    around the robot: its `system()` is a [`ConstrainedSystem`][lagrax.ConstrainedSystem]
    whose `φ(q)` is MuJoCo's residual (`efc_pos`; see
    `lagrax._multibody.formats.mjcf_equality`). lagrax solves the constraints exactly;
    MuJoCo solves them softly (`solref`, `solimp`), so its constrained `qacc` differs by
    that softness. `robot.robot` is the unconstrained robot.

    A body with several joints becomes a chain of massless tree bodies (its inertia on
    the last); a body with no joint is merged into the body it is welded to (mass,
    centre of mass and inertia by the parallel-axis theorem), and bodies welded to the
    world are dropped.

    Read: `body_mass`, `body_ipos`, `body_iquat`, `body_inertia` (the principal
    inertia rotated into the body frame), `dof_damping` (`params["damping"]`, MuJoCo's
    viscous `−b q̇`), `jnt_limited` / `jnt_range` (`tree.limits`),
    `jnt_actfrcrange` (`tree.effort_limits`, the larger bound's magnitude), gravity
    `opt.gravity` (`up = −gravity / |gravity|`, `g = |gravity|`; `g = 0` where gravity
    is disabled). Names are MuJoCo's (`joint3`, `body2` where unnamed); a body with
    several joints gives tree bodies `body/joint` before its last.

    Also read, as joint-space terms (`params` entries present only where the model has
    them; see [`Tree.params`][lagrax.chains.Tree.params]):

    - `dof_armature` (`params["armature"]`): a rotor's reflected inertia,
      `M += diag(armature)` (`T ⊃ ½ Σ a q̇²`), in the recursions and their derivatives;
    - `jnt_stiffness` about `qpos_spring` (the joint's `springref`;
      `params["stiffness"]`, `params["springref"]`): joint springs, the potential
      `½ Σ k (q − q_spring)²` (none where springs are disabled);
    - fixed tendons (`L = Σ c_i q_i`) with stiffness or damping: `params["tendon"]`
      (each tendon's coefficients on the joints, `(n_t, n)`), `"tendon_stiffness"`
      about `"tendon_length"` (`tendon_lengthspring`), the potential `½ k (L − L_0)²`,
      and `"tendon_damping"`, the dissipation `½ b L̇²`. A fixed or spatial tendon with
      neither carries only a length limit (a MuJoCo constraint, not enforced, as joint
      limits) and actuators' paths, and adds nothing;
    - `dof_frictionloss` (`params["frictionloss"]`, with `"friction_velocity"`): Coulomb
      joint friction, by the regularized law with stiction the contacts use
      (`lagrax.contact`): the force `−f μ̂(|q̇|/v_s) sign(q̇)` is `−f sign(q̇)` for
      `|q̇| ≥ v_s`, and a load `τ < f` is held by a creep `|q̇| = v_s (1 − √(1 − τ/f))`
      below `v_s` (none where friction loss or constraints are disabled). It derives
      from a dissipation function (so its power is in `Solution.work`), with its
      analytic derivative. MuJoCo solves friction loss as a soft constraint instead;
      away from rest (`|q̇| ≥ v_s`) the two forces agree. A small `v_s` makes the
      equations stiff near rest: an implicit solver (`solver="rodas4"` or
      `"kvaerno5"`) steps over it.

    **Contact** (`contact=True`, or a list of geom names): each colliding geom
    (`contype` or `conaffinity` nonzero) on a moving body becomes
    [`Sphere`][lagrax.contact.Sphere]s fixed to its tree body (by
    [`body_sphere`][lagrax.contact.body_sphere]): a sphere itself, a box its 8 corners
    (radius 0), a capsule its 2 end spheres, a cylinder 8 points on each end's rim, an
    ellipsoid its bounding sphere, a mesh its bounding sphere (`geom_rbound`, about the
    geom's origin) or its vertices (`meshes="vertices"`). The result is then a
    [`ContactSystem`][lagrax.contact.ContactSystem] on the model's ground, its first
    plane geom on the world body (else `z = 0`), with the contact's default coefficients
    and one friction coefficient per sphere in `params["contact_friction"]`: the larger of
    the geom's and the ground's sliding friction (`geom_friction[:, 0]`; MuJoCo's rule for
    geoms of equal priority), or `friction` if given. MuJoCo's torsional and rolling
    friction, `solref`/`solimp`, `condim` and contacts between the robot's own geoms are
    not modelled.

    Not read: contacts unless `contact=` (above; a model of one robot without equality
    constraints), actuators (`tau` is the generalized force: MuJoCo's `qfrc_applied`;
    [`lagrax.chains.mjcf_actuation`][] maps MuJoCo's `ctrl` to it), sensors, `timestep` and the
    integrator. Joint limits are MuJoCo constraints, inactive inside the range; with
    `limits="impact"` lagrax stops a joint at them instead (below). The equations agree with
    MuJoCo's `mj_fullM` and `mj_forward`'s `qacc` with contacts and constraints (limits,
    friction loss, equality) disabled, friction loss taken out of lagrax's too.

    **Arguments:**

    - `source`: a path to an MJCF (or URDF) file, the XML text itself (a string
      starting with `<`), or a compiled `mujoco.MjModel`.
    - `limits`: `None` (default): joint limits are kept in `tree.limits` and not
      enforced; `"impact"`: joints stop at their limits by impacts with coefficient of
      restitution `restitution`, as for [`lagrax.chains.from_urdf`][] (the params gain
      `"restitution"`; pass [`lagrax.chains.limit_events`][]`(tree)` to
      [`lagrax.simulate`][]); `"contact"` (with `contact=`): each finite limit is a
      compliant stop of the contact scene, the ground contact's normal law in joint
      space (a [`JointLimit`][lagrax.contact.JointLimit]; its energy and dissipation in
      the scene's energy balance, its coefficients scaled from the scene), as MuJoCo
      enforces its limits by soft constraints.
    - `restitution`: with `limits="impact"`, a number in `[0, 1]` or one per joint
      (default `0`: the joint stops dead at its limit).
    - `ignore_unsupported`: drop what lagrax does not model (gravity compensation,
      spatial tendons with stiffness or damping, tendon armature or friction loss,
      dead-band or nonlinear springs, fluid forces, damping, armature, friction loss or
      stiffness on a free joint, a spring or a limit on a ball joint; an equality on a
      spatial tendon or a flex drops every
      equality) with one `UserWarning` naming each, instead of refusing the model.
    - `friction_velocity`: the stiction velocity `v_s` of joint friction loss (default
      0.01: rad/s for a hinge, m/s for a slide).
    - `dtype`: of the params (default float64 with x64).
    - `contact`: `True` (every colliding geom on a moving body) or the names of the geoms
      that touch the ground; `False` (default): none. See *Contact* above.
    - `meshes`: `"bounding_sphere"` (default) or `"vertices"`, how a mesh geom becomes
      spheres.
    - `friction`: with `contact`, one friction coefficient for every sphere (default: read
      from the geoms, as above).
    - `margin`: with `contact`, grow each sphere by MuJoCo's contact margin, the geom's
      `margin` plus the ground's (MuJoCo's contacts act from that distance and rest
      near it: gymnasium's ant stands 20 mm above its floor); default `False`: the
      geometry itself. [`from_mujoco`][lagrax.chains.from_mujoco] sets it.

    **Returns:** `(tree, params)`: the [`Tree`][lagrax.chains.Tree] and
    `{"m", "offset", "com", "inertia", "damping", "g"}` (and `"restitution"`, and the
    joint-space terms above where the model has them); with a free joint, the
    [`FloatingTree`][lagrax.chains.FloatingTree] and the params plus `{"base_m",
    "base_com", "base_inertia"}`; with several free bodies, a
    [`Forest`][lagrax.chains.Forest] and a tuple of its parts' params; with equality
    constraints, a [`ConstrainedRobot`][lagrax.chains.ConstrainedRobot] around either.
    With `contact`: `(scene, params)`, the `ContactSystem` (`scene.system` the robot's
    system, `scene.spheres` in geom order) and the params plus `"contact_friction"`.

    **Raises:** [`lagrax.MJCFError`][] when MuJoCo cannot compile the file (MuJoCo's
    message); for a ball joint beside several free bodies, with equality constraints or
    with `contact=`, naming the joint; for a free body with
    other joints, or a massless floating base; for an equality lagrax does not model
    (on a spatial tendon, a flex); for a model with no hinge, slide or free joint;
    and, unless `ignore_unsupported`, for what it does not model (the list under
    `ignore_unsupported`), naming the first one and its value. `MJCFError` also when
    the `mujoco` package is not installed. [`lagrax.MissingFileError`][] (a
    `FileNotFoundError`) for a missing file;
    `ConfigurationError` for a bad `limits` or `restitution`, or `limits="contact"`
    without `contact=`.

    **Example:**

    ```python
    tree, params = lagrax.chains.from_mjcf("cartpole.xml")
    system = tree.system()
    qdd = system.forward_dynamics(qpos, qvel, params, tau)   # MuJoCo's qacc, contacts off
    ```
    """
    mujoco = _mujoco()
    check_meshes(meshes)
    limits_need_contact(limits, contact)
    model = _load(mujoco, source)
    names = Names(mujoco, model)
    found = unsupported(mujoco, model, names)
    if found and not ignore_unsupported:
        raise MJCFError(
            f"the model has {found[0]}, which lagrax does not model; pass "
            "ignore_unsupported=True to load it without (with a warning)"
            + (f"; also: {'; '.join(found[1:])}" if len(found) > 1 else "")
        )
    if found:
        warnings.warn(
            "from_mjcf ignores what lagrax does not model: " + "; ".join(found),
            UserWarning,
            stacklevel=2,
        )
    parts = split_parts(model, names)
    if not parts:
        raise MJCFError(
            "the model has no hinge or slide joint and no free joint: there is nothing to "
            "move (a scene that code fills with bodies, such as dm_control's lqr.xml, loads "
            "once filled: pass the generated model or XML)"
        )
    robots, all_params, places = [], [], {}
    for k, part in enumerate(parts):
        bodies, base, place = _bodies(model, names, part.free, set(part.bodies))
        balls_supported(names, bodies, base, contact, len(parts))
        tree, params = _tree_and_params(model, bodies, dtype, friction_velocity)
        places.update({b: (k, *place[b]) for b in part.bodies})
        if base is None:
            tree, params = with_limits(tree, params, limits, restitution)
            robots.append(tree)
        else:
            robot, params = _floating(tree, params, base)
            robots.append(robot)
            params = with_limits(tree, params, limits, restitution)[1]
        all_params.append(params)
    if len(parts) == 1:
        robot, params = robots[0], all_params[0]
    else:
        part_names = [names("body", p.free) if p.free is not None else "world" for p in parts]
        robot, params = Forest(robots, part_names), tuple(all_params)
    plain = robot
    robot = _equalities(mujoco, model, names, robot, places, ignore_unsupported)
    if contact is False or contact is None:
        return robot, params
    if len(parts) != 1 or robot is not plain:
        raise MJCFError(
            "contact= is read for a model of one robot without equality constraints; this "
            f"one has {len(parts)} part(s)"
            + (" and equality constraints" if robot is not plain else "")
        )
    points = mjcf_points(model, names, place, contact, meshes, base is not None, margin)
    return contact_scene(
        robot, params, points, mjcf_ground(model), contact_friction(friction), limits
    )


def _equalities(mujoco, model, names, robot, places: dict, ignore: bool):
    """`robot` under the model's active equality constraints (a
    [`ConstrainedRobot`][lagrax.chains.ConstrainedRobot]), or `robot` itself without
    any (or with equality disabled)."""
    if not model.neq or int(model.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_EQUALITY):
        return robot
    try:
        rows, kept = equality_rows(mujoco, model, names)
    except MJCFError as err:
        if not ignore:
            raise
        warnings.warn(f"from_mjcf ignores the equality constraints: {err}", UserWarning, 3)
        return robot
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)

    def world(b: int):
        return np.array(data.xmat[b]).reshape(3, 3), np.array(data.xpos[b])

    return constrained(model, robot, rows, kept, places, world)


def _floating(tree: Tree, params: dict, base: "TreeBody"):
    """The [`FloatingTree`][lagrax.chains.FloatingTree] on `base` (the free body, with
    the bodies welded to it) and its params."""
    from ..floating.loading import on_base

    if not base.mass > 0:
        raise MJCFError(
            f"the floating base {base.name!r} (with the bodies welded to it) has mass "
            f"{base.mass:g}: a floating base needs a positive mass"
        )
    (mass,), (com,), (inertia,) = about_centres([base])
    return on_base(tree, params, (mass, com, inertia), base.name, f"body {base.name!r}")


_WORLD = -2  # the world's tree body when a free body is the base (tree body −1)


def placements(model) -> dict[int, tuple[int, np.ndarray, np.ndarray]]:
    """Each MuJoCo body `b`'s place in `from_mjcf`'s tree of a model of one part (one
    robot, fixed or floating): `(tree body, rotation, position)` of its frame in the
    tree body's (tree body −1: the floating base, or the world without one; −2: the
    world beside a floating base). A model of several parts (a `Forest`) is an
    `MJCFError`."""
    names = Names(_mujoco(), model)
    parts = split_parts(model, names)
    if len(parts) != 1:
        raise MJCFError(
            f"the model has {len(parts)} parts (free bodies, or robots fixed to the world "
            "beside them): only a model of one robot is supported here"
        )
    return _bodies(model, names, parts[0].free, set(parts[0].bodies))[2]


def _bodies(
    model, names: Names, free: int | None, keep: set[int]
) -> tuple[list[TreeBody], TreeBody | None, dict]:
    """The tree's bodies (of the MuJoCo bodies `keep`), in MuJoCo's joint order, with
    every MuJoCo body's inertia merged into the tree body that carries it; with a free
    body `free`, the floating base (tree body −1: its frame is the free body's, and it
    carries the bodies welded to it), else `None`; and where each MuJoCo body's frame
    is, `(tree body, R, p)` (tree body −1: the base, or the world for a fixed tree;
    `_WORLD`: the world beside a floating base)."""
    bodies: list[TreeBody] = []
    base = None
    # each MuJoCo body's frame in its tree body's frame (tree body −1: the world, or the
    # floating base; `_WORLD`: the world beside a floating base)
    place = {0: (-1 if free is None else _WORLD, np.eye(3), np.zeros(3))}
    for b in range(1, model.nbody):
        if b not in keep:
            continue
        if b == free:
            place[b] = (-1, np.eye(3), np.zeros(3))
            base = TreeBody(
                names("body", b),
                names("joint", int(model.body_jntadr[b])),
                "F",
                _WORLD,
                np.eye(3),
                np.zeros(3),
                np.zeros(3),
                0.0,
                (-math.inf, math.inf),
                math.inf,
            )
            _add_inertia(model, b, base, np.eye(3), np.zeros(3))
            continue
        tb, rot, pos = place[int(model.body_parentid[b])]
        pos = pos + rot @ model.body_pos[b]
        rot = rot @ quat_matrix(model.body_quat[b])
        first, count = int(model.body_jntadr[b]), int(model.body_jntnum[b])
        for j in range(first, first + count):
            if int(model.jnt_type[j]) == _BALL:
                tb, rot, pos = ball_lanes(model, names, b, j, bodies, (tb, rot, pos))
                continue
            anchor = np.asarray(model.jnt_pos[j], float)
            axis = np.asarray(model.jnt_axis[j], float)
            axis = axis / np.linalg.norm(axis)
            ref = float(model.qpos0[model.jnt_qposadr[j]])
            hinge = int(model.jnt_type[j]) == _HINGE
            offset = pos + rot @ (anchor if hinge else anchor - ref * axis)
            fixed = rot @ _axis_angle(axis, -ref) if hinge else rot
            limited = bool(model.jnt_limited[j])
            low, high = (float(x) for x in model.jnt_range[j]) if limited else (-1.0, 1.0)
            effort = math.inf
            if bool(model.jnt_actfrclimited[j]):
                effort = float(np.max(np.abs(model.jnt_actfrcrange[j]))) or math.inf
            last = j == first + count - 1
            body, joint = names("body", b), names("joint", j)
            bodies.append(
                TreeBody(
                    body if last else f"{body}/{joint}",
                    joint,
                    "R" if hinge else "P",
                    tb,
                    fixed,
                    offset,
                    axis,
                    float(model.dof_damping[model.jnt_dofadr[j]]),
                    (low, high) if limited and low < high else (-math.inf, math.inf),
                    effort,
                    float(model.dof_armature[model.jnt_dofadr[j]]),
                    float(model.jnt_stiffness[j]),
                    float(model.qpos_spring[model.jnt_qposadr[j]]),
                    j,
                    float(model.dof_frictionloss[model.jnt_dofadr[j]]),
                )
            )
            tb, rot, pos = len(bodies) - 1, np.eye(3), -anchor
        place[b] = (tb, rot, pos)
        if tb >= 0:
            _add_inertia(model, b, bodies[tb], rot, pos)
        elif tb == -1 and base is not None:
            _add_inertia(model, b, base, rot, pos)  # welded to the floating base
        # else: welded to the world
    return bodies, base, place


def _add_inertia(model, b: int, target: TreeBody, rot: np.ndarray, pos: np.ndarray) -> None:
    """Add MuJoCo body `b`'s inertia to `target` (whose frame holds `b`'s frame at
    `pos`, rotated by `rot`): its mass, first moment and inertia about the origin."""
    mass = float(model.body_mass[b])
    if mass <= 0:
        return  # massless
    # MuJoCo's compiler marks an inertial frame within round-off of the body frame
    # (`body_sameframe`: 1 the same frame, 3 the same orientation) and its kinematics
    # then use the body frame itself: so does lagrax (convex meshes: ipos ~1e-9)
    sameframe = getattr(model, "body_sameframe", None)  # None: an older MuJoCo
    same = 0 if sameframe is None else int(sameframe[b])
    c = pos + (0.0 if same == 1 else rot @ model.body_ipos[b])
    r = rot if same in (1, 3) else rot @ quat_matrix(model.body_iquat[b])
    inertia = r @ np.diag(model.body_inertia[b]) @ r.T
    target.mass += mass
    target.moment = target.moment + mass * c
    target.inertia_o = target.inertia_o + inertia + steiner(mass, c)


def _joint_terms(model, bodies: list[TreeBody], dtype: Any, friction_velocity: float) -> dict:
    """The tree's joint-space params (`lagrax._multibody.joint_space`): `armature`,
    `stiffness` and `springref` (MuJoCo's `qpos_spring`), `frictionloss` (with
    `friction_velocity`) where any is nonzero, and the fixed tendons' (`mjcf_tendons`)."""
    mujoco = _mujoco()
    disabled = int(model.opt.disableflags)
    out: dict = {}
    rotor = np.array([b.armature for b in bodies])
    if np.any(rotor):
        out["armature"] = rotor
    stiffness = np.array([b.stiffness for b in bodies])
    if disabled & int(mujoco.mjtDisableBit.mjDSBL_SPRING):
        stiffness = np.zeros_like(stiffness)
    if np.any(stiffness):
        out["stiffness"] = stiffness
        out["springref"] = np.array([b.springref for b in bodies])
    friction = np.array([b.frictionloss for b in bodies])
    if np.any(friction) and not disabled & int(
        mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    ):
        out["frictionloss"] = friction
        out["friction_velocity"] = np.asarray(friction_velocity, float)
    out.update(fixed_tendons(mujoco, model, [b.joint_id for b in bodies]))
    dtype = float_dtype(dtype)
    return {k: jnp.asarray(v, dtype) for k, v in out.items()}


def _tree_and_params(
    model, bodies: list[TreeBody], dtype: Any, friction_velocity: float
) -> tuple[Tree, dict]:
    """The [`Tree`][lagrax.chains.Tree] and its params from the merged bodies."""
    masses, coms, inertias = about_centres(bodies)
    terms = _joint_terms(model, bodies, dtype, friction_velocity)
    gravity = np.asarray(model.opt.gravity, float)
    g = float(np.linalg.norm(gravity))
    mujoco = _mujoco()
    if int(model.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY):
        g = 0.0
    up = 0.0 - gravity / np.linalg.norm(gravity) if np.linalg.norm(gravity) > 0 else (0.0, 0.0, 1.0)
    damping = np.array([b.damping for b in bodies])
    if int(model.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_DAMPER):
        damping = np.zeros_like(damping)
    tree = Tree(
        "".join(b.kind for b in bodies),
        [b.parent for b in bodies],
        axes=[b.axis for b in bodies],
        rotations=[b.rot for b in bodies],
        up=up,
        joint_names=[b.joint for b in bodies],
        body_names=[b.name for b in bodies],
        limits=[b.limits for b in bodies],
        effort_limits=[b.effort for b in bodies],
        joint_terms=bool(terms),
        balls=[i for i, b in enumerate(bodies) if b.ball],
    )
    params = tree.params(
        m=masses,
        offset=np.reshape([b.offset for b in bodies], (-1, 3)),
        com=coms,
        inertia=inertias,
        damping=damping,
        g=g,
        dtype=float_dtype(dtype),
    )
    return tree, {**params, **terms}
