"""A tree's static descriptions, checked (joint names, position limits, positive
bounds (velocity, effort), mimic entries, axes and rotations), and its joint damping."""

import math
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._core.checks import param_shapes
from ..._core.errors import ConfigurationError
from .. import joint_space
from ..common import rotation_tuple, unit_vector


def names_of(values: Any, n: int, default: str, what: str) -> tuple[str, ...]:
    if values is None:
        return tuple(f"{default}{i}" for i in range(n))
    out = tuple(str(v) for v in values)
    if len(out) != n:
        raise ConfigurationError(f"{n} joints need {n} {what}, got {len(out)}")
    if len(set(out)) != n:
        raise ConfigurationError(f"{what} must be distinct, got {out}")
    return out


def joint_limits_of(values: Any, n: int) -> tuple[tuple[float, float], ...]:
    if values is None:
        return tuple((-math.inf, math.inf) for _ in range(n))
    arr = np.asarray(values, float)
    if arr.size == 0:  # no pairs (a tree with no joints)
        arr = arr.reshape(0, 2)
    if arr.shape != (n, 2) or np.any(np.isnan(arr)) or np.any(arr[:, 0] > arr[:, 1]):
        raise ConfigurationError(f"limits must be {n} pairs (lower <= upper), got {values!r}")
    return tuple((float(lo), float(hi)) for lo, hi in arr)


def positive_bounds(values: Any, n: int, what: str) -> tuple[float, ...]:
    if values is None:
        return (math.inf,) * n
    arr = np.broadcast_to(np.asarray(values, float), (n,))
    if np.any(~(arr > 0)):
        raise ConfigurationError(f"{what} must be positive (inf: none), got {values!r}")
    return tuple(float(x) for x in arr)


def mimic_entries(values: Any, n: int) -> tuple[tuple[int, int, float, float], ...]:
    """Mimic entries `(body, master, multiplier, offset)`, sorted by body and checked."""
    if not values:
        return ()
    items = [(b, *v) for b, v in values.items()] if isinstance(values, dict) else list(values)
    out = []
    for item in items:
        try:
            body, master, multiplier, offset = item
            body, master = int(body), int(master)
            multiplier, offset = float(multiplier), float(offset)
        except (TypeError, ValueError):
            raise ConfigurationError(
                f"a mimic entry is (body, master, multiplier, offset), got {item!r}"
            ) from None
        if not (0 <= body < n and 0 <= master < n) or body == master:
            raise ConfigurationError(
                f"mimic entry {item!r}: body and master must be two different bodies 0..{n - 1}"
            )
        if not (math.isfinite(multiplier) and math.isfinite(offset)):
            raise ConfigurationError(f"mimic entry {item!r}: multiplier and offset must be finite")
        out.append((body, master, multiplier, offset))
    bodies = [b for b, *_ in out]
    if len(set(bodies)) != len(bodies):
        raise ConfigurationError(f"mimic: a body mimics two joints, got {values!r}")
    for body, master, *_ in out:
        if master in bodies:
            raise ConfigurationError(
                f"mimic: body {body}'s master {master} is itself a mimic; give the master "
                "at the end of the chain (compose the multipliers and offsets)"
            )
    return tuple(sorted(out))


def structure(
    joint_types: str, axes: Any, rotations: Any, up: Any
) -> tuple[tuple[tuple[float, float, float], ...], tuple, tuple[float, float, float]]:
    """The static joint axes (normalized), fixed rotations and `up` of `n =
    len(joint_types)` joints (defaults: z axes, identity rotations);
    `ConfigurationError` for lists of the wrong length or values that are not unit
    vectors and rotations."""
    n = len(joint_types)
    axes = [(0.0, 0.0, 1.0)] * n if axes is None else list(axes)
    rotations = [np.eye(3)] * n if rotations is None else list(rotations)
    if len(axes) != n:
        raise ConfigurationError(f"{n} joints need {n} axes, got {len(axes)}")
    if len(rotations) != n:
        raise ConfigurationError(f"{n} joints need {n} fixed rotations, got {len(rotations)}")
    return (
        tuple(unit_vector(a, f"axes[{i}]") for i, a in enumerate(axes)),
        tuple(rotation_tuple(r, f"rotations[{i}]") for i, r in enumerate(rotations)),
        unit_vector(up, "up"),
    )


def joint_damping(q, qd, params):
    """Rayleigh dissipation of viscous joint friction: `D = ½ Σ b_i q̇_i²` (`q̇`: the
    rates of all joints, mimic ones included)."""
    param_shapes(
        params,
        {"damping": jnp.shape(qd)},
        f"the joint damping of {jnp.shape(qd)[0]} joints (mimic ones included)",
        ("damping",),
    )
    tendons = joint_space.tendon_dissipation(params, qd)  # fixed tendons' damping, if any
    friction = joint_space.friction_dissipation(params, qd)  # friction loss, if any
    return 0.5 * jnp.sum(jnp.asarray(params["damping"]) * qd**2) + tendons + friction


class CoupledDamping(eqx.Module):
    """The joint damping of a tree with mimic joints: `D = ½ Σ b_i θ̇_i²` over all
    joints, with `θ̇ = J q̇` (a damped mimic joint brakes its master)."""

    tree: Any  # an AbstractTree

    def __call__(self, q, qd, params):
        return joint_damping(q, self.tree.joint_rates(qd), params)
