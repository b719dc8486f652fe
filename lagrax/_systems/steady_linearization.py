r"""Linearization of a `ConstrainedSystem` about a steady motion in independent
coordinates and speeds (Peterson, Gede & Hubbard 2014, by autodiff at the operating
point).

With the holonomic constraints `φ(q) = 0` (Jacobian `J`, `m₁` rows) and the velocity
constraints `K(q) q̇ = 0` (`K = [J; A]`, `m` rows), the coordinates split into
independent `q_i` and dependent `q_d` and the speeds into independent `u_i` and dependent
`u_d`. To first order about the operating point `q*`,

$$
δq = P_q δq_i, \qquad P_q = \begin{bmatrix} 1 \\ −J_d^{-1} J_i \end{bmatrix},
\qquad
q̇ = P_u(q) u_i, \qquad P_u(q) = \begin{bmatrix} 1 \\ −K_d(q)^{-1} K_i(q) \end{bmatrix}
$$

(rows in the order of the coordinates). The minimal state `x = (q_i, u_i)` obeys
`q̇_i = [P_u(q) u_i]_{q_i}` and `u̇_i = [q̈(q, P_u(q) u_i, τ)]_{u_i}`, with `q̈` the KKT
accelerations and `q = q* + P_q δq_i`; one forward-mode Jacobian of this map at
`x* = (q*_i, u*_i)` is `A`, one in `τ` is `B`. Along it the state stays on `φ = 0` to
first order and on `K q̇ = 0` exactly, so the Baumgarte terms add nothing. The operating
point need not be an equilibrium: ignorable coordinates may move, but the reduced
accelerations `u̇_i` must vanish there (a steady motion)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.checks import finite, is_traced
from .._core.closures import closes_over_tracers
from .._core.errors import ConfigurationError, ConstraintError, LagraxError
from .interfaces import Constrained
from .lagrangian_checks import float_arrays

Independent = tuple[tuple[int, ...], tuple[int, ...]]


def steady_linearize(
    system: Constrained, q_op, qd_op, params, tau_op, t, independent, tol: float
) -> tuple[jax.Array, jax.Array]:
    """`ConstrainedSystem.linearize(..., independent=...)` (documented there)."""
    q, qd = system._state(q_op, qd_op)
    tau = jnp.zeros_like(q) if tau_op is None else system._state(q, tau=tau_op)[1]
    dtype = jnp.result_type(q, qd, tau, float)
    q, qd, tau = q.astype(dtype), qd.astype(dtype), tau.astype(dtype)
    tol = float(tol)
    if not (tol > 0.0 and np.isfinite(tol)):
        raise ConfigurationError(f"tol must be a finite positive number, got tol={tol}")
    m1 = jax.eval_shape(lambda a: system._phi(a, params), q).shape[0]
    m = m1 + jax.eval_shape(lambda a: system._amat(a, params), q).shape[0]
    qi, ui = _indices(system, independent, q.shape[0], m1, m)
    traced = is_traced(q, qd, tau, params, t) or closes_over_tracers(system)
    if not traced:
        finite(q, "q_op")
        finite(qd, "qd_op")
        finite(tau, "tau_op")
        _check_operating_point(system, q, qd, params, qi, ui, tol)
    program = _body if closes_over_tracers(system) else (_compiled if traced else _eager)
    args = params if traced else float_arrays(params)  # a float parameter: no recompile
    a_mat, b_mat, udot = program(system, t, q, qd, args, tau, qi, ui)
    if not traced:
        _check_steady(system, np.asarray(udot), ui, tol)
        finite(a_mat, "the linearization A")
        finite(b_mat, "the linearization B")
        return a_mat, b_mat
    bad = ~(jnp.all(jnp.isfinite(a_mat)) & jnp.all(jnp.isfinite(b_mat)))
    a_mat = eqx.error_if(
        a_mat,
        bad | jnp.any(jnp.abs(udot) > tol),
        f"linearize of {system.name} about a steady motion: the reduced accelerations are "
        f"not zero (within {tol:g}) or the Jacobians are not finite (a singular dependent "
        "block, NaN inputs). Outside jit the message names which.",
    )
    return a_mat, b_mat


def _complement(n: int, chosen: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(k for k in range(n) if k not in chosen)


def _index_tuple(values: Any, what: str, n: int) -> tuple[int, ...]:
    try:
        flat = np.asarray(values).reshape(-1)
        ok = flat.dtype.kind in "iu" or (flat.size == 0 and flat.dtype.kind == "f")
        out = tuple(int(v) for v in flat)
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ConfigurationError(f"independent {what} must be integer indices, got {values!r}")
    if len(set(out)) != len(out) or any(k < 0 or k >= n for k in out):
        raise ConfigurationError(
            f"independent {what} must be distinct indices in 0..{n - 1}, got {list(out)}"
        )
    return tuple(sorted(out))


def _indices(system, independent, n: int, m1: int, m: int) -> Independent:
    """`(q_i, u_i)` as sorted tuples: a pair of index sequences, or one sequence for both
    (holonomic constraints only, where there are as many independent speeds as
    coordinates)."""
    pair = isinstance(independent, Sequence) and len(independent) == 2
    pair = pair and all(np.ndim(part) == 1 for part in independent)
    if pair:
        qi = _index_tuple(independent[0], "coordinates", n)
        ui = _index_tuple(independent[1], "speeds", n)
    else:
        qi = ui = _index_tuple(independent, "coordinates", n)
    if len(qi) != n - m1 or len(ui) != n - m:
        raise ConfigurationError(
            f"{system.name} has {n} coordinates, {m1} holonomic and {m - m1} velocity "
            f"constraints: it needs {n - m1} independent coordinates and {n - m} "
            f"independent speeds, got {len(qi)} ({list(qi)}) and {len(ui)} ({list(ui)}); "
            "pass independent=(coordinate indices, speed indices)"
        )
    return qi, ui


def _name(system, k: int) -> str:
    names = system.coordinate_names
    return f"q[{k}]" if names is None else f"{names[k]} (q[{k}])"


def _check_operating_point(system, q, qd, params, qi, ui, tol) -> None:
    """Eagerly: the point is on the constraints, and the dependent blocks `J_d`, `K_d`
    are invertible (a `ConstraintError` naming the coordinates otherwise)."""
    n = q.shape[0]
    kmat = np.asarray(system._kmat(q, params))
    m1 = n - len(qi)
    phi = np.asarray(system._phi(q, params))
    if phi.size and np.max(np.abs(phi)) > tol:
        raise ConstraintError(
            f"the operating point of {system.name} is not on its constraints: phi(q) = "
            f"{phi} (tolerance {tol:g}); project it first (ConstrainedSystem.project)"
        )
    rate = kmat @ np.asarray(qd)
    if rate.size and np.max(np.abs(rate)) > tol * (1.0 + np.max(np.abs(qd))):
        raise ConstraintError(
            f"the operating velocities of {system.name} violate its constraints: "
            f"K(q) qd = {rate} (tolerance {tol:g}); project the state first"
        )
    blocks = (
        (kmat[:m1], _complement(n, qi), "coordinates", "J_d = dphi/dq_d"),
        (kmat, _complement(n, ui), "speeds", "K_d = [J; A]_d"),
    )
    for rows, dep, what, label in blocks:
        if not dep:
            continue
        block = rows[:, list(dep)]
        sv = np.linalg.svd(block, compute_uv=False)
        if sv[-1] <= 1e-10 * max(sv[0], np.max(np.abs(rows)), 1e-300):
            names = ", ".join(_name(system, k) for k in dep)
            raise ConstraintError(
                f"the dependent {what} {names} of {system.name} cannot be solved for: the "
                f"constraint Jacobian block {label} is singular at this point (singular "
                f"values {sv}); choose other independent {what}"
            )


def _check_steady(system, udot: np.ndarray, ui, tol: float) -> None:
    bad = [(k, float(a)) for k, a in zip(ui, udot, strict=True) if not abs(a) <= tol]
    if bad:
        listed = "; ".join(f"d/dt of the speed of {_name(system, k)} = {a:.3e}" for k, a in bad)
        raise LagraxError(
            f"the operating point of {system.name} is not a steady motion: the reduced "
            f"acceleration is not zero ({listed}; tolerance {tol:g}). Linearize about an "
            "equilibrium or a steady motion (constant independent speeds)"
        )


def _body(system, t, q0, qd0, params, tau0, qi, ui):
    """`(A, B, u̇_i*)` at the operating point (see the module docstring)."""
    n = q0.shape[0]
    eye = jnp.eye(n, dtype=q0.dtype)
    qdep, udep = _complement(n, qi), _complement(n, ui)
    iq, iu = np.array(qi, dtype=int), np.array(ui, dtype=int)
    pq = eye[:, iq]
    if qdep:
        jac = system._jacobian(q0, params)
        solved = jnp.linalg.solve(jac[:, np.array(qdep)], jac[:, iq])
        pq = pq - eye[:, np.array(qdep)] @ solved

    def speeds(q, u_i):
        u = jnp.zeros((n,), u_i.dtype).at[iu].set(u_i)
        if not udep:
            return u
        kmat = system._kmat(q, params).astype(u_i.dtype)
        u_d = -jnp.linalg.solve(kmat[:, np.array(udep)], kmat[:, iu] @ u_i)
        return u.at[np.array(udep)].set(u_d)

    def rates(x, tau):
        dq_i, u_i = x[: len(qi)], x[len(qi) :]
        q = q0 + pq @ dq_i
        u = speeds(q, u_i)
        qdd = system._kkt(t, q, u, params, tau)[0]
        return jnp.concatenate([u[iq], qdd[iu]])

    x0 = jnp.concatenate([jnp.zeros((len(qi),), q0.dtype), qd0[iu]])
    n_x = x0.shape[0]
    basis = jnp.eye(n_x + n, dtype=q0.dtype)

    def along(tangent):  # one JVP per basis direction of (x, τ); the primal once
        return jax.jvp(rates, (x0, tau0), (tangent[:n_x], tangent[n_x:]))

    primal, cols = jax.vmap(along, out_axes=(None, 1))(basis)
    return cols[:, :n_x], cols[:, n_x:], primal[len(qi) :]


_compiled = eqx.filter_jit(_body)
# An eager call is usually compiled for few calls: XLA's backend optimization level 0
# halves the compile (the benchmark bicycle: 21 s instead of 40 s on a loaded 2-core CPU)
# for a slower run (16 ms a call); under a user's `jit` or `vmap`, the optimized program.
_eager = eqx.filter_jit(_body, compiler_options={"xla_backend_optimization_level": 0})
