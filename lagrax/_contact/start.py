r"""Where a contact may start: no sphere deeper inside the ground, or another sphere,
than `max_penetration` allows.

A sphere that starts penetrating `δ` stores the elastic energy `k δ^{p+1}/(p+1)`, which
the contact spring gives back as motion (a push-out, part of the energy balance). A
shallow start is that; a deep one would be an explosion: at the default stiffness (a
static penetration of `10⁻⁴ ℓ`) a sphere started `δ` deep leaves with the energy of a
fall from about `0.4 δ (δ/δ_ref)^{3/2}`. So a `ContactSystem` refuses a start deeper than
`max_penetration` (default 1%) of the sphere's radius (a point, `radius=0`: of the scene's
size `ℓ`; a pair: of the smaller non-zero radius): `simulate` raises a `ContactError`
naming the sphere, its depth and the limit (under `jit` or in a sweep: the member's result
says that its initial state is not admissible).
"""

import jax.numpy as jnp
import numpy as np

from .._core.errors import ContactError
from . import forces, scale


def limits(contact, params, dtype):
    """`(plane, pair)`: the deepest start allowed for each sphere on the plane `(S,)`
    and each pair `(P,)` (`None` where there is no plane or no pair)."""
    frac = contact.max_penetration
    radii = forces.radii(contact, dtype)
    size = scale.scene_size(contact, params, dtype)
    plane = None
    if contact.plane is not None:
        plane = frac * jnp.where(radii > 0, radii, size)
    pair = None
    if contact.pairs:
        i = np.asarray([p[0] for p in contact.pairs])
        j = np.asarray([p[1] for p in contact.pairs])
        low, high = jnp.minimum(radii[i], radii[j]), jnp.maximum(radii[i], radii[j])
        pair = frac * jnp.where(low > 0, low, jnp.where(high > 0, high, size))
    return plane, pair


def admissible(contact, q, params):
    """Whether no contact starts deeper than its limit at `q` (traced; `True` when
    `max_penetration` is `None`)."""
    if contact.max_penetration is None:
        return jnp.asarray(True)
    dtype = jnp.result_type(q, float)
    ok = jnp.asarray(True)
    for gap, limit in zip(
        forces.gaps(contact, q, params), limits(contact, params, dtype), strict=True
    ):
        if gap is not None:
            ok = ok & jnp.all(-gap <= limit)
    return ok


def check(contact, q, params) -> None:
    """Eagerly: a `ContactError` naming the deepest contact past its limit at `q`."""
    if contact.max_penetration is None:
        return
    dtype = jnp.result_type(q, float)
    gaps = forces.gaps(contact, q, params)
    bounds = limits(contact, params, dtype)
    for kind, gap, limit in zip(("plane", "pair"), gaps, bounds, strict=True):
        if gap is None:
            continue
        depth, limit = -np.asarray(gap), np.asarray(limit)
        over = np.flatnonzero(depth > limit)
        if not over.size:
            continue
        k = int(over[np.argmax(depth[over] / limit[over])])
        if kind == "plane":
            what = (
                f"sphere {k} (radius {contact.spheres[k].radius:g}) starts {depth[k]:.3g} "
                "deep inside the ground"
            )
        else:
            i, j = contact.pairs[k]
            what = f"spheres {i} and {j} (pair {k}) start overlapping by {depth[k]:.3g}"
        raise ContactError(
            f"{contact.name}: {what}, past its limit {limit[k]:.3g} (max_penetration="
            f"{contact.max_penetration:g} of the radius, or of the scene's size for a point): "
            "the contact spring would throw it out. Start it touching or above (gap >= 0), "
            "or pass max_penetration= (None: no limit; the stored elastic energy then "
            "pushes it out)"
        )
