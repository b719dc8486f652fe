"""A tree's static descriptions, checked: joint names, position limits, positive
bounds (velocity, effort) and mimic entries."""

import math
from typing import Any

import numpy as np

from ..._core.errors import ConfigurationError


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
