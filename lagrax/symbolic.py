r"""The equations of motion on screen: symbolic `M`, `C`, `G` from the same JAX energies.

lagrax computes the equations of motion as numbers at a state. This module shows them as
formulas, from the very functions the user wrote: the energies are traced to jaxprs and
the jaxprs are evaluated on [SymPy](https://www.sympy.org) symbols (an interpreter of
JAX's primitives), then SymPy differentiates and simplifies. Nothing is written twice.

```python
import lagrax as lx

system, params = lx.models.planar_2r()
eq = lx.symbolic.equations(system, params, coordinates=("theta1", "theta2"))
eq.M            # Matrix([[I1 + I2 + l1**2*m2 + 2*l1*m2*r2*cos(theta2) + ...]])
eq              # in a notebook: τ = M q̈ + C q̇ + G, as on the lecture's slide
lx.symbolic.derivations_2r().agree()          # Lagrange = Newton–Euler = Kane = the slide
fast = lx.symbolic.lambdify(eq)               # NumPy (or JAX) functions of the formulas
print(lx.symbolic.c_code(eq, prefix="arm").source)   # C for an embedded controller
```

- [`equations`][lagrax.symbolic.equations] → [`Equations`][lagrax.symbolic.Equations]: `M`,
  the Christoffel `C`, `G`, `τ`, `C q̇`, the symbols.
- [`interpret`][lagrax.symbolic.interpret]: any JAX function on SymPy arguments (a pose map,
  a constraint, an oracle); [`supported_primitives`][lagrax.symbolic.supported_primitives].
- [`derivations_2r`][lagrax.symbolic.derivations_2r]: the lecture's three derivations of the
  2R arm (Lagrange, Newton–Euler, Kane) and its slide.
- [`lambdify`][lagrax.symbolic.lambdify], [`c_code`][lagrax.symbolic.c_code]: code from the
  formulas.

Errors: [`UnsupportedPrimitiveError`][lagrax.symbolic.UnsupportedPrimitiveError] names a JAX
operation without an exact SymPy meaning;
[`ExpressionSizeError`][lagrax.symbolic.ExpressionSizeError] names an expression past the size
or time budget; [`ConstrainedSystemError`][lagrax.symbolic.ConstrainedSystemError] refuses
a `ConstrainedSystem` and names its parts to use instead. All are
[`SymbolicError`][lagrax.symbolic.SymbolicError]s (a `lagrax.LagraxError`).

SymPy is imported on first use: `pip install "lagrax[symbolic]"`.
"""

from ._symbolic.codegen import CCode as CCode
from ._symbolic.codegen import NumericEquations as NumericEquations
from ._symbolic.codegen import c_code as c_code
from ._symbolic.codegen import lambdify as lambdify
from ._symbolic.codegen import parameter_vector as parameter_vector
from ._symbolic.conversions import tree_size as tree_size
from ._symbolic.derivations import Derivations2R as Derivations2R
from ._symbolic.derivations import derivations_2r as derivations_2r
from ._symbolic.derivations import kane_2r as kane_2r
from ._symbolic.derivations import newton_euler_2r as newton_euler_2r
from ._symbolic.derivations import planar_2r_scene as planar_2r_scene
from ._symbolic.derivations import slide_2r as slide_2r
from ._symbolic.equations import Equations as Equations
from ._symbolic.equations import equations as equations
from ._symbolic.errors import ConstrainedSystemError as ConstrainedSystemError
from ._symbolic.errors import ExpressionSizeError as ExpressionSizeError
from ._symbolic.errors import SymbolicError as SymbolicError
from ._symbolic.errors import SympyMissingError as SympyMissingError
from ._symbolic.errors import UnsupportedPrimitiveError as UnsupportedPrimitiveError
from ._symbolic.interpreter import interpret as interpret
from ._symbolic.interpreter import supported_primitives as supported_primitives
from ._symbolic.simplification import canonical as simplify

__all__ = [
    "equations",
    "Equations",
    "interpret",
    "supported_primitives",
    "simplify",
    "tree_size",
    "derivations_2r",
    "Derivations2R",
    "newton_euler_2r",
    "kane_2r",
    "slide_2r",
    "planar_2r_scene",
    "lambdify",
    "NumericEquations",
    "parameter_vector",
    "c_code",
    "CCode",
    "SymbolicError",
    "UnsupportedPrimitiveError",
    "ExpressionSizeError",
    "SympyMissingError",
    "ConstrainedSystemError",
]
