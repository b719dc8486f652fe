r"""The derivatives API of a [`FloatingBaseSystem`][lagrax.chains.FloatingBaseSystem], on
the tangent space of its configuration (Pinocchio's convention).

A floating base's configuration `q = (p, quat, joints)` (size `7 + n`) lives on
`SE(3) × ℝⁿ`, not in a vector space: its derivatives are taken along the `6 + n`
velocity directions `δ`, through Pinocchio's `integrate`,

$$
q ⊕ δ = \bigl(p + R\,δ_v + O(|δ|^2),\; quat ⊗ \exp(δ_ω / 2),\; joints + δ_{joints}\bigr),
$$

the base moved by the twist `δ_B = (δ_v, δ_ω)` in its own frame (`M · exp6(δ_B)`). These
are the columns that Pinocchio's `computeABADerivatives` and `computeRNEADerivatives`
return for a free-flyer model: `∂/∂q` here means `∂/∂δ` at `δ = 0`. (`q ⊕ δ` is written
here to first order in `δ`, which is all a first derivative sees.)

The accelerations' derivatives come from the inverse dynamics' at the primal `v̇`, as
everywhere in lagrax (`lagrax._systems.implicit`):

$$
\frac{∂v̇}{∂q} = −M⁻¹ \frac{∂τ}{∂q}, \qquad \frac{∂v̇}{∂v} = −M⁻¹ \frac{∂τ}{∂v},
\qquad \frac{∂v̇}{∂τ} = M⁻¹,
$$

with `τ = M v̇ + b + ∂D/∂v` (`FloatingBaseSystem.inverse_dynamics`, recursive
Newton–Euler with a free root), whose Jacobians and `M` come from one outward and one
inward pass of the analytic recursion with the base as a six-column root joint
(`derivative_recursions.free_root_derivatives`, `O(n²)` as for a fixed base). One
Cholesky factorization of `M` applies `M⁻¹` to all `3(6 + n)` columns.

**Linearization.** About `(q_eq, v_eq)`, write `q = q_eq ⊕ δ`. The base's twist in its
frame is `V = J_r(δ) δ̇` (`J_r` the right Jacobian of `SE(3)`'s exponential,
`J_r(δ) = I − ½ ad_δ + O(δ²)`), so `δ̇ = J_r(δ)⁻¹ V = V − ½ ad_V δ + O(δ²)`, with
`ad_V = [[ω×, v×], [0, ω×]]` for `V = (v, ω)`. With the state `x = (δ, v)`:

$$
A = \begin{pmatrix} −½\,\mathrm{ad}_{V_{eq}} ⊕ 0 & I \\ ∂v̇/∂q & ∂v̇/∂v \end{pmatrix},
\qquad B = \begin{pmatrix} 0 \\ M⁻¹ \end{pmatrix},
$$

where `−½ ad_{V_eq}` is the base's `6 × 6` block (zero for a base at rest) and the
joints' configuration block is zero.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import equinox as eqx
import jax
import jax.numpy as jnp

from .._core.blocking import blocked
from .._core.checks import finite, traced
from .._systems.dynamics_derivatives import _program, _state_space
from .._systems.lagrangian_checks import finite_derivatives, float_arrays
from .._systems.sensitivity import (
    ForwardDynamicsDerivatives,
    InverseDynamicsDerivatives,
    _jacobian_wrt_params,
    by_solves,
)
from . import derivative_recursions as dr
from . import floating_recursions as fr
from . import joint_space as js

if TYPE_CHECKING:
    from .floating import FloatingBaseSystem


def retract(q: Any, delta: Any) -> jnp.ndarray:
    """`q ⊕ δ` to first order in `δ` (see the module docstring): the base origin moved by
    `R δ_v`, the quaternion by `½ quat ⊗ (δ_ω, 0)` (normalized where it is read), the
    joints by `δ_joints`."""
    quat = q[3:7]
    moved = q[:3] + fr.quaternion_rotation(quat) @ delta[:3]
    return jnp.concatenate([moved, quat + fr.quaternion_rate(quat, delta[3:6]), q[7:] + delta[6:]])


def twist_adjoint(twist: Any) -> jnp.ndarray:
    """`ad_V = [[ω×, v×], [0, ω×]]` of a twist `V = (v, ω)` (linear part first, as
    Pinocchio's `Motion`): `ad_V W = V × W`."""
    v, w = fr.skew(twist[:3]), fr.skew(twist[3:6])
    return jnp.block([[w, v], [jnp.zeros_like(w), w]])


def _inverse_jacobians(system: FloatingBaseSystem, q, v, vdot, params):
    """`(τ, ∂τ/∂q, ∂τ/∂v, M)` at `(q, v, v̇)`, `∂τ/∂q` along `q ⊕ δ`: the analytic
    recursion with a free root (`derivative_recursions.free_root_derivatives`), reduced
    to the coordinates for mimic joints, with the joint damping's `∂τ/∂v`; a lone rigid
    body (no joints) by forward-mode derivatives of its Newton–Euler equations."""
    tree = system.robot.tree
    if tree.n_bodies == 0:
        zero = jnp.zeros(system.n_dof, q.dtype)
        jq, jv = jax.jacfwd(
            lambda d, w: system._inverse(retract(q, d), w, vdot, params), argnums=(0, 1)
        )(zero, v)
        return system._inverse(q, v, vdot, params), jq, jv, system._mass(system._at(q, params))[0]
    fc = system._at(q, params)
    links = fc.chain.passes.links
    v_all, vdot_all = system._full(v), system._full(vdot)
    tau, jq, jv, mass = dr.free_root_derivatives(
        fc.chain,
        fc.s_base,
        fc.inertia_base,
        links(v_all[6:]),
        links(vdot_all[6:]),
        v_all[:6],
        vdot_all[:6],
    )
    # armature and joint springs, on every body's joint: τ ⊃ a θ̈ + ∂V_s/∂θ, M ⊃ diag(a),
    # ∂τ/∂q ⊃ K_s (`joint_space`)
    tau = tau.at[6:].add(js.joint_inverse(params, fc.theta, vdot_all[6:]))
    mass = js.with_armature(mass, params, offset=6)
    stiffness = js.stiffness_matrix(params, tree.n_bodies, q.dtype)
    if stiffness is not None:
        jq = jq.at[6:, 6:].add(stiffness)
    if tree.mimic:  # θ = J q + b: every matrix is J_Bᵀ (·) J_B, τ is J_Bᵀ τ_θ
        j_b = system._coupling(q.dtype)
        tau, jq, jv, mass = j_b.T @ tau, j_b.T @ jq @ j_b, j_b.T @ jv @ j_b, j_b.T @ mass @ j_b
    damping = jax.jacfwd(lambda w: system._damping(params, w))(v)  # constant: `J_Bᵀ b J_B`
    return tau + system._damping(params, v), jq, jv + damping, mass


def _forward_body(system: FloatingBaseSystem, t, q, v, params, tau, wrt_params: bool):
    vdot = system.accelerations(t, q, v, params, tau)
    _, jq, jv, mass = _inverse_jacobians(system, q, v, vdot, params)
    dparams = None
    if wrt_params:
        dparams = _jacobian_wrt_params(lambda p: system.accelerations(t, q, v, p, tau), params)
    return by_solves(vdot, jq, jv, mass, dparams)


def _inverse_body(system: FloatingBaseSystem, t, q, v, vdot, params, wrt_params: bool):
    tau, jq, jv, mass = _inverse_jacobians(system, q, v, vdot, params)
    dparams = None
    if wrt_params:
        dparams = _jacobian_wrt_params(lambda p: system._inverse(q, v, vdot, p), params)
    return InverseDynamicsDerivatives(tau, jq, jv, mass, dparams)


_forward = eqx.filter_jit(_forward_body)
_inverse_program = eqx.filter_jit(_inverse_body)


def forward_dynamics_derivatives(
    system: FloatingBaseSystem, q, qd, params, tau, t, wrt_params: bool
) -> ForwardDynamicsDerivatives:
    """`FloatingBaseSystem.forward_dynamics_derivatives` (documented there)."""
    q, v, tau = finite_inputs(system, "tau", *system._inputs(q, qd=qd, tau=tau))
    tau = jnp.zeros_like(v) if tau is None else tau
    program, eager = _program(system, _forward, _forward_body, q, v, tau, params, t)
    out = blocked(program)(
        system, t, q, v, float_arrays(params) if eager else params, tau, wrt_params
    )
    return finite_derivatives(system, out, q, v, params, tau, t, "forward_dynamics")


def inverse_dynamics_derivatives(
    system: FloatingBaseSystem, q, qd, qdd, params, t, wrt_params: bool
) -> InverseDynamicsDerivatives:
    """`FloatingBaseSystem.inverse_dynamics_derivatives` (documented there)."""
    q, v, vdot = finite_inputs(system, "qdd", *system._inputs(q, qd=qd, qdd=qdd))
    program, eager = _program(system, _inverse_program, _inverse_body, q, v, vdot, params, t)
    out = blocked(program)(
        system, t, q, v, vdot, float_arrays(params) if eager else params, wrt_params
    )
    return finite_derivatives(system, out, q, v, params, None, t, "inverse_dynamics")


def finite_inputs(system: FloatingBaseSystem, third: str, q, v, w):
    """The inputs, checked finite: a NaN in the base's position, which the dynamics do
    not read, would otherwise pass unnoticed. Eagerly a `NonFiniteError` naming the
    input; traced, through `equinox.error_if`."""
    names = ("q", "qd", third)
    if not traced(system, q, v, w):
        for name, x in zip(names, (q, v, w), strict=True):
            if x is not None:
                finite(x, name)
        return q, v, w
    ok = jnp.all(jnp.isfinite(q)) & jnp.all(jnp.isfinite(v))
    if w is not None:
        ok = ok & jnp.all(jnp.isfinite(w))
    q = eqx.error_if(q, ~ok, f"the state or input of {system.name} is not finite (NaN/inf)")
    return q, v, w


def linearize(
    system: FloatingBaseSystem, q_eq, qd_eq, params, tau_eq, t
) -> tuple[jax.Array, jax.Array]:
    """`FloatingBaseSystem.linearize` (documented there): `(A, B)`."""
    out = forward_dynamics_derivatives(system, q_eq, qd_eq, params, tau_eq, t, False)
    (v,) = system._inputs(q_eq, qd=qd_eq)[1:]
    a_mat, b_mat = _state_space(out)  # a vector space's A, whose ∂δ̇/∂δ is zero
    return a_mat.at[:6, :6].set(-0.5 * twist_adjoint(v[:6].astype(a_mat.dtype))), b_mat
