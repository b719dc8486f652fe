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

import abc
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp

from ..._core.blocking import blocked
from ..._core.checks import finite, traced
from ..._core.custom_types import Params
from ..._systems.abstract import AbstractSystem
from ..._systems.dynamics_derivatives import choose_program, state_space
from ..._systems.lagrangian_checks import finite_derivatives, float_arrays
from ..._systems.sensitivity import (
    ForwardDynamicsDerivatives,
    InverseDynamicsDerivatives,
    forward_by_inverse_jacobians,
    inverse_by_jacobians,
)
from .. import joint_space as js
from ..algorithms import derivative_recursions as dr
from ..algorithms import floating_recursions as fr
from ..articulated import balls


def retract(q: Any, delta: Any, tree: Any = None) -> jnp.ndarray:
    """`q ⊕ δ` to first order in `δ` (see the module docstring): the base origin moved by
    `R δ_v`, the quaternion by `½ quat ⊗ (δ_ω, 0)` (normalized where it is read), the
    joints by `δ_joints` (a `tree` with ball joints: each ball's quaternion likewise by
    its `δ`, `balls.retract`)."""
    quat = q[3:7]
    moved = q[:3] + fr.quaternion_rotation(quat) @ delta[:3]
    if tree is not None and tree.balls:
        joints = balls.retract(tree, q[7:], delta[6:])
    else:
        joints = q[7:] + delta[6:]
    return jnp.concatenate([moved, quat + fr.quaternion_rate(quat, delta[3:6]), joints])


def twist_adjoint(twist: Any) -> jnp.ndarray:
    """`ad_V = [[ω×, v×], [0, ω×]]` of a twist `V = (v, ω)` (linear part first, as
    Pinocchio's `Motion`): `ad_V W = V × W`."""
    v, w = fr.skew(twist[:3]), fr.skew(twist[3:6])
    return jnp.block([[w, v], [jnp.zeros_like(w), w]])


def _inverse_jacobians(system: FloatingDerivatives, q, v, vdot, params):
    """`(τ, ∂τ/∂q, ∂τ/∂v, M)` at `(q, v, v̇)`, `∂τ/∂q` along `q ⊕ δ`: the analytic
    recursion with a free root (`derivative_recursions.free_root_derivatives`), reduced
    to the coordinates for mimic joints, with the joint damping's `∂τ/∂v` (ball joints:
    the lanes' at `θ̈ = v̇ − P δ`, with the balls' tangent terms,
    `balls.tangent_derivatives`); a lone rigid body (no joints) by forward-mode
    derivatives of its Newton–Euler equations."""
    tree = system.robot.tree
    if tree.n_bodies == 0:
        zero = jnp.zeros(system.n_dof, q.dtype)
        jq, jv = jax.jacfwd(
            lambda d, w: system._inverse(retract(q, d, tree), w, vdot, params), argnums=(0, 1)
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
        links(_lanes(tree, v_all, vdot_all) if tree.balls else vdot_all[6:]),
        v_all[:6],
        vdot_all[:6],
    )
    if tree.balls:  # along each ball's `R exp([ξ]×)` at fixed `(ω, ω̇)`
        jq, jv = balls.tangent_derivatives(
            tree.balls, tau, jq, jv, mass, v_all[6:], vdot_all[6:], offset=6
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


def _lanes(tree: Any, v: Any, vdot: Any) -> jnp.ndarray:
    """The lanes' accelerations `v̇_joints − P δ` of a tree with ball joints."""
    return vdot[6:] - balls.velocity_product(tree.balls, v[6:])


def _forward_body(system: FloatingDerivatives, t, q, v, params, tau, wrt_params: bool):
    return forward_by_inverse_jacobians(
        lambda p: system.accelerations(t, q, v, p, tau),
        lambda vdot: _inverse_jacobians(system, q, v, vdot, params),
        params,
        wrt_params,
    )


def _inverse_body(system: FloatingDerivatives, t, q, v, vdot, params, wrt_params: bool):
    return inverse_by_jacobians(
        lambda p: system._inverse(q, v, vdot, p),
        lambda w: _inverse_jacobians(system, q, v, w, params),
        vdot,
        params,
        wrt_params,
    )


def forward_dynamics_derivatives(
    system: FloatingDerivatives, q, qd, params, tau, t, wrt_params: bool, names=("q", "qd", "tau")
) -> ForwardDynamicsDerivatives:
    """`FloatingBaseSystem.forward_dynamics_derivatives` (documented there); `names`:
    the caller's arguments, for the messages."""
    checked = system._inputs(q, names[0], **{names[1]: qd, names[2]: tau})
    q, v, tau = finite_inputs(system, names, *checked)
    tau = jnp.zeros_like(v) if tau is None else tau
    program, eager = choose_program(system, _forward_body, q, v, tau, params, t)
    out = blocked(program)(
        system, t, q, v, float_arrays(params) if eager else params, tau, wrt_params
    )
    return finite_derivatives(system, out, q, v, params, tau, t, "forward_dynamics")


def inverse_dynamics_derivatives(
    system: FloatingDerivatives, q, qd, qdd, params, t, wrt_params: bool
) -> InverseDynamicsDerivatives:
    """`FloatingBaseSystem.inverse_dynamics_derivatives` (documented there)."""
    q, v, vdot = finite_inputs(system, ("q", "qd", "qdd"), *system._inputs(q, qd=qd, qdd=qdd))
    program, eager = choose_program(system, _inverse_body, q, v, vdot, params, t)
    out = blocked(program)(
        system, t, q, v, vdot, float_arrays(params) if eager else params, wrt_params
    )
    return finite_derivatives(system, out, q, v, params, None, t, "inverse_dynamics")


def finite_inputs(system: FloatingDerivatives, names: tuple[str, str, str], q, v, w):
    """The inputs, checked finite: a NaN in the base's position, which the dynamics do
    not read, would otherwise pass unnoticed. Eagerly a `NonFiniteError` naming the
    input (`names`: the caller's arguments); traced, through `equinox.error_if`."""
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
    system: FloatingDerivatives, q_eq, qd_eq, params, tau_eq, t
) -> tuple[jax.Array, jax.Array]:
    """`FloatingBaseSystem.linearize` (documented there): `(A, B)`."""
    names = ("q_eq", "qd_eq", "tau_eq")
    out = forward_dynamics_derivatives(system, q_eq, qd_eq, params, tau_eq, t, False, names)
    (v,) = system._inputs(q_eq, "q_eq", qd_eq=qd_eq)[1:]
    a_mat, b_mat = state_space(out)  # a vector space's A, whose ∂δ̇/∂δ is zero
    a_mat = a_mat.at[:6, :6].set(-0.5 * twist_adjoint(v[:6].astype(a_mat.dtype)))
    return balls.rotation_blocks(a_mat, system.robot.tree.balls, v, offset=6), b_mat


class FloatingDerivatives(AbstractSystem):
    """The derivatives calls of a floating-base system, on the tangent space of its
    configuration: the interface [`FloatingBaseSystem`][lagrax.chains.FloatingBaseSystem]
    implements (its recursions, `_at`, and the reductions by the mimic map), below it so
    that the system imports its derivatives and not the other way round."""

    robot: eqx.AbstractVar[Any]

    @abc.abstractmethod
    def _inputs(self, q: Any, q_name: str = "q", **velocities: Any) -> list[Any]: ...

    @abc.abstractmethod
    def _at(self, q: Any, params: Params) -> fr.FloatingChain: ...

    @abc.abstractmethod
    def _full(self, v: Any) -> Any: ...

    @abc.abstractmethod
    def _mass(self, fc: fr.FloatingChain) -> tuple[jnp.ndarray, jnp.ndarray]: ...

    @abc.abstractmethod
    def _coupling(self, dtype: Any) -> jnp.ndarray: ...

    @abc.abstractmethod
    def _inverse(self, q: Any, v: Any, vdot: Any, params: Params) -> jnp.ndarray: ...

    @abc.abstractmethod
    def _damping(self, params: Params, v: Any) -> jnp.ndarray: ...

    def forward_dynamics_derivatives(
        self,
        q: Any,
        qd: Any,
        params: Params,
        tau: Any = None,
        t: Any = 0.0,
        *,
        wrt_params: bool = False,
    ) -> ForwardDynamicsDerivatives:
        r"""`v̇` and its derivatives at one state, in one call (Pinocchio's
        `computeABADerivatives` on a free-flyer model, the same numbers).

        The derivatives with respect to the configuration are on its tangent space:
        along `q ⊕ δ` (Pinocchio's `integrate`: the base moved by the twist
        `δ[:6] = (δ_v, δ_ω)` in its own frame, the joints by `δ[6:]`), so `dq` is
        `(6 + n) × (6 + n)`, not `(6 + n) × (7 + n)`. From the inverse dynamics at the
        primal `v̇`:

        $$
        \frac{∂v̇}{∂q} = −M⁻¹ \frac{∂τ}{∂q}, \qquad
        \frac{∂v̇}{∂v} = −M⁻¹ \frac{∂τ}{∂v}, \qquad \frac{∂v̇}{∂τ} = M⁻¹.
        $$

        **Arguments:** `q` `(7 + n,)`, `qd` = `v` `(6 + n,)`, `params`, `tau`
        `(6 + n,)` (default zero), the time `t` (unused: the equations are autonomous),
        and `wrt_params=True` to add `∂v̇/∂params`.

        **Returns:** a [`ForwardDynamicsDerivatives`][lagrax.ForwardDynamicsDerivatives]
        (`qdd` = `v̇`, `dq`, `dqd`, `dtau`, `dparams`).

        **Raises:** `ShapeError` for wrong sizes; `NonFiniteError` for non-finite inputs
        or results, `MassMatrixError` for a mass matrix that is not positive-definite
        (under `jit`, a `NonFiniteError` through `equinox.error_if`).
        """
        return forward_dynamics_derivatives(self, q, qd, params, tau, t, wrt_params)

    def inverse_dynamics_derivatives(
        self,
        q: Any,
        qd: Any,
        qdd: Any,
        params: Params,
        t: Any = 0.0,
        *,
        wrt_params: bool = False,
    ) -> InverseDynamicsDerivatives:
        """`τ = M v̇ + b + ∂D/∂v` and its derivatives at one state, in one call
        (Pinocchio's `computeRNEADerivatives` on a free-flyer model): `∂τ/∂q` on the
        tangent space of the configuration (along `q ⊕ δ`, as
        [`forward_dynamics_derivatives`][lagrax.chains.FloatingBaseSystem.forward_dynamics_derivatives]),
        `∂τ/∂v`, `∂τ/∂v̇ = M` and, with `wrt_params=True`, `∂τ/∂params`.

        **Arguments:** `q` `(7 + n,)`, `qd` = `v` and `qdd` = `v̇` `(6 + n,)`,
        `params`, the time `t` (unused), `wrt_params`.

        **Returns:** an [`InverseDynamicsDerivatives`][lagrax.InverseDynamicsDerivatives].

        **Raises:** `ShapeError` for wrong sizes; `NonFiniteError` for non-finite inputs
        or results.
        """
        return inverse_dynamics_derivatives(self, q, qd, qdd, params, t, wrt_params)

    def linearize(
        self,
        q_eq: Any,
        qd_eq: Any,
        params: Params,
        tau_eq: Any = None,
        *,
        t: Any = 0.0,
    ) -> tuple[jax.Array, jax.Array]:
        r"""Linearization `δẋ = A δx + B δτ` on the tangent space, about
        `(q_eq, v_eq, τ_eq)`.

        The configuration is `q = q_eq ⊕ δ` (Pinocchio's `integrate`) and the state
        `x = (δ, v)`, of size `2(6 + n)`. The base's twist is `V = J_r(δ) δ̇` (`J_r` the
        right Jacobian of `SE(3)`'s exponential), so `δ̇ = V − ½ ad_V δ + O(δ²)`:

        $$
        A = \begin{pmatrix} −½\,\mathrm{ad}_{V_{eq}} ⊕ 0 & I \\
        ∂v̇/∂q & ∂v̇/∂v \end{pmatrix}, \qquad
        B = \begin{pmatrix} 0 \\ M⁻¹ \end{pmatrix},
        $$

        with `ad_V = [[ω×, v×], [0, ω×]]` for the base's `V = (v, ω)` (a zero block
        for a base at rest, and for the joints). `τ`'s first six entries act on the
        base: keep the columns of the inputs a robot has (`B[:, 6:]` for a free robot
        with every joint driven).

        **Arguments:** `q_eq` `(7 + n,)`, `qd_eq` = `v_eq` `(6 + n,)`, `params`, `tau_eq`
        (default zero), `t` (unused).

        **Returns:** `(A, B)`, shapes `(2(6 + n), 2(6 + n))` and `(2(6 + n), 6 + n)`.

        **Raises:** as
        [`forward_dynamics_derivatives`][lagrax.chains.FloatingBaseSystem.forward_dynamics_derivatives].
        """
        return linearize(self, q_eq, qd_eq, params, tau_eq, t)
