"""The arguments of a `ContactSystem`, checked: its spheres, its coefficients (numbers
now, functions of `params` when `check_state` runs) and `max_penetration`."""

import math
from collections.abc import Callable
from typing import Any

import equinox as eqx
import numpy as np

from .._core.errors import ArgumentTypeError, ConfigurationError
from .geometry import Sphere, real_number
from .shapes import Box, Capsule

Coefficient = float | Callable[[Any], Any] | None


def coefficient(name: str, value: Coefficient, *, allow_none: bool) -> Coefficient:
    """A number (checked now: finite, `>= 0`) or a function of `params` (checked when
    `check_state` runs)."""
    if value is None:
        if not allow_none:
            raise ConfigurationError(f"ContactSystem's {name} must be given")
        return None
    if callable(value):
        return value
    if isinstance(value, (bool, np.bool_)):
        raise ArgumentTypeError(f"ContactSystem's {name} must be a real number, got {value!r}")
    x = real_number(value, f"ContactSystem's {name} must be a real number or a function of params")
    if not (math.isfinite(x) and x >= 0):
        raise ConfigurationError(
            f"ContactSystem's {name} must be finite and >= 0, got {name}={value!r}"
        )
    return x


def sphere_tuple(spheres: Any, plane: Any) -> tuple[Sphere, ...]:
    """`spheres=` as a tuple of `Sphere`s (a `Capsule` or `Box` stands for its own),
    each oriented for the plane's dimension (or, without a plane, all alike)."""
    items = (spheres,) if isinstance(spheres, (Sphere, Capsule, Box)) else tuple(spheres)
    out = tuple(
        part for x in items for part in (x.spheres if isinstance(x, (Capsule, Box)) else (x,))
    )
    if not out or not all(isinstance(s, Sphere) for s in out):
        raise ConfigurationError(
            f"ContactSystem needs one or more lagrax.contact.Sphere (or Capsule, Box), got {out!r}"
        )
    planar = any(s.angle is not None for s in out)
    if planar and any(s.rotation is not None for s in out):
        raise ConfigurationError(
            "the Spheres mix angle= (planar) and rotation= (spatial) orientations"
        )
    dim = getattr(plane, "dim", None)
    if planar and dim == 3:
        raise ConfigurationError(
            "a Sphere with angle= (a planar body's orientation) needs a 2-D plane; this plane "
            "is 3-D: give rotation= instead"
        )
    if any(s.rotation is not None for s in out) and dim == 2:
        raise ConfigurationError(
            "a Sphere with rotation= (a 3x3 rotation matrix) needs a 3-D plane; this plane is "
            "2-D: give angle= instead"
        )
    return out


def limit_coefficient(name: str, value: Any) -> Coefficient:
    """A joint limits' coefficient: `None`, a function of `params`, or a number or one
    per limit (checked now: finite, `>= 0`)."""
    if value is None or callable(value):
        return value
    arr = np.asarray(value, float) if not isinstance(value, (bool, np.bool_)) else None
    if arr is None or arr.ndim > 1 or not (np.all(np.isfinite(arr)) and np.all(arr >= 0)):
        raise ConfigurationError(
            f"ContactSystem's {name} must be finite numbers >= 0 (one, or one per limit) or "
            f"a function of params, got {name}={value!r}"
        )
    return float(arr) if arr.ndim == 0 else tuple(arr.tolist())


def max_penetration(value: Any) -> float | None:
    """`max_penetration=`, checked: a finite number > 0, or `None`."""
    if value is None:
        return None
    x = real_number(value, "ContactSystem's max_penetration must be a number or None")
    if not (math.isfinite(x) and x > 0):
        raise ConfigurationError(
            f"ContactSystem's max_penetration must be finite and > 0 (or None), got "
            f"max_penetration={value!r}"
        )
    return x


def check_limit_coefficients(contact, co) -> None:
    """Eagerly: a `ConfigurationError` naming a joint limit's stiffness or dissipation
    (read from `params` or scaled) that is not finite, negative, or a zero stiffness."""
    for label, value, rule in (
        ("limit_stiffness", co.limit_stiffness, "> 0"),
        ("limit_dissipation", co.limit_dissipation, ">= 0"),
    ):
        for j, x in enumerate(np.asarray(value, float).tolist()):
            if not math.isfinite(x) or x < 0 or (rule == "> 0" and x == 0):
                raise ConfigurationError(
                    f"the contact of {contact.name} has {label}={x!r} on the limit of "
                    f"joint {contact.limits[j].name or contact.limits[j].index!r}; it must be "
                    f"finite and {rule}"
                )


def applied(force: Any, actuation: Any) -> tuple[Any, Any]:
    """`(force, actuation)` checked: a function `F(t, q, v, params)` or `None`, and an
    equinox Module called as `actuation(u, q, v)` with an `n_u`, or `None`."""
    if force is not None and not callable(force):
        raise ArgumentTypeError(
            f"ContactSystem's force must be a function F(t, q, v, params), got {force!r}"
        )
    if actuation is not None and not (callable(actuation) and isinstance(actuation, eqx.Module)):
        raise ArgumentTypeError(
            "ContactSystem's actuation must be an equinox Module called as "
            f"actuation(u, q, v) with an n_u (an MJCFActuation), got {actuation!r}"
        )
    return force, actuation
