"""A torque-free rigid body in ZYX Euler angles (singular at gimbal lock)."""

import jax.numpy as jnp

from .._multibody.rigid_body import body_angular_velocity
from .._systems.lagrangian import LagrangianSystem

NAME = "free rigid body in ZYX Euler angles (gimbal lock at pitch q[1] = ±π/2)"


def kinetic(q, qd, p):
    """`T = ½ ωᵀ diag(I1, I2, I3) ω` with the body angular velocity `ω = E(q) q̇`
    ([`lagrax.rigid_body.body_angular_velocity`][], `[ω]× = Rᵀ Ṙ`)."""
    omega = body_angular_velocity(q, qd)
    return 0.5 * (p["I1"] * omega[0] ** 2 + p["I2"] * omega[1] ** 2 + p["I3"] * omega[2] ** 2)


def free_rigid_body_euler_angles(I1: float = 1.0, I2: float = 2.0, I3: float = 2.5):
    """A torque-free rigid body rotating about its centre of mass, in Euler angles, as
    `(system, params)`.

    `q = (ψ, θ, φ)`: ZYX (yaw, pitch, roll) Euler angles, `R = R_z(ψ) R_y(θ) R_x(φ)`
    (body → space, [`lagrax.rigid_body.euler_angles_to_matrix`][]); body axes are the
    principal axes with moments `I1, I2, I3` (`params` keys). `T = ½ ωᵀ I ω` with
    `ω = E(q) q̇` the body angular velocity, `V = 0`. The mass matrix
    `M = Eᵀ I E` has `det M = I1 I2 I3 cos²θ`: it is singular at gimbal lock
    `θ = ±π/2`, where lagrax refuses the state with a `MassMatrixError` naming `q`
    (and a simulation that runs into it fails with a `SimulationError`). Use
    [`lagrax.rigid_body.simulate_euler`][] (Euler's equations on a unit quaternion) for
    motions that reach it. Convert an initial body angular velocity to Euler-angle rates
    with [`lagrax.rigid_body.euler_angle_rates`][].

    **Example:**

    ```python
    system, params = lagrax.models.free_rigid_body_euler_angles(1.0, 2.0, 3.0)
    q0 = jnp.array([0.1, 0.2, 0.3])
    qd0 = lagrax.rigid_body.euler_angle_rates(q0, jnp.array([0.05, 0.0, 2.0]))
    sol = lagrax.simulate(system, q0, qd0, params, t1=5.0)
    ```
    """
    params = {k: jnp.asarray(v, dtype=float) for k, v in (("I1", I1), ("I2", I2), ("I3", I3))}
    return LagrangianSystem(kinetic, n_dof=3, name=NAME), params
