"""Ready-made scenes: each returns `(system, params)` with default parameter values."""

from ._bicycle import benchmark_bicycle as benchmark_bicycle
from ._bicycle import bicycle_eigenvalues as bicycle_eigenvalues
from ._bicycle import bicycle_matrices as bicycle_matrices
from ._cartesian_pendulum import cartesian_pendulum as cartesian_pendulum
from ._four_bar import four_bar as four_bar
from ._free_rigid_body import free_rigid_body_euler_angles as free_rigid_body_euler_angles
from ._mass_spring_damper import mass_spring_damper as mass_spring_damper
from ._planar_2r import planar_2r as planar_2r
from ._robots import arm7 as arm7
from ._robots import torso_two_arms as torso_two_arms
from ._robots import urdf_path as urdf_path

__all__ = [
    "planar_2r",
    "mass_spring_damper",
    "cartesian_pendulum",
    "four_bar",
    "free_rigid_body_euler_angles",
    "arm7",
    "torso_two_arms",
    "urdf_path",
    "benchmark_bicycle",
    "bicycle_matrices",
    "bicycle_eigenvalues",
]
