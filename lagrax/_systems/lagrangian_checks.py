"""A `LagrangianSystem`'s eager checks: its fields at construction, a state (shapes,
finite values, parameters, a positive-definite `M(q)`), and the error that names why
the accelerations or their derivatives are not finite."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core import model_programs
from .._core.checks import (
    binds,
    eager_only,
    finite,
    finite_params,
    is_traced,
    pivot_threshold,
    positive_int,
    time_signature_message,
)
from .._core.custom_types import Params
from .._core.errors import ArgumentTypeError, ConfigurationError, MassMatrixError, NonFiniteError
from . import derivatives as d
from .abstract import AbstractSystem
from .interfaces import Energies


def float_arrays(params: Params) -> Params:
    """Python floats in `params` as NumPy scalars, so that a compiled call does not
    recompile for every new value (`filter_jit` keeps Python scalars static)."""
    return jax.tree_util.tree_map(lambda x: np.asarray(x) if isinstance(x, float) else x, params)


def check_init(system: Energies) -> None:
    """`LagrangianSystem.__check_init__`: the energies are functions of the right
    arity, `n_dof` and `coordinate_names` agree, and only an autonomous system has
    structure-aware `equations`."""
    if isinstance(system.kinetic, AbstractSystem):
        raise ArgumentTypeError(
            f"LagrangianSystem got a system ({system.kinetic.name!r}) where its kinetic "
            "energy function goes; pass the system itself where a system is expected"
        )
    for role, fn, signature in (
        ("kinetic", system.kinetic, "T(q, qd, params) -> scalar"),
        ("potential", system.potential, "V(q, params) -> scalar"),
        ("dissipation", system.dissipation, "D(q, qd, params) -> scalar"),
        ("force", system.force, "F(t, q, qd, params) -> (n,)"),
    ):
        if not (fn is None and role != "kinetic") and not callable(fn):
            raise ArgumentTypeError(
                f"LagrangianSystem's {role} must be a function {signature}, got "
                f"{fn!r} ({type(fn).__name__})"
            )
    if system.n_dof is not None:
        positive_int("n_dof", system.n_dof, "It is the number of generalized coordinates.")
    if not isinstance(system.time_dependent, bool):
        raise ArgumentTypeError(
            f"time_dependent must be True or False, got {system.time_dependent!r}"
        )
    if system.time_dependent:
        if system.equations is not None:
            raise ConfigurationError(
                "a time-dependent system cannot use structure-aware equations (a "
                "chain's recursions assume energies without explicit time): pass "
                "equations=None"
            )
        for fn, label, n_args in (
            (system.kinetic, d.KINETIC_T, 4),
            (system.potential, d.POTENTIAL_T, 3),
            (system.dissipation, d.DISSIPATION_T, 4),
        ):
            if fn is not None and binds(fn, n_args) is False:
                raise ArgumentTypeError(time_signature_message(label, n_args, fn, True))
    names = system.coordinate_names
    if names is not None and system.n_dof is not None and len(names) != system.n_dof:
        raise ConfigurationError(
            f"LagrangianSystem has n_dof={system.n_dof} but {len(names)} coordinate_names "
            f"{names!r}: give one name per coordinate"
        )


def check_state(system: Energies, q, qd, params, t) -> None:
    """`LagrangianSystem.check_state`: shapes, finite values and parameters, a finite
    energy and a symmetric positive-definite `M(q)`, with the values in the messages."""
    eager_only(f"check_state of {system.name}", system, q, qd, params, t)
    q, qd = system._state(q, qd)
    finite(q, "q")
    finite(qd, "qd")
    finite_params(params)
    # one compiled call; Python floats as arrays, so a new value does not recompile
    e, mass = model_programs.program(system, _energy_and_mass)(
        system, q, qd, float_arrays(params), np.asarray(t, q.dtype)
    )
    if not bool(jnp.isfinite(e)):
        raise NonFiniteError(f"the energy T + V is not finite at q={q}, qd={qd}")
    mass = np.asarray(mass)
    if not np.all(np.isfinite(mass)):
        raise MassMatrixError(f"mass matrix is not finite at q={np.asarray(q)}: {mass}")
    asym = np.max(np.abs(mass - mass.T))
    if asym > 1e3 * np.finfo(mass.dtype).eps * max(np.max(np.abs(mass)), 1e-300):
        raise MassMatrixError(f"mass matrix is not symmetric at q={np.asarray(q)}")
    eigs = np.linalg.eigvalsh(mass)
    if not eigs[0] > pivot_threshold(mass.dtype) * max(np.max(np.abs(eigs)), 0.0):
        raise MassMatrixError(mass_message(system, q, eigs))


def mass_message(system: Energies, q, params_eigs) -> str:
    """Why `M(q)` is refused, with its eigenvalues when known."""
    return (
        f"mass matrix M(q) = d2T/dqd2 of {system.name} is singular or not "
        f"positive-definite at q={np.asarray(q)}"
        + (f" (eigenvalues {params_eigs})" if params_eigs is not None else "")
        + ": check that T is quadratic in qd with positive masses and inertias, or "
        "change coordinates if q is a singular configuration of them"
    )


def finite_derivatives(system: Energies, out, q, qd, params, tau, t, what: str):
    """`out` if every array in it is finite, else the error `forward_dynamics` would
    raise there (eagerly), or a `NonFiniteError` (under `jit`, at run time)."""
    ok = jnp.all(jnp.stack([jnp.all(jnp.isfinite(x)) for x in jax.tree_util.tree_leaves(out)]))
    message = (
        f"{what}_derivatives of {system.name} are not finite: the state, tau or params "
        "contain NaN/inf, or M(q) is singular or not positive-definite there"
    )
    if is_traced(q, qd, tau, params, t, out):
        return eqx.error_if(out, ~ok, message + ". Outside jit the message names which.")
    if not bool(ok):
        finite(q, "q")
        finite(qd, "qd")
        system.check_state(q, qd, params, t=t)  # raises if M(q) or the energies are bad
        raise NonFiniteError(message)
    return out


def eager_forward_dynamics(system: Energies, t, q, qd, params, tau):
    """`LagrangianSystem.forward_dynamics` of concrete inputs: `q̈`, or the error that
    names the cause (non-finite inputs, a bad `M(q)` or energies, else the applied
    forces)."""
    # eager: precise messages with the offending values
    finite(q, "q")
    finite(qd, "qd")
    if tau is not None:
        finite(tau, "tau")
    # one compiled program of the system (freed with it), not thousands of dispatches
    qdd = model_programs.call(system, type(system).accelerations, system, t, q, qd, params, tau)
    if not bool(jnp.all(jnp.isfinite(qdd))):
        system.check_state(q, qd, params, t=t)  # raises if M(q) or the energies are bad
        applied = d.applied(system, t, q, qd, params, tau)
        raise NonFiniteError(
            f"forward_dynamics of {system.name} is not finite at q={np.asarray(q)}, "
            f"qd={np.asarray(qd)} although the mass matrix and energies are: the "
            f"applied force tau + force - dD/dqd = {np.asarray(applied)}; check the "
            "force, dissipation and tau, and the derivatives of T and V there"
        )
    return qdd


def _energy_and_mass(system: Energies, q, qd, params, t):
    """`(T + V, M)` at one state: one compiled call for `check_state`."""
    return system.energy(q, qd, params, t=t), system.mass_matrix(q, params, qd, t=t)
