"""Helpers shared by the tests: relative comparisons, random rotations and a central
difference against which gradients are checked."""

import jax
import numpy as np


def rel_error(a, b) -> float:
    """`max |a − b|` relative to `max(|b|, 1)`."""
    a, b = np.asarray(a), np.asarray(b)
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1.0))


def close(a, b, rtol=1e-12):
    """`a` equals `b` to `rtol` relative to `max(|b|, 1)`."""
    a, b = np.asarray(a), np.asarray(b)
    scale = max(np.max(np.abs(b)), 1.0)
    assert np.max(np.abs(a - b)) <= rtol * scale, (a, b)


def random_rotation(rng):
    """A random proper rotation matrix (`det = +1`), from the QR of a Gaussian matrix."""
    a, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return a * np.sign(np.linalg.det(a))


def central_difference(f, x, h):
    """`(f(x + h) − f(x − h)) / 2h`."""
    return (f(x + h) - f(x - h)) / (2 * h)


def check_grad_against_central_difference(f, x, h=1e-5, rtol=1e-6):
    """`jax.grad(f)(x)` of a scalar `f` of a scalar equals the central difference to
    `rtol` relative to `max(|fd|, 1)`."""
    grad = jax.grad(f)(x)
    fd = central_difference(f, x, h)
    assert abs(float(grad) - float(fd)) <= rtol * max(1.0, abs(float(fd)))
