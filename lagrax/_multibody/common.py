"""Small helpers the multibody modules share: parameter-valued fields, short reductions
written out in scalars, per-body values of a kinematic output, and the checks and
conversions of chain and tree structure."""

from collections.abc import Callable
from typing import Any

import jax.numpy as jnp
import numpy as np

from .._core.custom_types import Params, Point, Scalar, Vector
from .._core.errors import ConfigurationError, ShapeError


def value(x: Any, params: Params) -> Any:
    """Resolve a parameter-valued field: call it on `params` if callable."""
    return x(params) if callable(x) else x


def point(x: Callable | Any, q: Vector, params: Params) -> Point:
    """A point given as a function of `(q, params)` or as a constant (a fixed anchor)."""
    if callable(x):
        return jnp.asarray(x(q, params))
    return jnp.asarray(x, dtype=jnp.result_type(q))


def coordinate(x: int | Callable, q: Vector, params: Params) -> Scalar:
    """A scalar given as an index into `q` or as a function of `(q, params)`."""
    if callable(x):
        return jnp.asarray(x(q, params))
    return q[x]


# Reductions over axes this short are written out as scalar additions. Under ``vmap`` and
# the nested forward-mode derivatives of ``LagrangianSystem``, XLA fuses straight-line
# scalar arithmetic into one loop but not reductions over tiny axes (a (B, 2) ``sum`` is its
# own kernel): writing them out made the vmapped forward dynamics of the 2R arm ~10x faster.
UNROLL = 32


def small_sum(x) -> Scalar:
    """Sum of all elements (written out when there are few)."""
    x = jnp.asarray(x)
    if x.ndim == 0:
        return x
    if x.size > UNROLL:
        return jnp.sum(x)
    flat = [x[idx] for idx in np.ndindex(*x.shape)]
    total = flat[0]
    for term in flat[1:]:
        total = total + term
    return total


def dot_last(a, b):
    """`Σ_i a[..., i] b[..., i]` over the (short) last axis, written out."""
    terms = [a[..., i] * b[..., i] for i in range(a.shape[-1])]
    total = terms[0]
    for term in terms[1:]:
        total = total + term
    return total


def squared_norm(a):
    """`‖a‖²` over the last axis."""
    return dot_last(a, a)


def per_body(x, base_ndim: int):
    """The per-body values of a kinematic output: a list for a list/tuple of `k` bodies
    (or a single body), or the array itself when it holds the bodies along axis 0."""
    if isinstance(x, (list, tuple)):
        return [jnp.asarray(e) for e in x]
    x = jnp.asarray(x)
    if x.ndim == base_ndim:
        return [x]
    return x


def check_shape(values, shape: tuple, who: str, what: str) -> None:
    """Each body's value (a list item, or an array row) must have `shape`."""
    got = values[0].shape if isinstance(values, list) else values.shape[1:]
    if got != shape:
        raise ShapeError(f"{who}: {what} must give shape {shape} per body, got {got}")


def batch(x, base_ndim: int):
    """A body's per-item values as one array with the items along axis 0 (a list of `k`
    is stacked; a single item gains an axis). Stacking the few items of a list and doing
    one batched product beat a product per item by about 2x under `vmap`."""
    values = per_body(x, base_ndim)
    return jnp.stack(values) if isinstance(values, list) else values


def per_item(value, k: int, base_ndim: int, dtype):
    """A parameter shared by the `k` items or given per item, as `(k, ...)`."""
    value = jnp.asarray(value, dtype)
    return jnp.broadcast_to(value, (k,) + value.shape[value.ndim - base_ndim :])


def vee(s):
    """The axial vector of the skew part of `s[..., 3, 3, ...]` (leading batch axes and
    trailing axes kept): `½ (s₂₁ − s₁₂, s₀₂ − s₂₀, s₁₀ − s₀₁)`."""
    return 0.5 * jnp.stack(
        [
            s[..., 2, 1, :] - s[..., 1, 2, :],
            s[..., 0, 2, :] - s[..., 2, 0, :],
            s[..., 1, 0, :] - s[..., 0, 1, :],
        ],
        axis=-2,
    )


# ------------------------------------------------------------ chain and tree structure
def broadcast(name: str, value: Any, shape: tuple[int, ...], dtype: Any) -> jnp.ndarray:
    """A chain or tree parameter as an array of `shape` (`ShapeError` if it does not
    broadcast)."""
    arr = jnp.asarray(value, dtype=dtype)
    try:
        return jnp.broadcast_to(arr, shape)
    except ValueError:
        raise ShapeError(
            f"chain parameter {name!r} has shape {arr.shape}, which does not broadcast to {shape}"
        ) from None


def float_dtype(dtype: Any) -> Any:
    """`dtype`, or JAX's default float type (float64 with x64) for `None`."""
    return jnp.result_type(float) if dtype is None else dtype


def unit_vector(v, what: str) -> tuple[float, float, float]:
    """`v` normalized, as a static tuple (`ConfigurationError` for a zero, non-finite or
    non-3-vector)."""
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) == 0:
        raise ConfigurationError(f"{what} must be a non-zero finite 3-vector, got {v!r}")
    a = a / np.linalg.norm(a)
    return tuple(float(x) for x in a)


def rotation_tuple(rot, what: str) -> tuple:
    """A 3x3 rotation matrix as a static tuple of rows (`ConfigurationError` if it is not
    one)."""
    r = np.asarray(rot, dtype=float)
    if r.shape != (3, 3):
        raise ConfigurationError(f"{what} must be a 3x3 rotation matrix, got shape {r.shape}")
    if not np.allclose(r.T @ r, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
        raise ConfigurationError(f"{what} is not a rotation matrix (R^T R = 1, det R = +1):\n{r}")
    return tuple(tuple(float(x) for x in row) for row in r)


def steiner(mass: float, c: Any) -> np.ndarray:
    """`m (|c|² 1 − c cᵀ)`: the parallel-axis term of a mass `m` at `c` (NumPy, for the
    model loaders, which merge links on the host)."""
    c = np.asarray(c, float)
    return mass * (np.dot(c, c) * np.eye(3) - np.outer(c, c))


def about_centres(bodies: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`(masses, coms, inertias)` of bodies merged as sums (each with `mass`, the first
    moment `moment` and the inertia about its origin `inertia_o`): the centre of mass
    (the origin for a massless body) and the symmetrized inertia about it."""
    if not bodies:  # a floating base alone: no bodies below it
        return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3, 3))
    masses = np.array([b.mass for b in bodies])
    coms = np.stack([b.moment / b.mass if b.mass > 0 else np.zeros(3) for b in bodies])
    inertias = np.stack(
        [b.inertia_o - steiner(b.mass, c) for b, c in zip(bodies, coms, strict=True)]
    )
    return masses, coms, 0.5 * (inertias + np.swapaxes(inertias, 1, 2))
