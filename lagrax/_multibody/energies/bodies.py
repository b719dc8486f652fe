"""Bodies as energy terms: point masses, planar and spatial rigid bodies.

Every element is an `equinox.Module` that only *describes* a piece of the scene; its
energy is computed from the user's kinematics by JAX forward-mode differentiation
(`jax.jvp`), so no velocity is ever written by hand.
"""

import abc
from collections.abc import Callable, Mapping
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..._core.checks import is_traced, physical
from ..._core.custom_types import Params, Point, Rotation, Scalar, Vector
from ..._core.errors import ShapeError
from ..common import (
    batch,
    check_shape,
    dot_last,
    per_body,
    per_item,
    point,
    small_sum,
    squared_norm,
    value,
    vee,
)
from ..inertia import check_inertia

ParamLike = Any
"""A parameter-valued field: a constant (number or array), or a callable `params -> value`
(for example [`Param`][lagrax.bodies.Param]), evaluated each time the energy is."""

PointFn = Callable[[Vector, Params], Point]
"""`(q, params) -> (d,)` or `(k, d)`: a point (or `k` points) as a function of `q`."""


class Param(eqx.Module):
    """A parameter looked up by name: `Param("m")(params)` is `params["m"]`.

    Works for a mapping (`params[key]`) and for a NamedTuple / equinox Module / any object
    (`getattr(params, key)`). Use it wherever a field takes a parameter-valued
    [`ParamLike`][lagrax.bodies.ParamLike]; unlike a `lambda` it compares equal to another `Param`
    of the same key, so rebuilding a scene does not recompile jitted code. A missing key is reported
    by the system as a `ParameterError`.

    **Arguments:**

    - `key`: the name of the entry.
    """

    key: str = eqx.field(static=True)

    def __call__(self, params: Params) -> Any:
        if isinstance(params, Mapping):
            return params[self.key]
        return getattr(params, self.key)


def _pick(value, base_ndim: int, i: int):
    """Body `i`'s parameter: shared if it has the base rank, else indexed along axis 0."""
    return value if jnp.ndim(value) == base_ndim else value[i]


def _over_bodies(fn, params: list, kinematics: list) -> Scalar:
    """`Σ_bodies fn(params_i..., kinematics_i...)`.

    `params`: `(value, base_ndim)` pairs (shared, or one per body along axis 0);
    `kinematics`: `(output, base_ndim)` pairs of the pose (lists, or arrays with the
    bodies along axis 0). Lists are summed body by body in scalar code (fast under `vmap`
    and nested derivatives); many bodies in one array are summed vectorized.
    """
    parts = [per_body(x, nd) for x, nd in kinematics]
    if all(isinstance(x, jax.Array) for x in parts):  # vectorized over many bodies
        return small_sum(fn(*(v for v, _ in params), *parts))
    parts = [x if isinstance(x, list) else [x[i] for i in range(x.shape[0])] for x in parts]
    count = len(parts[0])
    if any(len(x) != count for x in parts):
        raise ShapeError(f"the pose gives different numbers of bodies: {[len(x) for x in parts]}")
    total = None
    for i in range(count):
        term = fn(*(_pick(v, nd, i) for v, nd in params), *(x[i] for x in parts))
        total = term if total is None else total + term
    return total


def _gravity_energy(mass, x, gravity, who: str) -> Scalar:
    """`V = −Σ m g⃗·x`; a scalar `g` means `g⃗ = −g e_last` (−y in 2-D, −z in 3-D)."""
    g = jnp.asarray(gravity) if not isinstance(gravity, (int, float)) else gravity
    if jnp.ndim(g) == 0:
        return _over_bodies(lambda m, x: m * g * x[..., -1], [(mass, 0)], [(x, 1)])
    items = per_body(x, 1)
    dim = (items[0] if isinstance(items, list) else items).shape[-1]
    if g.shape != (dim,):
        raise ShapeError(
            f"gravity vector has shape {g.shape} but the positions of {who} are "
            f"{dim}-dimensional; give a ({dim},) vector or a scalar magnitude"
        )
    return -_over_bodies(lambda m, x: m * dot_last(x, g), [(mass, 0)], [(x, 1)])


# ---------------------------------------------------------------------------------- bodies
def _check_body(body: Any, kind: str, inertia: Any = None) -> None:
    """Constant masses and inertias of a body, checked when it is built: masses `> 0`,
    inertias physical ([`lagrax.bodies.check_inertia`][]; semidefinite, so slender rods
    and point-like bodies pass). Parameter-valued ones (callables such as
    [`Param`][lagrax.bodies.Param]) are read from `params` later and are not checked here.
    `inertia`: the body's, for the kinds that have one (a point mass has none)."""
    if not callable(body.mass) and not is_traced(body.mass):
        physical(body.mass, f"{kind} mass", positive=True, item="body")
    if inertia is not None and not callable(inertia) and not is_traced(inertia):
        arr = np.asarray(inertia, dtype=float)
        if kind == "PlanarBody" and arr.ndim > 1:
            raise ShapeError(f"PlanarBody inertia must be a scalar or (k,), got shape {arr.shape}")
        check_inertia(arr, name=f"{kind} inertia", semidefinite=True)


class AbstractBody(eqx.Module):
    """A massive body: a kinetic energy and a gravity potential of its centre of mass.

    A body may stand for `k` bodies at once: parameters with a leading axis of length
    `k` (or shared), and kinematics returning `k` positions (and angles / rotations),
    either as a list of `k` values or as one array with the bodies along axis 0. Their
    energies are summed. A list is faster for a few bodies (the energy is then straight-line
    scalar code, which XLA fuses under `vmap`; stacking and re-slicing tiny arrays is
    not); an array suits many bodies. The chains in [`lagrax.chains`][] describe all
    their links with one forward-kinematics function returning lists.
    """

    mass: eqx.AbstractVar[ParamLike]
    position: eqx.AbstractVar[PointFn]

    @abc.abstractmethod
    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        """Kinetic energy `T(q, q̇)` of the body (summed over `k` if batched)."""

    def com_position(self, q: Vector, params: Params) -> Any:
        """Centre of mass `x_c(q)`: `(d,)`, or `k` of them (a list or `(k, d)`)."""
        return point(self.position, q, params)

    @abc.abstractmethod
    def pose(self, q: Vector, params: Params) -> tuple[Any, Any]:
        """`(x_c, orientation)`: the centre of mass and the angle (planar body), the
        rotation matrix (spatial body) or `None` (point mass), as pytrees of per-body
        values (the pose map the scene's equations differentiate)."""

    @abc.abstractmethod
    def check_pose(self, pose: tuple[Any, Any]) -> None:
        """`ShapeError` if the values of [`pose`][lagrax.bodies.AbstractBody.pose] do
        not have this kind of body's shapes."""

    @abc.abstractmethod
    def rotation_terms(
        self, mass: Any, bias: Any, derivatives: tuple[Any, ...], params: Params, dtype: Any
    ) -> tuple[Any, Any]:
        """`M` and `C q̇` with the body's rotational terms added: `J_ωᵀ I J_ω` and
        `J_ωᵀ (I α + ω × I ω)`. `derivatives` are the orientation, its Jacobian in `q`
        (a trailing axis of length `n`), and its first and second derivatives along `q̇`
        (`None` for `M` alone)."""

    def potential_energy(self, q: Vector, params: Params, gravity: Any) -> Scalar:
        """Gravity potential `V = −m g⃗·x_c`.

        `gravity` is a scalar magnitude `g` acting along the negative last axis (−y for a
        planar position, −z for a spatial one) or a full vector `g⃗`.
        """
        x = self.com_position(q, params)
        return _gravity_energy(value(self.mass, params), x, gravity, type(self).__name__)


class PointMass(AbstractBody):
    r"""A point mass at `x(q)`: `T = ½ m ‖ẋ‖²` with `ẋ = (∂x/∂q) q̇` by `jax.jvp`.

    Works in any dimension `d` (1, 2 or 3); gravity acts along the negative last axis.

    **Arguments:**

    - `mass`: `m`, a constant or a callable of `params` ([`ParamLike`][lagrax.bodies.ParamLike]).
    - `position`: `x(q, params) -> (d,)`; for `k` masses, a list of `k` such points
      or a `(k, d)` array, with `mass` shared or of shape `(k,)`.

    **Example:** a simple pendulum of length `l` hanging from the origin:

    ```python
    bob = PointMass(Param("m"), lambda q, p: p["l"] * jnp.stack([jnp.sin(q[0]), -jnp.cos(q[0])]))
    system = Scene([bob], gravity=Param("g"), n_dof=1).system()
    ```
    """

    mass: ParamLike
    position: PointFn

    def __check_init__(self):
        _check_body(self, "PointMass")

    def com_position(self, q: Vector, params: Params) -> Any:
        if callable(self.position):
            return self.position(q, params)
        return point(self.position, q, params)

    def pose(self, q: Vector, params: Params) -> tuple[Any, None]:
        """`(x_c, None)`: a point has no orientation."""
        return self.com_position(q, params), None

    def check_pose(self, pose: tuple[Any, Any]) -> None:
        """Any dimension is a point mass's."""

    def rotation_terms(
        self, mass: Any, bias: Any, derivatives: tuple[Any, ...], params: Params, dtype: Any
    ) -> tuple[Any, Any]:
        """`M`, `C q̇` unchanged: a point has no rotational inertia."""
        return mass, bias

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        _, v = jax.jvp(lambda a: self.position(a, params), (q,), (qd,))
        m = value(self.mass, params)
        return 0.5 * _over_bodies(lambda m, v: m * squared_norm(v), [(m, 0)], [(v, 1)])


class PlanarBody(AbstractBody):
    r"""A rigid body moving in the (x, y) plane.

    `T = ½ m ‖v_c‖² + ½ I_c θ̇²` with `v_c = (∂x_c/∂q) q̇` and `θ̇ = (∂θ/∂q) q̇`, both
    from one `jax.jvp` of the user's `(position, angle)`. Gravity acts along −y
    (`V = m g y_c`) unless a gravity vector is given.

    **Arguments:**

    - `mass`: `m` ([`ParamLike`][lagrax.bodies.ParamLike]).
    - `inertia`: `I_c`, the moment of inertia about the z axis through the centre of
      mass ([`ParamLike`][lagrax.bodies.ParamLike]).
    - `position`: `x_c(q, params) -> (2,)`, the centre of mass in the fixed frame.
    - `angle`: `θ(q, params) -> ()`, the body's orientation from the fixed x axis
      (counter-clockwise). `None`: `position` returns the pair `(x_c, θ)` (one
      function for both, when they share work).

    `k` bodies at once: `(k,)` masses and inertias (or shared ones), `position`
    returning a list of `k` points or a `(k, 2)` array, `angle` a list of `k` angles
    or a `(k,)` array.
    """

    mass: ParamLike
    inertia: ParamLike
    position: PointFn
    angle: Callable[[Vector, Params], Any] | None

    def __check_init__(self):
        _check_body(self, "PlanarBody", self.inertia)

    def pose(self, q: Vector, params: Params) -> tuple[Any, Any]:
        """`(x_c, θ)`."""
        if self.angle is None:
            return self.position(q, params)
        return self.position(q, params), self.angle(q, params)

    def com_position(self, q: Vector, params: Params) -> Any:
        return self.pose(q, params)[0]

    def check_pose(self, pose: tuple[Any, Any]) -> None:
        """Positions `(2,)` and angles `()` per body."""
        check_shape(per_body(pose[0], 1), (2,), "PlanarBody", "position")
        check_shape(per_body(pose[1], 0), (), "PlanarBody", "angle")

    def rotation_terms(
        self, mass: Any, bias: Any, derivatives: tuple[Any, ...], params: Params, dtype: Any
    ) -> tuple[Any, Any]:
        """`M + Σ I J_θᵀ J_θ` and `C q̇ + Σ I J_θᵀ θ̈|_{q̈=0}`."""
        _, jacobian, _, acc = derivatives
        jw = batch(jacobian, 1)  # (k, n)
        inertia = per_item(value(self.inertia, params), jw.shape[0], 0, dtype)
        mass = mass + jnp.einsum("k,ki,kj->ij", inertia, jw, jw)
        if acc is not None:
            bias = bias + jnp.einsum("k,ki,k->i", inertia, jw, batch(acc, 0))
        return mass, bias

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        _, (v, w) = jax.jvp(lambda a: self.pose(a, params), (q,), (qd,))
        check_shape(per_body(v, 1), (2,), "PlanarBody", "position")
        check_shape(per_body(w, 0), (), "PlanarBody", "angle")
        m, inertia = value(self.mass, params), value(self.inertia, params)
        return 0.5 * _over_bodies(
            lambda m, i, v, w: m * squared_norm(v) + i * w**2,
            [(m, 0), (inertia, 0)],
            [(v, 1), (w, 0)],
        )


def _body_rates(rot, rot_dot):
    """Body-frame angular velocity from `ω̂ = Rᵀ Ṙ` (its skew part `½ (ω̂ − ω̂ᵀ)`).

    Returns the three components (each of shape `rot.shape[:-2]`) as a list;
    `ω̂_ij = Σ_k R_ki Ṙ_kj` is written out (see `lagrax._multibody.common.UNROLL`).
    """

    def hat(i, j):
        return dot_last(rot[..., :, i], rot_dot[..., :, j])

    return [
        0.5 * (hat(2, 1) - hat(1, 2)),
        0.5 * (hat(0, 2) - hat(2, 0)),
        0.5 * (hat(1, 0) - hat(0, 1)),
    ]


def _spatial_energy(m, inertia, v, rot, rot_dot):
    """`m ‖v‖² + ω_Bᵀ I ω_B` (twice the kinetic energy), written out."""
    omega = _body_rates(rot, rot_dot)
    total = m * squared_norm(v)
    for i in range(3):
        for j in range(i, 3):
            total = total + inertia[..., i, j] * omega[i] * omega[j] * (1.0 if i == j else 2.0)
    return total


class SpatialBody(AbstractBody):
    r"""A rigid body moving in space.

    With `R(q)` the rotation from body to world components and `x_c(q)` the centre of
    mass in the world frame, one `jax.jvp` gives `v_c = ẋ_c` and `Ṙ`; the angular
    velocity in the body frame is read off `ω̂_B = Rᵀ Ṙ` (skew-symmetric because
    `RᵀR = 1`), and

    $$
    T = ½ m ‖v_c‖² + ½ ω_Bᵀ I_c ω_B
    $$

    with `I_c` the inertia about the centre of mass in body axes (constant). Gravity acts
    along −z (`V = m g z_c`) unless a gravity vector is given.

    **Arguments:**

    - `mass`: `m` ([`ParamLike`][lagrax.bodies.ParamLike]).
    - `inertia`: `I_c`, `(3, 3)` about the centre of mass in body axes
      ([`ParamLike`][lagrax.bodies.ParamLike]; see [`check_inertia`][lagrax.bodies.check_inertia]).
    - `position`: `x_c(q, params) -> (3,)`.
    - `rotation`: `R(q, params) -> (3, 3)`, a rotation matrix (body → world).
      `None`: `position` returns the pair `(x_c, R)` (one function for both, e.g. a
      chain's forward kinematics, traced once instead of twice).

    `k` bodies at once: `(k,)` masses and `(k, 3, 3)` inertias (or shared ones),
    positions and rotations as lists of `k` or arrays `(k, 3)`, `(k, 3, 3)`.
    """

    mass: ParamLike
    inertia: ParamLike
    position: PointFn
    rotation: Callable[[Vector, Params], Rotation] | None

    def __check_init__(self):
        _check_body(self, "SpatialBody", self.inertia)

    def pose(self, q: Vector, params: Params) -> tuple[Any, Any]:
        """`(x_c, R)`."""
        if self.rotation is None:
            return self.position(q, params)
        return self.position(q, params), self.rotation(q, params)

    def com_position(self, q: Vector, params: Params) -> Any:
        return self.pose(q, params)[0]

    def check_pose(self, pose: tuple[Any, Any]) -> None:
        """Positions `(3,)` and rotations `(3, 3)` per body."""
        check_shape(per_body(pose[0], 1), (3,), "SpatialBody", "position")
        check_shape(per_body(pose[1], 2), (3, 3), "SpatialBody", "rotation")

    def rotation_terms(
        self, mass: Any, bias: Any, derivatives: tuple[Any, ...], params: Params, dtype: Any
    ) -> tuple[Any, Any]:
        """`M + Σ J_ωᵀ I J_ω` with the columns `ω_j = vee(Rᵀ ∂R/∂q_j)` in body axes, and
        `C q̇ + Σ J_ωᵀ (I α + ω × I ω)`."""
        rot_, jacobian, vel, acc = derivatives
        rot, d_rot = batch(rot_, 2), batch(jacobian, 3)  # (k, 3, 3), (k, 3, 3, n)
        inertia = per_item(value(self.inertia, params), rot.shape[0], 2, dtype)
        omega_cols = vee(jnp.einsum("kai,kajn->kijn", rot, d_rot))  # (k, 3, n)
        mass = mass + jnp.einsum("kai,kab,kbj->ij", omega_cols, inertia, omega_cols)
        if acc is not None:
            w = vee(jnp.einsum("kai,kaj->kij", rot, batch(vel, 2))[..., None])[..., 0]
            al = vee(jnp.einsum("kai,kaj->kij", rot, batch(acc, 2))[..., None])[..., 0]
            iw = jnp.einsum("kab,kb->ka", inertia, w)
            torque = jnp.einsum("kab,kb->ka", inertia, al) + jnp.cross(w, iw)
            bias = bias + jnp.einsum("kai,ka->i", omega_cols, torque)
        return mass, bias

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        (_, rot), (v, rot_dot) = jax.jvp(lambda a: self.pose(a, params), (q,), (qd,))
        check_shape(per_body(v, 1), (3,), "SpatialBody", "position")
        check_shape(per_body(rot_dot, 2), (3, 3), "SpatialBody", "rotation")
        m, inertia = value(self.mass, params), jnp.asarray(value(self.inertia, params))
        return 0.5 * _over_bodies(
            _spatial_energy,
            [(m, 0), (inertia, 2)],
            [(v, 1), (rot, 2), (rot_dot, 2)],
        )
