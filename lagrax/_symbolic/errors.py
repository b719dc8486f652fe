"""The errors of `lagrax.symbolic`: each names what it could not do and what to do instead."""

from .._core.errors import ArgumentTypeError, LagraxError


class SymbolicError(LagraxError, ValueError):
    """Base class of the errors of [`lagrax.symbolic`][]: a function or a system whose
    equations it cannot write symbolically, or SymPy missing."""


class UnsupportedPrimitiveError(SymbolicError):
    """A JAX operation has no SymPy equivalent in lagrax's interpreter: a primitive it does
    not map (the message names it and the function it appeared in), a branch or a loop
    whose condition depends on `q` or `params` (`jnp.where(x > 0, ...)`), or a conversion
    to an integer type. Never replaced by a guess: the equations would be wrong."""


class ExpressionSizeError(SymbolicError):
    """An expression grew past the size budget (`max_size`, counted in nodes of its
    expression tree), or simplifying it took longer than the time budget (`timeout`): the
    message names the expression, its size and the budget. Symbolic equations of this size
    are pages long; use the numeric equations, or raise the budget."""


class SympyMissingError(SymbolicError, ImportError):
    """SymPy, which [`lagrax.symbolic`][] needs, is not installed: `pip install
    "lagrax[symbolic]"`."""


class ConstrainedSystemError(SymbolicError, ArgumentTypeError):
    """[`lagrax.symbolic.equations`][] was given a `ConstrainedSystem` (holonomic or
    velocity constraints: the rolling disk, the bicycle). Its `Equations` are `M`, `C`, `G`
    of one set of free coordinates; a constrained system's equations also need the
    constraint forces (`Jᵀλ`, `Aᵀλ`) or a reduction to independent speeds (Kane's form,
    through `K_d(q)⁻¹`: rational in sines and cosines, outside the canonical form the
    simplification works in), which they do not hold. The message says what to use
    instead: `equations(system.system, params)` for the free `M`, `C`, `G` and
    [`interpret`][lagrax.symbolic.interpret] for the constraints `φ(q)` and `A(q)`."""
