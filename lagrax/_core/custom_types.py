"""Shape-annotated array aliases shared by the public signatures (jaxtyping)."""

from typing import Any, TypeAlias

from jaxtyping import Array, ArrayLike, Float, PyTree

Params: TypeAlias = PyTree[Any]
"""Any JAX pytree of model parameters (dict, NamedTuple, equinox Module, ...)."""

Coordinates: TypeAlias = Float[ArrayLike, " n"]
Velocities: TypeAlias = Float[ArrayLike, " n"]
Vector: TypeAlias = Float[Array, " n"]
Matrix: TypeAlias = Float[Array, "n n"]
Scalar: TypeAlias = Float[Array, ""]
Time: TypeAlias = Float[ArrayLike, ""]

# Bodies, inertia and chains (``lagrax.bodies``, ``lagrax.chains``).
Point: TypeAlias = Float[Array, "*k d"]
"""A point (or `k` points) in the plane (`d = 2`) or in space (`d = 3`)."""
Rotation: TypeAlias = Float[Array, "*k 3 3"]
"""Rotation matrix (or `k` of them) taking body-frame components to world components."""
Inertia: TypeAlias = Float[ArrayLike, "*k 3 3"]
"""3×3 inertia tensor(s)."""

ConstraintValues: TypeAlias = Float[Array, " m"]
"""Values `φ(q)` of `m` holonomic constraints, or their multipliers `λ`."""
ConstraintJacobian: TypeAlias = Float[Array, "m n"]
Vector3: TypeAlias = Float[Array, "3"]
Matrix3: TypeAlias = Float[Array, "3 3"]
Quaternion: TypeAlias = Float[Array, "4"]
"""A unit quaternion `(w, x, y, z)`, scalar first (Hamilton convention)."""
