"""Rigid-body rotation: Euler's equations with a singularity-free (quaternion) attitude,
and the attitude maps between Euler angles, quaternions and rotation matrices.

Compare with `lagrax.models.free_rigid_body_euler_angles`: the same body as a
`LagrangianSystem` in ZYX Euler angles, which is singular at gimbal lock.
"""

from ._multibody.rigid_body import RigidBodySolution as RigidBodySolution
from ._multibody.rigid_body import body_angular_velocity as body_angular_velocity
from ._multibody.rigid_body import euler_angle_rates as euler_angle_rates
from ._multibody.rigid_body import euler_angles_to_matrix as euler_angles_to_matrix
from ._multibody.rigid_body import euler_angles_to_quaternion as euler_angles_to_quaternion
from ._multibody.rigid_body import euler_equations as euler_equations
from ._multibody.rigid_body import hat as hat
from ._multibody.rigid_body import quaternion_product as quaternion_product
from ._multibody.rigid_body import quaternion_to_matrix as quaternion_to_matrix
from ._multibody.rigid_body import simulate_euler as simulate_euler
from ._multibody.rigid_body import vee as vee

__all__ = [
    "simulate_euler",
    "RigidBodySolution",
    "euler_equations",
    "euler_angles_to_matrix",
    "euler_angles_to_quaternion",
    "body_angular_velocity",
    "euler_angle_rates",
    "quaternion_product",
    "quaternion_to_matrix",
    "hat",
    "vee",
]
