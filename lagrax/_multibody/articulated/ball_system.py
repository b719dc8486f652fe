r"""[`BallTreeSystem`][lagrax.chains.BallTreeSystem]: the equations of motion of a
[`Tree`][lagrax.chains.Tree] with ball joints, fixed to the world at its base.

A ball joint's coordinates are Pinocchio's spherical ones (`pin.JointModelSpherical`): 4
entries of the configuration `q`, the unit quaternion `(x, y, z, w)` of the child's
rotation relative to the joint frame, and 3 of the velocity `v`, the child's angular
velocity relative to its parent in the child frame. The recursions run over three
revolute lanes per ball (`lagrax._multibody.articulated.balls`) with the velocity-product
correction `P δ(ω)`; a tree without ball joints never comes here.
"""

from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..._core import model_programs
from ..._core.blocking import blocked
from ..._core.checks import (
    configuration_size,
    coords,
    eager_only,
    finite,
    finite_params,
    traced,
)
from ..._core.custom_types import Params
from ..._core.errors import MassMatrixError, NonFiniteError
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
from ..algorithms import recursions as a
from ..algorithms.derivative_recursions import rnea_derivatives
from . import balls
from .tree_equations import spatial_chain, spatial_energies
from .tree_fields import joint_damping


class BallTreeSystem(AbstractSystem):
    r"""The equations of motion of a [`Tree`][lagrax.chains.Tree] with ball joints:

    $$
    M(q) v̇ + b(q, v) = τ − ∂D/∂v, \qquad q̇ = N(q) v,
    $$

    with `q` of size [`n_configuration`][lagrax.chains.BallTreeSystem.n_configuration]
    (every joint in tree order: one angle, or a ball's quaternion `(x, y, z, w)`) and `v`
    of size `n_dof` (a joint's rate, or a ball's angular velocity `ω` in the child
    frame): Pinocchio's layout for `JointModelSpherical`, and MuJoCo's but for the
    quaternion's order ([`from_mujoco_state`][lagrax.chains.from_mujoco_state]
    converts). `M` comes from the composite-rigid-body algorithm, `v̇` from the
    articulated-body algorithm and `M v̇ + b` from recursive Newton–Euler, each over three
    revolute lanes per ball at angle zero, whose rates are `ω` (see
    `lagrax._multibody.articulated.balls`): `v̇ = ABA(q, v, τ − A P δ) + P δ` and
    `τ = RNEA(q, v, v̇ − P δ) + A v̇`, with `δ(ω) = (ω_y ω_z, −ω_x ω_z, ω_x ω_y)` on
    each ball's lanes and `A` the armature. Joint damping, armature and friction loss
    act on `v`'s entries (a ball's three).

    `simulate` integrates `q̇ = N(q) v`
    ([`configuration_rate`][lagrax.chains.BallTreeSystem.configuration_rate]: a
    quaternion moves as `½ quat ⊗ (ω, 0)`) and puts every quaternion back on the unit
    sphere after each accepted step
    ([`project_configuration`][lagrax.chains.BallTreeSystem.project_configuration]);
    `Solution.constraint_violation` reports each `|quat| − 1` at the saves.

    The derivatives calls take `∂/∂q` on the tangent space, along `q ⊕ ξ` (a ball's
    rotation moved to `R exp([ξ]×)`, the other joints by `ξ`; Pinocchio's `integrate`),
    analytically: the lanes' RNEA derivatives (`O(n²)`) plus closed-form tangent terms
    in the lanes' `J(θ)` (`ω = J θ̇`) and its first and second derivatives at `θ = 0`
    (`balls.tangent_derivatives`).

    Build it with [`Tree.system`][lagrax.chains.AbstractTree.system] of a tree with
    `balls` ([`lagrax.chains.from_mjcf`][] makes one from MJCF ball joints).
    """

    tree: Any  # a Tree with ball joints
    name: str = eqx.field(default="tree with ball joints", static=True)

    @property
    def n_dof(self) -> int:
        """The number of velocities: one per one-angle joint, three per ball."""
        return self.tree.n

    @property
    def n_configuration(self) -> int:
        """The size of `q`: one per one-angle joint, four per ball."""
        return self.tree.n_configuration

    @property
    def final_maxima(self) -> tuple[str, ...]:
        """`constraint_violation`: each quaternion's norm drift `|quat| − 1`."""
        return ("constraint_violation",)

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """The velocities' names: the joints' (a ball's three lanes: `<joint>_x`,
        `_y`, `_z`)."""
        return self.tree.joint_names

    @property
    def configuration_names(self) -> tuple[str, ...]:
        """The configuration's names: a one-angle joint's name, a ball's `<joint>_qx`,
        `_qy`, `_qz`, `_qw` (its first lane's name without the `_x`)."""
        return balls.configuration_names(self.tree)

    # ------------------------------------------------------------------ inputs
    def _inputs(self, q: Any, q_name: str = "q", **velocities: Any) -> list[Any]:
        size = configuration_size(self.n_configuration, self.n_dof)
        out = [coords(q, q_name, self.n_configuration, self.name, size=size)]
        for key, value in velocities.items():
            out.append(None if value is None else coords(value, key, self.n_dof, self.name))
        dtype = jnp.result_type(*(x for x in out if x is not None))
        return [None if x is None else x.astype(dtype) for x in out]

    def _at(self, q: Any, params: Params) -> tuple[a.Chain, jnp.ndarray]:
        """The lanes' chain at `q` and their angles `θ` (zero on the balls' lanes)."""
        js.check(params, self.tree.n_bodies)
        theta, big_a = balls.lane_state(self.tree, q)
        return spatial_chain(self.tree, theta, params, None, big_a), theta

    def _damping(self, params: Params, v: Any) -> jnp.ndarray:
        """`∂D/∂v` of the joint damping, fixed tendons' damping and friction loss."""
        return jax.grad(lambda w: joint_damping(None, w, params))(v)

    def _inverse(self, q: Any, v: Any, vdot: Any, params: Params) -> jnp.ndarray:
        """`M v̇ + b + ∂D/∂v` of checked arrays (`vdot` `None`: no `∂D/∂v`, the bias)."""
        chain, theta = self._at(q, params)
        links = chain.passes.links
        product = balls.velocity_product(self.tree.balls, v)
        lanes_dd = -product if vdot is None else vdot - product
        tau = chain.passes.vector(a.rnea(chain, links(v), links(lanes_dd)), v)
        rotor = js.armature(params, v.dtype)
        if rotor is not None and vdot is None:  # the armature's `−A P δ` of `A θ̈`
            tau = tau - rotor * product
        tau = tau + js.joint_inverse(params, theta, vdot)
        return tau if vdot is None else tau + self._damping(params, v)

    def _mass(self, chain: a.Chain, params: Params) -> jnp.ndarray:
        return js.with_armature(a.crba(chain), params)

    # ------------------------------------------------------------------ configuration
    def configuration_rate(self, q: Any, v: Any) -> jnp.ndarray:
        r"""`q̇ = N(q) v`: a one-angle joint's rate, and a ball's `q̇_quat = ½ q_quat ⊗
        (ω, 0)` (the Hamilton product, scalar last). Sizes: `q` `n_configuration`, `v`
        `n_dof`, the result `n_configuration`."""
        return balls.configuration_rate(self.tree, q, v)

    def project_configuration(self, q: Any) -> jnp.ndarray:
        """`q` with every ball's quaternion divided by its norm."""
        return balls.normalized(self.tree, q)

    def initial_state(self, q: Any, qd: Any, params: Params) -> tuple[Any, Any, Any]:
        """The initial state with its quaternions normalized (`ok` false for a zero
        quaternion)."""
        return self.project_configuration(q), qd, jnp.all(balls.quaternion_norms(self.tree, q) > 0)

    def observables(self, t: Any, q: Any, qd: Any, params: Params, tau: Any) -> dict[str, Any]:
        """`constraint_violation`: `|quat| − 1` of every ball, shape `(n_balls,)`."""
        return {"constraint_violation": balls.quaternion_norms(self.tree, q) - 1.0}

    # ------------------------------------------------------------------ dynamics
    def mass_matrix(self, q: Any, params: Params, qd: Any = None, *, t: Any = 0.0) -> jnp.ndarray:
        """`M(q)`, shape `(n_dof, n_dof)`, by the composite-rigid-body algorithm (Pinocchio's
        `crba`, MuJoCo's `mj_fullM`), armature included."""
        (q,) = self._inputs(q)
        return model_programs.call(self, _mass_of, self, q, params)

    def bias(self, q: Any, v: Any, params: Params) -> jnp.ndarray:
        """`b(q, v)`: Coriolis, centrifugal, gravity and spring terms (Pinocchio's
        `nonLinearEffects`), by recursive Newton–Euler."""
        q, v = self._inputs(q, qd=v)
        return model_programs.call(self, _inverse_of, self, q, v, None, params)

    def inverse_dynamics(
        self, q: Any, qd: Any, qdd: Any, params: Params, t: Any = 0.0
    ) -> jnp.ndarray:
        """`τ = M v̇ + b + ∂D/∂v` (Pinocchio's `rnea` plus the joint damping).
        **Arguments:** `q` `(n_configuration,)`, `qd` = `v` and `qdd` = `v̇` `(n_dof,)`,
        `params`."""
        q, v, vdot = self._inputs(q, qd=qd, qdd=qdd)
        return model_programs.call(self, _inverse_of, self, q, v, vdot, params)

    def accelerations(self, t: Any, q: Any, qd: Any, params: Params, tau: Any) -> jnp.ndarray:
        """`v̇` of checked arrays by the articulated-body algorithm over the lanes, never
        raising (NaN where an articulated inertia is not positive); vmapped over many
        states, in blocks (`lagrax._core.blocking`)."""
        return blocked(_lanes_aba)(self, q, qd, params, tau)

    def forward_dynamics(
        self, q: Any, qd: Any, params: Params, tau: Any = None, t: Any = 0.0
    ) -> jnp.ndarray:
        """`v̇ = M⁻¹ (τ − b − ∂D/∂v)` (Pinocchio's `aba`), shape `(n_dof,)`.

        **Arguments:** `q` `(n_configuration,)`, `qd` = `v` `(n_dof,)`, `params`, `tau`
        `(n_dof,)` (default zero).

        **Raises:** `ShapeError` for wrong sizes or a zero quaternion; `NonFiniteError`
        for NaN/inf inputs or non-finite accelerations; under `jit` through
        `equinox.error_if`.
        """
        q, v, tau = self._inputs(q, qd=qd, tau=tau)
        if not traced(self, q, v, tau, params):
            self._finite(q, v, tau, "tau")
            vdot = model_programs.call(self, _accelerations_of, self, t, q, v, params, tau)
            if not np.all(np.isfinite(np.asarray(vdot))):
                raise NonFiniteError(
                    f"forward_dynamics of {self.name} gave non-finite accelerations "
                    f"{np.asarray(vdot)} at q={np.asarray(q)}: check tau and that every "
                    "subtree has a positive mass"
                )
            return vdot
        vdot = self.accelerations(t, q, v, params, tau)
        return eqx.error_if(
            vdot,
            ~(jnp.all(jnp.isfinite(vdot)) & jnp.all(jnp.isfinite(q))),
            f"forward_dynamics of {self.name} produced non-finite accelerations, or its "
            "configuration q is not finite",
        )

    def _check_quaternions(self, q: Any) -> None:
        """`ShapeError` naming the first ball whose quaternion is zero (eagerly)."""
        balls.check_quaternions(self.tree, q)

    # ------------------------------------------------------------------ derivatives
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
        r"""`v̇` and its derivatives at one state (Pinocchio's `computeABADerivatives`
        on a model with `JointModelSpherical`, the same numbers): `dq` along `q ⊕ ξ`
        (`n_dof × n_dof`), from the inverse dynamics at the primal `v̇`,
        `∂v̇/∂q = −M⁻¹ ∂τ/∂q`, `∂v̇/∂v = −M⁻¹ ∂τ/∂v`, `∂v̇/∂τ = M⁻¹`.

        **Arguments:** `q` `(n_configuration,)`, `qd` = `v` `(n_dof,)`, `params`, `tau`
        (default zero), `t` (unused), `wrt_params=True` to add `∂v̇/∂params`.

        **Returns:** a [`ForwardDynamicsDerivatives`][lagrax.ForwardDynamicsDerivatives].

        **Raises:** as [`forward_dynamics`][lagrax.chains.BallTreeSystem.forward_dynamics].
        """
        q, v, tau = self._inputs(q, qd=qd, tau=tau)
        tau = jnp.zeros_like(v) if tau is None else tau
        self._finite(q, v, tau, "tau")
        program, eager = choose_program(self, _forward_body, q, v, tau, params, t)
        params = float_arrays(params) if eager else params
        out = blocked(program)(self, t, q, v, params, tau, wrt_params)
        return finite_derivatives(self, out, q, v, params, tau, t, "forward_dynamics")

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
        """`τ = M v̇ + b + ∂D/∂v` and its derivatives (Pinocchio's
        `computeRNEADerivatives`): `∂τ/∂q` along `q ⊕ ξ`, `∂τ/∂v`, `∂τ/∂v̇ = M`, and
        with `wrt_params=True` `∂τ/∂params`.

        **Arguments:** `q` `(n_configuration,)`, `qd` = `v`, `qdd` = `v̇` `(n_dof,)`,
        `params`, `t` (unused), `wrt_params`.

        **Returns:** an [`InverseDynamicsDerivatives`][lagrax.InverseDynamicsDerivatives].

        **Raises:** `ShapeError` for wrong sizes.
        """
        q, v, vdot = self._inputs(q, qd=qd, qdd=qdd)
        self._finite(q, v, vdot, "qdd")
        program, eager = choose_program(self, _inverse_body, q, v, vdot, params, t)
        params = float_arrays(params) if eager else params
        out = blocked(program)(self, t, q, v, vdot, params, wrt_params)
        return finite_derivatives(self, out, q, v, params, None, t, "inverse_dynamics")

    def linearize(
        self, q_eq: Any, qd_eq: Any, params: Params, tau_eq: Any = None, *, t: Any = 0.0
    ) -> tuple[jax.Array, jax.Array]:
        r"""Linearization `δẋ = A δx + B δτ` on the tangent space about
        `(q_eq, v_eq, τ_eq)`, with the state `x = (ξ, v)` (`q = q_eq ⊕ ξ`):

        $$
        A = \begin{pmatrix} −½ [ω_{eq}]× ⊕ 0 & I \\ ∂v̇/∂q & ∂v̇/∂v \end{pmatrix},
        \qquad B = \begin{pmatrix} 0 \\ M⁻¹ \end{pmatrix},
        $$

        a ball's `ω = J_r(ξ) ξ̇` (`J_r` the right Jacobian of `SO(3)`'s exponential)
        giving `ξ̇ = ω − ½ ω × ξ + O(ξ²)` on its block (zero for a ball at rest and for
        the other joints).

        **Arguments:** `q_eq` `(n_configuration,)`, `qd_eq` = `v_eq` `(n_dof,)`,
        `params`, `tau_eq` (default zero), `t` (unused).

        **Returns:** `(A, B)`, shapes `(2 n_dof, 2 n_dof)` and `(2 n_dof, n_dof)`.

        **Raises:** as [`forward_dynamics`][lagrax.chains.BallTreeSystem.forward_dynamics].
        """
        out = self.forward_dynamics_derivatives(q_eq, qd_eq, params, tau_eq, t)
        (v,) = self._inputs(q_eq, "q_eq", qd_eq=qd_eq)[1:]
        a_mat, b_mat = state_space(out)
        return balls.rotation_blocks(a_mat, self.tree.balls, v), b_mat

    def _finite(self, q: Any, v: Any, w: Any, name: str) -> None:
        """Eagerly, `NonFiniteError` for a non-finite input and `ShapeError` for a zero
        quaternion (under `jit`, the results' check catches both)."""
        if not traced(self, q, v, w):
            for key, x in (("q", q), ("qd", v), (name, w)):
                if x is not None:
                    finite(x, key)
            self._check_quaternions(q)

    # ------------------------------------------------------------------ energies
    def _energies(self, q: Any, v: Any, params: Params) -> tuple[jnp.ndarray, jnp.ndarray]:
        theta, big_a = balls.lane_state(self.tree, q)
        kinetic, potential = spatial_energies(self.tree, theta, v, params, big_a)
        rotor = js.armature(params, v.dtype)
        if rotor is not None:
            kinetic = kinetic + 0.5 * jnp.sum(rotor * v**2)
        return kinetic, potential + js.spring_energy(params, theta)

    def energy(self, q: Any, qd: Any, params: Params, *, t: Any = 0.0) -> jnp.ndarray:
        """The mechanical energy `T + V` (`T = ½ vᵀ M v`)."""
        q, v = self._inputs(q, qd=qd)
        return model_programs.call(self, _energy_of, self, q, v, params)

    def jacobi_integral(self, t: Any, q: Any, qd: Any, params: Params) -> jnp.ndarray:
        """`T + V` (`T` is quadratic in `v`)."""
        kinetic, potential = self._energies(q, qd, params)
        return kinetic + potential

    def explicit_power(self, t: Any, q: Any, qd: Any, params: Params) -> None:
        """`None`: the energies do not depend on time."""
        return None

    def input_power(self, t: Any, q: Any, qd: Any, params: Params, tau: Any) -> jnp.ndarray:
        """`v·(τ − ∂D/∂v)`: the power of the inputs and of the dissipation."""
        force = -self._damping(params, qd)
        return qd @ (force if tau is None else force + tau)

    def energy_and_magnitude(
        self, t: Any, q: Any, qd: Any, params: Params
    ) -> tuple[jnp.ndarray, jnp.ndarray]:
        """`(T + V, |T| + |V|)`."""
        kinetic, potential = self._energies(q, qd, params)
        return kinetic + potential, jnp.abs(kinetic) + jnp.abs(potential)

    def components(self, t: Any, q: Any, qd: Any, params: Params) -> dict[str, Any]:
        """The quaternions' norms, the mass matrix and the bias at one state."""
        chain, _ = self._at(q, params)
        return {
            "the ball joints' quaternion norms": balls.quaternion_norms(self.tree, q),
            "the mass matrix M (CRBA)": self._mass(chain, params),
            "the bias b = C v + G (RNEA)": self._inverse(q, qd, None, params),
        }

    def check_state(self, q: Any, qd: Any, params: Params, *, t: Any = 0.0) -> None:
        """Validate a state eagerly: sizes, finite values, no zero quaternion, finite
        params and a positive-definite `M(q)`.

        **Raises:** `ShapeError` (a zero quaternion named by its joint), `NonFiniteError`,
        `MassMatrixError`; `ConfigurationError` for traced values.
        """
        eager_only(f"check_state of {self.name}", self, q, qd, params, t)
        q, v = self._inputs(q, qd=qd)
        finite(q, "q")
        finite(v, "qd")
        finite_params(params)
        self._check_quaternions(q)
        mass = np.asarray(self.mass_matrix(q, params))
        eigs = np.linalg.eigvalsh(0.5 * (mass + mass.T))
        if not (np.all(np.isfinite(eigs)) and eigs[0] > 0):
            raise MassMatrixError(
                f"the mass matrix of {self.name} is not positive-definite at q={np.asarray(q)} "
                f"(smallest eigenvalue {eigs[0]:.3g}): check that every body and subtree "
                "has a positive mass"
            )


def _jacobians(system: BallTreeSystem, q, v, vdot, params):
    """`(τ, ∂τ/∂q along q ⊕ ξ, ∂τ/∂v, M)`: the lanes' analytic RNEA derivatives
    (`derivative_recursions.rnea_derivatives`, at `θ̈ = v̇ − P δ`) with the balls'
    tangent terms (`balls.tangent_derivatives`), the springs' stiffness, the damping's
    `∂/∂v` and the armature on `M`."""
    chain, theta = system._at(q, params)
    links, product = chain.passes.links, balls.velocity_product(system.tree.balls, v)
    tau, dq, dqd, mass = rnea_derivatives(chain, links(v), links(vdot - product))
    dq, dqd = balls.tangent_derivatives(system.tree.balls, tau, dq, dqd, mass, v, vdot)
    stiffness = js.stiffness_matrix(params, v.shape[0], v.dtype)
    dq = dq if stiffness is None else dq + stiffness
    dqd = dqd + jax.jacfwd(lambda w: system._damping(params, w))(v)
    return system._inverse(q, v, vdot, params), dq, dqd, js.with_armature(mass, params)


def _forward_body(system: BallTreeSystem, t, q, v, params, tau, wrt_params: bool):
    return forward_by_inverse_jacobians(
        lambda p: system.accelerations(t, q, v, p, tau),
        lambda vdot: _jacobians(system, q, v, vdot, params),
        params,
        wrt_params,
    )


def _inverse_body(system: BallTreeSystem, t, q, v, vdot, params, wrt_params: bool):
    return inverse_by_jacobians(
        lambda p: system._inverse(q, v, vdot, p),
        lambda w: _jacobians(system, q, v, w, params),
        vdot,
        params,
        wrt_params,
    )


# What the eager calls compile, one program per live system (`model_programs.call`)
def _mass_of(system: BallTreeSystem, q, params):
    return system._mass(system._at(q, params)[0], params)


def _inverse_of(system: BallTreeSystem, q, v, vdot, params):
    return system._inverse(q, v, vdot, params)


def _accelerations_of(system: BallTreeSystem, t, q, v, params, tau):
    return system.accelerations(t, q, v, params, tau)


def _energy_of(system: BallTreeSystem, q, v, params):
    kinetic, potential = system._energies(q, v, params)
    return kinetic + potential


def _lanes_aba(system: BallTreeSystem, q, qd, params, tau):
    """`BallTreeSystem.accelerations`: `ABA(q, v, τ − A P δ) + P δ` over the lanes."""
    chain, theta = system._at(q, params)
    links = chain.passes.links
    product = balls.velocity_product(system.tree.balls, qd)
    force = -system._damping(params, qd)
    if tau is not None:
        force = force + jnp.asarray(tau, qd.dtype)
    springs = js.spring_force(params, theta)
    if springs is not None:
        force = force - springs
    rotor = js.armature(params, qd.dtype)
    if rotor is not None:
        force = force - rotor * product
    lanes_dd = chain.passes.vector(a.aba(chain, links(qd), links(force)), qd)
    return lanes_dd + product
