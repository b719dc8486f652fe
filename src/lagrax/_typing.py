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
