"""One link's step of a spatial tree's kinematics, shared by the fixed-base and the
floating-base recursions: the joint's rotation from its constants, the link's motion
subspace and its spatial inertia in world coordinates."""

import jax.numpy as jnp

from . import recursions as a

UNROLL_MAX_SPATIAL = 2
"""Spatial chains up to this many links are written out link by link; longer ones loop
with `lax.scan`."""


def joint_trig(q) -> tuple[jnp.ndarray, jnp.ndarray, jnp.ndarray]:
    """`(q, sin q, 1 − cos q)` of joint angles `(n,)`, for `spatial_link`: computed for
    all joints at once, before a pass (XLA would otherwise repeat the sine and the cosine
    in every fused loop that reads them, up to nine times a joint)."""
    return q, jnp.sin(q), 1 - jnp.cos(q)


def spatial_link(carry, x):
    rot, origin = carry
    (q, sn, cs), big_a, big_b, big_c, slide, axis, rev, offset, com, inertia, m = x
    origin = a.vadd(origin, a.matvec(rot, a.vadd(offset, a.vscale(slide, q))))
    joint = tuple(
        tuple(
            a.add(big_a[r][k], a.add(a.mul(sn, big_b[r][k]), a.mul(cs, big_c[r][k])))
            for k in range(3)
        )
        for r in range(3)
    )
    cols = tuple(zip(*joint, strict=True))
    rot = tuple(tuple(a.dot(row, col) for col in cols) for row in rot)
    z = a.matvec(rot, axis)
    prismatic = a.sub(1.0, rev)
    s = a.vscale(z, rev) + a.vadd(a.vscale(a.cross(origin, z), rev), a.vscale(z, prismatic))
    centre = a.vadd(origin, a.matvec(rot, com))
    r_bar = [a.matvec(inertia, row) for row in rot]  # rows of R Ī (Ī symmetric)
    world = [[None] * 3 for _ in range(3)]
    for r_ in range(3):
        for k in range(r_, 3):
            world[r_][k] = world[k][r_] = a.dot(r_bar[r_], rot[k])
    return (rot, origin), (s, a.spatial_inertia(m, tuple(map(tuple, world)), centre))
