"""The first-order vector field `(q, q̇) ↦ (q̇, q̈)` that simulate hands to diffrax.

It also carries the system and the inputs, so that solvers which work with the
Lagrangian itself (the variational integrators) can reach them through the term.
"""

from collections.abc import Callable
from typing import Any

import equinox as eqx
from jaxtyping import Array

from .._core.checks import coords, finite, force_value, same_shape
from .._core.errors import ArgumentTypeError
from .._core.one_shot import one_shot_on
from .abstract import AbstractSystem

TauFn = Callable[[Any, Array, Array], Array]


class LagrangianVectorField(eqx.Module):
    """`f(t, (q, v), (params, tau_const)) = (N(q) v, v̇)` for any
    [`AbstractSystem`][lagrax.AbstractSystem]: `(q̇, q̈)` for an ordinary one, whose
    [`configuration_rate`][lagrax.AbstractSystem.configuration_rate] is `v` itself."""

    system: AbstractSystem
    tau_fn: TauFn | None = None

    def tau(self, t, q, qd, tau_const):
        """The input generalized force at `(t, q, q̇)` (`None` when there is none)."""
        tau = tau_const
        if self.tau_fn is not None:
            shape = _input_shape(self.system)
            out = force_value(self.tau_fn(t, q, qd), "tau(t, q, qd)", qd, shape)
            tau = out.astype(qd.dtype)
            if tau_const is not None:
                tau = tau + tau_const
        return tau

    def __call__(self, t, y, args):
        # A solver evaluates the field in several places (its first stage, the stages of
        # a step, lagrax's input check): through a nested jit it is traced once, and the
        # others reuse the cached trace (XLA inlines the call, so it costs nothing to run).
        # (whether the recursions take their one-shot form is part of the cache key)
        return _evaluate(self, t, y, args, one_shot_on())


def split_tau(system: AbstractSystem, tau: Any, q: Array, *, host: bool = False):
    """The `tau=` argument of `simulate` and `sweep` as `(tau_fn, tau_const)`: a
    function `tau(t, q, qd)` (or `None`), and a constant input `(n,)` of `q`'s dtype
    (or `None`); `LagrangianVectorField.tau` adds them up at each state.

    **Arguments:** `system`, `tau` (`None`, a function or an array of length `n`), the
    coordinates `q` it goes with (its shape and dtype), and `host=True` to convert a
    constant with NumPy (no device transfer; `simulate`'s eager set-up).

    A system whose input is its actuators' controls (`system.n_input != system.n_dof`)
    takes a constant of `n_input` entries, and a function returning that many.

    **Raises:** `ShapeError` (naming `tau`, its length and the system's) or
    `ArgumentTypeError` for a constant of the wrong shape or kind, `NonFiniteError` for
    one with NaN or inf.
    """
    if tau is None:
        return None, None
    if callable(tau):
        return tau, None
    shape = _input_shape(system)
    if shape is None:
        tau_const = coords(tau, "tau", system.n_dof, system.name, host=host)
        same_shape("tau", tau_const, q)
    else:  # the input is not a generalized force: its own size
        size = "inputs (one per actuator: MuJoCo's ctrl)"
        tau_const = coords(tau, "tau", shape[0], system.name, host=host, size=size)
    return None, finite(tau_const.astype(q.dtype), "tau")


def _input_shape(system: AbstractSystem) -> tuple[int, ...] | None:
    """`(n_input,)` for a system whose input is not one generalized force per velocity
    (see `AbstractSystem.n_input`), else `None`."""
    n = system.n_input
    return None if n == system.n_dof or n is None else (n,)


@eqx.filter_jit
def _evaluate(field: LagrangianVectorField, t, y, args, one_shot: bool):
    q, qd = y
    params, tau_const = args
    system = field.system
    qdd = system.accelerations(t, q, qd, params, field.tau(t, q, qd, tau_const))
    return system.configuration_rate(q, qd), qdd


def unwrapped_term(term: Any) -> Any:
    """The term inside diffrax's wrapping terms (`WrapTerm`, `AdjointTerm`: private
    classes, each holding the term it wraps as its `term` field), or `term` itself."""
    while (inner := getattr(term, "term", None)) is not None:
        term = inner
    return term


def lagrangian_field_of(terms) -> LagrangianVectorField:
    """Find the `LagrangianVectorField` inside (possibly wrapped) diffrax terms."""
    term = unwrapped_term(terms)
    field = getattr(term, "vector_field", None)
    if not isinstance(field, LagrangianVectorField):
        raise ArgumentTypeError(
            "this solver integrates a LagrangianSystem and needs the term built by "
            "lagrax.simulate (diffrax.ODETerm(LagrangianVectorField(system))); got "
            f"{type(term).__name__} with vector field {type(field).__name__}"
        )
    return field
