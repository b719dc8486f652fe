"""Springs and dampers: potential and Rayleigh dissipation terms of a scene."""

import abc
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from ..._core.custom_types import Params, Scalar, Vector
from ..common import coordinate, dot_last, point, small_sum, squared_norm, value
from .bodies import ParamLike, PointFn


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
        d = point(self.a, q, params)
        if self.b is not None:
            d = d - point(self.b, q, params)
        d2 = squared_norm(d)
        k = value(self.stiffness, params)
        if isinstance(self.rest_length, (int, float)) and self.rest_length == 0:
            return 0.5 * small_sum(k * d2)
        stretch = _safe_norm(d2) - value(self.rest_length, params)
        return 0.5 * small_sum(k * stretch**2)


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
        theta = coordinate(self.coordinate, q, params)
        k = value(self.stiffness, params)
        return 0.5 * small_sum(k * (theta - value(self.rest_angle, params)) ** 2)


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
            d = point(self.a, x, params)
            return d if self.b is None else d - point(self.b, x, params)

        d, w = jax.jvp(sep, (q,), (qd,))
        c = value(self.coefficient, params)
        if not self.axial:
            return 0.5 * small_sum(c * squared_norm(w))
        d2 = squared_norm(d)
        length = _safe_norm(d2)
        rate = dot_last(d, w) / jnp.where(d2 > 0, length, 1.0)
        return 0.5 * small_sum(c * rate**2)


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
            _, rate = jax.jvp(lambda a: coordinate(self.coordinate, a, params), (q,), (qd,))
        else:
            rate = qd[self.coordinate]
        return 0.5 * small_sum(value(self.coefficient, params) * rate**2)
