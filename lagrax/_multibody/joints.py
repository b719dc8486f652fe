"""Joint kinds of chains and trees: the one place a new kind of joint is declared.

A joint kind is a letter in a tree's `joint_types` string. Each kind gives the constants
of its joint transform (`joint_constants`): the rotation from the parent's frame to the
body's is `ᵖR_i = A + sin q B + (1 − cos q) C` and the origin slides by `q s` in the
parent's frame. The recursions and the Newton–Euler oracle read `revolute(kind)` for the
one place the kinds differ there (a revolute joint turns about its axis, a prismatic one
slides along it).

To add a kind with one coordinate, add its letter to `KINDS` and its constants to
`_CONSTANTS`, and give the recursions (`tree_equations.spatial_link`,
`spatial_energies`) and the oracle (`newton_euler`) its motion subspace. A joint with
several coordinates (a floating base: a free root joint) adds its coordinates in front of
the tree's, as the root of `parents`.
"""

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .._core.errors import ConfigurationError

KINDS: Mapping[str, str] = {"R": "revolute", "P": "prismatic"}
"""The joint kinds, by letter."""


def parse_joint_types(
    joint_types: Any, aliases: Mapping[str, str] | None = None, *, empty: bool = False
) -> str:
    """`joint_types` upper-cased, with `aliases` (e.g. `{"C": "R"}`: continuous is
    revolute) replaced; `ConfigurationError` for an unknown letter, or an empty string
    unless `empty` (a tree with no joints: a floating base's single rigid body)."""
    types = str(joint_types).upper()
    for alias, kind in (aliases or {}).items():
        types = types.replace(alias, kind)
    if (not types and not empty) or set(types) - set(KINDS):
        names = [f"'{k}' ({v})" for k, v in KINDS.items()]
        names += [f"'{a}' ({KINDS[k]})" for a, k in (aliases or {}).items()]
        kind = "a string" if empty else "a non-empty string"
        raise ConfigurationError(
            f"joint_types must be {kind} of {', '.join(names)}, got {joint_types!r}"
        )
    return types


def revolute(kind: str) -> bool:
    """Whether a joint of this kind turns about its axis (else it slides along it)."""
    return kind == "R"


def revolute_flags(types: str) -> np.ndarray:
    """`1.0` for every revolute joint, `0.0` for every prismatic one, shape `(n,)`."""
    return np.asarray([1.0 if revolute(k) else 0.0 for k in types])


def _skew(a: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _revolute(axis: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, ...]:
    k = _skew(axis)
    return rot, rot @ k, rot @ k @ k, np.zeros(3)


def _prismatic(axis: np.ndarray, rot: np.ndarray) -> tuple[np.ndarray, ...]:
    zero = np.zeros((3, 3))
    return rot, zero, zero, rot @ axis


_CONSTANTS: Mapping[str, Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, ...]]] = {
    "R": _revolute,
    "P": _prismatic,
}


def joint_constants(types: str, axes: Any, rotations: Any) -> tuple[np.ndarray, ...]:
    """Per-joint constants `(A, B, C, s)`, stacked: ``ⁱ⁻¹R_i = A + sin q B +
    (1 − cos q) C` and the origin slides by `q s` in frame `i − 1``.

    Revolute (Rodrigues): `A = S`, `B = S [a]×`, `C = S [a]×²`, `s = 0`;
    prismatic: `A = S`, `B = C = 0`, `s = S a`.
    """
    consts = [
        _CONSTANTS[kind](np.asarray(axis), np.asarray(fixed))
        for kind, axis, fixed in zip(types, axes, rotations, strict=True)
    ]
    if not consts:  # no joints (a floating base alone)
        return np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), np.zeros((0, 3))
    return tuple(np.stack(c) for c in zip(*consts, strict=True))
