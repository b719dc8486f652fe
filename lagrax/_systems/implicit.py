r"""Derivatives of the accelerations through the inverse dynamics.

The accelerations `q̈ = FD(t, q, q̇, p, τ)` solve `r(t, q, q̇, q̈, p) = τ` with the
*residual*

$$
r(t, q, q̇, q̈, p) = M(q) q̈ + C(q, q̇) q̇ + G(q) + ∂D/∂q̇ − F(t, q, q̇)
$$

(the inverse dynamics less the applied forces: what the input must be for `q̈`), and
`∂r/∂q̈ = M`. Differentiating `r(…, FD(…), …) = τ` (the implicit function theorem) gives
the tangent of the accelerations

$$
δq̈ = M⁻¹ \bigl(δτ − \tfrac{∂r}{∂q} δq − \tfrac{∂r}{∂q̇} δq̇ − \tfrac{∂r}{∂p} δp
− \tfrac{∂r}{∂t} δt\bigr), \qquad \frac{∂q̈}{∂τ} = M⁻¹,
$$

at the primal `q̈`: only derivatives of the inverse dynamics at a *fixed* `q̈` and the
mass matrix, never a derivative of the factorization or of the articulated-body recursion.
`accelerations` carries this rule (a custom JVP), so `jax.jvp`, `jax.jacfwd`, `jax.grad`
(JAX transposes the linear tangent map), `jax.vmap`, `linearize` and `simulate` all use it.

- `∂r/∂q`, `∂r/∂q̇` and `M` are formed once per state from the primal values (so a Jacobian
  of `3n` tangents costs them once): for chains and trees by the structure-aware equations'
  `derivatives` (Featherstone's recursions differentiated analytically, `O(n²)`), for
  energies by forward-mode derivatives of the inverse dynamics.
- `∂r/∂p δp` and `∂r/∂t δt` are directional derivatives, computed only when `p` or `t` is
  differentiated.
- `M⁻¹` is an explicit small inverse from one Cholesky factorization, shared by every
  tangent (NaN where `M` is not positive-definite, as the accelerations are).

The primal is the same computation as without the rule (bit for bit), so a solve gives the
same steps whether it is differentiated or not. Values a derivative should flow into must
come in through the arguments (`params`, the state, `τ`, `t`), not through a closure of
the energy functions over traced values.
"""

import contextlib
from collections.abc import Callable, Iterator
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu

from .._core.blocking import blocked
from .._core.closures import differentiated_closure
from .._core.linalg import small_matmul, spd_inverse
from . import derivatives as d

_RULE = {"on": True}


@contextlib.contextmanager
def switched_off(switch: dict) -> Iterator[None]:
    """Within this context `switch["on"]` is `False`: a trace-time switch for a custom
    derivative rule, which tests turn off to compare the rule with its definition."""
    before = switch["on"]
    switch["on"] = False
    try:
        yield
    finally:
        switch["on"] = before


def plain_autodiff() -> contextlib.AbstractContextManager[None]:
    """Within this context, functions traced differentiate the accelerations by plain
    automatic differentiation through their computation (the factorization, the
    articulated-body recursion) instead of through the inverse dynamics: the definition the
    tests hold the rule to. Trace-time only: a function compiled outside keeps its rule."""
    return switched_off(_RULE)


def rule_on(system: Any) -> bool:
    """Whether the accelerations of `system` traced now carry the inverse-dynamics rule:
    unless switched off (`plain_autodiff`), or where the system's functions close over a
    value that automatic differentiation traces (a rule sees only its arguments, so such
    a derivative must go through the computation itself)."""
    return _RULE["on"] and not differentiated_closure(system)


def residual(e: d.Energies, t, q, qd, qdd, params):
    """`r = M q̈ + C q̇ + G + ∂D/∂q̇ − F`: the input `τ` for which `q̈` are the accelerations."""
    if e.equations is not None:
        out = e.equations.inverse_dynamics(q, qd, qdd, params)
    elif d.timed(e):
        s = d.time_of(t, q)
        (t_q, _), (_, dp) = jax.jvp(
            lambda a, b, c: d.grad_kinetic(e, a, b, params, c),
            (q, qd, s),
            (qd, qdd, jnp.ones_like(s)),
        )
        out = dp - t_q + d.gravity(e, q, params, t)
    else:
        (t_q, _), (_, dp) = jax.jvp(
            lambda a, b: d.grad_kinetic(e, a, b, params), (q, qd), (qd, qdd)
        )
        out = dp - t_q + d.gravity(e, q, params, t)
    if e.force is not None or e.dissipation is not None:
        out = out - d.applied(e, t, q, qd, params, None)
    return out


def residual_small(e: d.Energies, t, q, qd, qdd, params):
    """`residual` by scalar forward-over-forward derivatives (`derivatives.eom_small`)."""
    rows, rhs = d.eom_small(e, q, qd, params, t)
    n = q.shape[0]
    out = jnp.stack([sum(rows[i][j] * qdd[j] for j in range(n)) - rhs[i] for i in range(n)])
    if e.force is not None or e.dissipation is not None:
        out = out - d.applied(e, t, q, qd, params, None)
    return out


def residual_jacobians(e: d.Energies, scalar: bool | None, t, q, qd, qdd, params):
    """`(∂r/∂q, ∂r/∂q̇, M)` at `(t, q, q̇, q̈)`, each `(n, n)`.

    Structure-aware equations give their own (`equations.derivatives`, analytic for chains
    and trees); the energies' come from `jax.jacfwd` of the residual, and `M` from the same
    derivatives of `T` the accelerations use. Applied forces and dissipation add their own
    Jacobians.
    """
    if e.equations is not None:
        jq, jqd, mass = e.equations.derivatives(q, qd, qdd, params)
        return (*_less_applied(e, t, q, qd, params, jq, jqd), mass)
    if d.use_scalar(q.shape[0], scalar):
        jq, jqd = jax.jacfwd(lambda a, b: residual_small(e, t, a, b, qdd, params), argnums=(0, 1))(
            q, qd
        )
        rows, _ = d.eom_small(e, q, qd, params, t)
        return jq, jqd, jnp.stack([jnp.stack(row) for row in rows])
    jq, jqd = jax.jacfwd(lambda a, b: residual(e, t, a, b, qdd, params), argnums=(0, 1))(q, qd)
    return jq, jqd, d.mass_matrix(e, q, qd, params, t)


def along_given(fn: Callable, primals: tuple, tangents: tuple):
    """`(along, values, directions)`: `fn(*primals)` as a function `along(*values)` of
    only the leaves whose tangent is given (a symbolic zero is `None`, leaf by leaf), those
    leaves, and their tangents; `jax.jvp(along, values, directions)` is then `fn`'s JVP."""
    leaves, tree = jtu.tree_flatten(primals)
    # Up to the primals' leaves: a `None` in the primals (an empty subtree, no leaf) must
    # not count as a tangent's place, or the tangents pair with the wrong leaves.
    given = tree.flatten_up_to(tangents)
    picked = [i for i, x in enumerate(given) if x is not None]

    def along(*values):
        full = list(leaves)
        for i, value in zip(picked, values, strict=True):
            full[i] = value
        return fn(*jtu.tree_unflatten(tree, full))

    return along, tuple(leaves[i] for i in picked), tuple(given[i] for i in picked)


def jvp_of_given(fn: Callable, primals: tuple, tangents: tuple):
    """`jax.jvp(fn, primals, tangents)[1]` along the leaves whose tangent is given (a
    symbolic zero is `None`, leaf by leaf); `None` when no tangent is given."""
    along, values, directions = along_given(fn, primals, tangents)
    if not values:
        return None
    return jax.jvp(along, values, directions)[1]


def _raw(e, scalar, t, q, qd, params, tau):
    return d.accelerations(e, scalar, t, q, qd, params, tau)


@eqx.filter_custom_jvp
def _with_rule(e, scalar, t, q, qd, params, tau):
    return _raw(e, scalar, t, q, qd, params, tau)


@_with_rule.def_jvp
def _tangent(primals, tangents):
    e, scalar, t, q, qd, params, tau = primals
    _, _, dt, dq, dqd, dparams, dtau = tangents
    sizes = blocks(e)
    if e.equations is not None and sizes[0] == sizes[1]:
        # one evaluation of the structure's kinematics for q̈ and the Jacobians
        qdd, jq, jqd, m_inv = blocked(_primal_and_jacobians, sizes[0])(e, t, q, qd, params, tau)
    else:
        qdd = blocked(_raw, sizes[0])(e, scalar, t, q, qd, params, tau)
        jq = None
    rhs = jnp.zeros_like(qdd) if dtau is None else dtau.astype(qdd.dtype)
    if e.equations is None and d.use_scalar(q.shape[0], scalar):
        rows, _ = d.eom_small(e, q, qd, params, t)
        rest = jvp_of_given(
            lambda a, b, s, p: residual_small(e, s, a, b, qdd, p),
            (q, qd, t, params),
            (dq, dqd, dt, dparams),
        )
        if rest is not None:
            rhs = rhs - rest
        return qdd, jnp.stack(d.solve_spd_unrolled(rows, [rhs[i] for i in range(q.shape[0])]))
    if jq is None:
        jq, jqd, m_inv = blocked(_jacobians, sizes[1])(e, scalar, t, q, qd, qdd, params)
    mm = matmul(e)
    if dq is not None:
        rhs = rhs - mm(jq, dq)
    if dqd is not None:
        rhs = rhs - mm(jqd, dqd)
    rest = jvp_of_given(lambda s, p: residual(e, s, q, qd, qdd, p), (t, params), (dt, dparams))
    if rest is not None:
        rhs = rhs - rest
    return qdd, mm(m_inv, rhs)


def primal_and_jacobians(e: d.Energies, t, q, qd, params, tau):
    """`(q̈, ∂r/∂q, ∂r/∂q̇, M)` from structure-aware equations: the accelerations and
    `residual_jacobians` with the structure's kinematics evaluated once."""
    f = d.applied_or_none(e, t, q, qd, params, tau)
    qdd, jq, jqd, mass = e.equations.accelerations_and_derivatives(q, qd, params, f)
    return (qdd, *_less_applied(e, t, q, qd, params, jq, jqd), mass)


def _primal_and_jacobians(e, t, q, qd, params, tau):
    """`(q̈, ∂r/∂q, ∂r/∂q̇, M⁻¹)`: `primal_and_jacobians` with `M` inverted (in the same
    block of states)."""
    qdd, jq, jqd, mass = primal_and_jacobians(e, t, q, qd, params, tau)
    return qdd, jq, jqd, spd_inverse(mass)


def _less_applied(e: d.Energies, t, q, qd, params, jq, jqd):
    """`(∂r/∂q, ∂r/∂q̇)` from the inverse dynamics' Jacobians: less those of the applied
    forces and dissipation, where there are any."""
    if e.force is None and e.dissipation is None:
        return jq, jqd
    aq, aqd = jax.jacfwd(lambda a, b: d.applied(e, t, a, b, params, None), argnums=(0, 1))(q, qd)
    return jq - aq, jqd - aqd


def _jacobians(e, scalar, t, q, qd, qdd, params):
    """`(∂r/∂q, ∂r/∂q̇, M⁻¹)`: what every tangent of the accelerations applies."""
    jq, jqd, mass = residual_jacobians(e, scalar, t, q, qd, qdd, params)
    return jq, jqd, spd_inverse(mass)


def accelerations(e: d.Energies, scalar: bool | None, t, q, qd, params, tau) -> Any:
    """`q̈ = M⁻¹(τ + F − C q̇ − G − ∂D/∂q̇)` (see `derivatives.accelerations`), whose
    derivatives go through the inverse dynamics (see the module docstring)."""
    if not rule_on(e):
        return _raw(e, scalar, t, q, qd, params, tau)
    return blocked(_with_rule, blocks(e)[0])(e, scalar, t, q, qd, params, tau)


def blocks(e: d.Energies) -> tuple[int | None, int | None]:
    """States per block of a large vmapped batch, for the accelerations and for their
    derivatives (`lagrax._core.blocking`): the structure-aware equations' choice; the
    energies' straight-line code is never blocked."""
    return (None, None) if e.equations is None else e.equations.blocks()


def matmul(e: d.Energies) -> Callable[[Any, Any], Any]:
    """The matrix product applying `∂r/∂q`, `∂r/∂q̇` and `M⁻¹`: written out
    (`linalg.small_matmul`) for the structure-aware equations, whose Jacobians come out of
    recursions; `@` for energies, whose fused derivative code XLA would otherwise
    re-evaluate for every written-out entry (2.4× slower for the 2R arm)."""
    return jnp.matmul if e.equations is None else small_matmul
