"""The derivatives API of a `LagrangianSystem`: the forward and inverse dynamics with
their derivatives (as Pinocchio's `computeABADerivatives` / `computeRNEADerivatives`)
and the linearization of the state equations, each one compiled program around
`sensitivity`'s kernels, with eager checks around it; and of a `ConstrainedSystem`, whose
accelerations' derivatives go through its KKT system (`kkt`'s tangent rule)."""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core import model_programs
from .._core.blocking import blocked
from .._core.checks import finite, is_traced
from .._core.closures import closes_over_tracers
from .._core.errors import ConfigurationError, LagraxError
from . import implicit, sensitivity
from .interfaces import Constrained, Energies
from .lagrangian_checks import finite_derivatives, float_arrays
from .sensitivity import ForwardDynamicsDerivatives, InverseDynamicsDerivatives


def forward_dynamics_derivatives(
    system: Energies, q, qd, params, tau, t, wrt_params: bool
) -> ForwardDynamicsDerivatives:
    """`LagrangianSystem.forward_dynamics_derivatives` (documented there)."""
    q, qd, tau = system._state(q, qd, tau=tau)
    program, eager = choose_program(system, _forward_body, q, qd, tau, params, t)
    out = blocked(program, implicit.blocks(system)[1])(
        system, t, q, qd, float_arrays(params) if eager else params, tau, wrt_params
    )
    return finite_derivatives(system, out, q, qd, params, tau, t, "forward_dynamics")


def inverse_dynamics_derivatives(
    system: Energies, q, qd, qdd, params, t, wrt_params: bool
) -> InverseDynamicsDerivatives:
    """`LagrangianSystem.inverse_dynamics_derivatives` (documented there)."""
    q, qd, qdd = system._state(q, qd, qdd=qdd)
    program, eager = choose_program(system, _inverse_body, q, qd, qdd, params, t)
    out = blocked(program, implicit.blocks(system)[1])(
        system, t, q, qd, qdd, float_arrays(params) if eager else params, wrt_params
    )
    return finite_derivatives(system, out, q, qd, params, None, t, "inverse_dynamics")


def linearize(system: Energies, q_eq, qd_eq, params, tau_eq, t) -> tuple[jax.Array, jax.Array]:
    """`LagrangianSystem.linearize` (documented there): `(A, B)`."""
    q, qd = system._state(q_eq, qd_eq, q_name="q_eq", qd_name="qd_eq")
    if tau_eq is None:
        tau = jnp.zeros_like(q)
    else:
        (tau,) = system._state(q, q_name="q_eq", tau_eq=tau_eq)[1:]
    dtype = jnp.result_type(q, qd, tau)
    q, qd, tau = q.astype(dtype), qd.astype(dtype), tau.astype(dtype)
    program, eager = choose_program(system, _linearization_body, q, qd, tau, params, t)
    if eager:
        finite(q, "q_eq")
        finite(qd, "qd_eq")
        finite(tau, "tau_eq")
        return _eager_linearization(system, t, q, qd, params, tau)
    a_mat, b_mat = program(system, t, q, qd, params, tau)
    ok = jnp.all(jnp.isfinite(a_mat)) & jnp.all(jnp.isfinite(b_mat))
    a_mat = eqx.error_if(
        a_mat,
        ~ok,
        f"linearize of {system.name} produced non-finite Jacobians: the state, tau_eq or "
        "params contain NaN/inf, or M(q_eq) is singular. Outside jit the message names "
        "which.",
    )
    return a_mat, b_mat


def constrained_forward_dynamics_derivatives(
    system: Constrained, q, qd, params, tau, t, wrt_params: bool
) -> ForwardDynamicsDerivatives:
    """`ConstrainedSystem.forward_dynamics_derivatives` (documented there)."""
    if system._manifold:
        raise ConfigurationError(
            f"forward_dynamics_derivatives and linearize of {system.name} are not available "
            "for constraints on a floating base or a forest (its q is not the integral of "
            "its velocity); differentiate forward_dynamics with jax.jacfwd instead"
        )
    q, qd, tau = system._state(q, qd, tau=tau)
    tau = jnp.zeros_like(q) if tau is None else tau
    program, eager = choose_program(system, _constrained_body, q, qd, tau, params, t)
    out = program(system, t, q, qd, float_arrays(params) if eager else params, tau, wrt_params)
    return finite_derivatives(system, out, q, qd, params, tau, t, "forward_dynamics")


def constrained_linearize(
    system: Constrained, q_eq, qd_eq, params, tau_eq, t
) -> tuple[jax.Array, jax.Array]:
    """`ConstrainedSystem.linearize` (documented there): `(A, B)`."""
    q_eq, qd_eq, tau_eq = system._state(
        q_eq, qd_eq, q_name="q_eq", qd_name="qd_eq", tau_eq=tau_eq
    )  # (the messages name the caller's arguments)
    out = constrained_forward_dynamics_derivatives(system, q_eq, qd_eq, params, tau_eq, t, False)
    return state_space(out)


def choose_program(system, body, *values) -> tuple[Callable, bool]:
    """`(program, eager)` of a call of `system` on `values`: `body` compiled as one
    program of the system (`model_programs.program`: freed with the system), and whether
    nothing in the call is traced; or `body` itself (traced) where the system's functions
    close over traced values, since a compiled program holds the functions as constants,
    which cannot hold a tracer of `jax.grad` or `jax.jvp`."""
    if closes_over_tracers(system):
        return body, False
    return model_programs.program(system, body), not is_traced(*values)


def state_space(out: ForwardDynamicsDerivatives) -> tuple[jax.Array, jax.Array]:
    """`(A, B)` of `ẋ = (q̇, q̈(q, q̇, τ))` from the derivatives of `q̈`:
    `A = [[0, I], [∂q̈/∂q, ∂q̈/∂q̇]]`, `B = [[0], [∂q̈/∂τ]]`."""
    n = out.qdd.shape[0]
    zero, eye = jnp.zeros((n, n), out.dq.dtype), jnp.eye(n, dtype=out.dq.dtype)
    return jnp.block([[zero, eye], [out.dq, out.dqd]]), jnp.concatenate([zero, out.dtau], axis=0)


def _constrained_body(system: Constrained, t, q, qd, params, tau, wrt_params: bool):
    """`sensitivity.forward_by_jacobian` of the KKT accelerations (whose tangents go
    through the KKT system at the primal solution)."""

    def accelerations(a, b, c, p):
        return system._kkt(t, a, b, p, c)[0]

    return sensitivity.forward_by_jacobian(accelerations, q, qd, tau, params, wrt_params)


def _eager_linearization(system: Energies, t, q, qd, params, tau):
    """`(A, B)` outside `jit`. The state is checked only when the linearization fails
    (a trace error, or non-finite Jacobians: NaN parameters, `M(q_eq)` not
    positive-definite), for `check_state`'s precise message: a first call then compiles
    one program, not two."""
    try:
        a_mat, b_mat = model_programs.program(system, _linearization_body, **_EAGER)(
            system, t, q, qd, float_arrays(params), tau, True
        )
    except LagraxError:
        raise
    except Exception:
        system.check_state(q, qd, params, t=t)  # shapes, parameters: names the problem
        raise
    if not (np.all(np.isfinite(a_mat)) and np.all(np.isfinite(b_mat))):
        system.check_state(q, qd, params, t=t)  # parameters, M positive-definite
        finite(a_mat, "the linearization A")
        finite(b_mat, "the linearization B")
    return a_mat, b_mat


def _forward_body(system: Energies, t, q, qd, params, tau, wrt_params: bool):
    """`sensitivity.forward` with the system's own derivative options."""
    return sensitivity.forward(system, system.scalar_derivatives, t, q, qd, params, tau, wrt_params)


def _inverse_body(system: Energies, t, q, qd, qdd, params, wrt_params: bool):
    """`sensitivity.inverse` with the system's own derivative options."""
    return sensitivity.inverse(system, system.scalar_derivatives, t, q, qd, qdd, params, wrt_params)


def _linearization_body(system: Energies, t, q, qd, params, tau, one_state=False):
    """`(A, B)` of the state equations at one state, as one compiled program
    (`one_state`: `M⁻¹` by LAPACK, see `sensitivity.forward`)."""
    out = sensitivity.forward(
        system, system.scalar_derivatives, t, q, qd, params, tau, False, one_state=one_state
    )
    return state_space(out)


# An eager `linearize` is a program for one state, usually compiled for one call: XLA's
# backend optimization level 0 compiles it in 0.84 s instead of 1.08 s (the URDF arm),
# and it then runs in 138 µs a call instead of 122 µs, nearly all of it dispatch. (Only a
# top-level jit takes compiler options: under a user's `jit` or `vmap`, the plain one.)
_EAGER = {"compiler_options": {"xla_backend_optimization_level": 0}}
