"""Equations of motion from energies: `LagrangianSystem`."""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp

from .._core import model_programs
from .._core.checks import call_user, traced
from .._core.custom_types import Coordinates, Matrix, Params, Scalar, Time, Vector, Velocities
from . import derivatives as d
from . import dynamics_derivatives as api
from . import implicit
from . import lagrangian_checks as checks
from .abstract import AbstractSystem
from .sensitivity import ForwardDynamicsDerivatives, InverseDynamicsDerivatives

# autonomous energies, or with the time first (time_dependent=True)
KineticFn = Callable[[Vector, Vector, Params], Scalar] | Callable[..., Scalar]
PotentialFn = Callable[[Vector, Params], Scalar] | Callable[..., Scalar]
DissipationFn = Callable[[Vector, Vector, Params], Scalar] | Callable[..., Scalar]
ForceFn = Callable[[Scalar, Vector, Vector, Params], Vector]


class LagrangianSystem(AbstractSystem):
    r"""A mechanical system given by its energies; its equations of motion by autodiff.

    With `L(q, q̇) = T(q, q̇) − V(q)`, generalized input forces `τ`, an applied
    generalized force `F(t, q, q̇)` and a Rayleigh dissipation function `D(q, q̇)`,
    the Euler–Lagrange equations

    $$
    \frac{d}{dt}\frac{∂L}{∂q̇} − \frac{∂L}{∂q} = τ + F − \frac{∂D}{∂q̇}
    $$

    expand to `M(q) q̈ + C(q, q̇) q̇ + G(q) = τ + F − ∂D/∂q̇` with

    - `M = ∂²T/∂q̇²` (`mass_matrix`), symmetric positive-definite for a physical system;
    - `C(q, q̇) q̇ = (∂²T/∂q̇∂q) q̇ − ∂T/∂q` (`coriolis`), one forward-over-reverse
      product, no Jacobian formed;
    - `G = ∂V/∂q` (`gravity`).

    **Time-dependent (rheonomic) systems.** With `time_dependent=True` the energies
    take the time first, `T(t, q, q̇)`, `V(t, q)`, `D(t, q, q̇)` (a moving support,
    a prescribed rotation, a pendulum reeled in, a time-varying spring), and
    `d/dt ∂L/∂q̇` gains the explicit time derivative of the momenta:

    $$
    M(t, q) q̈ = ∂L/∂q − (∂²L/∂q̇∂q) q̇ − ∂²L/∂q̇∂t + τ + F − ∂D/∂q̇.
    $$

    Every method then takes `t=` (default `0.0`) and evaluates at that time; for an
    autonomous system (the default) `t` is ignored and the code is exactly that of a
    system without the option. The energy a solution reports is the Jacobi integral
    `h = q̇·∂L/∂q̇ − L` ([`jacobi_integral`][lagrax.LagrangianSystem.jacobi_integral]), which
    changes at the rate `dh/dt = −∂L/∂t + q̇·(τ + F − ∂D/∂q̇)`: `Solution.work` integrates that
    rate, and `Solution.energy_error` is the balance `h(t) − h(t0) − W(t)` over the path's energy
    scale `max(|h(t0)|, |T| + |V|)`.
    The structure-aware `equations` of chains are for autonomous energies only.

    **Terms linear in q̇.** `T` may contain terms linear in `q̇` (`T ⊃ a(q)·q̇`, a
    charge in a magnetic field with `a = e A(q)`, or a rotating frame): the equations are
    right as they stand, the conserved energy is `h` (not `T + V`), and
    [`coriolis_matrix`][lagrax.LagrangianSystem.coriolis_matrix] includes the gyroscopic skew term
    of `a`.

    Every method is a pure function of its array arguments and works under `jax.jit`,
    `jax.vmap` (over states and over `params`) and `jax.grad`.

    **Arguments:**

    - `kinetic`: `T(q, qd, params) -> scalar`. For a mechanical system, a quadratic
      form in `qd` whose Hessian `M(q)` is positive-definite.
    - `potential`: `V(q, params) -> scalar` (gravity, springs). Optional.
    - `dissipation`: Rayleigh `D(q, qd, params) -> scalar`; the damping force is
      `−∂D/∂q̇`. Optional.
    - `force`: `F(t, q, qd, params) -> (n,)` applied generalized force (controllers,
      prescribed torques, non-conservative loads). Optional.
    - `n_dof`: number of generalized coordinates (recommended); inputs of another length
      are refused with a `ShapeError`. Without it, `q` of any length is passed to the
      energies, and what can be detected is refused instead: an energy or force that
      indexes past the end of `q` (JAX would clamp `q[1]` of a length-1 `q` to
      `q[0]`) is found once per function and shape while JAX traces it, and raises a
      `ShapeError`. A slice past the end (`q[1:3]`) or a vectorized energy
      (`jnp.sum(qd**2)`) cannot be told from a shorter system that way.

    `T`, `V` and `D` must return real scalars and `force` a real `(n,)` array:
    checked on shape and dtype while tracing (`ShapeError` / `ArgumentTypeError`
    naming the function), so these checks cost nothing when the compiled code runs.

    - `time_dependent`: `True` for energies with an explicit time argument first,
      `T(t, q, qd, params)`, `V(t, q, params)`, `D(t, q, qd, params)` (see above);
      energies of another arity are refused with an `ArgumentTypeError` naming them.
      Default `False`.
    - `name`: a label used in messages and plots.
    - `scalar_derivatives`: how [`forward_dynamics`][lagrax.LagrangianSystem.forward_dynamics]
      differentiates `L`: `True` by scalar forward-over-forward directional derivatives (fastest to
      run for small, cheap energies), `False` by one vmapped forward-over-reverse pass (much faster
      to compile when `L` is large, e.g. spatial rigid bodies). Default `None`: scalar for
      `n <= 6`.
    - `equations`: structure-aware equations of the *same* `T` and `V`, used in place
      of differentiating them (chains' `system()` sets this to Featherstone's recursions,
      O(n) per evaluation). `None` (default): autodiff of the energies, the definition.
      `dataclasses.replace(system, equations=None)` gives the autodiff path of a chain.
    - `coordinate_names`: a label for each coordinate (a tree's joint names), used to
      label the `dof` coordinate of [`lagrax.sweep`][] results. Optional.

    **Example:**

    ```python
    import jax.numpy as jnp
    import lagrax as lx

    def T(q, qd, p):   # simple pendulum of mass m, length l
        return 0.5 * p["m"] * p["l"] ** 2 * qd[0] ** 2

    def V(q, p):
        return -p["m"] * p["g"] * p["l"] * jnp.cos(q[0])

    pendulum = lx.LagrangianSystem(T, V, n_dof=1)
    params = {"m": 1.0, "l": 1.0, "g": 9.81}
    pendulum.forward_dynamics(jnp.array([0.3]), jnp.array([0.0]), params)  # -g/l sin(0.3)
    ```
    """

    kinetic: KineticFn
    potential: PotentialFn | None = None
    dissipation: DissipationFn | None = None
    force: ForceFn | None = None
    n_dof: int | None = eqx.field(default=None, static=True)
    name: str = eqx.field(default="system", static=True)
    scalar_derivatives: bool | None = eqx.field(default=None, static=True)
    equations: d.AbstractEquations | None = None
    time_dependent: bool = eqx.field(default=False, static=True)
    coordinate_names: tuple[str, ...] | None = eqx.field(default=None, static=True)

    def __check_init__(self):
        checks.check_init(self)

    @property
    def final_maxima(self) -> tuple[str, ...]:
        """None: a Lagrangian system has no observables that `sweep` reports as a
        maximum at the final state."""
        return ()

    # ------------------------------------------------------------------ energies
    # Every method takes the time t= (default 0.0); only a time_dependent system reads it.
    def kinetic_energy(
        self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0
    ) -> Scalar:
        """`T(q, q̇)` (`T(t, q, q̇)` for a time-dependent system)."""
        q, qd = self._state(q, qd)
        return jnp.asarray(d.kinetic(self, q, qd, params, t))

    def potential_energy(self, q: Coordinates, params: Params, *, t: Time = 0.0) -> Scalar:
        """`V(q)` (`V(t, q)`; zero when the system has no potential)."""
        (q,) = self._state(q)
        return d.potential(self, q, params, t)

    def energy(self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0) -> Scalar:
        """Total mechanical energy `E = T + V` (see
        [`jacobi_integral`][lagrax.LagrangianSystem.jacobi_integral] for the conserved quantity
        when `T` has terms linear in `q̇`)."""
        q, qd = self._state(q, qd)
        return d.kinetic(self, q, qd, params, t) + d.potential(self, q, params, t)

    def lagrangian(
        self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0
    ) -> Scalar:
        """`L = T − V`."""
        q, qd = self._state(q, qd)
        return d.lagrangian(self, q, qd, params, t)

    def momentum(self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0) -> Vector:
        """Generalized momenta `p = ∂L/∂q̇` (one reverse pass of `T`)."""
        q, qd = self._state(q, qd)
        return d.grad_kinetic(self, q, qd, params, t)[1]

    def hamiltonian(
        self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0
    ) -> Scalar:
        """`H = p·q̇ − L` in the velocities: the Jacobi integral, see
        [`jacobi_integral`][lagrax.LagrangianSystem.jacobi_integral] (the same value)."""
        q, qd = self._state(q, qd)
        return d.jacobi(self, q, qd, params, t)

    def jacobi_integral(self, t: Time, q: Vector, qd: Vector, params: Params) -> Scalar:
        r"""The energy a solution reports: the Jacobi integral (the Hamiltonian in the
        velocities)

        $$
        h = q̇·∂L/∂q̇ − L = q̇·∂T/∂q̇ − T + V.
        $$

        For `T` quadratic in `q̇` (`T = ½ q̇ᵀM q̇`) `q̇·∂T/∂q̇ = 2T` and `h = T + V`;
        with terms linear in `q̇` (`T ⊃ a(q)·q̇`: a magnetic vector potential, a
        rotating frame) `h` drops them, and it is `h`, not `T + V`, that an
        autonomous, undamped, unforced motion conserves. Along any motion
        `dh/dt = −∂L/∂t + q̇·(τ + F − ∂D/∂q̇)`. One JVP of `T` along `q̇`; a system
        with structure-aware `equations` (bodies, chains, trees: `T` is quadratic in
        `q̇` by construction) gives `T + V`, which is cheaper.

        **Arguments:** the time `t` (read by a time-dependent system only), `q`,
        `qd` (shape `(n,)`), `params`. **Returns:** `h`, a scalar.
        """
        q, qd = self._state(q, qd)
        if self.equations is not None and not self.time_dependent:
            kinetic, potential = d.structured_energies(self, q, qd, params, t)
            return kinetic + potential
        return d.jacobi(self, q, qd, params, t)

    def explicit_power(self, t: Time, q: Vector, qd: Vector, params: Params) -> Scalar | None:
        """`−∂L/∂t = ∂V/∂t − ∂T/∂t` at one state of a time-dependent system, the rate at
        which the explicit time dependence changes
        [`jacobi_integral`][lagrax.LagrangianSystem.jacobi_integral]; `None` for an autonomous
        system."""
        if not self.time_dependent:
            return None
        q, qd = self._state(q, qd)
        return d.explicit_power(self, q, qd, params, t)

    def input_power(self, t: Time, q: Vector, qd: Vector, params: Params, tau) -> Scalar | None:
        """`q̇·(τ + F − ∂D/∂q̇)` at one state: the power of the inputs `τ`, the applied
        force `F` and the dissipation (`−q̇·∂D/∂q̇ = −2D` for a quadratic `D`), the
        rate at which they change [`jacobi_integral`][lagrax.LagrangianSystem.jacobi_integral];
        `None` without any of them."""
        if not d.has_applied(self, tau):
            return None
        q, qd = self._state(q, qd)
        return jnp.dot(qd, d.applied(self, t, q, qd, params, tau))

    def energy_and_magnitude(
        self, t: Time, q: Vector, qd: Vector, params: Params
    ) -> tuple[Scalar, Scalar]:
        """`(h, |T| + |V|)` at one state (at time `t` for a time-dependent system): the
        Jacobi integral (as [`jacobi_integral`][lagrax.LagrangianSystem.jacobi_integral]) and the
        magnitude from which `Solution.energy_error` takes its scale, which does not vanish where
        `h` does. One evaluation of `T` (with its JVP along `q̇`) and `V`."""
        q, qd = self._state(q, qd)
        if self.equations is not None and not self.time_dependent:
            kinetic, potential = d.structured_energies(self, q, qd, params, t)
            h = kinetic + potential
        else:
            potential = d.potential(self, q, params, t)
            kinetic, h = d.kinetic_and_jacobi(self, q, qd, params, t, potential)
        return h, jnp.abs(kinetic) + jnp.abs(potential)

    # ------------------------------------------------------------------ derivatives
    def mass_matrix(
        self,
        q: Coordinates,
        params: Params,
        qd: Velocities | None = None,
        *,
        t: Time = 0.0,
    ) -> Matrix:
        """Mass (inertia) matrix `M(q) = ∂²T/∂q̇²` (`M(t, q)` for a time-dependent
        system), shape `(n, n)`.

        Formed by `n` JVPs of `∂T/∂q̇` (forward-over-reverse). For a `T` quadratic in
        `q̇` the result does not depend on `qd` (default: zero velocities).
        """
        q, qd = self._state(q, jnp.zeros_like(jnp.asarray(q)) if qd is None else qd)
        return model_programs.call(self, d.mass_matrix, self, q, qd, params, t)

    def coriolis(self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0) -> Vector:
        """Coriolis, centrifugal and gyroscopic forces
        `C(q, q̇) q̇ = (∂²T/∂q̇∂q) q̇ − ∂T/∂q`.

        One JVP of `(∂T/∂q, ∂T/∂q̇)` along `(q̇, 0)`; no matrix is formed. For a
        time-dependent system this is at the fixed time `t`; the explicit-time term
        `∂²T/∂q̇∂t` of the equations is not part of it.
        """
        q, qd = self._state(q, qd)
        return d.coriolis(self, q, qd, params, t)

    def coriolis_matrix(
        self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0
    ) -> Matrix:
        r"""Coriolis matrix `C(q, q̇)` with `C(q, q̇) q̇ =`
        [`coriolis`][lagrax.LagrangianSystem.coriolis] for any `T`.

        Write `T = ½ q̇ᵀM(q)q̇ + a(q)·q̇ + T₀(q)` (quadratic, linear and velocity-free
        parts; `M = ∂²T/∂q̇²`). The quadratic part gives the Christoffel form
        `C_M,ij = Σ_k Γ_ijk q̇_k` with `Γ_ijk = ½(∂M_ij/∂q_k + ∂M_ik/∂q_j − ∂M_jk/∂q_i)`,
        computed as `½(Ṁ + A − Aᵀ)` with `Ṁ = (∂M/∂q)·q̇` (one JVP of `M`) and
        `A = ∂(M(q) q̇)/∂q`; `Ṁ − 2C_M` is skew-symmetric. The linear part gives the
        gyroscopic force `(∂a/∂q − (∂a/∂q)ᵀ) q̇` (a magnetic field's Lorentz force, a
        rotating frame's Coriolis force), a skew-symmetric matrix `S` that does no work;
        `C = C_M + S`, so `Ṁ − 2C` stays skew-symmetric. `a(q) = ∂T/∂q̇` at `q̇ = 0`
        (one more reverse pass; `S = 0` for a `T` quadratic in `q̇`).

        The velocity-free part `T₀(q) = T(q, 0)` (the centrifugal potential of a rotating
        frame, `½ m ω² r²`) adds `−∂T₀/∂q` to [`coriolis`][lagrax.LagrangianSystem.coriolis], a
        force that is not a product with `q̇` and so has no place in `C`: for `T` at most quadratic
        in `q̇` (every mechanical `T`)

        $$
        C(q, q̇) q̇ = \text{coriolis}(q, q̇) − \text{coriolis}(q, 0),
        $$

        which is `coriolis(q, q̇)` itself when `T₀` does not depend on `q` (any
        `T = ½ q̇ᵀM q̇ + a(q)·q̇`). For a `T` of higher degree in `q̇` (relativistic,
        or an `M` that depends on `q̇`) no such split exists and this matrix, formed
        with `M(q, q̇)` at the given `q̇`, is only an approximation: use
        [`coriolis`][lagrax.LagrangianSystem.coriolis]. For a time-dependent system everything is at
        the fixed time `t`.
        """
        q, qd = self._state(q, qd)

        def m_of(a):
            return d.mass_matrix(self, a, qd, params, t)

        m_dot = jax.jvp(m_of, (q,), (qd,))[1]
        a_mat = jax.jacfwd(lambda a: m_of(a) @ qd)(q)
        c_mat = 0.5 * (m_dot + a_mat - a_mat.T)
        zero = jnp.zeros_like(qd)
        da = jax.jacfwd(lambda a: d.grad_kinetic(self, a, zero, params, t)[1])(q)
        return c_mat + (da - da.T)

    def gravity(self, q: Coordinates, params: Params, *, t: Time = 0.0) -> Vector:
        """Potential forces `G(q) = ∂V/∂q` (gravity, springs), shape `(n,)`."""
        (q,) = self._state(q)
        return d.gravity(self, q, params, t)

    def damping(self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0) -> Vector:
        """Dissipative force magnitude `∂D/∂q̇` (the force acting is its negative)."""
        q, qd = self._state(q, qd)
        return d.damping(self, q, qd, params, t)

    # ------------------------------------------------------------------ dynamics
    def accelerations(self, t, q, qd, params, tau):
        """Forward dynamics of checked 1-D arrays without raising: `q̈`, NaN where `M`
        is not positive-definite (what the solvers integrate)."""
        return implicit.accelerations(self, self.scalar_derivatives, t, q, qd, params, tau)

    def forward_dynamics(
        self,
        q: Coordinates,
        qd: Velocities,
        params: Params,
        tau: Velocities | None = None,
        t: Time = 0.0,
    ) -> Vector:
        """Accelerations `q̈ = M⁻¹(τ + F − C q̇ − G − ∂D/∂q̇)`.

        For `n <= 6` (or as `scalar_derivatives` says), `M` and
        `∂L/∂q − (∂²L/∂q̇∂q) q̇` come from scalar forward-over-forward directional
        derivatives of `L` (straight-line code that XLA fuses into one kernel); above, from
        one vmapped forward-over-reverse pass. The
        solve is a Cholesky factorization (unrolled for `n <= 8`), never an inverse.

        **Raises:** `ShapeError` for mismatched shapes; `NonFiniteError` for NaN/inf
        inputs; `MassMatrixError` when `M(q)` is singular or not positive-definite.
        Under `jit` the last two are raised at run time by `equinox.error_if`.
        """
        q, qd, tau = self._state(q, qd, tau=tau)
        if not traced(self, q, qd, tau, params, t):
            return checks.eager_forward_dynamics(self, t, q, qd, params, tau)
        # traced: one check on the output (NaN inputs and a non-PD mass matrix both make
        # it non-finite); checking the output keeps XLA from splitting the fused kernel.
        qdd = self.accelerations(t, q, qd, params, tau)
        return eqx.error_if(
            qdd,
            ~jnp.all(jnp.isfinite(qdd)),
            f"forward_dynamics of {self.name} produced non-finite accelerations: q, qd, "
            "tau or params contain NaN/inf, or the mass matrix M(q) = d2T/dqd2 is "
            "singular or not positive-definite at this state (check that T is quadratic "
            "in qd with positive masses and inertias, or change coordinates if q is a "
            "singular configuration). Outside jit the message names which.",
        )

    def components(self, t, q, qd, params):
        """`F(t, q, q̇)`, `T`, `∂T/∂q`, `∂T/∂q̇`, `M`, `V`, `∂V/∂q`, `∂D/∂q̇`
        at one state (see [`AbstractSystem.components`][lagrax.AbstractSystem.components])."""
        out = {}
        if self.force is not None:
            out["the force function F(t, q, qd, params)"] = call_user(  # as diagnose.FORCE
                self.force, "force", params, t, q, qd
            )
        out["the kinetic energy T"] = d.kinetic(self, q, qd, params, t)
        t_q, t_qd = d.grad_kinetic(self, q, qd, params, t)
        out["dT/dq (the derivative of T)"] = t_q
        out["dT/dqd (the momenta)"] = t_qd
        if self.time_dependent:
            out["d2T/dqd dt (the explicit time rate of the momenta)"] = d.time_rate_of_momentum(
                self, q, qd, params, t
            )
        out["the mass matrix M = d2T/dqd2"] = d.mass_matrix(self, q, qd, params, t)
        if self.potential is not None:
            out["the potential energy V"] = d.potential(self, q, params, t)
            out["dV/dq (gravity and springs)"] = d.gravity(self, q, params, t)
        if self.dissipation is not None:
            out["dD/dqd (the damping force)"] = d.damping(self, q, qd, params, t)
        return out

    def inverse_dynamics(
        self,
        q: Coordinates,
        qd: Velocities,
        qdd: Velocities,
        params: Params,
        t: Time = 0.0,
    ) -> Vector:
        """Input forces `τ = M q̈ + C q̇ + G + ∂D/∂q̇ − F` that produce `q̈`.

        Computed without forming `M`: one JVP of `(∂T/∂q, ∂T/∂q̇)` along `(q̇, q̈)`
        gives `d/dt ∂T/∂q̇ = M q̈ + (∂²T/∂q̇∂q) q̇`. `F` is the system's own applied
        force, so `τ` is what must be added to it. For a time-dependent system the JVP
        also moves `t` at unit rate, adding `∂²T/∂q̇∂t`; all terms are at time `t`.
        """
        q, qd, qdd = self._state(q, qd, qdd=qdd)
        return model_programs.call(self, implicit.residual, self, t, q, qd, qdd, params)

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
        r"""The accelerations and their derivatives at one state, in one call (as
        Pinocchio's `computeABADerivatives`).

        Differentiating the inverse dynamics `r(q, q̇, q̈) = τ` at the primal `q̈`:

        $$
        \frac{∂q̈}{∂q} = −M⁻¹ \frac{∂r}{∂q}, \qquad \frac{∂q̈}{∂q̇} = −M⁻¹ \frac{∂r}{∂q̇},
        \qquad \frac{∂q̈}{∂τ} = M⁻¹, \qquad \frac{∂q̈}{∂p} = −M⁻¹ \frac{∂r}{∂p},
        $$

        with `r = M q̈ + C q̇ + G + ∂D/∂q̇ − F`. For chains and trees `∂r/∂q`, `∂r/∂q̇` come
        from Featherstone's recursions differentiated analytically (`O(n²)`); for energies
        from forward-mode derivatives of the inverse dynamics. `jax.jacfwd` of
        [`forward_dynamics`][lagrax.LagrangianSystem.forward_dynamics] gives the same numbers
        (it goes through the same rule), at the cost of `3n` tangents.

        **Arguments:** the state `q`, `qd` (shape `(n,)`), `params`, the input `tau`
        (default zero), the time `t`, and `wrt_params=True` to add `∂q̈/∂params`.

        **Returns:** a [`ForwardDynamicsDerivatives`][lagrax.ForwardDynamicsDerivatives]
        (`qdd`, `dq`, `dqd`, `dtau`, `dparams`).

        **Raises:** as [`forward_dynamics`][lagrax.LagrangianSystem.forward_dynamics].

        **Example:**

        ```python
        system, params = lagrax.models.planar_2r()
        out = system.forward_dynamics_derivatives(jnp.array([0.3, 0.8]), jnp.zeros(2), params)
        out.dq, out.dqd, out.dtau        # ∂q̈/∂q, ∂q̈/∂q̇, M⁻¹
        ```
        """
        return api.forward_dynamics_derivatives(self, q, qd, params, tau, t, wrt_params)

    def inverse_dynamics_derivatives(
        self,
        q: Coordinates,
        qd: Velocities,
        qdd: Velocities,
        params: Params,
        t: Time = 0.0,
        *,
        wrt_params: bool = False,
    ) -> InverseDynamicsDerivatives:
        """The inputs `τ = M q̈ + C q̇ + G + ∂D/∂q̇ − F` and their derivatives at one state,
        in one call (as Pinocchio's `computeRNEADerivatives`): `∂τ/∂q`, `∂τ/∂q̇`,
        `∂τ/∂q̈ = M` and, with `wrt_params=True`, `∂τ/∂params` (`τ` is linear in masses
        and inertias: the regressor of identification). Chains and trees differentiate
        Featherstone's recursions analytically (`O(n²)`).

        **Arguments:** `q`, `qd`, `qdd` (shape `(n,)`), `params`, the time `t`, and
        `wrt_params`.

        **Returns:** an [`InverseDynamicsDerivatives`][lagrax.InverseDynamicsDerivatives]
        (`tau`, `dq`, `dqd`, `dqdd`, `dparams`).

        **Raises:** `ShapeError` for mismatched shapes; `NonFiniteError` for NaN/inf
        inputs or results (under `jit` by `equinox.error_if`).
        """
        return api.inverse_dynamics_derivatives(self, q, qd, qdd, params, t, wrt_params)

    def check_state(self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0) -> None:
        """Validate a state eagerly (outside `jit`) with the values in the messages.

        Checks shapes, finiteness of `q`, `q̇`, `params` and the energies, that every
        parameter the energies read is present, and that `M(q)` is symmetric
        positive-definite (reporting its eigenvalues if not); at time `t` for a
        time-dependent system.

        **Raises:** `ShapeError`, `NonFiniteError`, `ParameterError`,
        `MassMatrixError`; `ConfigurationError` for traced values (inside `jax.jit`).
        """
        checks.check_state(self, q, qd, params, t)

    # ------------------------------------------------------------------ linearization
    def linearize(
        self,
        q_eq: Coordinates,
        qd_eq: Velocities,
        params: Params,
        tau_eq: Velocities | None = None,
        *,
        t: Time = 0.0,
    ) -> tuple[jax.Array, jax.Array]:
        r"""Continuous-time linearization `δẋ = A δx + B δτ` of the state equations.

        With the state `x = (q, q̇)` (shape `2n`), the equations of motion as a first-order
        system are `ẋ = f(x, τ) = (q̇, q̈(q, q̇, τ))` with
        `q̈ = M(q)⁻¹ (τ + F − C(q, q̇) q̇ − G(q) − ∂D/∂q̇)`
        ([`forward_dynamics`][lagrax.LagrangianSystem.forward_dynamics]). About `(x_eq, τ_eq)`:

        $$
        A = \frac{∂f}{∂x} = \begin{pmatrix} 0 & I \\ ∂q̈/∂q & ∂q̈/∂q̇ \end{pmatrix},
        \qquad
        B = \frac{∂f}{∂τ} = \begin{pmatrix} 0 \\ M(q_{eq})^{-1} \end{pmatrix}.
        $$

        At an equilibrium (`q̇_eq = 0` and `q̈(q_eq, 0, τ_eq) = 0`, e.g. ``τ_eq =
        G(q_eq)` to hold a pose against gravity) the derivative of `M⁻¹`` multiplies a
        zero force and `C q̇` is quadratic in `q̇`, so both drop out:
        `∂q̈/∂q = M⁻¹ (∂F/∂q − ∂²V/∂q²)` (the stiffness) and
        `∂q̈/∂q̇ = M⁻¹ (∂F/∂q̇ − ∂²D/∂q̇²)` (the damping). Away from an equilibrium the same
        call gives the Jacobian of the vector field along a trajectory; no check is made
        that `x_eq` is an equilibrium (compare ``forward_dynamics(q_eq, qd_eq, params,
        tau_eq)`` with zero).

        Both come from the derivatives of the inverse dynamics at the primal `q̈` and
        `M⁻¹` (as in
        [`forward_dynamics_derivatives`][lagrax.LagrangianSystem.forward_dynamics_derivatives]),
        compiled as one program.

        Works under `jax.jit`, `jax.vmap` and `jax.grad` (e.g. to differentiate an
        LQR design with respect to `params`).

        **Arguments:**

        - `q_eq`, `qd_eq`: the state to linearize about, shape `(n,)` each.
        - `params`: the parameters (any pytree).
        - `tau_eq`: the input there, shape `(n,)` (default zero).
        - `t`: the time, for a time-dependent system or `force` (default 0): the
          Jacobians of the field frozen at that time.

        **Returns:** `(A, B)` with `A` of shape `(2n, 2n)` and `B` of shape
        `(2n, n)`, both in the state ordering `x = (q_1…q_n, q̇_1…q̇_n)`.

        **Raises:** `ShapeError` for mismatched shapes; `NonFiniteError` for NaN/inf
        inputs or Jacobians; `MassMatrixError` when `M(q_eq)` is not positive-definite
        (eagerly; under `jit` a non-finite result fails through `equinox.error_if`).

        **Example:**

        ```python
        system, params = lagrax.models.planar_2r()
        q_up = jnp.array([jnp.pi / 2, 0.0])              # both links straight up
        A, B = system.linearize(q_up, jnp.zeros(2), params)
        jnp.linalg.eigvals(A)                              # a positive real pair: unstable
        ```
        """
        return api.linearize(self, q_eq, qd_eq, params, tau_eq, t)
