"""Holonomic constraints `φ(q) = 0` and velocity (non-holonomic) constraints
`A(q) q̇ = 0` by Lagrange multipliers: `ConstrainedSystem`."""

from collections.abc import Callable, Sequence
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._core.custom_types import (
    ConstraintJacobian,
    ConstraintValues,
    Coordinates,
    Matrix,
    Params,
    Scalar,
    Time,
    Vector,
    Velocities,
)
from .._core.errors import ArgumentTypeError, ConfigurationError
from . import constraint_checks as checks
from . import constraint_rows, implicit, kkt, projection
from . import derivatives as d
from . import dynamics_derivatives as api
from .abstract import AbstractSystem
from .kkt import solve_kkt
from .lagrangian import LagrangianSystem
from .sensitivity import ForwardDynamicsDerivatives
from .steady_linearization import steady_linearize

ConstraintFn = Callable[[Vector, Params], ConstraintValues]
VelocityConstraintFn = Callable[[Vector, Params], ConstraintJacobian]


class ConstrainedSystem(AbstractSystem):
    r"""A `LagrangianSystem` subject to holonomic constraints `φ(q) = 0` and/or
    velocity (non-holonomic) constraints `A(q) q̇ = 0`.

    The constrained equations of motion, with Lagrange multipliers `λ` (`m₁` for the
    holonomic rows) and `μ` (`m₂` for the velocity rows),

    $$
    M(q) q̈ + C(q, q̇) q̇ + G(q) = τ + F − ∂D/∂q̇ + J(q)ᵀ λ + A(q)ᵀ μ,
    \qquad φ(q) = 0, \quad A(q) q̇ = 0,
    $$

    with `J = ∂φ/∂q` (shape `(m₁, n)`) and `A` (shape `(m₂, n)`, any matrix: its
    rows need not be the gradient of anything, as for a knife edge or a rolling wheel),
    are solved as the index-1 KKT system

    $$
    \begin{bmatrix} M & Jᵀ & Aᵀ \\ J & 0 & 0 \\ A & 0 & 0 \end{bmatrix}
    \begin{bmatrix} q̈ \\ −λ \\ −μ \end{bmatrix}
    = \begin{bmatrix} τ + F − C q̇ − G − ∂D/∂q̇ \\
    −\dot J q̇ − 2α J q̇ − β² φ \\
    −\dot A q̇ − β A q̇ \end{bmatrix}.
    $$

    The second row is the holonomic constraint differentiated twice, `φ̈ = J q̈ + J̇ q̇`,
    with Baumgarte's stabilization: it enforces `φ̈ + 2α φ̇ + β² φ = 0`, so a drift of
    the integrator away from `φ = 0` decays instead of growing (critically damped for
    `α = β`; `α = β = 0` is the bare index-1 formulation). The third row is the
    velocity constraint `ψ = A q̇` differentiated once, `ψ̇ = A q̈ + Ȧ q̇`, stabilized
    on the velocity level, `ψ̇ + β ψ = 0` (drift decays like `exp(−β t)`). `J̇ q̇`
    is the second directional derivative of `φ` along `q̇` and `Ȧ q̇` the
    directional derivative of `A(q) q̇` along `q̇` (one JVP each; no Hessian, no
    derivative of `A` beyond the one needed); `J` comes from `n` JVPs of `φ`.
    Both kinds of row share one solve, by the Schur complement `K M⁻¹ Kᵀ` of the
    stacked constraint matrix `K = [J; A]` (Cholesky factorizations only); it is
    singular exactly when `K` loses rank (redundant constraints, or a singular
    configuration such as a linkage at a change point), which is refused with a
    `ConstraintError` instead of returning NaN.

    `Kᵀ (λ, μ) = Jᵀλ + Aᵀμ` is the generalized constraint force
    ([`constraint_forces`][lagrax.ConstrainedSystem.constraint_forces]); the multipliers
    ([`multipliers`][lagrax.ConstrainedSystem.multipliers]) are ordered holonomic rows first, then
    velocity rows: `(λ₁ … λ_{m₁}, μ₁ … μ_{m₂})`. For the Cartesian pendulum `φ = x² + y² − l²`, `Jᵀλ
    = 2λ (x, y)`, so the rod tension is `−2 l λ`; for a knife edge `A = (−sin θ, cos θ, 0)`, `μ` is
    the lateral force on the blade.

    `lagrax.simulate` accepts a `ConstrainedSystem`. It first projects the initial
    state onto the constraints (`project_initial=True`, see
    [`project`][lagrax.ConstrainedSystem.project]), then integrates; the `Solution` carries
    `constraint_violation` (`φ(q)` at the saved times, without holonomic constraints `None`),
    `velocity_constraint_violation` (`A(q) q̇`, with velocity constraints) and `multipliers` (`(λ,
    μ)`). The energy (the Jacobi integral, `T + V` for `T` quadratic in `q̇`) is conserved by the
    exact constrained motion: constraints without explicit time do no work
    (`q̇ · (Jᵀλ + Aᵀμ) = λ·J q̇ + μ·A q̇ = 0`).

    **Arguments:**

    - `system`: the unconstrained `LagrangianSystem` (in redundant coordinates).
    - `constraints`: `φ(q, params) -> (m₁,)`, zero on admissible configurations. A
      scalar is taken as `m₁ = 1`. `None` for none (then `velocity_constraints`
      is required).
    - `velocity_constraints`: `A(q, params) -> (m₂, n)`, the matrix of the velocity
      constraints `A(q) q̇ = 0` (default none). A 1-D `(n,)` result is taken as one
      row. Integrable rows (`A = ∂ψ/∂q`) are allowed but only their velocity level is
      enforced; state a holonomic constraint through `constraints` instead.
    - `alpha`, `beta`: Baumgarte gains in 1/time units (default 10 each: drift decays
      like `exp(−10 t)`). Larger values hold the constraint tighter but make the
      equations stiffer; keep `α, β` well below `1/dt` for a fixed-step method.
    - `project_initial`: project the initial state of `simulate` onto `φ = 0`,
      `J q̇ = 0`, `A q̇ = 0` (default `True`).
    - `name`: a label for messages (default: the system's name with "constrained").

    **Example:**

    ```python
    import jax.numpy as jnp
    import lagrax as lx

    free = lx.LagrangianSystem(lambda q, qd, p: 0.5 * p["m"] * qd @ qd,
                               lambda q, p: p["m"] * p["g"] * q[1], n_dof=2)
    rod = lambda q, p: jnp.stack([q @ q - p["l"] ** 2])   # |r| = l
    pendulum = lx.ConstrainedSystem(free, rod)
    params = {"m": 1.0, "g": 9.81, "l": 1.0}
    sol = lx.simulate(pendulum, [0.6, -0.8], [0.0, 0.0], params, t1=10.0)
    abs(sol.constraint_violation).max(), sol.multipliers[0]   # ~5e-9, λ = −T/(2l)

    # a knife edge (skate) on a plane, q = (x, y, θ): no velocity across the blade
    skate = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * p["m"] * (qd[0] ** 2 + qd[1] ** 2) + 0.5 * p["I"] * qd[2] ** 2,
        lambda q, p: 0.0 * q[0], n_dof=3)
    blade = lambda q, p: jnp.stack([-jnp.sin(q[2]), jnp.cos(q[2]), 0.0 * q[2]])[None]
    knife = lx.ConstrainedSystem(skate, None, velocity_constraints=blade)
    sol = lx.simulate(knife, [0.0, 0.0, 0.0], [1.0, 0.0, 0.5], {"m": 1.0, "I": 0.1}, t1=10.0)
    # a circle of radius 2: speed 1 along the blade, turning at 0.5 rad/s
    ```

    **Raises** (from its methods and `simulate`): `ConstraintError` when `[J; A]`
    is rank-deficient or a state cannot be projected onto `φ = 0`; `ShapeError` when
    `φ` or `A` returns the wrong shape; the errors of `LagrangianSystem`
    (`ShapeError`, `NonFiniteError`, `ParameterError`, `MassMatrixError`).
    """

    system: LagrangianSystem | Any
    constraints: ConstraintFn | None
    velocity_constraints: VelocityConstraintFn | None
    alpha: float = eqx.field(static=True)
    beta: float = eqx.field(static=True)
    project_initial: bool = eqx.field(static=True)
    name: str = eqx.field(static=True)

    def __init__(
        self,
        system: LagrangianSystem | Any,
        constraints: ConstraintFn | None = None,
        *,
        velocity_constraints: VelocityConstraintFn | None = None,
        alpha: float = 10.0,
        beta: float = 10.0,
        project_initial: bool = True,
        name: str | None = None,
    ):
        if not isinstance(system, AbstractSystem) or isinstance(system, ConstrainedSystem):
            raise ArgumentTypeError(
                "ConstrainedSystem wraps a LagrangianSystem (or a floating-base or forest "
                f"system), got {type(system).__name__}"
            )
        if constraints is None and velocity_constraints is None:
            raise ConfigurationError(
                "ConstrainedSystem needs constraints phi(q, params) -> (m,), "
                "velocity_constraints A(q, params) -> (m, n), or both; got neither"
            )
        if constraints is not None and not callable(constraints):
            raise ArgumentTypeError(
                f"constraints must be a function phi(q, params) -> (m,) or None, got "
                f"{constraints!r}"
            )
        if velocity_constraints is not None and not callable(velocity_constraints):
            raise ArgumentTypeError(
                "velocity_constraints must be a function A(q, params) -> (m, n) (the "
                f"constraint A(q) qd = 0) or None, got {velocity_constraints!r}"
            )
        alpha, beta = float(alpha), float(beta)
        if not (alpha >= 0.0 and beta >= 0.0 and np.isfinite(alpha) and np.isfinite(beta)):
            raise ConfigurationError(
                f"Baumgarte gains must be finite and non-negative, got alpha={alpha}, "
                f"beta={beta} (negative gains make the constraint drift grow)"
            )
        self.system = system
        self.constraints = constraints
        self.velocity_constraints = velocity_constraints
        # Python floats: static (hashable, so jax.jit(system.method) works) and weakly
        # typed (a float32 state stays float32); changing a gain recompiles simulate
        self.alpha = alpha
        self.beta = beta
        self.project_initial = bool(project_initial)
        self.name = f"{system.name} (constrained)" if name is None else name

    # ------------------------------------------------------------ shared with the system
    @property
    def n_dof(self) -> int | None:
        """Number of (redundant) generalized coordinates `n`, if the system states it."""
        return self.system.n_dof

    @property
    def coordinate_names(self) -> tuple[str, ...] | None:
        """The system's coordinate names (a label for each redundant coordinate)."""
        return self.system.coordinate_names

    @property
    def _manifold(self) -> bool:
        """Whether the system is not a `LagrangianSystem` (a floating base, a forest):
        its configuration's rate is `N(q) v` (see `constraint_rows`)."""
        return not isinstance(self.system, LagrangianSystem)

    @property
    def n_configuration(self) -> int | None:
        """The size of `q`: the system's (a floating base: `7 + n`)."""
        return self.system.n_configuration

    @property
    def configuration_names(self) -> tuple[str, ...] | None:
        """The system's configuration names."""
        return self.system.configuration_names

    def configuration_rate(self, q, v):
        """The system's `q̇ = N(q) v`."""
        return self.system.configuration_rate(q, v)

    def project_configuration(self, q):
        """The system's `q` put back on its manifold (quaternions normalized)."""
        return self.system.project_configuration(q)

    def _state(self, q, qd=None, *, q_name="q", qd_name="qd", **others):
        if not self._manifold:
            return super()._state(q, qd, q_name=q_name, qd_name=qd_name, **others)
        return constraint_rows.manifold_state(self, q, qd, q_name, qd_name, others)

    def energy(self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0) -> Scalar:
        """Total mechanical energy `E = T + V` (constraint forces do no work)."""
        return self.system.energy(q, qd, params, t=t)

    def jacobi_integral(self, t, q, qd, params):
        """The system's Jacobi integral `h` (the constraints, `φ(q) = 0` without
        explicit time, do no work, so `h` balances as for the free system)."""
        return self.system.jacobi_integral(t, q, qd, params)

    def explicit_power(self, t, q, qd, params):
        """The system's `−∂L/∂t` (`None` when autonomous)."""
        return self.system.explicit_power(t, q, qd, params)

    def input_power(self, t, q, qd, params, tau):
        """The system's `q̇·(τ + F − ∂D/∂q̇)` (the constraint forces add none:
        `q̇·(Jᵀλ + Aᵀμ) = λ·J q̇ + μ·A q̇ = 0` on admissible velocities)."""
        return self.system.input_power(t, q, qd, params, tau)

    def energy_and_magnitude(self, t, q, qd, params):
        """The system's `(h, |T| + |V|)`."""
        return self.system.energy_and_magnitude(t, q, qd, params)

    def kinetic_energy(
        self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0
    ) -> Scalar:
        """`T(q, q̇)` of the underlying system."""
        return self.system.kinetic_energy(q, qd, params, t=t)

    def potential_energy(self, q: Coordinates, params: Params, *, t: Time = 0.0) -> Scalar:
        """`V(q)` of the underlying system."""
        return self.system.potential_energy(q, params, t=t)

    def mass_matrix(
        self,
        q: Coordinates,
        params: Params,
        qd: Velocities | None = None,
        *,
        t: Time = 0.0,
    ) -> Matrix:
        """Mass matrix `M(q)` of the unconstrained system, shape `(n, n)`."""
        return self.system.mass_matrix(q, params, qd, t=t)

    # ------------------------------------------------------------ constraint functions
    def _phi(self, q, params):
        """`φ(q)`, shape `(m₁,)` (`(0,)` without holonomic constraints)."""
        return constraint_rows.phi(self, q, params)

    def _amat(self, q, params):
        """`A(q)`, shape `(m₂, n)` (`(0, n)` without velocity constraints)."""
        return constraint_rows.amat(self, q, params)

    def _jacobian(self, q, params):
        """`J = ∂φ/∂q`; on a manifold `J_v = ∂φ/∂q · N(q)` (see `constraint_rows`)."""
        n = q.shape[0] if self.n_dof is None else self.n_dof
        if self.constraints is None:
            return jnp.zeros((0, n), q.dtype)
        if self._manifold:
            return constraint_rows.tangent_jacobian(
                self.system, lambda a: self._phi(a, params), q, n
            )
        return jax.jacfwd(lambda a: self._phi(a, params))(q)

    def _kmat(self, q, params):
        """The stacked constraint matrix `K = [J; A]`, shape `(m₁ + m₂, n)`."""
        rows = []
        if self.constraints is not None:
            rows.append(self._jacobian(q, params))
        if self.velocity_constraints is not None:
            rows.append(self._amat(q, params))
        dtype = jnp.result_type(*rows)
        return jnp.concatenate([r.astype(dtype) for r in rows], axis=0)

    def violation(self, q: Coordinates, params: Params) -> ConstraintValues:
        """Constraint values `φ(q)`, shape `(m₁,)`: zero on the constraint manifold
        (shape `(0,)` without holonomic constraints)."""
        (q,) = self._state(q)
        return self._phi(q, params)

    def velocity_violation(
        self, q: Coordinates, qd: Velocities, params: Params
    ) -> ConstraintValues:
        """`K(q) q̇ = (J q̇, A q̇)`, shape `(m₁ + m₂,)`: `φ̇` of the holonomic rows (one
        JVP of `φ`), then `A(q) q̇` of the velocity rows; zero for admissible
        velocities. Rows in the order of [`multipliers`][lagrax.ConstrainedSystem.multipliers]."""
        q, qd = self._state(q, qd)
        return self._kmat(q, params) @ qd

    def constraint_matrix(self, q: Coordinates, params: Params) -> ConstraintJacobian:
        """The stacked constraint matrix `K = [J; A]`, shape `(m₁ + m₂, n)`: the
        holonomic Jacobian `J = ∂φ/∂q`, then the velocity-constraint matrix `A(q)`.
        Admissible velocities satisfy `K q̇ = 0`; the constraint force is
        `Kᵀ (λ, μ)`."""
        (q,) = self._state(q)
        return self._kmat(q, params)

    # ------------------------------------------------------------ dynamics
    def _rows(self, q, qd, params):
        """The stacked constraint matrix `K = [J; A]` and the right-hand side `γ` of
        `K q̈ = γ` (with Baumgarte stabilization; on a manifold, `J = J_v`: see
        `constraint_rows`)."""
        return constraint_rows.rows(self, q, qd, params, self._manifold)

    def _kkt_raw(self, t, q, qd, params, tau):
        sys = self.system
        if isinstance(sys, LagrangianSystem):
            mass, force = d.mass_and_force(sys, sys.scalar_derivatives, t, q, qd, params, tau)
        else:
            mass, force = constraint_rows.mass_and_force(sys, q, qd, params, tau)
        kmat, gamma = self._rows(q, qd, params)
        dtype = jnp.result_type(mass, kmat)
        return solve_kkt(mass, kmat.astype(dtype), force, gamma.astype(dtype))

    def _kkt(self, t, q, qd, params, tau):
        """`(q̈, (λ, μ))` without raising: NaN where `M` is not PD or `K` loses
        rank. Differentiated through the KKT system (`_kkt_with_rule`)."""
        if self._manifold or not implicit.rule_on(self):
            return self._kkt_raw(t, q, qd, params, tau)
        return kkt.kkt_with_rule(self, t, q, qd, params, tau)

    def accelerations(self, t, q, qd, params, tau):
        """Constrained accelerations without raising (what `simulate` integrates)."""
        return self._kkt(t, q, qd, params, tau)[0]

    def initial_state(self, q, qd, params):
        """The state projected onto `φ = 0`, `J q̇ = 0`, `A q̇ = 0` (when
        `project_initial`), and whether that succeeded; see
        [`project`][lagrax.ConstrainedSystem.project]."""
        if not self.project_initial:
            return q, qd, jnp.asarray(True)
        return projection.project_state(self, q, qd, params)

    @property
    def final_maxima(self) -> tuple[str, ...]:
        """`("constraint_violation",)` with holonomic constraints, then
        `"velocity_constraint_violation"` with velocity constraints: `sweep` reports
        `max |φ(q)|` and `max |A(q) q̇|` at the final state (see
        [`observables`][lagrax.ConstrainedSystem.observables])."""
        holonomic = ("constraint_violation",) if self.constraints is not None else ()
        velocity = () if self.velocity_constraints is None else ("velocity_constraint_violation",)
        return holonomic + velocity

    def observables(self, t, q, qd, params, tau):
        """At one state: `constraint_violation` `φ(q)` (with holonomic constraints),
        `velocity_constraint_violation` `A(q) q̇` (with velocity constraints) and
        `multipliers` `(λ, μ)`."""
        out = {}
        if self.constraints is not None:
            out["constraint_violation"] = self._phi(q, params)
        if self.velocity_constraints is not None:
            out["velocity_constraint_violation"] = self._amat(q, params) @ qd
        out["multipliers"] = self._kkt(t, q, qd, params, tau)[1]
        return out

    def components(self, t, q, qd, params):
        """The system's components plus `φ(q)`, `J(q)` and `A(q)`."""
        out = self.system.components(t, q, qd, params)
        if self.constraints is not None:
            out["the constraint values phi(q)"] = self._phi(q, params)
            out["the constraint Jacobian J = dphi/dq"] = self._jacobian(q, params)
        if self.velocity_constraints is not None:
            out["the velocity constraint matrix A(q)"] = self._amat(q, params)
        return out

    def failure_hint(self, q, params):
        """The rank deficiency of `[J; A](q)`, if any (see
        [`check_state`][lagrax.ConstrainedSystem.check_state])."""
        return checks.rank_message(self, q, params)

    def forward_dynamics(
        self,
        q: Coordinates,
        qd: Velocities,
        params: Params,
        tau: Velocities | None = None,
        t: Time = 0.0,
    ) -> Vector:
        """Constrained accelerations `q̈` from the KKT system (see the class docstring).

        **Arguments:** the state `q`, `qd` (shape `(n,)`), `params`, input forces
        `tau` (default none) and the time `t` (for the system's `force`).

        **Returns:** `q̈`, shape `(n,)`.

        **Raises:** `ConstraintError` when `[J; A](q)` is rank-deficient;
        `MassMatrixError` when `M(q)` is not positive-definite; `ShapeError`,
        `NonFiniteError`. Under `jit`, a run-time error by `equinox.error_if`.
        """
        return checks.checked_kkt(self, q, qd, params, tau, t, "forward_dynamics")[0]

    def forward_dynamics_derivatives(
        self,
        q: Coordinates,
        qd: Velocities,
        params: Params,
        tau: Velocities | None = None,
        t: Time = 0.0,
        *,
        wrt_params: bool = False,
    ) -> ForwardDynamicsDerivatives:
        r"""The constrained accelerations and their derivatives at one state, in one call.

        Differentiating the KKT system `[[M, Kᵀ], [K, 0]] (q̈, −λ) = (f, γ)` at its
        solution (`K = [J; A]`, `f = τ + F − C q̇ − G − ∂D/∂q̇`, `γ` the constraints'
        velocity products and Baumgarte terms):

        $$
        \begin{bmatrix} M & −Kᵀ \\ K & 0 \end{bmatrix}
        \begin{bmatrix} δq̈ \\ δλ \end{bmatrix}
        = \begin{bmatrix} δτ − \tfrac{∂r}{∂(q, q̇)} δ(q, q̇) + δKᵀ λ \\
          δγ − δK q̈ \end{bmatrix},
        $$

        with `r` the unconstrained system's inverse dynamics less its applied forces. So
        `∂q̈/∂τ = M⁻¹ − M⁻¹Kᵀ S⁻¹ K M⁻¹` with the Schur complement `S = K M⁻¹ Kᵀ` (not
        `M⁻¹`: an input along a constrained direction does not accelerate), and
        `∂q̈/∂q`, `∂q̈/∂q̇` include the motion of the constraints and of the Baumgarte
        terms. One linearization of the accelerations, then the `3n` basis tangents
        through the KKT system's tangent rule (the numbers of
        `jax.jacfwd(forward_dynamics)`).

        **Arguments:** the state `q`, `qd` (shape `(n,)`, redundant coordinates),
        `params`, the input `tau` (default zero), the time `t`, and `wrt_params=True` to
        add `∂q̈/∂params`.

        **Returns:** a [`ForwardDynamicsDerivatives`][lagrax.ForwardDynamicsDerivatives]
        (`qdd`, `dq`, `dqd`, `dtau`, `dparams`).

        **Raises:** `NonFiniteError` where the derivatives are not finite (a rank-deficient
        `K`, `M` not positive-definite, NaN inputs; eagerly the cause by
        [`check_state`][lagrax.ConstrainedSystem.check_state]); `ShapeError`. Under
        `jit`, a run-time error by `equinox.error_if`.
        """
        return api.constrained_forward_dynamics_derivatives(self, q, qd, params, tau, t, wrt_params)

    def linearize(
        self,
        q_eq: Coordinates,
        qd_eq: Velocities,
        params: Params,
        tau_eq: Velocities | None = None,
        *,
        t: Time = 0.0,
        independent: Sequence[int] | tuple[Sequence[int], Sequence[int]] | None = None,
        tol: float = 1e-8,
    ) -> tuple[jax.Array, jax.Array]:
        r"""Linearization `δẋ = A δx + B δτ` of the constrained state equations
        `ẋ = (q̇, q̈(q, q̇, τ))` in the redundant coordinates, about `(x_eq, τ_eq)`:
        `A = [[0, I], [∂q̈/∂q, ∂q̈/∂q̇]]`, `B = [[0], [∂q̈/∂τ]]` from
        [`forward_dynamics_derivatives`][lagrax.ConstrainedSystem.forward_dynamics_derivatives].

        With `independent=(q_i, u_i)` (index sequences; one for both with holonomic
        constraints only): about a steady motion, in the minimal state `x = (q_i, u_i)`
        (Peterson, Gede & Hubbard 2014): `δq = P_q δq_i`, `q̇ = P_u(q) u_i`, `P = [1;
        −K_d⁻¹K_i]` (`K = J` for `P_q`, `[J; A]` for `P_u`), by autodiff (constraints page).

        Besides the motion along the constraints, `A` holds the Baumgarte dynamics of the
        drift across them: for each holonomic constraint the eigenvalues
        `−α ± √(α² − β²)` of `φ̈ + 2α φ̇ + β² φ = 0` (a pendulum in Cartesian
        coordinates hanging at rest: `±i √(g/l)` and those two).

        **Arguments:** the state `q_eq`, `qd_eq` (`(n,)`), `params`, the input `tau_eq`
        (default zero), the time `t`; `independent` (default `None`), `tol` (the largest
        constraint residual and reduced acceleration taken as zero).

        **Returns:** `(A, B)`, `(2n, 2n)` and `(2n, n)`; with `independent`, `(k, k)` and
        `(k, n)` in the state `(q_i, u_i)` (sorted), `k = len(q_i) + len(u_i)`.

        **Raises:** as
        [`forward_dynamics_derivatives`][lagrax.ConstrainedSystem.forward_dynamics_derivatives];
        with `independent`: `LagraxError` naming each nonzero reduced acceleration (not
        steady), `ConstraintError` naming dependent coordinates or speeds with a singular
        Jacobian block (or a point off the constraints), `ConfigurationError` for indices
        of the wrong number. Under `jit`, a run-time error by `equinox.error_if`.
        """
        if independent is not None:
            return steady_linearize(self, q_eq, qd_eq, params, tau_eq, t, independent, tol)
        return api.constrained_linearize(self, q_eq, qd_eq, params, tau_eq, t)

    def multipliers(
        self,
        q: Coordinates,
        qd: Velocities,
        params: Params,
        tau: Velocities | None = None,
        t: Time = 0.0,
    ) -> ConstraintValues:
        """Lagrange multipliers `(λ, μ)`, shape `(m₁ + m₂,)`: the holonomic rows' `λ`
        first, then the velocity rows' `μ`. `J(q)ᵀ λ + A(q)ᵀ μ` is the generalized force
        the constraints exert (sign: `M q̈ + C q̇ + G = τ + F − ∂D/∂q̇ + Jᵀλ + Aᵀμ`).

        Computed with the Baumgarte terms, which vanish on the constraint manifold.
        Arguments and errors as [`forward_dynamics`][lagrax.ConstrainedSystem.forward_dynamics].
        """
        return checks.checked_kkt(self, q, qd, params, tau, t, "multipliers")[1]

    def constraint_forces(
        self,
        q: Coordinates,
        qd: Velocities,
        params: Params,
        tau: Velocities | None = None,
        t: Time = 0.0,
    ) -> Vector:
        """Generalized constraint force `J(q)ᵀ λ + A(q)ᵀ μ`, shape `(n,)`: what the
        constraints add to the right-hand side of `M q̈ + C q̇ + G = τ + F − ∂D/∂q̇`.

        Arguments and errors as [`forward_dynamics`][lagrax.ConstrainedSystem.forward_dynamics].
        """
        q, qd, tau = self._state(q, qd, tau=tau)
        lam = checks.checked_kkt(self, q, qd, params, tau, t, "constraint_forces")[1]
        return self._kmat(q, params).T @ lam

    # ------------------------------------------------------------ projection
    def project(self, q: Coordinates, qd: Velocities, params: Params) -> tuple[Vector, Vector]:
        r"""The nearest consistent state: `φ(q*) = 0`, `J(q*) q̇* = 0` and
        `A(q*) q̇* = 0`.

        Positions by Newton's method on `φ(q) = 0` with minimal-norm steps in the
        kinetic metric `M(q0)`: `Δq = −M⁻¹Jᵀ(J M⁻¹ Jᵀ)⁻¹ φ(q)` (converges
        quadratically from a start near the manifold). Velocities by the `M`-orthogonal
        projection `q̇* = q̇ − M⁻¹Kᵀ(K M⁻¹ Kᵀ)⁻¹ K q̇` at `q*` with `K = [J; A]` (the
        holonomic and the velocity rows together), the admissible velocity closest in
        kinetic energy (what an impulsive constraint does). Without holonomic
        constraints `q* = q`.

        **Arguments:** `q`, `qd` (shape `(n,)`) and `params`.

        **Returns:** `(q*, q̇*)`.

        **Raises:** `ConstraintError` when Newton's method does not converge within 30
        iterations (no admissible configuration near `q`: inconsistent constraints or a
        start too far away) or `J` or `[J; A]` is rank-deficient on the way. Under
        `jit`, a
        run-time error by `equinox.error_if`.
        """
        return projection.project(self, q, qd, params)

    # ------------------------------------------------------------ checks
    def check_state(
        self,
        q: Coordinates,
        qd: Velocities,
        params: Params,
        *,
        project: bool | None = None,
        t: Time = 0.0,
    ) -> None:
        """Validate a state eagerly (outside `jit`), with the values in the messages.

        The checks of [`LagrangianSystem.check_state`][lagrax.LagrangianSystem.check_state] (shapes,
        finiteness, parameters, `M(q)` positive-definite), that `φ` returns a 1-D array and `A` an
        `(m₂, n)` matrix, both finite, that the state can be projected onto the
        constraints (if `project`, default `project_initial`), and that `[J; A]` has
        full row rank at the (projected) configuration.

        **Raises:** `ConstraintError`, `ShapeError`, `NonFiniteError`,
        `ParameterError`, `MassMatrixError`; `ConfigurationError` for traced values
        (inside `jax.jit`).
        """
        checks.check_state(self, q, qd, params, project, t)
