"""Robots the benchmarks share: example-robot-data's folder and random floating-base
states."""

import importlib.metadata
import os

import numpy as np

SOLO12 = os.path.join("solo_description", "robots", "solo12.urdf")
"""solo12's URDF in example-robot-data's ``robots`` folder."""


def robots_folder():
    """example-robot-data's ``robots`` folder, or None when it is not installed."""
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    for f in dist.files or ():
        if f.name == "package.xml" and "example-robot-data" in f.parts:
            return os.path.join(os.path.dirname(str(dist.locate_file(f))), "robots")
    return None


def floating_states(rng, n, size):
    """Random ``(q, v)`` of a floating base: a unit quaternion, joints in [-1, 1]."""
    quat = rng.normal(size=(size, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    q = np.concatenate([rng.normal(size=(size, 3)), quat, rng.uniform(-1, 1, (size, n))], 1)
    return q, rng.normal(size=(size, 6 + n))


def floating_inputs(n, size):
    """``(q, v, tau)`` of ``size`` random floating-base states with ``n`` joints, as
    ``jax`` arrays: ``floating_states`` drawn with seed 0, ``tau`` normal with seed 1."""
    import jax.numpy as jnp

    q, v = floating_states(np.random.default_rng(0), n, size)
    tau = np.random.default_rng(1).normal(size=(size, 6 + n))
    return jnp.asarray(q), jnp.asarray(v), jnp.asarray(tau)
