"""Random spatial mechanisms with physical inertias, and a check of their energies, shared
by the chain and tree tests."""

import numpy as np
from scipy.spatial.transform import Rotation

from _helpers import close


def random_spatial(make, n, seed, *, gravity=False):
    """`make(axes=, rotations=, up=)` with random joint axes, joint-frame rotations and
    up direction, and random parameters: masses, offsets, centres of mass, inertias of
    boxes in random frames (physical by construction) and, with `gravity=True`, a random
    `g`. Returns `(model, params, rng)`, the generator positioned after the draws."""
    rng = np.random.default_rng(seed)
    model = make(
        axes=[tuple(rng.normal(size=3)) for _ in range(n)],
        rotations=[Rotation.random(random_state=seed + i).as_matrix() for i in range(n)],
        up=tuple(rng.normal(size=3)),
    )
    d = rng.uniform(0.1, 0.8, (n, 3)) ** 2  # a box's second moments: a physical inertia
    frames = [Rotation.random(random_state=100 + seed + i).as_matrix() for i in range(n)]
    inertia = np.stack(
        [
            r @ np.diag([d[i, 1] + d[i, 2], d[i, 0] + d[i, 2], d[i, 0] + d[i, 1]]) @ r.T
            for i, r in enumerate(frames)
        ]
    )
    m = rng.uniform(0.5, 2, n)
    offset = rng.normal(size=(n, 3)) * 0.5
    com = rng.normal(size=(n, 3)) * 0.3
    extra = {"g": rng.uniform(5, 12)} if gravity else {}
    params = model.params(m=m, offset=offset, com=com, inertia=inertia, **extra)
    return model, params, rng


def check_energies(fast_systems, definition, q, qd, params):
    """The energies a solution reports (a spatial chain's outward pass in link frames,
    `ChainEquations.energies`) equal the definition's `T + V` from the pose maps."""
    h_ref, mag_ref = definition.energy_and_magnitude(0.0, q, qd, params)
    for system in fast_systems:
        h, mag = system.energy_and_magnitude(0.0, q, qd, params)
        close(h, h_ref)
        close(mag, mag_ref)
        close(system.jacobi_integral(0.0, q, qd, params), h_ref)
