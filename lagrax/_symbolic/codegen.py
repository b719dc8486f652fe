"""Code from symbolic equations: NumPy or JAX functions (`sympy.lambdify`) and C for an
embedded controller (`sympy.utilities.codegen`), both with common subexpressions
eliminated."""

from __future__ import annotations

import dataclasses
import pathlib
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from .._core.errors import ConfigurationError
from .conversions import load_sympy
from .equations import Equations


def _expressions(eq: Equations) -> dict[str, Any]:
    return {
        "mass_matrix": eq.M,
        "coriolis": eq.coriolis,
        "coriolis_matrix": eq.C,
        "gravity": eq.G,
        "inverse_dynamics": eq.tau,
    }


def parameter_vector(eq: Equations, params: Mapping[str, Any], xp: Any = np) -> Any:
    """The values of `eq.parameters` in `params`, as one vector (`xp`: `numpy` or
    `jax.numpy`), in the order the generated code reads them."""
    if not eq.parameter_keys:
        return xp.zeros(0)
    return xp.stack([xp.asarray(params[key])[index] for key, index in eq.parameter_keys])


@dataclasses.dataclass(frozen=True)
class NumericEquations:
    """NumPy or JAX functions of symbolic equations, with the signatures of
    [`lagrax.LagrangianSystem`][]'s methods (`params` is the dict the equations were
    derived with, or any dict with the same keys and shapes).

    Made by [`lambdify`][lagrax.symbolic.lambdify]. The JAX functions work under `jit`,
    `vmap` and `grad`.
    """

    equations: Equations
    """The symbolic equations."""
    modules: str
    """`"numpy"` or `"jax"`."""
    functions: dict[str, Callable[..., Any]]
    """The generated functions by part, each `f(q, qd, qdd, p, t)` with `p` the
    [`parameter_vector`][lagrax.symbolic.parameter_vector]."""

    def _call(self, part: str, q, qd, qdd, params, t) -> Any:
        xp = self._xp()
        n = self.equations.n
        zeros = xp.zeros(n)
        args = (
            xp.asarray(q),
            zeros if qd is None else xp.asarray(qd),
            zeros if qdd is None else xp.asarray(qdd),
            parameter_vector(self.equations, params, xp),
            t,
        )
        out = xp.asarray(self.functions[part](*args), dtype=float)
        return out if part in ("mass_matrix", "coriolis_matrix") else out[:, 0]

    def _xp(self) -> Any:
        if self.modules == "jax":
            import jax.numpy as jnp

            return jnp
        return np

    def mass_matrix(self, q, params, qd=None, *, t=0.0) -> Any:
        """`M(q)`, shape `(n, n)`."""
        return self._call("mass_matrix", q, qd, None, params, t)

    def coriolis(self, q, qd, params, *, t=0.0) -> Any:
        """`(∂²T/∂q̇∂q) q̇ − ∂T/∂q`, shape `(n,)`."""
        return self._call("coriolis", q, qd, None, params, t)

    def coriolis_matrix(self, q, qd, params, *, t=0.0) -> Any:
        """The Christoffel matrix `C(q, q̇)`, shape `(n, n)`."""
        return self._call("coriolis_matrix", q, qd, None, params, t)

    def gravity(self, q, params, *, t=0.0) -> Any:
        """`G = ∂V/∂q`, shape `(n,)`."""
        return self._call("gravity", q, None, None, params, t)

    def inverse_dynamics(self, q, qd, qdd, params, t=0.0) -> Any:
        """`τ = M q̈ + C q̇ + G (+ ∂²T/∂q̇∂t + ∂D/∂q̇ − F)`, shape `(n,)`."""
        return self._call("inverse_dynamics", q, qd, qdd, params, t)


def lambdify(eq: Equations, *, modules: str = "numpy") -> NumericEquations:
    """NumPy or JAX functions of symbolic equations (`sympy.lambdify`, common
    subexpressions eliminated).

    **Arguments:**

    - `eq`: the [`Equations`][lagrax.symbolic.Equations].
    - `modules`: `"numpy"` (default) or `"jax"`.

    **Returns:** a [`NumericEquations`][lagrax.symbolic.NumericEquations] whose
    `mass_matrix(q, params)`, `coriolis(q, qd, params)`, `coriolis_matrix`, `gravity`
    and `inverse_dynamics(q, qd, qdd, params)` match the system's methods.

    **Raises:** `ConfigurationError` for another `modules`.

    **Example:**

    ```python
    system, params = lx.models.planar_2r()
    fast = lx.symbolic.lambdify(lx.symbolic.equations(system, params))
    fast.mass_matrix(np.array([0.3, -0.2]), params)   # == system.mass_matrix(...)
    ```
    """
    if modules not in ("numpy", "jax"):
        raise ConfigurationError(f'lambdify modules must be "numpy" or "jax", got {modules!r}')
    sp = load_sympy()
    args = (list(eq.q), list(eq.qd), list(eq.qdd), list(eq.parameters), eq.t)
    functions = {
        part: sp.lambdify(args, expr, modules=modules, cse=True)
        for part, expr in _expressions(eq).items()
    }
    return NumericEquations(eq, modules, functions)


@dataclasses.dataclass(frozen=True)
class CCode:
    """C99 source and header of a system's equations, for an embedded controller.

    Made by [`c_code`][lagrax.symbolic.c_code]. Every function reads `q`, `qd`, `qdd`
    (length `n`) and `p` (the parameters, in the order of `parameters`) and writes its
    output array: `{prefix}_mass_matrix(q, p, M)` (`n × n`, row-major),
    `{prefix}_coriolis(q, qd, p, c)` (`C(q, q̇) q̇`), `{prefix}_coriolis_matrix(q, qd,
    p, C)`, `{prefix}_gravity(q, p, G)` and `{prefix}_inverse_dynamics(q, qd, qdd, p,
    tau)`. A function whose expressions depend on the time (a time-dependent system, a
    force `F(t, …)`) takes a `double t` after `p`, and one whose `M` depends on `q̇` (a
    `T` not quadratic in `q̇`) takes `qd` after `q`. Only `<math.h>` is needed.
    """

    source: str
    """The `.c` file."""
    header: str
    """The `.h` file."""
    prefix: str
    """The prefix of the file and function names."""
    parameters: tuple[str, ...]
    """The names of the entries of `p`, in order."""
    functions: dict[str, str]
    """The C function names by part (`"mass_matrix"`, `"coriolis"`, ...)."""

    def write(self, directory: str | pathlib.Path) -> tuple[pathlib.Path, pathlib.Path]:
        """Write `{prefix}.c` and `{prefix}.h` into `directory`; returns their paths."""
        directory = pathlib.Path(directory)
        c_path, h_path = directory / f"{self.prefix}.c", directory / f"{self.prefix}.h"
        c_path.write_text(self.source)
        h_path.write_text(self.header)
        return c_path, h_path


def c_code(eq: Equations, *, prefix: str = "lagrax") -> CCode:
    """C99 code of the equations (SymPy's `codegen`, common subexpressions eliminated).

    **Arguments:**

    - `eq`: the [`Equations`][lagrax.symbolic.Equations].
    - `prefix`: the prefix of the function names and the file names (a C identifier).

    **Returns:** a [`CCode`][lagrax.symbolic.CCode] (see it for the functions and their
    arguments).

    **Raises:** `ConfigurationError` for a prefix that is not a C identifier.
    """
    if not prefix.isidentifier() or not prefix.isascii():
        raise ConfigurationError(f"c_code prefix must be a C identifier, got {prefix!r}")
    sp = load_sympy()
    from sympy.utilities.codegen import C99CodeGen

    n, k = eq.n, len(eq.parameters)
    arrays = {
        "q": sp.MatrixSymbol("q", n, 1),
        "qd": sp.MatrixSymbol("qd", n, 1),
        "qdd": sp.MatrixSymbol("qdd", n, 1),
        "p": sp.MatrixSymbol("p", max(k, 1), 1),
    }
    replace = {}
    for name, symbols in (("q", eq.q), ("qd", eq.qd), ("qdd", eq.qdd), ("p", eq.parameters)):
        replace.update({s: arrays[name][i, 0] for i, s in enumerate(symbols)})
    t = sp.Symbol("t", real=True)
    replace[eq.t] = t
    gen = C99CodeGen(project=prefix, cse=True)
    routines, names = [], {}
    for part, expr in _expressions(eq).items():
        expr = expr.xreplace(replace)
        out = sp.MatrixSymbol(_OUTPUT[part], *expr.shape)
        used = [a for a in ("q", "qd", "qdd") if expr.has(arrays[a]) or a in _ALWAYS[part]]
        sequence = [arrays[a] for a in used] + [arrays["p"]]
        sequence += [t] if expr.has(t) else []
        names[part] = f"{prefix}_{part}"
        routines.append(gen.routine(names[part], sp.Eq(out, expr), sequence + [out], None))
    (_, source), (_, header) = gen.write(routines, prefix, header=False, empty=True)
    labels = tuple(s.name for s in eq.parameters)
    return CCode(source, header, prefix, labels, names)


_OUTPUT = {
    "mass_matrix": "M",
    "coriolis": "c",
    "coriolis_matrix": "C",
    "gravity": "G",
    "inverse_dynamics": "tau",
}
_ALWAYS = {
    "mass_matrix": ("q",),
    "coriolis": ("q", "qd"),
    "coriolis_matrix": ("q", "qd"),
    "gravity": ("q",),
    "inverse_dynamics": ("q", "qd", "qdd"),
}
