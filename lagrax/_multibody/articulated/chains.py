"""Serial chains: planar n-link arms and spatial revolute/prismatic chains.

A chain object holds the *structure* (number of links, joint types, axes, fixed rotations);
the numbers a sweep may vary (masses, lengths, offsets, inertias, g) live in `params` as
arrays with a leading axis of length `n`. The chain's energies are built from the bodies
of [`lagrax.bodies`][] (one batched body for all links) and its structure is what
[`lagrax.newton_euler.rnea`][] reads for the independent recursive Newton–Euler oracle.
"""

import dataclasses
from typing import Any, ClassVar, Literal

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._core.checks import physical
from ..._core.custom_types import Params, Vector
from ..._core.errors import ConfigurationError, ShapeError
from ..._systems.lagrangian import LagrangianSystem
from ..algorithms.recursions import Chain
from ..common import broadcast, float_dtype
from ..energies.bodies import Param, PlanarBody, SpatialBody
from ..energies.scene import Scene
from ..inertia import check_inertia
from ..joints import parse_joint_types
from .tree_equations import AbstractArticulated, ChainEquations
from .tree_equations import planar_chain as planar_articulated
from .trees import UNROLL_MAX, AbstractTree, structure

BodyKind = Literal["planar", "spatial"]

# Forward kinematics of chains up to this length is unrolled joint by joint and hands the
# bodies one small array per link (a list, not stacked across links): under ``vmap`` and
# nested forward-mode derivatives XLA fuses that into straight-line code, where stacking
# and re-slicing tiny arrays made the 2R arm's forward dynamics ~15x slower (measured,
# batch of 4096 on CPU). Planar links are written out in scalars up to 32 links; spatial
# chains see `SpatialChain.kinematics_scan_above`.
_UNROLL_MAX_PLANAR = 32
# Planar chains from this many links evaluate their equations by the recursions.
_RECURSIONS_MIN_PLANAR = 4


# ------------------------------------------------------------------------------ planar
class PlanarChain(AbstractArticulated):
    r"""A planar serial chain of `n` links joined by revolute joints (the lecture's 2R arm,
    generalized).

    Joint 1 is fixed at the origin. `q_1` is link 1's angle from the x axis and `q_i`
    (`i > 1`) is link `i`'s angle relative to link `i − 1`, so link `i` points along
    `u_i = (cos φ_i, sin φ_i)` with `φ_i = q_1 + … + q_i`. Link `i` has mass `m_i`,
    length `l_i` (joint `i` to joint `i + 1`), its centre of mass on the link at distance
    `r_i` from joint `i` and z-inertia `I_i` about that centre of mass. Gravity acts
    along −y with magnitude `g`.

    `params` (from [`params`][lagrax.chains.PlanarChain.params]) is a dict of arrays `m, l, r, I:
    (n,)` and `g: ()`. For `n = 2` this is [`lagrax.models.planar_2r`][] with `m1 = m[0]`, `r2 =
    r[1]`...

    **Arguments:**

    - `n`: the number of links (and joints).

    **Example:**

    ```python
    chain = lagrax.chains.PlanarChain(3)
    system, params = chain.system(), chain.params(m=[1.0, 0.8, 0.5])
    tau = lagrax.newton_euler.rnea(chain, q, qd, qdd, params)   # oracle
    ```
    """

    n: int = eqx.field(static=True)

    def __check_init__(self):
        if not isinstance(self.n, int) or self.n < 1:
            raise ConfigurationError(f"PlanarChain needs n >= 1 links, got {self.n!r}")

    def params(
        self,
        *,
        m: Any = 1.0,
        l: Any = 1.0,
        r: Any = None,
        I: Any = None,  # noqa: N803 - the lecture's symbol
        g: Any = 9.81,
        dtype: Any = None,
    ) -> dict[str, jnp.ndarray]:
        """Parameters as arrays: scalars are broadcast to all `n` links.

        Defaults: uniform 1 kg, 1 m rods (`r = l/2`, `I = m l²/12`), `g = 9.81`.

        **Arguments:** `m`, `l`, `r`, `I` (scalars or `(n,)`), `g` (scalar),
        `dtype` (default float64 with x64).

        **Returns:** `{"m", "l", "r", "I": (n,), "g": ()}`.

        **Raises:** `ShapeError` if a value does not broadcast to `(n,)`;
        `ParameterError` for a negative mass or inertia (naming the link).
        """
        dtype = float_dtype(dtype)
        shape = (self.n,)
        m_, l_ = broadcast("m", m, shape, dtype), broadcast("l", l, shape, dtype)
        r_ = 0.5 * l_ if r is None else broadcast("r", r, shape, dtype)
        m_ = physical(m_, "PlanarChain.params m", item="link")
        i_ = m_ * l_**2 / 12 if I is None else broadcast("I", I, shape, dtype)
        i_ = check_inertia(i_, name="PlanarChain.params I", semidefinite=True)
        return {"m": m_, "l": l_, "r": r_, "I": i_, "g": jnp.asarray(g, dtype=dtype)}

    def _check_q(self, q: Vector) -> None:
        if q.shape != (self.n,):
            raise ShapeError(f"q has shape {q.shape}, expected ({self.n},) for this chain")

    def _directions(self, q):
        phi = jnp.cumsum(q)
        return phi, jnp.stack([jnp.cos(phi), jnp.sin(phi)], axis=-1)

    def joint_positions(self, q: Vector, params: Params) -> jnp.ndarray:
        """Joints `1…n` and the tip, shape `(n + 1, 2)`; joint 1 is the origin."""
        self._check_q(q)
        _, u = self._directions(q)
        ends = jnp.cumsum(params["l"][:, None] * u, axis=0)
        return jnp.concatenate([jnp.zeros((1, 2), ends.dtype), ends], axis=0)

    def com_positions(self, q: Vector, params: Params) -> jnp.ndarray:
        """Centres of mass `x_ci = joint_i + r_i u_i`, shape `(n, 2)`."""
        return jnp.stack(list(self._pose(q, params)[0]))

    def _pose(self, q, params):
        """Every link's centre of mass and angle in one pass along the chain: lists of
        `n` `(2,)` points and `n` angles, written out link by link in scalars (see
        `_UNROLL_MAX_PLANAR`); arrays `(n, 2)`, `(n,)` by cumulative sums for very long
        chains."""
        self._check_q(q)
        self._check_params(params)
        length, r = jnp.asarray(params["l"]), jnp.asarray(params["r"])
        if self.n > _UNROLL_MAX_PLANAR:
            phi, u = self._directions(q)
            ends = jnp.cumsum(length[:, None] * u, axis=0)
            starts = jnp.concatenate([jnp.zeros((1, 2), ends.dtype), ends[:-1]], axis=0)
            return starts + r[:, None] * u, phi
        coms, angles = [], []
        phi = joint_x = joint_y = None
        for i in range(self.n):
            phi = q[i] if phi is None else phi + q[i]
            c, s = jnp.cos(phi), jnp.sin(phi)
            cx, cy = r[i] * c, r[i] * s
            if joint_x is not None:
                cx, cy = joint_x + cx, joint_y + cy
            coms.append(jnp.stack([cx, cy]))
            angles.append(phi)
            jx, jy = length[i] * c, length[i] * s
            joint_x, joint_y = (jx, jy) if joint_x is None else (joint_x + jx, joint_y + jy)
        return coms, angles

    # spatial embedding of the same links (z = 0, rotation about z), for comparison
    def _pose_3d(self, q, params):
        coms, angles = self._pose(q, params)
        coms3, rots = [], []
        for com, phi in zip(coms, angles, strict=True):
            c, s = jnp.cos(phi), jnp.sin(phi)
            z, o = jnp.zeros_like(c), jnp.ones_like(c)
            coms3.append(jnp.stack([com[0], com[1], z]))
            rots.append(
                jnp.stack([jnp.stack([c, -s, z]), jnp.stack([s, c, z]), jnp.stack([z, z, o])])
            )
        return coms3, rots

    def _inertia_3d(self, params):
        i = jnp.asarray(params["I"])
        return i[:, None, None] * jnp.eye(3, dtype=i.dtype)[None]

    def _gravity_3d(self, params):
        g = jnp.asarray(params["g"])
        zero = jnp.zeros_like(g)
        return jnp.stack([zero, -g, zero])

    @property
    def parents(self) -> tuple[int, ...]:
        """`(−1, 0, …, n − 2)`: link `i` hangs from link `i − 1`."""
        return tuple(range(-1, self.n - 1))

    def articulated(self, q, params: Params, scan: bool | None = None) -> Chain:
        """Motion subspaces and link inertias at `q` (see
        `lagrax._multibody.articulated.tree_equations.planar_chain`)."""
        self._check_params(params)
        return planar_articulated(self.n, q, params, scan)

    def _param_shapes(self) -> dict[str, tuple[int, ...]]:
        return {"m": (self.n,), "l": (self.n,), "r": (self.n,), "I": (self.n,), "g": ()}

    def link_energies(self, q, qd, params: Params) -> None:
        """`None`: the vectorized pose maps are already the cheaper route to `(T, V)`."""
        return None

    def scene(self, *, bodies: BodyKind = "planar") -> Scene:
        """The chain as a [`lagrax.bodies.Scene`][].

        **Arguments:**

        - `bodies`: `"planar"` (default): one batched [`PlanarBody`][lagrax.bodies.PlanarBody]
          for all links: 2 position components and one angle per link, the smallest
          description. `"spatial"`: the same links as a batched
          [`SpatialBody`][lagrax.bodies.SpatialBody] in the z = 0 plane (rotation about z,
          inertia `I_i` about every axis, gravity `(0, −g, 0)`) — identical equations,
          more work; kept to measure what the planar description saves.
        """
        if bodies == "planar":
            body = PlanarBody(Param("m"), Param("I"), self._pose, None)
            gravity = Param("g")
        elif bodies == "spatial":
            body = SpatialBody(Param("m"), self._inertia_3d, self._pose_3d, None)
            gravity = self._gravity_3d
        else:
            raise ConfigurationError(f"bodies must be 'planar' or 'spatial', got {bodies!r}")
        return Scene([body], gravity=gravity, n_dof=self.n, name=f"planar {self.n}-link chain")

    def system(self, *, bodies: BodyKind = "planar") -> LagrangianSystem:
        """The chain's [`lagrax.LagrangianSystem`][] (see
        [`scene`][lagrax.chains.PlanarChain.scene]).

        With `bodies="planar"` and `n >= 4` its equations are evaluated by Featherstone's
        recursions (`q̈` by the articulated-body algorithm, O(n)); up to 3 links the scalar
        autodiff of the energies is faster (measured in `benchmarks/bench_scale.py`: 0.06
        against 0.27 µs per state at n = 2) and is kept. `bodies="spatial"` keeps the
        autodiff of the spatial embedding's energies, for comparison.
        """
        system = self.scene(bodies=bodies).system()
        if bodies == "planar" and self.n >= _RECURSIONS_MIN_PLANAR:
            system = dataclasses.replace(system, equations=ChainEquations(self))
        return system

    def to_spatial(self, params: Params) -> tuple["SpatialChain", dict]:
        """The same chain as a [`SpatialChain`][lagrax.chains.SpatialChain] and its parameters.

        All joints revolute about z, joint `i + 1` at `(l_i, 0, 0)` in link `i`'s
        frame, centres of mass at `(r_i, 0, 0)`, inertia `diag(I_i, I_i, I_i)` (only the
        z entry acts in plane motion) and `up = (0, 1, 0)` so that gravity is along −y.
        Its equations equal this chain's; it costs more to compile and run (see
        `benchmarks/bench_planar_vs_spatial.py`).

        **Arguments:** `params`: this chain's parameters.

        **Returns:** `(SpatialChain, params)`.
        """
        n = self.n
        chain = SpatialChain("R" * n, up=(0.0, 1.0, 0.0))
        length, r = jnp.asarray(params["l"]), jnp.asarray(params["r"])
        zeros = jnp.zeros_like(length)
        joints = jnp.concatenate([zeros[:1], length[:-1]])
        inertia = jnp.asarray(params["I"])[:, None, None] * jnp.eye(3, dtype=length.dtype)[None]
        spatial = chain.params(
            m=params["m"],
            offset=jnp.stack([joints, zeros, zeros], axis=-1),
            com=jnp.stack([r, zeros, zeros], axis=-1),
            inertia=inertia,
            g=params["g"],
            dtype=length.dtype,
        )
        return chain, spatial


def planar_chain(
    n: int, *, bodies: BodyKind = "planar", **values: Any
) -> tuple[LagrangianSystem, dict]:
    """A planar `n`-link chain as `(system, params)`.

    `values` are passed to [`PlanarChain.params`][lagrax.chains.PlanarChain.params] (`m, l, r, I, g,
    dtype`); for the Newton–Euler oracle use `lagrax.newton_euler.rnea(PlanarChain(n), ...)`.

    **Example:** `system, params = lagrax.chains.planar_chain(5, l=0.4)`
    """
    chain = PlanarChain(n)
    return chain.system(bodies=bodies), chain.params(**values)


# ----------------------------------------------------------------------------- spatial
def axis_angle_rotation(axis: Any, angle: Any) -> jnp.ndarray:
    """Rodrigues' formula: rotation by `angle` about the unit `axis`.

    `R = 1 + sin θ [a]× + (1 − cos θ) [a]×²`.
    """
    a = jnp.asarray(axis, dtype=jnp.result_type(angle))
    k = jnp.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]], dtype=a.dtype)
    eye = jnp.eye(3, dtype=a.dtype)
    return eye + jnp.sin(angle) * k + (1 - jnp.cos(angle)) * (k @ k)


class SpatialChain(AbstractTree):
    r"""A spatial serial chain of revolute (`"R"`) and prismatic (`"P"`) joints.

    Frames: frame 0 is the fixed (world) frame; frame `i` is attached to link `i`. Joint
    `i` sits at `offset_i` (components in frame `i − 1`), with a fixed orientation
    `S_i` (`rotations[i]`) relative to frame `i − 1`; then

    - revolute: link `i` turns by `q_i` about the unit `axis_i` through that point:
      `ⁱ⁻¹R_i = S_i Rot(axis_i, q_i)`, `ⁱ⁻¹p_i = offset_i`;
    - prismatic: link `i` slides by `q_i` along `axis_i`: `ⁱ⁻¹R_i = S_i`,
      `ⁱ⁻¹p_i = offset_i + S_i axis_i q_i`.

    `axis_i` is written in frame `i` (equivalently, in the joint frame `S_i`). Link
    `i` has mass `m_i`, its centre of mass at `com_i` and inertia `inertia_i` about
    the centre of mass, both in frame `i`. Gravity has magnitude `g` along `−up`
    (default `up = (0, 0, 1)`: gravity along −z).

    Structure (static): `joint_types`, `axes`, `rotations`, `up`. Parameters (arrays,
    from [`params`][lagrax.chains.SpatialChain.params]): `m: (n,)`, `offset: (n, 3)`, `com: (n, 3)`,
    `inertia: (n, 3, 3)`, `g: ()`.

    **Arguments:**

    - `joint_types`: a string such as `"RRP"`.
    - `axes`: `n` joint axes (normalized here); default z for every joint.
    - `rotations`: `n` fixed rotations `S_i`; default the identity.
    - `up`: the direction opposite to gravity.

    **Example:** a 3-DOF arm with a vertical waist, two horizontal elbows:

    ```python
    chain = SpatialChain("RRR", axes=[(0, 0, 1), (0, 1, 0), (0, 1, 0)])
    params = chain.params(offset=[(0, 0, 0), (0, 0, 0.3), (1.0, 0, 0)])
    system = chain.system()
    ```
    """

    joint_types: str = eqx.field(static=True)
    axes: tuple[tuple[float, float, float], ...] = eqx.field(static=True)
    rotations: tuple[tuple[tuple[float, ...], ...], ...] = eqx.field(static=True)
    up: tuple[float, float, float] = eqx.field(static=True)

    # Forward kinematics: 3×3 matrix products joint by joint up to 6 joints (written out
    # entry by entry in scalars, the program of the nested derivatives of a 5-joint chain
    # grew ~10x and compiled ~20x slower), then a ``lax.scan``, which compiles in time
    # independent of n and ran about as fast as unrolled code at n = 10.
    kinematics_scan_above: ClassVar[float] = UNROLL_MAX

    def __init__(
        self,
        joint_types: str,
        axes: Any = None,
        rotations: Any = None,
        up: Any = (0.0, 0.0, 1.0),
    ):
        self.joint_types = parse_joint_types(joint_types)
        self.axes, self.rotations, self.up = structure(self.joint_types, axes, rotations, up)

    @property
    def parents(self) -> tuple[int, ...]:
        """`(−1, 0, …, n − 2)`: link `i` hangs from link `i − 1`."""
        return tuple(range(-1, self.n - 1))

    @property
    def mimic(self) -> tuple[tuple[int, int, float, float], ...]:
        """`()`: every joint of a spatial chain is a coordinate."""
        return ()

    def params(
        self,
        *,
        m: Any = 1.0,
        offset: Any = None,
        com: Any = None,
        inertia: Any = None,
        g: Any = 9.81,
        dtype: Any = None,
    ) -> dict[str, jnp.ndarray]:
        """Parameters as arrays, broadcast to all `n` links.

        Defaults describe 1 m links along each link's x axis: joint 1 at the origin and
        joint `i > 1` at `(1, 0, 0)` in frame `i − 1`; centre of mass at
        `(0.5, 0, 0)`; inertia of a solid cylinder of radius 0.05 m and length 1 m along
        x; `m = 1`, `g = 9.81`.

        **Arguments:** `m` (scalar or `(n,)`), `offset` and `com` (`(3,)` or
        `(n, 3)`), `inertia` (`(3, 3)` or `(n, 3, 3)`; default from `m`), `g`,
        `dtype`.

        **Returns:** ``{"m": (n,), "offset": (n, 3), "com": (n, 3), "inertia": (n, 3, 3),
        "g": ()}``.

        **Raises:** `ShapeError` if a value does not broadcast; `ParameterError` if an
        inertia is not symmetric positive-semidefinite or violates `I1 + I2 ≥ I3`
        ([`lagrax.bodies.check_inertia`][], naming the link).
        """
        if offset is None:
            offset = np.zeros((self.n, 3))
            offset[1:, 0] = 1.0
        if com is None:
            com = (0.5, 0.0, 0.0)
        rod = np.diag([0.5 * 0.05**2, (3 * 0.05**2 + 1.0) / 12, (3 * 0.05**2 + 1.0) / 12])
        dtype = float_dtype(dtype)
        values = {"m": m, "offset": offset, "com": com, "inertia": inertia}
        out = self._body_params(values, rod, dtype, item="link")
        out["g"] = jnp.asarray(g, dtype=dtype)
        return out

    def dissipation(self) -> None:
        """`None`: a spatial chain has no joint damping."""
        return None

    def label(self) -> str:
        """`"<joint_types> chain"`."""
        return f"{self.joint_types} chain"

    def coordinate_names(self) -> None:
        """`None`: a spatial chain's coordinates are unnamed."""
        return None


def spatial_chain(
    joint_types: str,
    axes: Any = None,
    *,
    rotations: Any = None,
    up: Any = (0.0, 0.0, 1.0),
    **values: Any,
) -> tuple[LagrangianSystem, dict]:
    """A spatial chain as `(system, params)`; `values` go to
    [`SpatialChain.params`][lagrax.chains.SpatialChain.params].

    For the Newton–Euler oracle, keep the chain:
    `chain = SpatialChain(joint_types, axes, ...)`, then `rnea(chain, ...)`.
    """
    chain = SpatialChain(joint_types, axes, rotations, up)
    return chain.system(), chain.params(**values)
