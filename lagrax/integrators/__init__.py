"""Integrators that diffrax lacks, as `diffrax.AbstractSolver` subclasses."""

from ._rk4 import RK4 as RK4
from ._rosenbrock import Rodas4 as Rodas4
from ._rosenbrock import RodasInterpolation as RodasInterpolation
from ._variational import Variational as Variational

__all__ = ["RK4", "Rodas4", "RodasInterpolation", "Variational"]
