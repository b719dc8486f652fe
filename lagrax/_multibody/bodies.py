"""Bodies, springs and dampers as energy terms; a `Scene` sums them into a system.

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

from .._core.checks import is_traced, physical
from .._core.custom_types import Params, Point, Rotation, Scalar, Vector
from .._core.errors import ShapeError
from .._systems.lagrangian import DissipationFn, ForceFn, KineticFn, LagrangianSystem, PotentialFn
from .inertia import check_inertia

ParamLike = Any
"""A parameter-valued field: a constant (number or array), or a callable `params -> value`
(for example [`Param`][lagrax.bodies.Param]), evaluated each time the energy is."""

PointFn = Callable[[Vector, Params], Point]
"""`(q, params) -> (d,)` or `(k, d)`: a point (or `k` points) as a function of `q`."""


def _value(x: ParamLike, params: Params) -> Any:
    """Resolve a parameter-valued field: call it on `params` if callable."""
    return x(params) if callable(x) else x


def _point(x: PointFn | Any, q: Vector, params: Params) -> Point:
    """A point given as a function of `(q, params)` or as a constant (a fixed anchor)."""
    if callable(x):
        return jnp.asarray(x(q, params))
    return jnp.asarray(x, dtype=jnp.result_type(q))


def _coordinate(x: int | Callable, q: Vector, params: Params) -> Scalar:
    if callable(x):
        return jnp.asarray(x(q, params))
    return q[x]


# Reductions over axes this short are written out as scalar additions. Under ``vmap`` and
# the nested forward-mode derivatives of ``LagrangianSystem``, XLA fuses straight-line
# scalar arithmetic into one loop but not reductions over tiny axes (a (B, 2) ``sum`` is its
# own kernel): writing them out made the vmapped forward dynamics of the 2R arm ~10x faster.
_UNROLL = 32


def _sum(x) -> Scalar:
    """Sum of all elements (written out when there are few)."""
    x = jnp.asarray(x)
    if x.ndim == 0:
        return x
    if x.size > _UNROLL:
        return jnp.sum(x)
    flat = [x[idx] for idx in np.ndindex(*x.shape)]
    total = flat[0]
    for term in flat[1:]:
        total = total + term
    return total


def _dot(a, b):
    """`Σ_i a[..., i] b[..., i]` over the (short) last axis, written out."""
    terms = [a[..., i] * b[..., i] for i in range(a.shape[-1])]
    total = terms[0]
    for term in terms[1:]:
        total = total + term
    return total


def _sq(a):
    """`‖a‖²` over the last axis."""
    return _dot(a, a)


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


def _items(x, base_ndim: int):
    """The per-body values of a kinematic output: a list for a list/tuple of `k` bodies
    (or a single body), or the array itself when it holds the bodies along axis 0."""
    if isinstance(x, (list, tuple)):
        return [jnp.asarray(e) for e in x]
    x = jnp.asarray(x)
    if x.ndim == base_ndim:
        return [x]
    return x


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
    parts = [_items(x, nd) for x, nd in kinematics]
    if all(isinstance(x, jax.Array) for x in parts):  # vectorized over many bodies
        return _sum(fn(*(v for v, _ in params), *parts))
    parts = [x if isinstance(x, list) else [x[i] for i in range(x.shape[0])] for x in parts]
    count = len(parts[0])
    if any(len(x) != count for x in parts):
        raise ShapeError(f"the pose gives different numbers of bodies: {[len(x) for x in parts]}")
    total = None
    for i in range(count):
        term = fn(*(_pick(v, nd, i) for v, nd in params), *(x[i] for x in parts))
        total = term if total is None else total + term
    return total


def _check_shape(items, shape: tuple, who: str, what: str) -> None:
    """Each body's value (a list item, or an array row) must have `shape`."""
    got = items[0].shape if isinstance(items, list) else items.shape[1:]
    if got != shape:
        raise ShapeError(f"{who}: {what} must give shape {shape} per body, got {got}")


def _gravity_energy(mass, x, gravity, who: str) -> Scalar:
    """`V = −Σ m g⃗·x`; a scalar `g` means `g⃗ = −g e_last` (−y in 2-D, −z in 3-D)."""
    g = jnp.asarray(gravity) if not isinstance(gravity, (int, float)) else gravity
    if jnp.ndim(g) == 0:
        return _over_bodies(lambda m, x: m * g * x[..., -1], [(mass, 0)], [(x, 1)])
    items = _items(x, 1)
    dim = (items[0] if isinstance(items, list) else items).shape[-1]
    if g.shape != (dim,):
        raise ShapeError(
            f"gravity vector has shape {g.shape} but the positions of {who} are "
            f"{dim}-dimensional; give a ({dim},) vector or a scalar magnitude"
        )
    return -_over_bodies(lambda m, x: m * _dot(x, g), [(mass, 0)], [(x, 1)])


# ---------------------------------------------------------------------------------- bodies
def _check_body(body: Any, kind: str) -> None:
    """Constant masses and inertias of a body, checked when it is built: masses `> 0`,
    inertias physical ([`lagrax.bodies.check_inertia`][]; semidefinite, so slender rods
    and point-like bodies pass). Parameter-valued ones (callables such as
    [`Param`][lagrax.bodies.Param]) are read from `params` later and are not checked here."""
    if not callable(body.mass) and not is_traced(body.mass):
        physical(body.mass, f"{kind} mass", positive=True, item="body")
    inertia = getattr(body, "inertia", None)
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
        return _point(self.position, q, params)

    def potential_energy(self, q: Vector, params: Params, gravity: Any) -> Scalar:
        """Gravity potential `V = −m g⃗·x_c`.

        `gravity` is a scalar magnitude `g` acting along the negative last axis (−y for a
        planar position, −z for a spatial one) or a full vector `g⃗`.
        """
        x = self.com_position(q, params)
        return _gravity_energy(_value(self.mass, params), x, gravity, type(self).__name__)


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
        return _point(self.position, q, params)

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        _, v = jax.jvp(lambda a: self.position(a, params), (q,), (qd,))
        m = _value(self.mass, params)
        return 0.5 * _over_bodies(lambda m, v: m * _sq(v), [(m, 0)], [(v, 1)])


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
        _check_body(self, "PlanarBody")

    def _pose(self, q, params):
        if self.angle is None:
            return self.position(q, params)
        return self.position(q, params), self.angle(q, params)

    def com_position(self, q: Vector, params: Params) -> Any:
        return self._pose(q, params)[0]

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        _, (v, w) = jax.jvp(lambda a: self._pose(a, params), (q,), (qd,))
        _check_shape(_items(v, 1), (2,), "PlanarBody", "position")
        _check_shape(_items(w, 0), (), "PlanarBody", "angle")
        m, inertia = _value(self.mass, params), _value(self.inertia, params)
        return 0.5 * _over_bodies(
            lambda m, i, v, w: m * _sq(v) + i * w**2,
            [(m, 0), (inertia, 0)],
            [(v, 1), (w, 0)],
        )


def _body_rates(rot, rot_dot):
    """Body-frame angular velocity from `ω̂ = Rᵀ Ṙ` (its skew part `½ (ω̂ − ω̂ᵀ)`).

    Returns the three components (each of shape `rot.shape[:-2]`) as a list;
    `ω̂_ij = Σ_k R_ki Ṙ_kj` is written out (see `_UNROLL`).
    """

    def hat(i, j):
        return _dot(rot[..., :, i], rot_dot[..., :, j])

    return [
        0.5 * (hat(2, 1) - hat(1, 2)),
        0.5 * (hat(0, 2) - hat(2, 0)),
        0.5 * (hat(1, 0) - hat(0, 1)),
    ]


def _spatial_energy(m, inertia, v, rot, rot_dot):
    """`m ‖v‖² + ω_Bᵀ I ω_B` (twice the kinetic energy), written out."""
    omega = _body_rates(rot, rot_dot)
    total = m * _sq(v)
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
        _check_body(self, "SpatialBody")

    def _pose(self, q, params):
        if self.rotation is None:
            return self.position(q, params)
        return self.position(q, params), self.rotation(q, params)

    def com_position(self, q: Vector, params: Params) -> Any:
        return self._pose(q, params)[0]

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        (_, rot), (v, rot_dot) = jax.jvp(lambda a: self._pose(a, params), (q,), (qd,))
        _check_shape(_items(v, 1), (3,), "SpatialBody", "position")
        _check_shape(_items(rot_dot, 2), (3, 3), "SpatialBody", "rotation")
        m, inertia = _value(self.mass, params), jnp.asarray(_value(self.inertia, params))
        return 0.5 * _over_bodies(
            _spatial_energy,
            [(m, 0), (inertia, 2)],
            [(v, 1), (rot, 2), (rot_dot, 2)],
        )


# ------------------------------------------------------------------- springs and dampers
class AbstractSpring(eqx.Module):
    """A conservative element: a potential energy `V(q)`."""

    @abc.abstractmethod
    def potential_energy(self, q: Vector, params: Params) -> Scalar:
        """Its potential energy."""


def _safe_norm(d2):
    pos = d2 > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, d2, 1.0)), 0.0)


class LinearSpring(AbstractSpring):
    r"""A linear spring between two points: `V = ½ k (‖x_a − x_b‖ − L₀)²`.

    With `L₀ = 0` (the default) this is `V = ½ k ‖x_a − x_b‖²`, smooth everywhere; with
    `L₀ > 0` the force direction is undefined when the points meet (the gradient is taken
    as zero there).

    **Arguments:**

    - `stiffness`: `k` ([`ParamLike`][lagrax.bodies.ParamLike]).
    - `a`: the first end, `x_a(q, params) -> (d,)` or a constant point (a fixed anchor).
    - `b`: the second end, likewise; default the origin.
    - `rest_length`: `L₀` ([`ParamLike`][lagrax.bodies.ParamLike], default 0).
    """

    stiffness: ParamLike
    a: PointFn | Any
    b: PointFn | Any | None = None
    rest_length: ParamLike = 0.0

    def potential_energy(self, q: Vector, params: Params) -> Scalar:
        d = _point(self.a, q, params)
        if self.b is not None:
            d = d - _point(self.b, q, params)
        d2 = _sq(d)
        k = _value(self.stiffness, params)
        if isinstance(self.rest_length, (int, float)) and self.rest_length == 0:
            return 0.5 * _sum(k * d2)
        stretch = _safe_norm(d2) - _value(self.rest_length, params)
        return 0.5 * _sum(k * stretch**2)


class TorsionalSpring(AbstractSpring):
    r"""A spring on one coordinate (or any scalar function of `q`): `V = ½ k (θ − θ₀)²`.

    **Arguments:**

    - `stiffness`: `k` ([`ParamLike`][lagrax.bodies.ParamLike]).
    - `coordinate`: the index `i` of `θ = q_i`, or a function `θ(q, params)` (e.g. a
      relative angle `q[1] − q[0]`).
    - `rest_angle`: `θ₀` ([`ParamLike`][lagrax.bodies.ParamLike], default 0).
    """

    stiffness: ParamLike
    coordinate: int | Callable[[Vector, Params], Any] = eqx.field(static=True)
    rest_angle: ParamLike = 0.0

    def potential_energy(self, q: Vector, params: Params) -> Scalar:
        theta = _coordinate(self.coordinate, q, params)
        k = _value(self.stiffness, params)
        return 0.5 * _sum(k * (theta - _value(self.rest_angle, params)) ** 2)


class AbstractDamper(eqx.Module):
    """A dissipative element: a Rayleigh function `D(q, q̇)`; its force is `−∂D/∂q̇`."""

    @abc.abstractmethod
    def dissipation(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        """Its Rayleigh dissipation function (half the power it dissipates)."""


class LinearDamper(AbstractDamper):
    r"""A viscous damper between two points, by their relative velocity `w = ẋ_a − ẋ_b`.

    - `axial=False` (default): `D = ½ c ‖w‖²`, a force `−c w` opposing the whole
      relative velocity (viscous drag; with `b` omitted, drag against the fixed frame).
    - `axial=True`: a dashpot along the line between the points,
      `D = ½ c L̇²` with `L̇ = (x_a − x_b)·w / ‖x_a − x_b‖`; it resists only changes of
      length (undefined when the points meet; taken as zero there).

    Velocities come from `jax.jvp` of the point functions.

    **Arguments:**

    - `coefficient`: `c` ([`ParamLike`][lagrax.bodies.ParamLike]).
    - `a`, `b`: the ends, functions `(q, params) -> (d,)` or constants; `b` defaults
      to a fixed point (the origin).
    - `axial`: see above.
    """

    coefficient: ParamLike
    a: PointFn | Any
    b: PointFn | Any | None = None
    axial: bool = eqx.field(default=False, static=True)

    def dissipation(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        def sep(x):
            d = _point(self.a, x, params)
            return d if self.b is None else d - _point(self.b, x, params)

        d, w = jax.jvp(sep, (q,), (qd,))
        c = _value(self.coefficient, params)
        if not self.axial:
            return 0.5 * _sum(c * _sq(w))
        d2 = _sq(d)
        length = _safe_norm(d2)
        rate = _dot(d, w) / jnp.where(d2 > 0, length, 1.0)
        return 0.5 * _sum(c * rate**2)


class TorsionalDamper(AbstractDamper):
    r"""A viscous damper on one coordinate (or scalar function of `q`): `D = ½ c θ̇²`.

    **Arguments:**

    - `coefficient`: `c` ([`ParamLike`][lagrax.bodies.ParamLike]).
    - `coordinate`: the index `i` of `θ = q_i`, or a function `θ(q, params)`
      (its rate `θ̇` by `jax.jvp`).
    """

    coefficient: ParamLike
    coordinate: int | Callable[[Vector, Params], Any] = eqx.field(static=True)

    def dissipation(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        if callable(self.coordinate):
            _, rate = jax.jvp(lambda a: _coordinate(self.coordinate, a, params), (q,), (qd,))
        else:
            rate = qd[self.coordinate]
        return 0.5 * _sum(_value(self.coefficient, params) * rate**2)


# ------------------------------------------------------------------------------- scene
def _check_members(items, kind, name: str) -> None:
    for i, item in enumerate(items):
        if not isinstance(item, kind):
            raise TypeError(
                f"Scene.{name}[{i}] is a {type(item).__name__}; expected a {kind.__name__} "
                f"subclass (e.g. {', '.join(c.__name__ for c in _EXAMPLES[kind])})"
            )


class Scene(eqx.Module):
    r"""A mechanical scene: the sum of its bodies, springs, dampers and hand-written terms.

    $$
    T = Σ_{bodies} T_b + T_{extra},\qquad
    V = Σ_{bodies} (−m_b g⃗·x_b) + Σ_{springs} V_s + V_{extra},\qquad
    D = Σ_{dampers} D_d + D_{extra}
    $$

    [`system`][lagrax.bodies.Scene.system] turns it into a [`lagrax.LagrangianSystem`][] with these
    energies.

    **Arguments:**

    - `bodies`: [`PointMass`][lagrax.bodies.PointMass], [`PlanarBody`][lagrax.bodies.PlanarBody],
      [`SpatialBody`][lagrax.bodies.SpatialBody] (any mix).
    - `springs`: [`LinearSpring`][lagrax.bodies.LinearSpring],
      [`TorsionalSpring`][lagrax.bodies.TorsionalSpring] (potential terms).
    - `dampers`: [`LinearDamper`][lagrax.bodies.LinearDamper],
      [`TorsionalDamper`][lagrax.bodies.TorsionalDamper] (Rayleigh terms).
    - `gravity`: the gravitational acceleration: a magnitude `g` (default 9.81 m/s²)
      acting along each body's negative last axis (−y for planar positions, −z for spatial
      ones), or a vector `g⃗` of the bodies' dimension; a constant or a callable of
      `params` (e.g. `Param("g")`, so sweeps can vary it); `None` for none.
    - `kinetic`, `potential`, `dissipation`: hand-written extra terms with the
      signatures of [`lagrax.LagrangianSystem`][] (`T(q, qd, params)`,
      `V(q, params)`, `D(q, qd, params)`).
    - `force`: applied generalized force `F(t, q, qd, params)`, passed on to the system.
    - `n_dof`: number of generalized coordinates (recommended: shapes are then checked).
    - `name`: a label for messages and plots.
    - `equations`: how [`system`][lagrax.bodies.Scene.system] evaluates the equations of motion.
      `"poses"`: from the bodies' pose maps (`M = Σ m J_vᵀJ_v + J_ωᵀ I J_ω` from one forward-mode
      Jacobian of the poses, the velocity products from one second-order derivative
      along `q̇`, Newton's and Euler's equations of each body projected on the
      coordinates; no second derivatives of `T`). `"energies"`: by differentiating
      `T` and `V` (the definition; both agree to round-off). `"auto"` (default):
      `"poses"` when the scene has a [`SpatialBody`][lagrax.bodies.SpatialBody] or `n_dof >= 4` and
      no hand-written `kinetic` term, else `"energies"`.
    - `scalar_derivatives`: passed to [`lagrax.LagrangianSystem`][]. Default `None`:
      `False` when the scene has a [`SpatialBody`][lagrax.bodies.SpatialBody] (the energy of
      rotation matrices is large; forward-over-reverse derivatives compiled 2–10× faster and ran
      about as fast or faster in `benchmarks/bench_planar_vs_spatial.py`), else the system's
      default.

    **Example:** a damped pendulum on a torsional spring:

    ```python
    import jax.numpy as jnp
    from lagrax.bodies import Param, PlanarBody, Scene, TorsionalDamper, TorsionalSpring

    rod = PlanarBody(
        mass=Param("m"), inertia=lambda p: p["m"] * p["l"] ** 2 / 12,
        position=lambda q, p: 0.5 * p["l"] * jnp.stack([jnp.sin(q[0]), -jnp.cos(q[0])]),
        angle=lambda q, p: q[0],
    )
    scene = Scene([rod], springs=[TorsionalSpring(Param("k"), 0)],
                  dampers=[TorsionalDamper(Param("c"), 0)], gravity=Param("g"), n_dof=1)
    system = scene.system()
    ```
    """

    bodies: tuple[AbstractBody, ...] = eqx.field(default=(), converter=tuple)
    springs: tuple[AbstractSpring, ...] = eqx.field(default=(), converter=tuple)
    dampers: tuple[AbstractDamper, ...] = eqx.field(default=(), converter=tuple)
    gravity: ParamLike | None = 9.81
    kinetic: KineticFn | None = None
    potential: PotentialFn | None = None
    dissipation: DissipationFn | None = None
    force: ForceFn | None = None
    n_dof: int | None = eqx.field(default=None, static=True)
    name: str = eqx.field(default="scene", static=True)
    scalar_derivatives: bool | None = eqx.field(default=None, static=True)
    equations: str = eqx.field(default="auto", static=True)

    def __check_init__(self):
        if self.equations not in _EQUATIONS:
            raise ValueError(
                f"Scene equations must be one of {sorted(_EQUATIONS)}, got {self.equations!r}"
            )
        _check_members(self.bodies, AbstractBody, "bodies")
        _check_members(self.springs, AbstractSpring, "springs")
        _check_members(self.dampers, AbstractDamper, "dampers")
        if not self.bodies and self.kinetic is None:
            raise ValueError("a Scene needs at least one body or a hand-written kinetic energy")

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        """`T = Σ T_b + T_extra`."""
        total = sum(b.kinetic_energy(q, qd, params) for b in self.bodies)
        if self.kinetic is not None:
            total = total + self.kinetic(q, qd, params)
        return jnp.asarray(total)

    def potential_energy(self, q: Vector, params: Params) -> Scalar:
        """`V = Σ gravity of bodies + Σ springs + V_extra`."""
        total = jnp.zeros((), jnp.result_type(q))
        if self.gravity is not None and self.bodies:
            g = _value(self.gravity, params)
            for body in self.bodies:
                total = total + body.potential_energy(q, params, g)
        for spring in self.springs:
            total = total + spring.potential_energy(q, params)
        if self.potential is not None:
            total = total + self.potential(q, params)
        return total

    def dissipation_function(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        """`D = Σ D_d + D_extra`."""
        total = jnp.zeros((), jnp.result_type(q))
        for damper in self.dampers:
            total = total + damper.dissipation(q, qd, params)
        if self.dissipation is not None:
            total = total + self.dissipation(q, qd, params)
        return total

    def system(self) -> LagrangianSystem:
        """The [`lagrax.LagrangianSystem`][] of this scene.

        Terms the scene does not have are left out (no potential without gravity, springs
        or an extra potential; no dissipation without dampers), so they cost nothing.
        """
        has_v = bool(self.springs) or self.potential is not None
        has_v = has_v or (self.gravity is not None and bool(self.bodies))
        has_d = bool(self.dampers) or self.dissipation is not None
        scalar = self.scalar_derivatives
        if scalar is None and any(isinstance(b, SpatialBody) for b in self.bodies):
            scalar = False
        equations = None
        if self._use_poses():
            from .scene_equations import SceneEquations

            equations = SceneEquations(self)
        return LagrangianSystem(
            self.kinetic_energy,
            self.potential_energy if has_v else None,
            dissipation=self.dissipation_function if has_d else None,
            force=self.force,
            n_dof=self.n_dof,
            name=self.name,
            scalar_derivatives=scalar,
            equations=equations,
        )

    def _use_poses(self) -> bool:
        """Whether [`system`][lagrax.bodies.Scene.system] evaluates the equations from the
        bodies' pose maps."""
        if self.equations == "energies" or not self.bodies:
            return False
        if self.kinetic is not None:
            if self.equations == "poses":
                raise ValueError(
                    "Scene(equations='poses') needs every kinetic term to come from bodies; "
                    "this scene has a hand-written kinetic energy"
                )
            return False
        if self.equations == "poses":
            return True
        spatial = any(isinstance(b, SpatialBody) for b in self.bodies)
        return spatial or (self.n_dof is not None and self.n_dof >= _POSES_MIN_PLANAR)


_EQUATIONS = ("auto", "poses", "energies")
# Scenes without spatial bodies use the pose-map equations from this many coordinates: a
# planar chain of bodies ran 1.7x / 3x / 9x faster than autodiff of its energy at n = 4 /
# 6 / 8 (and compiled 2-7x faster); at n = 2 scalar autodiff is 4x faster.
_POSES_MIN_PLANAR = 4

_EXAMPLES = {
    AbstractBody: (PointMass, PlanarBody, SpatialBody),
    AbstractSpring: (LinearSpring, TorsionalSpring),
    AbstractDamper: (LinearDamper, TorsionalDamper),
}
