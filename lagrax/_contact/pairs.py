r"""Sphere–sphere pairs: which spheres of a `ContactSystem` touch each other, and the
geometry of a pair.

A pair `(i, j)` of spheres with centres `c_i`, `c_j` and radii `r_i`, `r_j` has the
gap `g = |c_j − c_i| − r_i − r_j` (negative: the spheres overlap) and the unit normal
`n = (c_j − c_i)/|c_j − c_i|` from `i` to `j`. They touch at `c_i + r_i n` (on `i`)
and `c_j − r_j n` (on `j`); the relative velocity of those two points,
`v = (ċ_j + ω_j × (−r_j n)) − (ċ_i + ω_i × (r_i n))`, has the normal part `n·v = ġ`
(the gap's rate) and a tangential part, the slip that friction opposes. The contact
force `F` acts on `j` and `−F` on `i`: the normal law and the friction are those of
the plane's contacts (`laws`), with the same coefficients.
"""

import itertools
from typing import Any

import jax.numpy as jnp
import numpy as np

from .._core.errors import ArgumentTypeError, ConfigurationError
from .laws import safe_norm


def pair_list(pairs: Any, n_spheres: int) -> tuple[tuple[int, int], ...]:
    """`pairs=` of a `ContactSystem` as a tuple of index pairs `(i, j)`, `i < j`:
    `None` (none), `"all"` (every pair of spheres) or a sequence of index pairs.

    **Raises:** `ConfigurationError` for an index out of range, a sphere paired with
    itself or a pair given twice; `ArgumentTypeError` for anything else."""
    if pairs is None:
        return ()
    if isinstance(pairs, str):
        if pairs != "all":
            raise ConfigurationError(
                f"pairs must be 'all', None or a sequence of sphere index pairs (i, j), got "
                f"pairs={pairs!r}"
            )
        return tuple(itertools.combinations(range(n_spheres), 2))
    try:
        given = [tuple(p) for p in pairs]
    except TypeError as err:
        raise ArgumentTypeError(
            f"pairs must be 'all', None or a sequence of sphere index pairs (i, j), got "
            f"pairs={pairs!r}"
        ) from err
    out: list[tuple[int, int]] = []
    for p in given:
        ok = len(p) == 2 and all(
            isinstance(k, (int, np.integer)) and not isinstance(k, bool) for k in p
        )
        if not ok:
            raise ArgumentTypeError(
                f"each entry of pairs must be two sphere indices (i, j), got {p!r}"
            )
        i, j = sorted(int(k) for k in p)
        if i < 0 or j >= n_spheres:
            raise ConfigurationError(
                f"pairs has the pair {p!r}, but the spheres are numbered 0 … {n_spheres - 1}"
            )
        if i == j:
            raise ConfigurationError(f"pairs has the pair {p!r}: a sphere cannot touch itself")
        if (i, j) in out:
            raise ConfigurationError(f"pairs has the pair {p!r} twice")
        out.append((i, j))
    return tuple(out)


def turn(omega, arm):
    """`ω × a` for each sphere: `omega` `(S,)` (planar: `ω (−a_y, a_x)`) or `(S, 3)`,
    `arm` `(S, d)`."""
    if arm.shape[-1] == 2:
        return omega[..., None] * jnp.stack([-arm[..., 1], arm[..., 0]], axis=-1)
    return jnp.cross(omega, arm)


def pair_geometry(centres, radii, pairs):
    """`(normal, gap)` of each pair: `n` `(P, d)` from `i` to `j` (along the first axis
    where the centres coincide) and `g = |c_j − c_i| − r_i − r_j` `(P,)`."""
    i = np.asarray([p[0] for p in pairs])
    j = np.asarray([p[1] for p in pairs])
    d = centres[j] - centres[i]
    dist = safe_norm(d)
    apart = dist > 0
    first = jnp.zeros_like(d).at[:, 0].set(1.0)
    normal = jnp.where(apart[:, None], d / jnp.where(apart, dist, 1.0)[:, None], first)
    return normal, dist - radii[i] - radii[j]


def relative_velocity(rates, omegas, radii, normal, pairs):
    """`(P, d)`: the velocity of `j`'s contact point `c_j − r_j n` relative to `i`'s,
    `c_i + r_i n` (linear in the centres' rates `(S, d)` and angular velocities)."""
    i = np.asarray([p[0] for p in pairs])
    j = np.asarray([p[1] for p in pairs])
    on_j = rates[j] + turn(omegas[j], -radii[j][:, None] * normal)
    on_i = rates[i] + turn(omegas[i], radii[i][:, None] * normal)
    return on_j - on_i
