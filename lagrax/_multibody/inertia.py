"""Inertia tensors: common shapes, the parallel-axis theorem, rotation, principal axes.

Conventions (the lecture's): the inertia matrix of a body about a point `P` in a frame
`A` is `ᴬI_P = ∫ −[r]² ρ dV`, with `r` the position of the volume element relative to
`P` in `A` components and `[r]` its skew-symmetric cross-product matrix. Diagonal
entries are `I_xx = ∫ (y² + z²) ρ dV` etc., off-diagonal entries `I_xy = −∫ x y ρ dV`.
"""

from typing import Any, NamedTuple

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import core as _jax_core
from jaxtyping import Array, ArrayLike, Float

from .._core.custom_types import Inertia, Rotation
from .._core.errors import ConfigurationError, ParameterError, ShapeError

_AXES = {"x": 0, "y": 1, "z": 2, 0: 0, 1: 1, 2: 2}


def _axis(axis: Any) -> int:
    try:
        return _AXES[axis]
    except (KeyError, TypeError):
        raise ConfigurationError(f"axis must be 0, 1, 2 or 'x', 'y', 'z', got {axis!r}") from None


def _diag3(a, b, c) -> Float[Array, "3 3"]:
    d = jnp.stack(jnp.broadcast_arrays(a, b, c))
    return jnp.diag(d)


def _diag_along(axis: int, along, across) -> Float[Array, "3 3"]:
    vals = [across, across, across]
    vals[axis] = along
    return _diag3(*vals)


def rod_inertia(mass: ArrayLike, length: ArrayLike, axis: int | str = "x") -> Float[Array, "3 3"]:
    """Inertia of a slender uniform rod about its centre, in axes aligned with the rod.

    `I = m L² / 12` about both axes perpendicular to the rod, `0` about the rod's own
    axis (the slender-rod idealization: this tensor is only positive *semi*-definite; use
    [`cylinder_inertia`][lagrax.bodies.cylinder_inertia] when the spin about the rod's axis
    matters).

    **Arguments:**

    - `mass`: `m`.
    - `length`: `L`.
    - `axis`: the axis the rod lies along, `"x"` (default), `"y"` or `"z"` (or 0, 1, 2).

    **Returns:** a `(3, 3)` diagonal matrix.
    """
    m, length = jnp.asarray(mass), jnp.asarray(length)
    return _diag_along(_axis(axis), jnp.zeros_like(m * length), m * length**2 / 12)


def box_inertia(mass: ArrayLike, size: Float[ArrayLike, "3"]) -> Float[Array, "3 3"]:
    """Inertia of a uniform solid box (cuboid) about its centre, in axes along its edges.

    With edge lengths `(a, b, c)` along `(x, y, z)`:
    `I = m/12 · diag(b² + c², a² + c², a² + b²)`.

    **Arguments:**

    - `mass`: `m`.
    - `size`: the edge lengths `(a, b, c)`.

    **Returns:** a `(3, 3)` diagonal matrix.
    """
    m = jnp.asarray(mass)
    size = jnp.asarray(size)
    if size.shape != (3,):
        raise ShapeError(f"box_inertia: size must be the 3 edge lengths (a, b, c), got {size}")
    a2, b2, c2 = size[0] ** 2, size[1] ** 2, size[2] ** 2
    return _diag3(m * (b2 + c2) / 12, m * (a2 + c2) / 12, m * (a2 + b2) / 12)


def cylinder_inertia(
    mass: ArrayLike, radius: ArrayLike, height: ArrayLike, axis: int | str = "z"
) -> Float[Array, "3 3"]:
    """Inertia of a uniform solid circular cylinder about its centre.

    About its own axis `I = m R² / 2`; about any axis through the centre perpendicular to
    it `I = m (3 R² + h²) / 12`.

    **Arguments:**

    - `mass`: `m`.
    - `radius`: `R`.
    - `height`: `h` (its length along the axis).
    - `axis`: the cylinder's axis, `"z"` (default), `"x"` or `"y"` (or 0, 1, 2).

    **Returns:** a `(3, 3)` diagonal matrix.
    """
    m, r, h = jnp.asarray(mass), jnp.asarray(radius), jnp.asarray(height)
    return _diag_along(_axis(axis), m * r**2 / 2, m * (3 * r**2 + h**2) / 12)


def sphere_inertia(mass: ArrayLike, radius: ArrayLike) -> Float[Array, "3 3"]:
    """Inertia of a uniform solid sphere about its centre: `I = 2/5 m R²` about every axis.

    **Arguments:**

    - `mass`: `m`.
    - `radius`: `R`.

    **Returns:** a `(3, 3)` diagonal matrix.
    """
    m, r = jnp.asarray(mass), jnp.asarray(radius)
    i = 2 * m * r**2 / 5
    return _diag3(i, i, i)


def parallel_axis(
    inertia: Inertia | Float[ArrayLike, ""],
    mass: ArrayLike,
    offset: Float[ArrayLike, " d"],
) -> Float[Array, "..."]:
    """Parallel-axis theorem: inertia about a point `P` from the inertia about the CoM.

    In 3-D, `I_P = I_C + m (‖d‖² 1 − d dᵀ)`; in the plane (a scalar inertia about the
    z axis and `d` of length 2), `I_P = I_C + m ‖d‖²`. `d` is the vector between the
    centre of mass `C` and `P` (its sign does not matter), in the same frame as `I_C`.
    Only valid from the centre of mass: shifting between two other points needs two steps.

    **Arguments:**

    - `inertia`: `I_C`, a `(3, 3)` matrix about the centre of mass (or a scalar for a
      planar body).
    - `mass`: `m`.
    - `offset`: `d`, shape `(3,)` (or `(2,)` with a scalar inertia).

    **Returns:** `I_P`, the same shape as `inertia`.

    **Raises:** `ShapeError` if the shapes do not match either case.
    """
    inertia, m, d = jnp.asarray(inertia), jnp.asarray(mass), jnp.asarray(offset)
    if inertia.ndim == 0 and d.shape in ((2,), (3,)):
        return inertia + m * jnp.dot(d, d)
    if inertia.shape != (3, 3) or d.shape != (3,):
        raise ShapeError(
            "parallel_axis: expected a (3, 3) inertia with a (3,) offset, or a scalar "
            f"(planar) inertia with a (2,) offset; got {inertia.shape} and {d.shape}"
        )
    eye = jnp.eye(3, dtype=jnp.result_type(inertia, d))
    return inertia + m * (jnp.dot(d, d) * eye - jnp.outer(d, d))


def rotate_inertia(inertia: Inertia, rotation: Rotation) -> Float[Array, "3 3"]:
    """Change of frame of an inertia tensor about a fixed point: `ᴬI = ᴬR_B ᴮI ᴬR_Bᵀ`.

    **Arguments:**

    - `inertia`: `ᴮI`, the inertia in frame `B` components.
    - `rotation`: `ᴬR_B`, the rotation matrix taking `B` components to `A`
      components (its columns are `B`'s axes written in `A`).

    **Returns:** `ᴬI`, shape `(3, 3)`. Trace, eigenvalues (principal moments) and
    determinant are unchanged.
    """
    inertia, rotation = jnp.asarray(inertia), jnp.asarray(rotation)
    if inertia.shape != (3, 3) or rotation.shape != (3, 3):
        raise ShapeError(
            f"rotate_inertia: expected (3, 3) arrays, got {inertia.shape} and {rotation.shape}"
        )
    return rotation @ inertia @ rotation.T


class PrincipalAxes(NamedTuple):
    """Principal moments and axes of an inertia tensor: `I = axes @ diag(moments) @ axes.T`."""

    moments: Float[Array, "3"]
    """Principal moments of inertia, ascending (`I1 ≤ I2 ≤ I3`)."""
    axes: Float[Array, "3 3"]
    """Principal axes as columns (unit eigenvectors); a proper rotation (`det = +1`)."""


def principal_axes(inertia: Inertia) -> PrincipalAxes:
    """Principal moments and axes of a symmetric inertia tensor by `jnp.linalg.eigh`.

    The eigenvectors are real and orthonormal because `I` is symmetric; the last axis is
    flipped if needed so that the axes form a right-handed frame (`det = +1`), i.e. a
    rotation from the principal frame to the frame of `inertia`.

    **Arguments:**

    - `inertia`: a symmetric `(3, 3)` matrix.

    **Returns:** [`PrincipalAxes`][lagrax.bodies.PrincipalAxes] `(moments, axes)`.
    """
    inertia = jnp.asarray(inertia)
    if inertia.shape != (3, 3):
        raise ShapeError(f"principal_axes: expected a (3, 3) inertia, got {inertia.shape}")
    moments, axes = jnp.linalg.eigh(0.5 * (inertia + inertia.T))
    sign = jnp.sign(jnp.linalg.det(axes))
    axes = axes.at[:, 2].multiply(sign)
    return PrincipalAxes(moments, axes)


def _tolerance(dtype: Any, rtol: float | None) -> float:
    return 1e3 * float(jnp.finfo(dtype).eps) if rtol is None else float(rtol)


def check_inertia(
    inertia: Inertia | Float[ArrayLike, "*k"],
    *,
    name: str = "inertia",
    semidefinite: bool = False,
    rtol: float | None = None,
    triangle: bool = True,
) -> Float[Array, "..."]:
    """Check that `inertia` is a physical inertia tensor, and return it.

    A 3×3 inertia about any point must be

    - symmetric (`|I − Iᵀ| ≤ rtol · max|I|`),
    - positive-definite (all principal moments `> rtol · max moment`; with
      `semidefinite=True`, `≥ −rtol · max moment`, which admits slender rods and point
      masses (all moments zero)),
    - and satisfy the triangle inequality of its principal moments, `I1 + I2 ≥ I3`
      (`I_xx + I_yy = ∫ (x² + y² + 2 z²) ρ dV ≥ ∫ (x² + y²) ρ dV = I_zz` in principal axes).

    A scalar (planar) inertia must be positive (non-negative with `semidefinite=True`). A
    stack of shape `(k, 3, 3)` or `(k,)` is checked member by member.

    Outside `jit` the checks run on concrete values and the error names the offending
    member and the values seen; under `jit` they become one `equinox.error_if` with a
    generic message.

    **Arguments:**

    - `inertia`: a `(3, 3)` matrix, a `(k, 3, 3)` stack, or scalar/`(k,)` planar
      inertias.
    - `name`: what to call it in messages.
    - `semidefinite`: accept zero principal moments.
    - `rtol`: relative tolerance (default `1000 ε` of the dtype).
    - `triangle`: check the triangle inequality (default); `False` checks symmetry and
      (semi)definiteness only: the spatial inertia of a body of positive mass is then still
      positive-semidefinite, so its equations of motion stay defined (a URDF whose
      `<inertia>` slightly violates it, see [`lagrax.chains.from_urdf`][]).

    **Returns:** `inertia` as an array.

    **Raises:** `ParameterError` naming the value seen when a check fails; `ShapeError`
    for a shape that is neither of the above.
    """
    arr = jnp.asarray(inertia)
    if not jnp.issubdtype(arr.dtype, jnp.floating):
        arr = arr.astype(jnp.result_type(float))
    planar = arr.ndim <= 1
    if arr.ndim > 3 or (not planar and arr.shape[-2:] != (3, 3)):
        raise ShapeError(
            f"{name} must be a (3, 3) matrix, a (k, 3, 3) stack, or scalar planar inertias; "
            f"got shape {arr.shape}"
        )
    tol = _tolerance(arr.dtype, rtol)
    if isinstance(arr, _jax_core.Tracer):
        return _check_traced(arr, planar, semidefinite, tol, name, triangle)
    values = np.asarray(arr)
    if not np.all(np.isfinite(values)):
        raise ParameterError(f"{name} is not finite: {values}")
    if planar:
        flat = values.reshape(-1)
        bad = flat < 0 if semidefinite else flat <= 0
        if np.any(bad):
            which = int(np.argmax(bad))
            where = f"[{which}]" if values.ndim else ""
            raise ParameterError(
                f"{name}{where} = {float(flat[which]):.6g} is not a positive moment of inertia: "
                "a planar inertia about the centre of mass must be > 0"
            )
        return arr
    for k, mat in enumerate(values.reshape(-1, 3, 3)):
        where = f"[{k}]" if values.ndim == 3 else ""
        _check_one(mat, f"{name}{where}", semidefinite, tol, triangle)
    return arr


def _check_one(
    mat: np.ndarray, label: str, semidefinite: bool, tol: float, triangle: bool = True
) -> None:
    scale = float(np.max(np.abs(mat)))
    asym = float(np.max(np.abs(mat - mat.T)))
    if asym > tol * max(scale, np.finfo(mat.dtype).tiny):
        raise ParameterError(
            f"{label} is not symmetric (largest |I - I^T| = {asym:.3g}):\n{mat}\n"
            "products of inertia must satisfy I_xy = I_yx, I_xz = I_zx, I_yz = I_zy"
        )
    moments = np.linalg.eigvalsh(0.5 * (mat + mat.T))
    top = max(float(moments[-1]), 0.0)
    floor = -tol * top if semidefinite else tol * top
    definite = moments[0] >= floor if semidefinite else moments[0] > floor
    if not definite or (top == 0.0 and not semidefinite):
        kind = "positive-semidefinite" if semidefinite else "positive-definite"
        raise ParameterError(
            f"{label} is not {kind}: principal moments {moments} (smallest "
            f"{moments[0]:.6g}):\n{mat}\ncheck the signs of the products of inertia and "
            "that every moment is positive"
            + ("" if semidefinite else " (pass semidefinite=True for a slender rod)")
        )
    i1, i2, i3 = (float(x) for x in moments)
    if triangle and i1 + i2 < i3 - tol * top:
        raise ParameterError(
            f"{label} violates the triangle inequality of principal moments: "
            f"I1 + I2 = {i1:.6g} + {i2:.6g} = {i1 + i2:.6g} < I3 = {i3:.6g} (moments "
            f"{moments}); no distribution of positive mass has these moments, since "
            "I1 + I2 - I3 = 2 * integral of (distance along axis 3)^2 dm >= 0"
        )


def _check_traced(
    arr, planar: bool, semidefinite: bool, tol: float, name: str, triangle: bool = True
):
    if planar:
        bad = jnp.any(arr < 0) if semidefinite else jnp.any(arr <= 0)
        return eqx.error_if(arr, bad, f"{name}: a planar inertia is not positive")
    mats = jnp.reshape(arr, (-1, 3, 3))
    scale = jnp.max(jnp.abs(mats), axis=(-2, -1))
    asym = jnp.max(jnp.abs(mats - jnp.swapaxes(mats, -1, -2)), axis=(-2, -1))
    moments = jnp.linalg.eigvalsh(0.5 * (mats + jnp.swapaxes(mats, -1, -2)))
    top = moments[:, 2]
    floor = -tol * top if semidefinite else tol * top
    not_pd = (moments[:, 0] < floor) if semidefinite else (moments[:, 0] <= floor)
    bad = (
        ~jnp.all(jnp.isfinite(mats))
        | jnp.any(asym > tol * scale)
        | jnp.any(not_pd | ((top <= 0) & (not semidefinite)))
        | (triangle & jnp.any(moments[:, 0] + moments[:, 1] < moments[:, 2] - tol * top))
    )
    return eqx.error_if(
        arr,
        bad,
        f"{name} is not a physical inertia (symmetric, positive-definite, I1 + I2 >= I3); "
        "call check_inertia outside jit for the values",
    )
