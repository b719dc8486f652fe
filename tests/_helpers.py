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


def pin_state(pin, model, tree, q, qd):
    """lagrax's coordinates as Pinocchio's (joints matched by name; a continuous joint is
    `(cos q, sin q)` in Pinocchio's configuration, its tangent the angle)."""
    qp, vp, order = pin.neutral(model), np.zeros(model.nv), []
    for k, name in enumerate(tree.joint_names):
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 2:
            qp[joint.idx_q : joint.idx_q + 2] = np.cos(q[k]), np.sin(q[k])
        else:
            qp[joint.idx_q] = q[k]
        vp[joint.idx_v] = qd[k]
        order.append(joint.idx_v)
    return qp, vp, np.asarray(order)
