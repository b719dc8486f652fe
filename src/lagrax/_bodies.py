"""Bodies, springs and dampers as energy terms; a ``Scene`` sums them into a system.

Every element is an ``equinox.Module`` that only *describes* a piece of the scene; its
energy is computed from the user's kinematics by JAX forward-mode differentiation
(``jax.jvp``), so no velocity is ever written by hand.
"""

import abc
from collections.abc import Callable, Mapping
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from ._errors import ShapeError
from ._system import DissipationFn, ForceFn, KineticFn, LagrangianSystem, PotentialFn
from ._typing import Params, Point, Rotation, Scalar, Vector

ParamLike = Any
"""A parameter-valued field: a constant (number or array), or a callable ``params -> value``
(for example :class:`Param`), evaluated each time the energy is."""

PointFn = Callable[[Vector, Params], Point]
"""``(q, params) -> (d,)`` or ``(k, d)``: a point (or ``k`` points) as a function of ``q``."""


def _value(x: ParamLike, params: Params) -> Any:
    """Resolve a parameter-valued field: call it on ``params`` if callable."""
    return x(params) if callable(x) else x


def _point(x: PointFn | Any, q: Vector, params: Params) -> Point:
    """A point given as a function of ``(q, params)`` or as a constant (a fixed anchor)."""
    if callable(x):
        return jnp.asarray(x(q, params))
    return jnp.asarray(x, dtype=jnp.result_type(q))


def _coordinate(x: int | Callable, q: Vector, params: Params) -> Scalar:
    if callable(x):
        return jnp.asarray(x(q, params))
    return q[x]


def _sum(x) -> Scalar:
    return jnp.sum(jnp.asarray(x))


class Param(eqx.Module):
    """A parameter looked up by name: ``Param("m")(params)`` is ``params["m"]``.

    Works for a mapping (``params[key]``) and for a NamedTuple / equinox Module / any object
    (``getattr(params, key)``). Use it wherever a field takes a parameter-valued
    :data:`ParamLike`; unlike a ``lambda`` it compares equal to another ``Param`` of the same
    key, so rebuilding a scene does not recompile jitted code. A missing key is reported by
    the system as a ``ParameterError``.

    **Arguments:**

    - ``key``: the name of the entry.
    """

    key: str = eqx.field(static=True)

    def __call__(self, params: Params) -> Any:
        if isinstance(params, Mapping):
            return params[self.key]
        return getattr(params, self.key)


def _gravity_energy(mass, x: Point, gravity, who: str) -> Scalar:
    """``V = −Σ m g⃗·x``; a scalar ``g`` means ``g⃗ = −g e_last`` (−y in 2-D, −z in 3-D)."""
    g = jnp.asarray(gravity) if not isinstance(gravity, (int, float)) else gravity
    if jnp.ndim(g) == 0:
        return _sum(mass * g * x[..., -1])
    if g.shape != (x.shape[-1],):
        raise ShapeError(
            f"gravity vector has shape {g.shape} but the positions of {who} are "
            f"{x.shape[-1]}-dimensional; give a ({x.shape[-1]},) vector or a scalar magnitude"
        )
    return -_sum(mass * (x @ g))


# ---------------------------------------------------------------------------------- bodies
class AbstractBody(eqx.Module):
    """A massive body: a kinetic energy and a gravity potential of its centre of mass.

    A body may stand for ``k`` bodies at once: fields with a leading axis of length ``k``
    and kinematics returning ``k`` positions (and angles / rotations). Their energies are
    summed. This is how the chains in :mod:`lagrax.chains` describe all their links with
    one (vectorized) forward-kinematics function.
    """

    mass: eqx.AbstractVar[ParamLike]
    position: eqx.AbstractVar[PointFn]

    @abc.abstractmethod
    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        """Kinetic energy ``T(q, q̇)`` of the body (summed over ``k`` if batched)."""

    def com_position(self, q: Vector, params: Params) -> Point:
        """Centre of mass ``x_c(q)`` (``(d,)``, or ``(k, d)`` if batched)."""
        return _point(self.position, q, params)

    def potential_energy(self, q: Vector, params: Params, gravity: Any) -> Scalar:
        """Gravity potential ``V = −m g⃗·x_c``.

        ``gravity`` is a scalar magnitude ``g`` acting along the negative last axis (−y for a
        planar position, −z for a spatial one) or a full vector ``g⃗``.
        """
        x = self.com_position(q, params)
        return _gravity_energy(_value(self.mass, params), x, gravity, type(self).__name__)


def _shape_error(who: str, what: str, shape) -> ShapeError:
    return ShapeError(f"{who}: {what}, got shape {shape}")


class PointMass(AbstractBody):
    r"""A point mass at ``x(q)``: ``T = ½ m ‖ẋ‖²`` with ``ẋ = (∂x/∂q) q̇`` by ``jax.jvp``.

    Works in any dimension ``d`` (1, 2 or 3); gravity acts along the negative last axis.

    **Arguments:**

    - ``mass``: ``m``, a constant or a callable of ``params`` (:data:`ParamLike`).
    - ``position``: ``x(q, params) -> (d,)`` (or ``(k, d)`` for ``k`` masses with a ``(k,)``
      mass).

    **Example:** a simple pendulum of length ``l`` hanging from the origin:

    ```python
    bob = PointMass(Param("m"), lambda q, p: p["l"] * jnp.stack([jnp.sin(q[0]), -jnp.cos(q[0])]))
    system = Scene([bob], gravity=Param("g"), n_dof=1).system()
    ```
    """

    mass: ParamLike
    position: PointFn

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        _, v = jax.jvp(lambda a: jnp.asarray(self.position(a, params)), (q,), (qd,))
        m = _value(self.mass, params)
        return 0.5 * _sum(m * jnp.sum(v**2, axis=-1))


class PlanarBody(AbstractBody):
    r"""A rigid body moving in the (x, y) plane.

    ``T = ½ m ‖v_c‖² + ½ I_c θ̇²`` with ``v_c = (∂x_c/∂q) q̇`` and ``θ̇ = (∂θ/∂q) q̇``, both
    from one ``jax.jvp`` of the user's ``(position, angle)``. Gravity acts along −y
    (``V = m g y_c``) unless a gravity vector is given.

    **Arguments:**

    - ``mass``: ``m`` (:data:`ParamLike`).
    - ``inertia``: ``I_c``, the moment of inertia about the z axis through the centre of
      mass (:data:`ParamLike`).
    - ``position``: ``x_c(q, params) -> (2,)``, the centre of mass in the fixed frame.
    - ``angle``: ``θ(q, params) -> ()``, the body's orientation from the fixed x axis
      (counter-clockwise). ``None``: ``position`` returns the pair ``(x_c, θ)`` (one
      function for both, when they share work).

    With ``(k,)`` masses and inertias, ``position`` may return ``(k, 2)`` and ``angle``
    ``(k,)``: ``k`` bodies sharing one kinematics function.
    """

    mass: ParamLike
    inertia: ParamLike
    position: PointFn
    angle: Callable[[Vector, Params], Any] | None

    def _pose(self, q, params):
        if self.angle is None:
            x, th = self.position(q, params)
        else:
            x, th = self.position(q, params), self.angle(q, params)
        return jnp.asarray(x), jnp.asarray(th)

    def com_position(self, q: Vector, params: Params) -> Point:
        if self.angle is None:
            return jnp.asarray(self.position(q, params)[0])
        return jnp.asarray(self.position(q, params))

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        def pose(a):
            return self._pose(a, params)

        (x, th), (v, w) = jax.jvp(pose, (q,), (qd,))
        if x.shape[-1:] != (2,):
            raise _shape_error("PlanarBody", "position must return (2,) or (k, 2)", x.shape)
        if th.shape != x.shape[:-1]:
            raise _shape_error(
                "PlanarBody",
                f"angle must return shape {x.shape[:-1]} to match position",
                th.shape,
            )
        m, inertia = _value(self.mass, params), _value(self.inertia, params)
        return 0.5 * (_sum(m * jnp.sum(v**2, axis=-1)) + _sum(inertia * w**2))


def _vee_skew(omega_hat):
    """``ω`` from ``ω̂`` (using its skew part: ``½ (ω̂ − ω̂ᵀ)``)."""
    o = omega_hat
    return 0.5 * jnp.stack(
        [o[..., 2, 1] - o[..., 1, 2], o[..., 0, 2] - o[..., 2, 0], o[..., 1, 0] - o[..., 0, 1]],
        axis=-1,
    )


class SpatialBody(AbstractBody):
    r"""A rigid body moving in space.

    With ``R(q)`` the rotation from body to world components and ``x_c(q)`` the centre of
    mass in the world frame, one ``jax.jvp`` gives ``v_c = ẋ_c`` and ``Ṙ``; the angular
    velocity in the body frame is read off ``ω̂_B = Rᵀ Ṙ`` (skew-symmetric because
    ``RᵀR = 1``), and

    .. math:: T = ½ m ‖v_c‖² + ½ ω_Bᵀ I_c ω_B

    with ``I_c`` the inertia about the centre of mass in body axes (constant). Gravity acts
    along −z (``V = m g z_c``) unless a gravity vector is given.

    **Arguments:**

    - ``mass``: ``m`` (:data:`ParamLike`).
    - ``inertia``: ``I_c``, ``(3, 3)`` about the centre of mass in body axes
      (:data:`ParamLike`; see :func:`check_inertia`).
    - ``position``: ``x_c(q, params) -> (3,)``.
    - ``rotation``: ``R(q, params) -> (3, 3)``, a rotation matrix (body → world).
      ``None``: ``position`` returns the pair ``(x_c, R)`` (one function for both, e.g. a
      chain's forward kinematics, traced once instead of twice).

    Batched: ``(k,)`` masses, ``(k, 3, 3)`` inertias, positions ``(k, 3)``, rotations
    ``(k, 3, 3)``.
    """

    mass: ParamLike
    inertia: ParamLike
    position: PointFn
    rotation: Callable[[Vector, Params], Rotation] | None

    def _pose(self, q, params):
        if self.rotation is None:
            x, rot = self.position(q, params)
        else:
            x, rot = self.position(q, params), self.rotation(q, params)
        return jnp.asarray(x), jnp.asarray(rot)

    def com_position(self, q: Vector, params: Params) -> Point:
        if self.rotation is None:
            return jnp.asarray(self.position(q, params)[0])
        return jnp.asarray(self.position(q, params))

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        def pose(a):
            return self._pose(a, params)

        (x, rot), (v, rot_dot) = jax.jvp(pose, (q,), (qd,))
        if x.shape[-1:] != (3,):
            raise _shape_error("SpatialBody", "position must return (3,) or (k, 3)", x.shape)
        if rot.shape != x.shape[:-1] + (3, 3):
            raise _shape_error(
                "SpatialBody",
                f"rotation must return shape {x.shape[:-1] + (3, 3)} to match position",
                rot.shape,
            )
        omega = _vee_skew(jnp.swapaxes(rot, -1, -2) @ rot_dot)  # body frame
        m, inertia = _value(self.mass, params), jnp.asarray(_value(self.inertia, params))
        if inertia.ndim == 2:
            i_omega = omega @ inertia.T
        else:
            i_omega = jnp.einsum("...ij,...j->...i", inertia, omega)
        return 0.5 * (_sum(m * jnp.sum(v**2, axis=-1)) + _sum(jnp.sum(omega * i_omega, -1)))


# ------------------------------------------------------------------- springs and dampers
class AbstractSpring(eqx.Module):
    """A conservative element: a potential energy ``V(q)``."""

    @abc.abstractmethod
    def potential_energy(self, q: Vector, params: Params) -> Scalar:
        """Its potential energy."""


def _safe_norm(d2):
    pos = d2 > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, d2, 1.0)), 0.0)


class LinearSpring(AbstractSpring):
    r"""A linear spring between two points: ``V = ½ k (‖x_a − x_b‖ − L₀)²``.

    With ``L₀ = 0`` (the default) this is ``V = ½ k ‖x_a − x_b‖²``, smooth everywhere; with
    ``L₀ > 0`` the force direction is undefined when the points meet (the gradient is taken
    as zero there).

    **Arguments:**

    - ``stiffness``: ``k`` (:data:`ParamLike`).
    - ``a``: the first end, ``x_a(q, params) -> (d,)`` or a constant point (a fixed anchor).
    - ``b``: the second end, likewise; default the origin.
    - ``rest_length``: ``L₀`` (:data:`ParamLike`, default 0).
    """

    stiffness: ParamLike
    a: PointFn | Any
    b: PointFn | Any | None = None
    rest_length: ParamLike = 0.0

    def potential_energy(self, q: Vector, params: Params) -> Scalar:
        d = _point(self.a, q, params)
        if self.b is not None:
            d = d - _point(self.b, q, params)
        d2 = jnp.sum(d**2, axis=-1)
        k = _value(self.stiffness, params)
        if isinstance(self.rest_length, (int, float)) and self.rest_length == 0:
            return 0.5 * _sum(k * d2)
        stretch = _safe_norm(d2) - _value(self.rest_length, params)
        return 0.5 * _sum(k * stretch**2)


class TorsionalSpring(AbstractSpring):
    r"""A spring on one coordinate (or any scalar function of ``q``): ``V = ½ k (θ − θ₀)²``.

    **Arguments:**

    - ``stiffness``: ``k`` (:data:`ParamLike`).
    - ``coordinate``: the index ``i`` of ``θ = q_i``, or a function ``θ(q, params)`` (e.g. a
      relative angle ``q[1] − q[0]``).
    - ``rest_angle``: ``θ₀`` (:data:`ParamLike`, default 0).
    """

    stiffness: ParamLike
    coordinate: int | Callable[[Vector, Params], Any] = eqx.field(static=True)
    rest_angle: ParamLike = 0.0

    def potential_energy(self, q: Vector, params: Params) -> Scalar:
        theta = _coordinate(self.coordinate, q, params)
        k = _value(self.stiffness, params)
        return 0.5 * _sum(k * (theta - _value(self.rest_angle, params)) ** 2)


class AbstractDamper(eqx.Module):
    """A dissipative element: a Rayleigh function ``D(q, q̇)``; its force is ``−∂D/∂q̇``."""

    @abc.abstractmethod
    def dissipation(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        """Its Rayleigh dissipation function (half the power it dissipates)."""


class LinearDamper(AbstractDamper):
    r"""A viscous damper between two points, by their relative velocity ``w = ẋ_a − ẋ_b``.

    - ``axial=False`` (default): ``D = ½ c ‖w‖²``, a force ``−c w`` opposing the whole
      relative velocity (viscous drag; with ``b`` omitted, drag against the fixed frame).
    - ``axial=True``: a dashpot along the line between the points,
      ``D = ½ c L̇²`` with ``L̇ = (x_a − x_b)·w / ‖x_a − x_b‖``; it resists only changes of
      length (undefined when the points meet; taken as zero there).

    Velocities come from ``jax.jvp`` of the point functions.

    **Arguments:**

    - ``coefficient``: ``c`` (:data:`ParamLike`).
    - ``a``, ``b``: the ends, functions ``(q, params) -> (d,)`` or constants; ``b`` defaults
      to a fixed point (the origin).
    - ``axial``: see above.
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
            return 0.5 * _sum(c * jnp.sum(w**2, axis=-1))
        d2 = jnp.sum(d**2, axis=-1)
        length = _safe_norm(d2)
        rate = jnp.sum(d * w, axis=-1) / jnp.where(d2 > 0, length, 1.0)
        return 0.5 * _sum(c * rate**2)


class TorsionalDamper(AbstractDamper):
    r"""A viscous damper on one coordinate (or scalar function of ``q``): ``D = ½ c θ̇²``.

    **Arguments:**

    - ``coefficient``: ``c`` (:data:`ParamLike`).
    - ``coordinate``: the index ``i`` of ``θ = q_i``, or a function ``θ(q, params)``
      (its rate ``θ̇`` by ``jax.jvp``).
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

    .. math::

        T = Σ_{bodies} T_b + T_{extra},\qquad
        V = Σ_{bodies} (−m_b g⃗·x_b) + Σ_{springs} V_s + V_{extra},\qquad
        D = Σ_{dampers} D_d + D_{extra}

    :meth:`system` turns it into a :class:`lagrax.LagrangianSystem` with these energies.

    **Arguments:**

    - ``bodies``: :class:`PointMass`, :class:`PlanarBody`, :class:`SpatialBody` (any mix).
    - ``springs``: :class:`LinearSpring`, :class:`TorsionalSpring` (potential terms).
    - ``dampers``: :class:`LinearDamper`, :class:`TorsionalDamper` (Rayleigh terms).
    - ``gravity``: the gravitational acceleration: a magnitude ``g`` (default 9.81 m/s²)
      acting along each body's negative last axis (−y for planar positions, −z for spatial
      ones), or a vector ``g⃗`` of the bodies' dimension; a constant or a callable of
      ``params`` (e.g. ``Param("g")``, so sweeps can vary it); ``None`` for none.
    - ``kinetic``, ``potential``, ``dissipation``: hand-written extra terms with the
      signatures of :class:`lagrax.LagrangianSystem` (``T(q, qd, params)``,
      ``V(q, params)``, ``D(q, qd, params)``).
    - ``force``: applied generalized force ``F(t, q, qd, params)``, passed on to the system.
    - ``n_dof``: number of generalized coordinates (recommended: shapes are then checked).
    - ``name``: a label for messages and plots.

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

    def __check_init__(self):
        _check_members(self.bodies, AbstractBody, "bodies")
        _check_members(self.springs, AbstractSpring, "springs")
        _check_members(self.dampers, AbstractDamper, "dampers")
        if not self.bodies and self.kinetic is None:
            raise ValueError("a Scene needs at least one body or a hand-written kinetic energy")

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        """``T = Σ T_b + T_extra``."""
        total = sum(b.kinetic_energy(q, qd, params) for b in self.bodies)
        if self.kinetic is not None:
            total = total + self.kinetic(q, qd, params)
        return jnp.asarray(total)

    def potential_energy(self, q: Vector, params: Params) -> Scalar:
        """``V = Σ gravity of bodies + Σ springs + V_extra``."""
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
        """``D = Σ D_d + D_extra``."""
        total = jnp.zeros((), jnp.result_type(q))
        for damper in self.dampers:
            total = total + damper.dissipation(q, qd, params)
        if self.dissipation is not None:
            total = total + self.dissipation(q, qd, params)
        return total

    def system(self) -> LagrangianSystem:
        """The :class:`lagrax.LagrangianSystem` of this scene.

        Terms the scene does not have are left out (no potential without gravity, springs
        or an extra potential; no dissipation without dampers), so they cost nothing.
        """
        has_v = bool(self.springs) or self.potential is not None
        has_v = has_v or (self.gravity is not None and bool(self.bodies))
        has_d = bool(self.dampers) or self.dissipation is not None
        return LagrangianSystem(
            self.kinetic_energy,
            self.potential_energy if has_v else None,
            dissipation=self.dissipation_function if has_d else None,
            force=self.force,
            n_dof=self.n_dof,
            name=self.name,
        )


_EXAMPLES = {
    AbstractBody: (PointMass, PlanarBody, SpatialBody),
    AbstractSpring: (LinearSpring, TorsionalSpring),
    AbstractDamper: (LinearDamper, TorsionalDamper),
}
