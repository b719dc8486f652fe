"""`AbstractSystem`: what `simulate`, `sweep`, the vector field and the integrators
may ask of any mechanical system."""

import abc
from typing import Any

import equinox as eqx
import jax.numpy as jnp

from .._core.checks import configuration_size, coords, same_shape
from .._core.custom_types import Coordinates, Matrix, Params, Scalar, Time, Vector, Velocities


class AbstractSystem(eqx.Module):
    r"""The interface every kind of mechanical system implements.

    A system has `n` generalized coordinates `q` and velocities `q̇` and defines
    accelerations `q̈(t, q, q̇; params, τ)`. `simulate` and `sweep` integrate the
    first-order system `(q, q̇)' = (q̇, q̈)` through this interface only, so a new kind
    of system (a constrained one, one that knows its rigid bodies …) is a subclass that
    fills in the abstract members below; nothing in the solve and sweep paths asks which
    kind it is.

    Following equinox's abstract/final rule, this class is never instantiated and its
    concrete subclasses ([`lagrax.LagrangianSystem`][],
    [`lagrax.ConstrainedSystem`][]) are never subclassed.

    **Abstract attributes:**

    - `n_dof`: the number of generalized coordinates, or `None` if not fixed.
    - `name`: a label for messages and plots.
    - `final_maxima`: the names of the [`observables`][lagrax.AbstractSystem.observables]
      that `sweep` reports per member as their largest magnitude at the final state,
      `max_i |x_i(t_end)|` (a constrained system: its constraint violations; none for a
      `LagrangianSystem`), in the order they are reported.
    - `coordinate_names`: a label for each coordinate (a tree's joint names), or `None`.

    **Abstract methods** (each documented below): [`energy`][lagrax.AbstractSystem.energy],
    [`mass_matrix`][lagrax.AbstractSystem.mass_matrix],
    [`forward_dynamics`][lagrax.AbstractSystem.forward_dynamics] (checked, raising),
    [`accelerations`][lagrax.AbstractSystem.accelerations] (unchecked, for inside a solver loop),
    [`check_state`][lagrax.AbstractSystem.check_state].

    **Abstract methods of a solution's energy balance** (each documented below):
    [`jacobi_integral`][lagrax.AbstractSystem.jacobi_integral],
    [`explicit_power`][lagrax.AbstractSystem.explicit_power],
    [`input_power`][lagrax.AbstractSystem.input_power],
    [`energy_and_magnitude`][lagrax.AbstractSystem.energy_and_magnitude]; and
    [`components`][lagrax.AbstractSystem.components], for a failure diagnosis.

    **The configuration manifold, with defaults for ordinary systems** (each documented
    below): [`n_configuration`][lagrax.AbstractSystem.n_configuration] (the size of `q`;
    default `n_dof`), [`configuration_rate`][lagrax.AbstractSystem.configuration_rate]
    (`q̇ = N(q) v`; default `v`) and
    [`project_configuration`][lagrax.AbstractSystem.project_configuration] (back onto the
    manifold; default the identity). A floating base, whose quaternion's rate is not its
    angular velocity, overrides these; `simulate`, `sweep`, events and the energy balance
    only ever go through them.

    **Hooks with defaults:** [`initial_state`][lagrax.AbstractSystem.initial_state] (identity),
    [`observables`][lagrax.AbstractSystem.observables] (none) and their
    [`observable_dims`][lagrax.AbstractSystem.observable_dims] (none named),
    [`stiff_rate`][lagrax.AbstractSystem.stiff_rate] (none),
    [`failure_hint`][lagrax.AbstractSystem.failure_hint] (none).
    """

    n_dof: eqx.AbstractVar[int | None]
    name: eqx.AbstractVar[str]
    final_maxima: eqx.AbstractVar[tuple[str, ...]]
    coordinate_names: eqx.AbstractVar[tuple[str, ...] | None]

    # ------------------------------------------------------------------ the interface
    @abc.abstractmethod
    def energy(self, q: Coordinates, qd: Velocities, params: Params) -> Scalar:
        """The mechanical energy `T + V`."""

    @abc.abstractmethod
    def mass_matrix(self, q: Coordinates, params: Params, qd: Velocities | None = None) -> Matrix:
        """`M(q) = ∂²T/∂q̇²`, shape `(n, n)`; `simulate` and `sweep` check that it is
        positive-definite at the initial state."""

    @abc.abstractmethod
    def forward_dynamics(
        self,
        q: Coordinates,
        qd: Velocities,
        params: Params,
        tau: Velocities | None = None,
        t: Time = 0.0,
    ) -> Vector:
        """Accelerations `q̈`, with every input checked (raises a `LagraxError`)."""

    @abc.abstractmethod
    def accelerations(self, t: Any, q: Vector, qd: Vector, params: Params, tau: Any) -> Vector:
        """Accelerations `q̈` of already-checked 1-D arrays, never raising: NaN where they
        are undefined (a singular mass matrix, …). This is what a solver integrates;
        `tau` is the input generalized force or `None`."""

    @abc.abstractmethod
    def check_state(self, q: Coordinates, qd: Velocities, params: Params, *, t: Time = 0.0) -> None:
        """Validate a state eagerly (outside `jit`), raising a `LagraxError` that names
        the problem and the values (at time `t` for a time-dependent system)."""

    # ------------------------------------------------------------------ the energy balance
    @abc.abstractmethod
    def jacobi_integral(self, t: Any, q: Vector, qd: Vector, params: Params) -> Any:
        """The energy reported along a solution (`Solution.energy`): the Jacobi integral
        `h = q̇·∂L/∂q̇ − L` at time `t` (`T + V` when `T` is quadratic in `q̇`). Never
        raises."""

    @abc.abstractmethod
    def explicit_power(self, t: Any, q: Vector, qd: Vector, params: Params) -> Any:
        """`−∂L/∂t` at one state, the rate at which an explicit time dependence changes
        [`jacobi_integral`][lagrax.AbstractSystem.jacobi_integral]; `None` for an
        autonomous system, whose `h` only inputs and dissipation change. Never raises."""

    @abc.abstractmethod
    def input_power(self, t: Any, q: Vector, qd: Vector, params: Params, tau: Any) -> Any:
        """`q̇·(τ + F − ∂D/∂q̇)` at one state: the rate at which the inputs, applied forces
        and dissipation change [`jacobi_integral`][lagrax.AbstractSystem.jacobi_integral]; `None`
        when there are none (`tau` is `None` and the system has no force or dissipation).
        Never raises."""

    @abc.abstractmethod
    def energy_and_magnitude(self, t: Any, q: Vector, qd: Vector, params: Params) -> Any:
        """`(h, m)` at one state: the Jacobi integral
        ([`jacobi_integral`][lagrax.AbstractSystem.jacobi_integral]) and a magnitude of the energy
        that does not vanish where `h` does (`|T| + |V|`), from which `Solution.energy_error` takes
        its scale; both from one evaluation of the energies. Never raises."""

    @abc.abstractmethod
    def components(self, t: Any, q: Vector, qd: Vector, params: Params) -> dict[str, Any]:
        """The pieces the accelerations are made of at one state, by a readable name
        (applied forces first, then the energies' derivatives, the mass matrix, …), for
        a failure diagnosis to say which one is non-finite. Never raises on non-finite
        values."""

    # ------------------------------------------------------------------ configuration manifold
    @property
    def n_configuration(self) -> int | None:
        """The size of the configuration `q` (`None` if not fixed). The velocity `v`
        (called `qd` throughout) has `n_dof` entries; by default the two sizes agree
        (`q̇ = v`). A floating base has `7 + n` coordinates (position, unit quaternion,
        joints) and `6 + n` velocities."""
        return self.n_dof

    @property
    def n_input(self) -> int | None:
        """The size of the input `tau` that `simulate`, `sweep` and
        [`accelerations`][lagrax.AbstractSystem.accelerations] take. By default it is
        `n_dof` (one generalized force per velocity); a scene whose input is its
        actuators' controls (a [`from_mujoco`][lagrax.chains.from_mujoco] model: MuJoCo's
        `ctrl`) has one entry per actuator, and maps them to the generalized force
        itself."""
        return self.n_dof

    @property
    def configuration_names(self) -> tuple[str, ...] | None:
        """A label for each entry of the configuration `q` (`None`: unnamed); by default
        the `coordinate_names` (`q` and the velocity have one size). A floating base
        names its position and quaternion (`base_x … base_qw`) before its joints;
        `sweep` labels `q`'s `q_dof` axis with them."""
        return self.coordinate_names

    def configuration_rate(self, q: Vector, v: Vector) -> Vector:
        r"""`q̇ = N(q) v`: the rate of the configuration given the velocity, what a solver
        integrates for `q` (the state `(q, v)` evolves as `(N(q) v, v̇)`).

        The default is `v` itself (`N = 1`: the velocities are the coordinates' time
        derivatives). A system whose configuration lives on a manifold overrides it: for
        a floating base `ṗ = R v_b` and `q̇_quat = ½ q_quat ⊗ (ω_b, 0)`. Never raises.

        **Arguments:** `q` (size `n_configuration`), `v` (size `n_dof`).
        **Returns:** `q̇`, shaped like `q`.
        """
        return v

    def project_configuration(self, q: Vector) -> Vector:
        """`q` put back onto its manifold (a floating base: the quaternion divided by its
        norm). `simulate` applies it after every accepted step, so that round-off and
        truncation do not drift off the manifold; the default is the identity. Never
        raises."""
        return q

    @property
    def projects(self) -> bool:
        """Whether [`project_configuration`][lagrax.AbstractSystem.project_configuration]
        is more than the identity (a system that overrides it); the solvers skip the
        identity, and the forward sensitivities of `simulate` (an augmented system,
        whose tangents a projection would have to follow) need it."""
        return type(self).project_configuration is not AbstractSystem.project_configuration

    @property
    def rough_jacobian(self) -> bool:
        """Whether the vector field's Jacobian is not smooth where the motion goes (a
        compliant contact's onset and release: `∂f_n/∂δ = p k δ^{p−1}`, of infinite slope
        at `δ = 0` for Hertz's `p = 3/2`). Then the forward sensitivities of a
        differentiated `simulate` are put under the step-size control beside the state
        (the state's error alone does not see the Jacobian's roughness). Default
        `False`."""
        return False

    # ------------------------------------------------------------------ hooks with defaults
    def initial_state(self, q: Vector, qd: Vector, params: Params) -> tuple[Any, Any, Any]:
        """`(q, q̇, ok)`: the state a solve starts from, given the user's initial state.

        The default returns it unchanged with `ok = True`; a constrained system projects
        it onto its constraints (`ok` false where that fails). Never raises.
        """
        return q, qd, jnp.asarray(True)

    def prepared(self, params: Params, dtype: Any) -> "AbstractSystem":
        """This system with what depends on `params` alone computed once, for evaluations
        at these `params` only (a contact's default coefficients, scaled from the scene).

        `simulate` and `sweep` call it inside their compiled programs, before the loop, so
        that the vector field, the events and the energies at the saves do not trace
        that work again at every evaluation. Derivatives with respect to `params` flow
        through it. The default is the system itself. Never raises.
        """
        return self

    def observables(
        self, t: Any, q: Vector, qd: Vector, params: Params, tau: Any
    ) -> dict[str, Any]:
        """Extra quantities this kind reports at one state of a solution, by
        [`lagrax.Solution`][] field name (default none). Never raises."""
        return {}

    def observable_dims(self) -> dict[str, tuple[str, ...]]:
        """The dimension names of an [`observable`][lagrax.AbstractSystem.observables]'s
        axes at one state, by its name, for a sweep's Dataset (`sweep(...,
        observables=)`); an observable not named here gets `"<name>_dim_<k>"` (the
        default: none named)."""
        return {}

    def stiff_rate(self, q: Vector, v: Vector, params: Params) -> Any:
        """The magnitude `λ` (1/s) of the fastest eigenvalue of the system's stiff forces
        at one state (a contact's spring and its stiction), or `None`: none known (the
        default). A fixed-step solve with an explicit method checks `h λ ≤ 2` after every
        step and stops with `RESULTS.step_past_stability_limit` past it, before the state
        can blow up. Never raises."""
        return None

    @property
    def default_method(self) -> str:
        """The method `simulate` and `sweep` use when given neither `solver=` nor `dt=`:
        `"tsit5"` (explicit, adaptive), the right one for smooth, non-stiff scenes. A
        kind whose forces are stiff by construction (a contact scene) names an implicit
        one."""
        return "tsit5"

    def stiff_account(self, q: Any, v: Any, params: Params) -> tuple[str, float] | None:
        """Eagerly, `(sentence, λ)`: the system's stiffest force at a state, named with
        the coefficients it comes from, and its rate `λ` (1/s), for the message of a
        solve that ran out of steps (`None`: nothing stiff to name, the default)."""
        return None

    def failure_hint(self, q: Any, params: Params) -> str | None:
        """Eagerly, a sentence on why the accelerations may be undefined at `q` beyond a
        singular mass matrix (`None`: nothing to add). Used in failure messages."""
        return None

    # ------------------------------------------------------------------ input shapes
    def _coords(self, q: Coordinates, name: str = "q", host: bool = False):
        return coords(q, name, self.n_dof, self.name, host=host)

    def _state(
        self,
        q: Coordinates,
        qd: Velocities | None = None,
        *,
        q_name: str = "q",
        qd_name: str = "qd",
        **others: Any,
    ):
        """`q` (and `qd`, …) as 1-D arrays of one shape and dtype, or a `ShapeError`
        naming the caller's arguments (`q_name`, `qd_name`, the keys of `others`)."""
        q = self._coords(q, q_name)
        out = [q]
        named = {qd_name: qd, **others} if qd is not None else dict(others)
        for key, value in named.items():
            if value is None:
                out.append(None)
                continue
            v = self._coords(value, key)
            same_shape(key, v, q, q_name)
            out.append(v.astype(jnp.result_type(q, v)))
        return out


def host_state(system: AbstractSystem, q: Coordinates, qd: Velocities):
    """`(q0, q̇0)` as NumPy arrays, with `_state`'s checks (the messages naming `q0`
    and `qd0`) and no device transfer, for `sweep`'s set-up. A function, not a method:
    equinox binds a method of a Module by building a `BoundMethod` Module around it,
    which walks the system's pytree (~50 µs for a 7-link chain)."""
    n, name = system.n_dof, system.name
    size = configuration_size(system.n_configuration, n)
    q = coords(q, "q0", system.n_configuration, name, host=True, size=size)
    qd = coords(qd, "qd0", n, name, host=True)
    if system.n_configuration == n:
        same_shape("qd0", qd, q, "q0")
    return q, qd
