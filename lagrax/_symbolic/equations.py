r"""The symbolic equations of motion of a system, from the same JAX energies it simulates.

The energies `T`, `V`, the dissipation `D` and the force `F` are interpreted on SymPy
symbols (`interpreter.py`); SymPy then differentiates them, as lagrax's autodiff does
with numbers:

$$
M = \frac{∂^2 T}{∂q̇^2},\qquad C(q, q̇)\,q̇ = \frac{∂^2 T}{∂q̇\,∂q}\,q̇ − \frac{∂T}{∂q},
\qquad G = \frac{∂V}{∂q},
$$

$$
τ = M q̈ + C(q, q̇)\,q̇ + G + \frac{∂^2 T}{∂q̇\,∂t} + \frac{∂D}{∂q̇} − F.
$$

The Coriolis matrix is the Christoffel form of `M`,
`C_ij = Σ_k Γ_ijk q̇_k` with `Γ_ijk = ½ (∂M_ij/∂q_k + ∂M_ik/∂q_j − ∂M_jk/∂q_i)`, plus the
skew gyroscopic term `∂a/∂q − (∂a/∂q)ᵀ` of a `T` linear in `q̇` (`a = ∂T/∂q̇` at `q̇ = 0`):
the matrix [`LagrangianSystem.coriolis_matrix`][lagrax.LagrangianSystem.coriolis_matrix]
evaluates, so that `Ṁ − 2C` is skew-symmetric.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from .._core.errors import ArgumentTypeError, ParameterError, ShapeError
from .._systems.constrained import ConstrainedSystem
from .._systems.lagrangian import LagrangianSystem
from .conversions import load_sympy, to_sympy, tree_size
from .errors import ConstrainedSystemError
from .interpreter import interpret_arrays
from .simplification import DEFAULT_MAX_SIZE, DEFAULT_TIMEOUT, Budget, Deadline, check_size
from .simplification import simplify as simplify_expr
from .symbols import check_unique, coordinate_names, coordinate_symbols, parameter_symbols


@dataclasses.dataclass(frozen=True)
class Equations:
    r"""The symbolic equations of motion `M(q) q̈ + C(q, q̇) q̇ + G(q) = τ` of a system.

    Made by [`equations`][lagrax.symbolic.equations]. Every matrix is a SymPy `Matrix`
    (vectors are columns), in the symbols of `symbols`. In a notebook the object shows
    itself as the lecture writes it, `τ = M q̈ + C q̇ + G`.
    """

    M: Any
    """The mass matrix `∂²T/∂q̇²`, `(n, n)`."""
    C: Any
    """The Coriolis matrix (Christoffel form, with the gyroscopic term), `(n, n)`."""
    G: Any
    """The generalized gravity and spring forces `∂V/∂q`, `(n, 1)`."""
    tau: Any
    """The generalized forces `τ = M q̈ + C q̇ + G (+ ∂²T/∂q̇∂t + ∂D/∂q̇ − F)`, `(n, 1)`."""
    coriolis: Any
    """The velocity-product forces `(∂²T/∂q̇∂q) q̇ − ∂T/∂q` (`C q̇` for `T` quadratic in
    `q̇`), as [`LagrangianSystem.coriolis`][lagrax.LagrangianSystem.coriolis], `(n, 1)`."""
    damping: Any
    """`∂D/∂q̇` (`None` without a dissipation function)."""
    force: Any
    """The applied force `F(t, q, q̇)` (`None` without one)."""
    time_rate: Any
    """`∂²T/∂q̇∂t` of a time-dependent system (`None` otherwise)."""
    T: Any
    """The kinetic energy."""
    V: Any
    """The potential energy (`0` without one)."""
    q: Any
    """The coordinates, a column `Matrix` of real symbols."""
    qd: Any
    """Their rates `q̇`."""
    qdd: Any
    """Their accelerations `q̈`."""
    t: Any
    """The time symbol (it appears in a time-dependent system's energies and in `F`)."""
    parameters: tuple[Any, ...]
    """The parameter symbols, in the order of `params` (array entries in C order)."""
    parameter_keys: tuple[tuple[str, tuple[int, ...]], ...]
    """`(key, index)` in `params` of each of `parameters`."""
    symbols: dict[str, Any]
    """Every symbol by name: parameters, coordinates, rates, accelerations and `t`."""
    name: str = "system"
    """The system's name."""

    @property
    def n(self) -> int:
        """The number of coordinates."""
        return int(self.M.shape[0])

    @property
    def size(self) -> int:
        """Nodes of the expression trees of `M`, `C q̇` (`coriolis`) and `G` together: the
        size that the docs' table of systems reports."""
        return sum(tree_size(e) for m in (self.M, self.coriolis, self.G) for e in m)

    def latex(self) -> str:
        r"""`τ = M q̈ + C q̇ + G` (with the damping, force and time terms present) in LaTeX,
        the matrices written out (an `aligned` block, without `$`)."""
        sp = load_sympy()
        terms = [rf"{sp.latex(self.M)} {sp.latex(self.qdd)}", sp.latex(self.coriolis)]
        terms.append(sp.latex(self.G))
        for extra, sign in ((self.time_rate, "+"), (self.damping, "+"), (self.force, "-")):
            if extra is not None:
                terms.append(f"{sign} {sp.latex(extra)}")
        body = " \\\\ &+ ".join(terms[:3])
        tail = " ".join(terms[3:])
        return rf"\begin{{aligned}} \tau &= {body} {tail} \end{{aligned}}"

    def _repr_latex_(self) -> str:
        return f"$${self.latex()}$$"


def _check_system(system: Any) -> None:
    if isinstance(system, ConstrainedSystem):
        kinds = [
            kind
            for kind, fn in (
                ("holonomic constraints phi(q)", system.constraints),
                ("velocity constraints A(q) qd = 0", system.velocity_constraints),
            )
            if fn is not None
        ]
        raise ConstrainedSystemError(
            f"lagrax.symbolic.equations writes M, C, G of free coordinates; {system.name} "
            f"is a ConstrainedSystem (with {' and '.join(kinds)}), whose equations also "
            "need the constraint forces or a reduction to independent speeds, which "
            "Equations does not hold. Use lagrax.symbolic.equations(system.system, "
            "params) for the unconstrained M, C, G and lagrax.symbolic.interpret("
            "system.constraints or system.velocity_constraints, q, params) for phi(q) "
            "and A(q); ConstrainedSystem.linearize(..., independent=...) gives the "
            "reduced equations' linearization numerically"
        )
    if not isinstance(system, LagrangianSystem):
        raise ArgumentTypeError(
            "lagrax.symbolic.equations needs a lagrax.LagrangianSystem (its energies are "
            f"interpreted), got {type(system).__name__}; for a ConstrainedSystem pass its "
            ".system and write the constraints with lagrax.symbolic.interpret"
        )


class _Derivation:
    """One derivation's symbols, budget and simplification (a helper of `equations`)."""

    def __init__(self, system, params, coordinates, signed, numeric, budget, simplify):
        sp = load_sympy()
        self.sp, self.system, self.budget, self.simplify_on = sp, system, budget, simplify
        names = coordinate_names(system, coordinates)
        self.q, self.qd, self.qdd = coordinate_symbols(names)
        self.t = sp.Symbol("t", real=True)
        self.params = parameter_symbols(params, signed, numeric)
        all_symbols = [*self.params.symbols, *self.q, *self.qd, *self.qdd, self.t]
        self.table = check_unique(all_symbols)
        self.deadline = Deadline(budget)

    def call(self, fn, *args, what: str, shape: tuple[int, ...] = ()) -> Any:
        """`fn` interpreted at the symbols (the time first for a time-dependent energy),
        checked to have `shape`."""
        try:
            out = interpret_arrays(fn, *args)
        except KeyError as err:
            if isinstance(err, ParameterError):
                raise
            raise ParameterError(
                f"{what} reads params[{err.args[0]!r}], which params lacks: add it (its "
                f"value decides the symbol's assumptions); params has {sorted(self.params.values)}"
            ) from err
        if np.shape(out) != shape:
            raise ShapeError(f"{what} returns shape {np.shape(out)}, expected {shape}")
        expr = to_sympy(out)
        self.deadline.check()
        whole = expr if np.ndim(out) == 0 else self.sp.Add(*expr, evaluate=False)
        check_size(whole, self.budget, what)
        return expr

    def simp(self, expr: Any, what: str) -> Any:
        if not self.simplify_on:
            check_size(expr, self.budget, what)
            self.deadline.check()
            return expr
        return simplify_expr(expr, self.budget, self.deadline, what)

    def simp_matrix(self, mat: Any, what: str, symmetric: bool = False) -> Any:
        out = mat.copy()
        for i in range(mat.rows):
            for j in range(mat.cols):
                if symmetric and j < i:
                    out[i, j] = out[j, i]
                else:
                    out[i, j] = self.simp(mat[i, j], f"{what}[{i}, {j}]")
        return out


def _energies(d: _Derivation) -> tuple[Any, Any, Any, Any]:
    """`T`, `V`, `D`, `F` at the symbols (`None` for the absent ones)."""
    s, p, timed = d.system, d.params.values, d.system.time_dependent
    t = (d.t,) if timed else ()
    name = s.name
    kinetic = d.call(s.kinetic, *t, d.q, d.qd, p, what=f"the kinetic energy T of {name!r}")
    potential = None
    if s.potential is not None:
        potential = d.call(s.potential, *t, d.q, p, what=f"the potential energy V of {name!r}")
    dissipation = None
    if s.dissipation is not None:
        dissipation = d.call(s.dissipation, *t, d.q, d.qd, p, what=f"the dissipation D of {name!r}")
    force = None
    if s.force is not None:
        what = f"the force F of {name!r}"
        force = d.call(s.force, d.t, d.q, d.qd, p, what=what, shape=(len(d.q),))
    return kinetic, potential, dissipation, force


def _christoffel(d: _Derivation, mass: Any, momentum_at_rest: Any) -> Any:
    """`C_ij = Σ_k Γ_ijk q̇_k + (∂a/∂q − (∂a/∂q)ᵀ)_ij` (see the module docstring)."""
    sp, q, qd = d.sp, list(d.q), list(d.qd)
    n = len(q)
    c = sp.zeros(n, n)
    for i in range(n):
        for j in range(n):
            c[i, j] = sum(
                (
                    sp.Rational(1, 2)
                    * (mass[i, j].diff(q[k]) + mass[i, k].diff(q[j]) - mass[j, k].diff(q[i]))
                    * qd[k]
                    for k in range(n)
                ),
                sp.Integer(0),
            )
    da = momentum_at_rest.jacobian(q)
    return c + da - da.T


def _derive(d: _Derivation) -> Equations:
    sp = d.sp
    q, qd, qdd = (sp.Matrix(list(v)) for v in (d.q, d.qd, d.qdd))
    kinetic, potential, dissipation, force = _energies(d)
    kinetic = d.simp(kinetic, "the kinetic energy T")
    potential = sp.Integer(0) if potential is None else d.simp(potential, "the potential energy V")
    momentum = sp.Matrix([kinetic]).jacobian(qd).T
    mass = d.simp_matrix(momentum.jacobian(qd), "M", symmetric=True)
    gravity = d.simp_matrix(sp.Matrix([potential]).jacobian(q).T, "G")
    coriolis = momentum.jacobian(q) * qd - sp.Matrix([kinetic]).jacobian(q).T
    coriolis = d.simp_matrix(coriolis, "C qd")
    at_rest = momentum.subs(dict.fromkeys(list(qd), 0))
    c_mat = d.simp_matrix(_christoffel(d, mass, at_rest), "C")
    tau = mass * qdd + coriolis + gravity
    time_rate = damping = applied = None
    if d.system.time_dependent:
        time_rate = d.simp_matrix(momentum.diff(d.t), "the time rate of the momenta")
        tau += time_rate
    if dissipation is not None:
        damping = d.simp_matrix(sp.Matrix([dissipation]).jacobian(qd).T, "dD/dqd")
        tau += damping
    if force is not None:
        applied = d.simp_matrix(force, "F")
        tau -= applied
    fixed = sp.ImmutableMatrix
    return Equations(
        M=fixed(mass),
        C=fixed(c_mat),
        G=fixed(gravity),
        tau=fixed(tau),
        coriolis=fixed(coriolis),
        damping=None if damping is None else fixed(damping),
        force=None if applied is None else fixed(applied),
        time_rate=None if time_rate is None else fixed(time_rate),
        T=kinetic,
        V=potential,
        q=fixed(q),
        qd=fixed(qd),
        qdd=fixed(qdd),
        t=d.t,
        parameters=d.params.symbols,
        parameter_keys=d.params.keys,
        symbols=d.table,
        name=d.system.name,
    )


def equations(
    system: Any,
    params: Any,
    *,
    coordinates: Sequence[str] | None = None,
    signed: Sequence[str] = (),
    numeric: Sequence[str] = (),
    simplify: bool = True,
    max_size: int = DEFAULT_MAX_SIZE,
    timeout: float | None = DEFAULT_TIMEOUT,
) -> Equations:
    r"""The symbolic equations of motion of a system, from its own JAX energies.

    The system's `T`, `V` (and `D`, `F`) are interpreted on SymPy symbols (see
    [`interpret`][lagrax.symbolic.interpret]), differentiated by SymPy (`M = ∂²T/∂q̇²`,
    `C q̇ = (∂²T/∂q̇∂q) q̇ − ∂T/∂q`, `G = ∂V/∂q`, the Christoffel matrix `C`) and
    simplified ([`simplify`][lagrax.symbolic.simplify]: an exact canonical form for the
    trigonometric polynomials of mechanisms), so the 2R arm's `M₁₂` reads
    `I₂ + m₂ r₂² + l₁ m₂ r₂ cos θ₂` as on the lecture's slide. A system with
    structure-aware `equations` (a chain's recursions) is derived from its energies, the
    definition.

    **Arguments:**

    - `system`: a [`lagrax.LagrangianSystem`][] (autonomous or time-dependent).
    - `params`: a dict of numbers or arrays of numbers. Each key names a symbol (an array
      gives one per entry, numbered from 1: `m1, m2, …`); the values decide the
      assumptions: a symbol is positive when all its values are positive (masses,
      lengths, inertias, `g`), real otherwise.
    - `coordinates`: names of the coordinates (`("theta1", "theta2")` prints `θ₁, θ₂`);
      default the system's `coordinate_names`, else `q0, q1, …`.
    - `signed`: keys whose symbols are only real, even if their values are positive.
    - `numeric`: keys kept as their numbers (exactly) instead of symbols.
    - `simplify`: `False` skips the simplification (fast; long, but exact, results).
    - `max_size`: the largest expression simplified, in nodes of its expression tree.
    - `timeout`: seconds for the whole derivation (`None`: no limit).

    **Returns:** an [`Equations`][lagrax.symbolic.Equations] with `M`, `C`, `G`, `tau`,
    `coriolis`, `q`, `qd`, `qdd`, `symbols`, ...

    **Raises:** `UnsupportedPrimitiveError` for an operation of the energies without a
    SymPy meaning (named); `ExpressionSizeError` past `max_size` or `timeout` (naming the
    expression and its size); `ArgumentTypeError` for `params` that is not a dict of
    numbers, or a system that is not a `LagrangianSystem` (`ConstrainedSystemError`, one,
    for a `ConstrainedSystem`: its parts instead); `ParameterError` for a
    parameter an energy reads that `params` lacks; `ShapeError` for an energy that is not a
    scalar (or a force that is not `(n,)`); `ConfigurationError` for coordinates or
    options that do not fit the system; `SympyMissingError` without SymPy.

    **Example:**

    ```python
    system, params = lx.models.planar_2r()
    eq = lx.symbolic.equations(system, params, coordinates=("theta1", "theta2"))
    eq.M[0, 1]   # I2 + l1*m2*r2*cos(theta2) + m2*r2**2
    ```
    """
    _check_system(system)
    budget = Budget(max_size=max_size, timeout=timeout)
    d = _Derivation(system, params, coordinates, signed, numeric, budget, simplify)
    with d.deadline.running():
        return _derive(d)
