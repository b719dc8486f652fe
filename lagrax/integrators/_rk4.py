"""Classic fixed-step Runge–Kutta methods as diffrax solvers (coefficients + a few lines)."""

from collections.abc import Callable
from typing import ClassVar

import numpy as np
from diffrax import AbstractERK, ButcherTableau, ThirdOrderHermitePolynomialInterpolation

# Kutta (1901): the classic fourth-order method. No embedded error estimate (b_error = 0),
# so it runs at a fixed step only; lagrax.simulate refuses it without dt=.
_rk4_tableau = ButcherTableau(
    a_lower=(np.array([1 / 2]), np.array([0.0, 1 / 2]), np.array([0.0, 0.0, 1.0])),
    b_sol=np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
    b_error=np.zeros(4),
    c=np.array([1 / 2, 1 / 2, 1.0]),
)


class RK4(AbstractERK):
    """The classic fourth-order Runge–Kutta method (fixed step only).

    Four stages, no error estimate: use it with `dt=` (`diffrax.ConstantStepSize`).
    Included as the fixed-step workhorse many engines use (e.g. MuJoCo's `RK4`), so
    lagrax can be compared with them at the same step. Reference: W. Kutta, Z. Math.
    Phys. 46 (1901) 435–453.
    """

    tableau: ClassVar[ButcherTableau] = _rk4_tableau
    interpolation_cls: ClassVar[Callable[..., ThirdOrderHermitePolynomialInterpolation]] = (
        ThirdOrderHermitePolynomialInterpolation.from_k
    )

    def order(self, terms):
        del terms
        return 4
