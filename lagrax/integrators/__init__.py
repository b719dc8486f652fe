"""Integrators that diffrax lacks, as `diffrax.AbstractSolver` subclasses."""

from ._rk4 import RK4 as RK4
from ._variational import Variational as Variational

__all__ = ["RK4", "Variational"]
