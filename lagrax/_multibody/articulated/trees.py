"""Kinematic trees of rigid bodies: robots with branches (a torso with two arms, a hand).

`AbstractTree` is what every spatial tree shares (a serial chain is a tree whose parents
are `(−1, 0, 1, …)`): forward kinematics over parents, gravity, the scene, the system
and what the recursions read. [`Tree`][lagrax.chains.Tree] and
[`SpatialChain`][lagrax.chains.SpatialChain] are its final kinds; the joint kinds are in
`lagrax._multibody.joints`.

A [`Tree`][lagrax.chains.Tree] holds the *structure* (joint types, the parent of every body, joint
axes, fixed joint rotations, names, limits); the numbers a sweep may vary (masses, joint
placements, centres of mass, inertias, damping, g) live in `params` as arrays with a
leading axis of length `n`, as for chains. Its energies are one batched
[`SpatialBody`][lagrax.bodies.SpatialBody]; its equations are Featherstone's recursions
run over parents (`lagrax._multibody.algorithms.recursions`);
[`lagrax.newton_euler.rnea`][] reads its structure for the independent oracle.
[`lagrax.chains.from_urdf`][] builds one from a URDF file.
"""

import abc
import dataclasses
import math
from collections.abc import Callable
from typing import Any, ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..._core.checks import physical
from ..._core.custom_types import Params, Vector
from ..._core.errors import ConfigurationError, ShapeError
from ..._systems.lagrangian import LagrangianSystem
from .. import joint_space
from ..algorithms.recursions import Chain
from ..common import broadcast, float_dtype
from ..energies.bodies import Param, SpatialBody
from ..energies.scene import Scene
from ..inertia import check_inertia
from ..joints import joint_constants, parse_joint_types, revolute
from . import balls as balls_
from .tree_equations import (
    AbstractArticulated,
    ChainEquations,
    CoupledEquations,
    spatial_chain,
    spatial_energies,
)
from .tree_fields import (
    CoupledDamping,
    joint_damping,
    joint_limits_of,
    mimic_entries,
    names_of,
    positive_bounds,
    structure,
)

# Forward kinematics of a chain longer than this may loop (``lax.scan``) over its joints
# instead of being written out joint by joint (see `SpatialChain`).
UNROLL_MAX = 6


class AbstractTree(AbstractArticulated):
    r"""A spatial kinematic tree of rigid bodies fixed to the world at its base: what a
    [`SpatialChain`][lagrax.chains.SpatialChain] (parents `(−1, 0, 1, …)`) and a
    [`Tree`][lagrax.chains.Tree] share: forward kinematics over parents, gravity, the
    scene of one batched [`SpatialBody`][lagrax.bodies.SpatialBody] and the system whose
    equations are Featherstone's recursions.

    Body `i` hangs from body `parents[i]` (`−1`: the base) by joint `i`, a letter of
    `joint_types` (see `lagrax._multibody.joints`), which sits at `offset_i` in the
    parent's frame with a fixed orientation `S_i` (`rotations[i]`) and moves along or
    about `axis_i`. Gravity has magnitude `g` along `−up`.
    """

    joint_types: eqx.AbstractVar[str]
    parents: eqx.AbstractVar[tuple[int, ...]]
    axes: eqx.AbstractVar[tuple[tuple[float, float, float], ...]]
    rotations: eqx.AbstractVar[tuple[tuple[tuple[float, ...], ...], ...]]
    up: eqx.AbstractVar[tuple[float, float, float]]
    # `(body, master, multiplier, offset)` for every body whose joint mimics another's
    # (see `Tree`); empty for most trees.
    mimic: eqx.AbstractVar[tuple[tuple[int, int, float, float], ...]]

    # Forward kinematics loops over the joints (`lax.scan`, which follows one chain of
    # parents) beyond this many joints; `inf` (a tree, whose bodies may branch): always
    # written out body by body.
    kinematics_scan_above: ClassVar[float] = math.inf

    @property
    def n_bodies(self) -> int:
        """Number of moving joints (and bodies), mimic joints included."""
        return len(self.joint_types)

    @property
    def n(self) -> int:
        """Number of coordinates: one per moving joint that does not mimic another (equal
        to [`n_bodies`][lagrax.chains.AbstractTree.n_bodies] for a tree without mimic
        joints)."""
        return len(self.joint_types) - len(self.mimic)

    @property
    def coordinates(self) -> tuple[int, ...]:
        """The bodies whose joint angles are the coordinates, in order (all bodies but
        the mimic ones)."""
        mimics = {body for body, *_ in self.mimic}
        return tuple(i for i in range(self.n_bodies) if i not in mimics)

    def coupling(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The affine map from the coordinates `q` to the joint angles `θ` of all
        bodies, `θ_i = a_i q_{k_i} + b_i`, as NumPy arrays `(k, a, b)` of length
        [`n_bodies`][lagrax.chains.AbstractTree.n_bodies] (a coordinate's body: its own
        index, `a = 1`, `b = 0`; a mimic body: its master's coordinate, the URDF
        `<mimic multiplier offset>`)."""
        index = {body: k for k, body in enumerate(self.coordinates)}
        k = np.array([index.get(i, -1) for i in range(self.n_bodies)], int)
        a, b = np.ones(self.n_bodies), np.zeros(self.n_bodies)
        for body, master, multiplier, offset in self.mimic:
            k[body], a[body], b[body] = index[master], multiplier, offset
        return k, a, b

    def coupling_matrix(self) -> np.ndarray:
        """`J = ∂θ/∂q`, shape `(n_bodies, n)`: joint rates `θ̇ = J q̇`, and a joint
        torque `τ_θ` acts on the coordinates as `Jᵀ τ_θ` (a mimic joint's torque adds
        to its master's, times the multiplier)."""
        k, a, _ = self.coupling()
        out = np.zeros((self.n_bodies, self.n))
        out[np.arange(self.n_bodies), k] = a
        return out

    def joint_angles(self, q: Vector) -> jnp.ndarray:
        """`θ = J q + b`: every body's joint angle from the coordinates (`q` itself
        for a tree without mimic joints)."""
        if not self.mimic:
            return q
        k, a, b = self.coupling()
        return q[k] * jnp.asarray(a, q.dtype) + jnp.asarray(b, q.dtype)

    def joint_rates(self, qd: Vector) -> jnp.ndarray:
        """`θ̇ = J q̇` (`q̇` itself for a tree without mimic joints)."""
        if not self.mimic:
            return qd
        k, a, _ = self.coupling()
        return qd[k] * jnp.asarray(a, qd.dtype)

    @property
    def balls(self) -> tuple[int, ...]:
        """The first lanes of the tree's ball joints (`lagrax._multibody.articulated.balls`;
        none but a [`Tree`][lagrax.chains.Tree]'s)."""
        return ()

    @property
    def n_configuration(self) -> int:
        """The size of the configuration `q`: [`n`][lagrax.chains.AbstractTree.n] plus
        one per ball joint (its quaternion's 4 entries against its velocity's 3)."""
        return self.n + len(self.balls)

    def children(self, i: int) -> tuple[int, ...]:
        """The bodies hanging from body `i` (`−1`: from the base)."""
        return tuple(k for k, p in enumerate(self.parents) if p == i)

    @abc.abstractmethod
    def params(self, **values: Any) -> dict[str, jnp.ndarray]:
        """Parameters as arrays with a leading axis of length `n`: `m: (n,)`,
        `offset: (n, 3)`, `com: (n, 3)`, `inertia: (n, 3, 3)`, `g: ()`, and any more
        the kind of tree reads (a tree's joint `damping`)."""

    @abc.abstractmethod
    def dissipation(self) -> Callable | None:
        """The scene's Rayleigh dissipation `D(q, q̇, params)` (`None`: none)."""

    @abc.abstractmethod
    def label(self) -> str:
        """The scene's and the system's name."""

    @abc.abstractmethod
    def coordinate_names(self) -> tuple[str, ...] | None:
        """The system's coordinate names (`None`: unnamed)."""

    def _body_params(
        self, values: dict[str, Any], inertia_per_kg: Any, dtype: Any, item: str
    ) -> dict[str, jnp.ndarray]:
        """`values["m"], ["offset"], ["com"], ["inertia"]` broadcast to the `n_bodies`
        bodies and checked (`inertia` `None`: `m` times `inertia_per_kg`); messages name
        the class and the `item` (link or body)."""
        n, who, inertia = self.n_bodies, type(self).__name__, values["inertia"]
        m_ = physical(broadcast("m", values["m"], (n,), dtype), f"{who}.params m", item=item)
        if inertia is None:
            inertia = m_[:, None, None] * jnp.asarray(inertia_per_kg, dtype)[None]
        inertia = broadcast("inertia", inertia, (n, 3, 3), dtype)
        inertia = check_inertia(inertia, name=f"{who}.params inertia", semidefinite=True)
        return {
            "m": m_,
            "offset": broadcast("offset", values["offset"], (n, 3), dtype),
            "com": broadcast("com", values["com"], (n, 3), dtype),
            "inertia": inertia,
        }

    def joint_constants(self) -> tuple[np.ndarray, ...]:
        """Per-joint constants `(A, B, C, s)`, stacked (see
        `lagrax._multibody.joints.joint_constants`)."""
        return joint_constants(self.joint_types, self.axes, self.rotations)

    def frames(self, q: Vector, params: Params) -> tuple[jnp.ndarray, jnp.ndarray]:
        """Forward kinematics at the coordinates `q`: body-frame origins
        `(n_bodies, 3)` and rotations `(n_bodies, 3, 3)` in
        the world frame (`R_i` takes frame-`i` components to world ones): `R_i = R_p ᵖR_i`,
        `o_i = o_p + R_p ᵖp_i` with `p` the parent (the base: `R = 1`, `o = 0`)."""
        origins, rots, _ = self._kinematics(q, params, with_com=False)
        return _stacked(origins), _stacked(rots)

    def com_positions(self, q: Vector, params: Params) -> jnp.ndarray:
        """Centres of mass in the world frame, `o_i + R_i com_i`, shape `(n_bodies, 3)`."""
        return _stacked(self._kinematics(q, params, with_com=True)[2])

    def _pose(self, q, params):
        _, rots, coms = self._kinematics(q, params, with_com=True)
        return coms, rots

    def _kinematics(self, q, params, *, with_com: bool):
        """Origins, rotations and (`with_com`) centres of mass: lists of `n` small
        arrays written out body by body (fused into straight-line code under `vmap`), or
        stacked arrays from a `lax.scan` for a long chain (`kinematics_scan_above`)."""
        size = self.n_configuration
        if q.shape != (size,):
            raise ShapeError(f"q has shape {q.shape}, expected ({size},) for the {self.label()}")
        self._check_params(params)
        offset = jnp.asarray(params["offset"])
        dtype = jnp.result_type(q, offset)
        q, offset = self.joint_angles(q.astype(dtype)), offset.astype(dtype)
        com = jnp.asarray(params["com"]).astype(dtype) if with_com else None
        a, b, c, slide = (jnp.asarray(x, dtype) for x in self.joint_constants())
        if self.balls:  # the lanes' angles (zero) and the balls' rotations in `A`
            q, a = balls_.lane_state(self, q)
        if self.n_bodies > self.kinematics_scan_above:
            return self._kinematics_scan(q, offset, com, dtype)
        base = (jnp.eye(3, dtype=dtype), jnp.zeros(3, dtype))
        origins, rots, coms = [], [], []
        for i, kind in enumerate(self.joint_types):
            p = self.parents[i]
            rot, origin = base if p < 0 else (rots[p], origins[p])
            step = offset[i] if revolute(kind) else offset[i] + q[i] * slide[i]
            origins.append(origin + rot @ step)
            if revolute(kind):
                rots.append(rot @ (a[i] + jnp.sin(q[i]) * b[i] + (1 - jnp.cos(q[i])) * c[i]))
            else:
                rots.append(rot @ a[i])
            if com is not None:
                coms.append(origins[i] + rots[i] @ com[i])
        return origins, rots, coms if com is not None else None

    def _kinematics_scan(self, q, offset, com, dtype):
        """`_kinematics` of a chain as one `lax.scan` over its joints."""
        a, b, c, slide = (jnp.asarray(x, dtype) for x in self.joint_constants())

        def joint(carry, x):
            rot, origin = carry
            qi, ai, bi, ci, si, off = x
            origin = origin + rot @ (off + qi * si)
            rot = rot @ (ai + jnp.sin(qi) * bi + (1 - jnp.cos(qi)) * ci)
            return (rot, origin), (origin, rot)

        init = (jnp.eye(3, dtype=dtype), jnp.zeros(3, dtype))
        _, (origins, rots) = jax.lax.scan(joint, init, (q, a, b, c, slide, offset))
        coms = None if com is None else origins + jnp.einsum("nij,nj->ni", rots, com)
        return origins, rots, coms

    def _param_shapes(self) -> dict[str, tuple[int, ...]]:
        n = self.n_bodies
        return {"m": (n,), "offset": (n, 3), "com": (n, 3), "inertia": (n, 3, 3), "g": ()}

    def _gravity(self, params):
        g = jnp.asarray(params["g"])
        return -g * jnp.asarray(self.up, g.dtype)

    def articulated(self, q, params: Params, scan: bool | None = None) -> Chain:
        """World joint axes, motion subspaces and body inertias at the joint angles `q`
        of all bodies (`θ`: the coordinates for a tree without mimic joints; see
        `lagrax._multibody.articulated.tree_equations.spatial_chain`)."""
        return spatial_chain(self, q, params, scan)

    def link_energies(self, q, qd, params: Params) -> tuple[jnp.ndarray, jnp.ndarray]:
        """`(T, V)` by one outward pass in link frames at the joint angles and rates of
        all bodies (see `lagrax._multibody.articulated.tree_equations.spatial_energies`)."""
        return spatial_energies(self, q, qd, params)

    def _check_moves(self) -> None:
        """`ConfigurationError` for a tree with no joints: fixed to the world, it has no
        coordinates (it is a floating base's single rigid body)."""
        if self.n_bodies == 0:
            raise ConfigurationError(
                "the tree has no joints: fixed to the world, nothing moves. A single "
                "rigid body moves on a floating base: lagrax.chains.FloatingTree(tree)"
            )

    def scene(self) -> Scene:
        """The tree as a [`lagrax.bodies.Scene`][]: one batched
        [`SpatialBody`][lagrax.bodies.SpatialBody] for all bodies, gravity `−g up`, and
        the tree's [`dissipation`][lagrax.chains.AbstractTree.dissipation] (a tree's joint
        damping, `½ Σ b_i q̇_i²`).

        **Raises:** `ConfigurationError` for a tree with no joints (see
        [`FloatingTree`][lagrax.chains.FloatingTree]) or with ball joints."""
        self._check_moves()
        balls_.no_scene(self)
        body = SpatialBody(Param("m"), Param("inertia"), self._pose, None)
        terms = self._joint_terms()  # armature and springs (`joint_space`)
        return Scene(
            [body],
            gravity=self._gravity,
            dissipation=self.dissipation(),
            n_dof=self.n,
            name=self.label(),
            kinetic=joint_space.JointKinetic(self) if terms else None,
            potential=joint_space.JointPotential(self) if terms else None,
        )

    def _joint_terms(self) -> bool:
        """Whether the energies carry the joint-space terms (`joint_space`: armature,
        springs): a spatial chain's never do; a [`Tree`][lagrax.chains.Tree] says."""
        return False

    def system(self) -> LagrangianSystem:
        """The tree's [`lagrax.LagrangianSystem`][], its equations evaluated by
        Featherstone's recursions over parents (`q̈` by the articulated-body algorithm,
        O(n); `M` by the composite-rigid-body algorithm), its coordinates named by
        [`coordinate_names`][lagrax.chains.AbstractTree.coordinate_names].
        `dataclasses.replace(system, equations=None)` differentiates the energies
        instead (the definition).

        **Raises:** `ConfigurationError` for a tree with no joints: fixed to the world it
        cannot move (put it on a floating base, [`FloatingTree`][lagrax.chains.FloatingTree])."""
        self._check_moves()
        if self.balls:
            from .ball_system import BallTreeSystem

            return BallTreeSystem(self)  # type: ignore[return-value]
        equations = CoupledEquations(self) if self.mimic else ChainEquations(self)
        return dataclasses.replace(
            self.scene().system(),
            equations=equations,
            coordinate_names=self.coordinate_names(),
        )


def _stacked(x):
    """Per-body values as one array (a list of `n` is stacked; an array is kept)."""
    return jnp.stack(x) if isinstance(x, list) else x


class Tree(AbstractTree):
    r"""A kinematic tree of rigid bodies joined by revolute (`"R"`) and prismatic
    (`"P"`) joints, fixed to the world at its base.

    Body `i` hangs from body `parents[i]` (`−1`: the base, i.e. the world), with
    `parents[i] < i`, so bodies are numbered from the base outwards; a serial chain has
    `parents = (−1, 0, 1, …)`. Joint `i` connects body `parents[i]` (frame `p`) to
    body `i` exactly as a [`SpatialChain`][lagrax.chains.SpatialChain]'s joint connects link `i − 1`
    to `i`: it sits at `offset_i` in frame `p` with a fixed orientation `S_i`
    (`rotations[i]`), and

    - revolute: `ᵖR_i = S_i Rot(axis_i, q_i)`, `ᵖp_i = offset_i`;
    - prismatic: `ᵖR_i = S_i`, `ᵖp_i = offset_i + S_i axis_i q_i`.

    This is the URDF joint: `S_i` and `offset_i` are its `<origin rpy xyz>` and
    `axis_i` its `<axis>` in the joint (= child link) frame. Body `i` has mass
    `m_i`, centre of mass `com_i` and inertia `inertia_i` about the centre of mass,
    both in frame `i`. Gravity has magnitude `g` along `−up`. Each joint may have
    viscous damping `damping_i` (Rayleigh `D = ½ Σ b_i q̇_i²`, a torque `−b_i q̇_i`).

    Fixed joints are not bodies of the tree: [`lagrax.chains.from_urdf`][] merges a link
    on a fixed joint into the body it is fixed to (mass, centre of mass and inertia by the
    parallel-axis theorem, rotated into that body's frame), so the equations have one
    coordinate per moving joint.

    **Mimic joints.** A body may follow another's joint instead of having a coordinate
    (URDF's `<mimic joint multiplier offset>`: a gripper's second finger): its joint
    angle is `θ_i = a q_k + b` with `q_k` its master's coordinate. The tree then has
    `n_bodies` bodies and `n = n_bodies − len(mimic)` coordinates
    ([`coordinates`][lagrax.chains.AbstractTree.coordinates]: the bodies that are not
    mimics). With `J = ∂θ/∂q` ([`coupling_matrix`][lagrax.chains.AbstractTree.coupling_matrix])
    the equations are those of the tree of independent joints at `θ`, reduced:
    `M = Jᵀ M_θ J`, `C q̇ + G = Jᵀ (C_θ θ̇ + G_θ)`, so the master's generalized force
    includes the mimic's; `q̈` is then a Cholesky solve (the articulated-body algorithm
    needs independent joints). A tree without mimic joints runs exactly the plain
    recursions.

    Structure (static): `joint_types`, `parents`, `axes`, `rotations`, `up`,
    `joint_names`, `body_names`, `limits`, `velocity_limits`, `effort_limits`, `mimic`
    (all per body, mimic ones included). Parameters (arrays, from
    [`params`][lagrax.chains.Tree.params]), per body: `m: (n,)`, `offset: (n, 3)`,
    `com: (n, 3)`, `inertia: (n, 3, 3)`, `damping: (n,)`, and `g: ()`.

    The system's equations are Featherstone's recursions run over parents: `q̈` by the
    articulated-body algorithm (O(n)), `M` by the composite-rigid-body algorithm
    (`M_ji = S_jᵀ I^c_i S_i` for `j` on `i`'s path to the base, zero otherwise),
    `M q̈ + C q̇ + G` by recursive Newton–Euler; the energies remain the definition
    (`dataclasses.replace(system, equations=None)`).

    **Arguments:**

    - `joint_types`: a string such as `"RRPR"` (`"C"`, continuous, is read as `"R"`).
      An empty string (with `parents=()`) is a tree with no joints: the joint tree of
      a [`FloatingTree`][lagrax.chains.FloatingTree] that is a single rigid body (a
      quadrotor); fixed to the world it has no system.
    - `parents`: `n` parent indices (`−1`: the base; `parents[i] < i`).
    - `axes`: `n` joint axes (normalized here); default z.
    - `rotations`: `n` fixed rotations `S_i`; default the identity.
    - `up`: the direction opposite to gravity (default `(0, 0, 1)`).
    - `joint_names`, `body_names`: labels (default `joint0…`, `body0…`).
    - `limits`: `n` pairs `(lower, upper)` of joint positions (default unlimited),
      stored for the user (e.g. for events); the equations do not enforce them.
    - `velocity_limits`, `effort_limits`: `n` positive bounds (default `inf`),
      stored likewise.
    - `mimic`: `(body, master, multiplier, offset)` tuples (or a mapping
      `{body: (master, multiplier, offset)}`): body `body`'s joint angle is
      `multiplier · θ_master + offset` (default: none, every joint a coordinate).
    - `joint_terms`: whether the params may carry armature, joint springs or fixed
      tendons ([`params`][lagrax.chains.Tree.params]' `armature`, `stiffness`,
      `springref`; `tendon*` entries, see [`lagrax.chains.from_mjcf`][]): then the
      scene's energies (the definition, `dataclasses.replace(system,
      equations=None)`) include them. The recursions read them in any case.
    - `balls`: the first bodies of ball joints (default none). A ball joint is three
      revolute bodies `b, b + 1, b + 2` about `x`, `y`, `z`, each hanging from the one
      before, the last two with the identity rotation and zero offset (the joint's body
      last); its coordinates are a unit quaternion `(x, y, z, w)` in `q` and the
      body's angular velocity in its own frame in `v`
      ([`n_configuration`][lagrax.chains.AbstractTree.n_configuration] `= n +
      len(balls)`), and the tree's system is a
      [`BallTreeSystem`][lagrax.chains.BallTreeSystem]
      ([`lagrax.chains.from_mjcf`][] builds these from MJCF ball joints).

    **Raises:** `ConfigurationError` (a `ValueError`) for an unknown joint type, a
    parent index that is not an earlier body, lists of the wrong length, a mimic entry
    whose body or master is not a body, or whose master is itself a mimic, or a `balls`
    entry that is not three such lanes (or beside mimic joints).

    **Example:** a torso joint carrying two one-joint arms:

    ```python
    tree = lagrax.chains.Tree("RRR", parents=(-1, 0, 0), axes=[(0, 0, 1), (0, 1, 0), (0, 1, 0)])
    params = tree.params(offset=[(0, 0, 0), (0, 0.2, 0.5), (0, -0.2, 0.5)])
    system = tree.system()
    ```
    """

    joint_types: str = eqx.field(static=True)
    parents: tuple[int, ...] = eqx.field(static=True)
    axes: tuple[tuple[float, float, float], ...] = eqx.field(static=True)
    rotations: tuple[tuple[tuple[float, ...], ...], ...] = eqx.field(static=True)
    up: tuple[float, float, float] = eqx.field(static=True)
    joint_names: tuple[str, ...] = eqx.field(static=True)
    body_names: tuple[str, ...] = eqx.field(static=True)
    limits: tuple[tuple[float, float], ...] = eqx.field(static=True)
    velocity_limits: tuple[float, ...] = eqx.field(static=True)
    effort_limits: tuple[float, ...] = eqx.field(static=True)
    mimic: tuple[tuple[int, int, float, float], ...] = eqx.field(static=True)
    joint_terms: bool = eqx.field(static=True)
    ball_lanes: tuple[int, ...] = eqx.field(static=True)

    @property
    def balls(self) -> tuple[int, ...]:
        """The first lanes of the tree's ball joints (the `balls` argument)."""
        return self.ball_lanes

    def _joint_terms(self) -> bool:
        return self.joint_terms

    def __init__(
        self,
        joint_types: str,
        parents: Any,
        axes: Any = None,
        rotations: Any = None,
        up: Any = (0.0, 0.0, 1.0),
        *,
        joint_names: Any = None,
        body_names: Any = None,
        limits: Any = None,
        velocity_limits: Any = None,
        effort_limits: Any = None,
        mimic: Any = None,
        joint_terms: bool = False,
        balls: Any = None,
    ):
        types = parse_joint_types(joint_types, aliases={"C": "R"}, empty=True)
        n = len(types)
        parents = tuple(int(p) for p in parents)
        if len(parents) != n:
            raise ConfigurationError(f"{n} joints need {n} parent indices, got {len(parents)}")
        for i, p in enumerate(parents):
            if not -1 <= p < i:
                raise ConfigurationError(
                    f"parents[{i}] = {p}: a body's parent must be an earlier body (0 <= p < "
                    f"{i}) or -1 (the base); number the bodies from the base outwards"
                )
        self.joint_types = types
        self.parents = parents
        self.axes, self.rotations, self.up = structure(types, axes, rotations, up)
        self.joint_names = names_of(joint_names, n, "joint", "joint_names")
        self.body_names = names_of(body_names, n, "body", "body_names")
        self.limits = joint_limits_of(limits, n)
        self.velocity_limits = positive_bounds(velocity_limits, n, "velocity_limits")
        self.effort_limits = positive_bounds(effort_limits, n, "effort_limits")
        self.mimic = mimic_entries(mimic, n)
        self.joint_terms = bool(joint_terms)
        args = (types, parents, self.axes, self.rotations, self.mimic)
        self.ball_lanes = balls_.ball_entries(balls, *args)

    def params(
        self,
        *,
        m: Any = 1.0,
        offset: Any = 0.0,
        com: Any = 0.0,
        inertia: Any = None,
        damping: Any = 0.0,
        g: Any = 9.81,
        dtype: Any = None,
        armature: Any = None,
        stiffness: Any = None,
        springref: Any = 0.0,
        frictionloss: Any = None,
        friction_velocity: Any = joint_space.FRICTION_VELOCITY,
    ) -> dict[str, jnp.ndarray]:
        """Parameters as arrays, broadcast to all `n_bodies` bodies.

        Defaults: 1 kg bodies with their centre of mass at the joint, joints at their
        parent's origin, the inertia of a solid 1 kg sphere of radius 0.1 m
        (`0.004 kg m²`) times `m`, no damping, `g = 9.81`.

        **Arguments:** `m`, `damping` (scalar or `(n,)`), `offset` and `com`
        (`(3,)` or `(n, 3)`), `inertia` (`(3, 3)` or `(n, 3, 3)`), `g`,
        `dtype` (default float64 with x64)); optional joint-space terms (see
        `lagrax._multibody.joint_space`), left out of the dict unless given:
        `armature` (scalar or `(n,)`: rotor inertia, `M += diag(armature)`),
        `stiffness` and `springref` (scalar or `(n,)`: joint springs
        `V += ½ Σ k (q − q_ref)²`), `frictionloss` (scalar or `(n,)`: Coulomb joint
        friction `f`, regularized with the stiction velocity `friction_velocity`
        `v_s`, a dissipation; see [`lagrax.chains.from_mjcf`][]). Give the tree
        `joint_terms=True` for its scene's energies to include armature and springs.

        **Returns:** ``{"m": (n,), "offset": (n, 3), "com": (n, 3), "inertia": (n, 3, 3),
        "damping": (n,), "g": ()}`` (and `"armature"`, `"stiffness"`, `"springref"`,
        `"frictionloss"`, `"friction_velocity"` where given).

        **Raises:** `ShapeError` if a value does not broadcast; `ParameterError` for a
        negative mass or damping, or an inertia that is not symmetric positive-semidefinite
        or violates `I1 + I2 ≥ I3` (naming the body).
        """
        dtype = float_dtype(dtype)
        values = {"m": m, "offset": offset, "com": com, "inertia": inertia}
        out = self._body_params(values, 0.004 * np.eye(3), dtype, item="body")
        b = broadcast("damping", damping, (self.n_bodies,), dtype)
        out["damping"] = physical(b, "Tree.params damping", item="joint")
        out["g"] = jnp.asarray(g, dtype=dtype)
        shape = (self.n_bodies,)
        if armature is not None:
            a = broadcast("armature", armature, shape, dtype)
            out["armature"] = physical(a, "Tree.params armature", what="armature", item="joint")
        if stiffness is not None:
            k = broadcast("stiffness", stiffness, shape, dtype)
            out["stiffness"] = physical(k, "Tree.params stiffness", what="stiffness", item="joint")
            out["springref"] = broadcast("springref", springref, shape, dtype)
        if frictionloss is not None:
            f = broadcast("frictionloss", frictionloss, shape, dtype)
            what = "friction loss"
            out["frictionloss"] = physical(f, "Tree.params frictionloss", what=what, item="joint")
            v_s = broadcast("friction_velocity", friction_velocity, (), dtype)
            what = "stiction velocity"
            out["friction_velocity"] = physical(
                v_s, "Tree.params friction_velocity", what=what, positive=True
            )
        return out

    def dissipation(self) -> Callable:
        """Viscous joint damping: the Rayleigh dissipation `½ Σ b_i θ̇_i²` over all
        joints (`θ̇ = q̇` without mimic joints), with fixed tendons' damping and joint
        friction loss where `params` has them (`lagrax._multibody.joint_space`)."""
        return CoupledDamping(self) if self.mimic else joint_damping

    def label(self) -> str:
        """`"<n>-joint tree"` (with mimic joints: `"<n_bodies>-joint tree (<n>
        coordinates)"`)."""
        if self.mimic:
            return f"{self.n_bodies}-joint tree ({self.n} coordinates)"
        return f"{self.n}-joint tree"

    def coordinate_names(self) -> tuple[str, ...]:
        """The joint names of the [`coordinates`][lagrax.chains.AbstractTree.coordinates]:
        a tree's system names its coordinates after its joints (all of them, without
        mimic joints)."""
        if not self.mimic:
            return self.joint_names
        return tuple(self.joint_names[i] for i in self.coordinates)
