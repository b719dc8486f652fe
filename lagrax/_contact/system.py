"""`ContactSystem`: a system whose spheres touch a ground plane."""

import math
from collections.abc import Callable, Sequence
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._core.checks import coords, eager_only, traced
from .._core.errors import ArgumentTypeError, ConfigurationError
from .._solve.events import Event, keep
from .._systems.abstract import AbstractSystem
from . import arguments, forces, pairs, scale, stability, start
from . import limits as joint_limits
from .arguments import Coefficient
from .geometry import Plane, Sphere, placement_groups
from .limits import JointLimit
from .pairs import pair_list as pairs_of
from .scale import Coefficients


class ContactSystem(AbstractSystem):
    r"""A system whose [`Sphere`][lagrax.contact.Sphere]s touch a ground
    [`Plane`][lagrax.contact.Plane]: compliant contact with Coulomb friction.

    Each sphere `i`, with centre `c_i(q)` and radius `r_i`, has the gap
    `g_i = n·c_i − offset − r_i` and the penetration `δ_i = −g_i`. The contact adds to
    the wrapped system:

    - the **normal force** (Hunt–Crossley), along `n` at the contact point
      `c_i − r_i n`, never pulling:
      `f_n = k δ^p max(0, 1 + (3/2) c δ̇)`. Its elastic part derives from the potential
      `V_c = Σ k δ₊^{p+1}/(p+1)`, which is part of
      [`energy`][lagrax.contact.ContactSystem.energy]; the rest is a dissipation, whose
      power is part of [`input_power`][lagrax.contact.ContactSystem.input_power] (so
      `Solution.work`), and `Solution.energy_error` stays the energy balance.
      Restitution: `e ≈ 1 − c v` at the impact speed `v` for `c v ≪ 1` (see the
      contact guide for the whole curve); `c = 0` is elastic.
    - **friction** (regularized Coulomb with stiction), on the contact point's
      tangential velocity `v_t` (which includes `ω × (−r n)`: a rolling sphere does not
      slip): `F_t = −μ(s) f_n v_t/|v_t|`, `s = |v_t|/v_s`, `μ(s)` rising as
      `μ_s s(2 − s)` to `μ_s` at `s = 1`, easing to `μ` by `s = 3`. A contact held by
      friction creeps at `|v_t| ≤ v_s` (below `μ_s f_n`: `|v_t| = v_s (1 − √(1 − F/(μ_s
      f_n)))`, about `v_s F/(2 μ_s f_n)`).

    Both enter the wrapped system's dynamics as a generalized input force
    `Q = Σ J_iᵀ F_i` (`J_i` the contact point's velocity Jacobian, with respect to the
    velocities `v`: a floating base's too), so `simulate`, `sweep`, events and
    `jax.grad` take a `ContactSystem` as they take the system itself.

    **Arguments:**

    - `system`: the system the spheres are fixed to (any `AbstractSystem`: a
      `LagrangianSystem`, a chain's or tree's `system()`, a floating base).
    - `spheres`: a `Sphere` or a sequence of them; a [`Capsule`][lagrax.contact.Capsule]
      or [`Box`][lagrax.contact.Box] among them stands for its spheres (its end spheres,
      its corners), in order.
    - `plane`: the ground, a `Plane` of the spheres' dimension, or `None` (only
      `pairs`: a Newton's cradle).
    - `pairs`: the spheres that touch each other, as sphere–sphere contacts with the
      same normal law, friction and coefficients: `"all"` (every pair), a sequence of
      index pairs `(i, j)` into `spheres`, or `None` (default: none). A pair's gap is
      `|c_j − c_i| − r_i − r_j`; its force acts on `j` along `n = (c_j − c_i)/|c_j −
      c_i|` and on `i` opposite.
    - `friction`: the kinetic friction coefficient `μ ≥ 0` (default 0: frictionless).
    - `static_friction`: `μ_s ≥ μ` (default `μ`).
    - `stiffness`: `k` (force per length^p), `dissipation`: `c` (time per length),
      `stiction_velocity`: `v_s`; default (`None`) scaled from the scene (see the
      contact guide: a static penetration of `10⁻⁴` of the scene's size, a critically
      damped resting contact, `v_s = 10⁻⁴ √(g ℓ)`).
    - `exponent`: `p` (default 1.5, Hertz's sphere).
    - `reference`: the configuration the defaults are scaled at (default zeros; a
      floating base upright).
    - `max_penetration`: the deepest start allowed, as a fraction of the sphere's
      radius (a point: of the scene's size; a pair: of the smaller radius); default
      `0.01`. A deeper start is a `ContactError` (see `check_state`); a shallower one is
      pushed out by the contact spring, its stored energy part of the energy balance.
      `None`: no limit.
    - `limits`: joint limits enforced as compliant stops, a sequence of
      [`JointLimit`][lagrax.contact.JointLimit] (default none): each finite bound of
      joint `i` is a contact of the same normal law and exponent whose gap is
      `q_i − lo` (or `hi − q_i`) and whose force `±f_n` acts on joint `i` alone; its
      elastic energy is part of `energy` and its dissipation of `input_power`, as the
      ground's. The loaders' `limits="contact"` fills it from the robot's file. A
      joint that starts past its limit starts at it (`initial_state`), as MuJoCo's soft
      limit puts it there within its time constant: a stop started deep would release
      its stored energy only at the slow pace the damping allows (the law's force
      vanishes where the joint leaves faster than `2/(3c)`). MuJoCo's files often start
      outside (gymnasium's ant, its ankles at 0 against limits from 30°).
    - `limit_stiffness`, `limit_dissipation`: the stops' `k` (torque per rad^p, or
      force per m^p) and `c` (time per radian, or per metre), a number, one per limit
      or a function of `params`; default (`None`) scaled from the scene per joint, as
      critically damped stops as fast as the ground contact (see the contact guide).
    - `force`: an applied generalized force `F(t, q, v, params) -> (n_dof,)` added to
      the input, its power `F·v` in `input_power` (default `None`: none);
      [`from_mujoco`][lagrax.chains.from_mujoco] puts the model's fluid forces here.
    - `actuation`: actuators `τ = actuation(u, q, v)` (an
      [`MJCFActuation`][lagrax.chains.MJCFActuation]: MuJoCo's `ctrl` to
      `qfrc_actuator`); then the input `tau=` is `u`, `n_input = actuation.n_u` long,
      `u = 0` where none is given (default `None`: `tau` is the generalized force).
    - `unsupported`: what the scene's source file has that the scene does not simulate,
      one sentence each (default none; set by `from_mujoco`, which warns with them).
    - `name`: a label for messages.

    Each coefficient is a number or a function `f(params)`: a function reads it from
    `params`, so that `jax.grad` and `sweep` can vary it (`friction=lambda p: p["mu"]`).
    A function for `friction` or `static_friction` may return one coefficient per
    sphere, `(S,)` (the model-file loaders' `params["contact_friction"]`).

    **Raises:** `ConfigurationError` for a coefficient that is negative or not finite,
    `static_friction < friction`, a sphere whose plane dimension does not match or no
    spheres; `ArgumentTypeError` for a system that is not an `AbstractSystem`. At run
    time (`check_state`, which `simulate` calls on bad input) the same for coefficients
    read from `params`, and a scene without weight on the plane when the defaults are
    used.

    **Example:**

    ```python
    from lagrax.contact import ContactSystem, Plane, Sphere
    disk = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * p["m"] * (qd[0]**2 + qd[1]**2) + 0.25 * p["m"] * 0.1**2 * qd[2]**2,
        lambda q, p: p["m"] * 9.81 * q[1], n_dof=3)
    wheel = Sphere(0.1, lambda q, p: q[:2], angle=lambda q, p: q[2])
    scene = ContactSystem(disk, wheel, Plane([np.sin(0.2), np.cos(0.2)]), friction=0.5)
    q0 = [0.1 * np.sin(0.2), 0.1 * np.cos(0.2), 0.0]   # touching the slope
    sol = lx.simulate(scene, q0, [0.0, 0.0, 0.0], {"m": 1.0}, t1=1.0)  # rodas4: it sticks
    ```
    """

    system: AbstractSystem
    spheres: tuple[Sphere, ...]
    plane: Plane | None
    friction: Coefficient
    static_friction: Coefficient
    stiffness: Coefficient
    dissipation: Coefficient
    stiction_velocity: Coefficient
    exponent: float = eqx.field(static=True)
    reference: tuple[float, ...] | None = eqx.field(static=True)
    name: str = eqx.field(static=True)
    pairs: tuple[tuple[int, int], ...] = eqx.field(static=True)
    max_penetration: float | None = eqx.field(static=True)
    groups: tuple[tuple[int, ...], ...] = eqx.field(static=True)
    limits: tuple[JointLimit, ...] = eqx.field(static=True)
    limit_stiffness: Coefficient
    limit_dissipation: Coefficient
    force: Callable[..., Any] | None
    actuation: Any
    unsupported: tuple[str, ...] = eqx.field(static=True)

    def __init__(
        self,
        system: AbstractSystem,
        spheres: Sphere | Sequence[Sphere],
        plane: Plane | None = None,
        *,
        pairs: Any = None,
        friction: Coefficient = 0.0,
        static_friction: Coefficient = None,
        stiffness: Coefficient = None,
        dissipation: Coefficient = None,
        stiction_velocity: Coefficient = None,
        exponent: float = 1.5,
        reference: Any = None,
        max_penetration: float | None = 0.01,
        limits: Sequence[JointLimit] | None = None,
        limit_stiffness: Coefficient = None,
        limit_dissipation: Coefficient = None,
        force: Callable[..., Any] | None = None,
        actuation: Any = None,
        unsupported: Sequence[str] = (),
        name: str | None = None,
    ):
        if not isinstance(system, AbstractSystem):
            raise ArgumentTypeError(
                f"ContactSystem wraps a lagrax system (an AbstractSystem), got "
                f"{type(system).__name__}"
            )
        spheres = arguments.sphere_tuple(spheres, plane)
        if plane is not None and not isinstance(plane, Plane):
            raise ArgumentTypeError(f"plane must be a lagrax.contact.Plane or None, got {plane!r}")
        self.pairs = pairs_of(pairs, len(spheres))
        if plane is None and not self.pairs:
            raise ConfigurationError(
                "a ContactSystem needs something to touch: a plane, or pairs= of spheres "
                "(pairs='all': every pair)"
            )
        self.system = system
        self.spheres = spheres
        self.groups = placement_groups(spheres)
        self.plane = plane
        self.friction = arguments.coefficient("friction", friction, allow_none=False)
        self.static_friction = arguments.coefficient(
            "static_friction", static_friction, allow_none=True
        )
        mu, mus = self.friction, self.static_friction
        if isinstance(mu, float) and isinstance(mus, float) and mus < mu:
            raise ConfigurationError(
                f"static_friction must be >= friction (stiction holds at least as much as "
                f"sliding), got static_friction={mus!r} < friction={mu!r}"
            )
        self.stiffness = arguments.coefficient("stiffness", stiffness, allow_none=True)
        if isinstance(self.stiffness, float) and self.stiffness == 0:
            raise ConfigurationError("ContactSystem's stiffness must be > 0, got stiffness=0")
        self.dissipation = arguments.coefficient("dissipation", dissipation, allow_none=True)
        self.stiction_velocity = arguments.coefficient(
            "stiction_velocity", stiction_velocity, allow_none=True
        )
        if self.stiction_velocity == 0:
            raise ConfigurationError(
                "ContactSystem's stiction_velocity must be > 0, got stiction_velocity=0"
            )
        exponent = float(exponent)
        if not (math.isfinite(exponent) and exponent >= 1):
            raise ConfigurationError(
                f"ContactSystem's exponent must be finite and >= 1, got exponent={exponent!r}"
            )
        self.exponent = exponent
        self.reference = None if reference is None else tuple(float(x) for x in np.ravel(reference))
        self.name = f"{system.name} (contact)" if name is None else name
        self.max_penetration = arguments.max_penetration(max_penetration)
        self.limits = joint_limits.checked(limits)
        self.limit_stiffness = arguments.limit_coefficient("limit_stiffness", limit_stiffness)
        self.limit_dissipation = arguments.limit_coefficient("limit_dissipation", limit_dissipation)
        self.force, self.actuation = arguments.applied(force, actuation)
        self.unsupported = tuple(str(x) for x in unsupported)

    # ------------------------------------------------------------ shared with the system
    @property
    def n_dof(self) -> int | None:
        """The wrapped system's number of velocities."""
        return self.system.n_dof

    @property
    def n_input(self) -> int | None:
        """The input's size: the actuators' (`ctrl`) with an `actuation`, else `n_dof`."""
        return self.system.n_input if self.actuation is None else int(self.actuation.n_u)

    def generalized_input(self, q, qd, tau):
        """The generalized force `(n_dof,)` of the input `tau` at `(q, q̇)`: `tau`, or
        with an `actuation`, `actuation(u, q, q̇)` at `u = tau` (`u = 0` for `None`:
        MuJoCo's `qfrc_actuator` at `ctrl = 0`). Never raises."""
        if self.actuation is None:
            return tau
        dtype = jnp.result_type(qd)
        u = jnp.zeros((self.n_input,), dtype) if tau is None else jnp.asarray(tau, dtype)
        return self.actuation(u, q, qd)

    @property
    def n_configuration(self) -> int | None:
        """The wrapped system's configuration size."""
        return self.system.n_configuration

    @property
    def coordinate_names(self) -> tuple[str, ...] | None:
        """The wrapped system's coordinate names."""
        return self.system.coordinate_names

    @property
    def configuration_names(self) -> tuple[str, ...] | None:
        """The wrapped system's configuration names."""
        return self.system.configuration_names

    @property
    def final_maxima(self) -> tuple[str, ...]:
        """The wrapped system's final maxima."""
        return self.system.final_maxima

    def configuration_rate(self, q, v):
        """The wrapped system's `q̇ = N(q) v`."""
        return self.system.configuration_rate(q, v)

    def project_configuration(self, q):
        """The wrapped system's projection onto its configuration manifold."""
        return self.system.project_configuration(q)

    @property
    def rough_jacobian(self) -> bool:  # the slope p k δ^(p−1) at each onset and release
        return True

    @property
    def projects(self) -> bool:  # the wrapped system's
        return self.system.projects

    def initial_state(self, q, qd, params):
        """The wrapped system's, a joint past one of its `limits` moved onto it (its rate
        kept); `ok` false also where a sphere starts deeper than `max_penetration`."""
        q, qd, ok = self.system.initial_state(q, qd, params)
        q = joint_limits.clipped(self.limits, q)  # a joint started past a limit: at it
        return q, qd, ok & start.admissible(self, q, params)

    def prepared(self, params, dtype):
        """The scene with its coefficients computed at `params` (the defaults scaled from
        the scene once, not at every evaluation), and the wrapped system prepared. Where
        the defaults cannot be scaled (no weight on the plane), the stiffness is NaN, so
        the accelerations are NaN and the solve reports it."""
        system = self.system.prepared(params, dtype)
        own = (self.stiffness, self.dissipation, self.stiction_velocity)
        if self.limits:
            own = (*own, self.limit_stiffness, self.limit_dissipation)
        if None in own:
            co = self.coefficients(params, dtype)
            scaled = (jnp.where(co.ok, co.stiffness, jnp.nan), co.dissipation)
            scaled = (*scaled, co.stiction_velocity, co.limit_stiffness, co.limit_dissipation)
            scaled = scaled[: len(own)]
        else:
            scaled = own

        def fields(s):
            out = (s.system, s.stiffness, s.dissipation, s.stiction_velocity)
            return (*out, s.limit_stiffness, s.limit_dissipation) if self.limits else out

        return eqx.tree_at(fields, self, (system, *scaled), is_leaf=lambda x: x is None)

    def mass_matrix(self, q, params, qd=None, *, t=0.0):
        """The wrapped system's mass matrix (the contact adds no inertia)."""
        return self.system.mass_matrix(q, params, qd, t=t)

    def stiff_rate(self, q, v, params):
        """The magnitude `λ` of the fastest eigenvalue of the touching contacts at one
        state (1/s; 0 with none touching): the spring's `ω = √(k_eff/m_n)` (or its
        overdamped rate) and the friction's `f_n (μ(s)/s)/(v_s m_t)`, on the contact's
        effective masses along its normal and tangent (see the contact guide). A
        fixed-step explicit solve is stopped where `h λ > 2`."""
        return stability.rate(self, q, v, params)

    @property
    def default_method(self) -> str:
        """With neither `solver=` nor `dt=`: `"rodas4"` where a contact can stick (a
        `friction` or `static_friction` not the constant 0) or limits are enforced,
        else `"tsit5"` (see the contact guide, "The default method")."""
        frictionless = self.friction == 0.0 and self.static_friction in (None, 0.0)
        return "tsit5" if frictionless and not self.limits else "rodas4"

    def stiff_account(self, q, v, params):
        """Eagerly, `(sentence, λ)`: the contact of fastest rate `λ` at `(q, v)` (a
        sphere, a pair, a limit's stop), its stiff part (spring or friction) and its
        coefficients; the wrapped system's where none touches. Never raises."""
        return stability.account(self, q, v, params) or self.system.stiff_account(q, v, params)

    def failure_hint(self, q, params):
        """The wrapped system's hint."""
        return self.system.failure_hint(q, params)

    # ------------------------------------------------------------ geometry
    @property
    def dim(self) -> int | None:
        """The dimension of the space, 2 or 3: the plane's, or the spheres' orientation's
        (`None`: known from the centres once traced)."""
        if self.plane is not None:
            return self.plane.dim
        if any(s.angle is not None for s in self.spheres):
            return 2
        if any(s.rotation is not None for s in self.spheres):
            return 3
        return None

    def centres(self, q, params):
        """The spheres' centres, shape `(S, d)`."""
        return forces.centres(self, q, params)

    def gaps(self, q, params):
        """The gaps `g_i = n·c_i − offset − r_i` to the plane, shape `(S,)` (negative:
        penetration); with no plane, the pairs' gaps (see `pair_gaps`)."""
        plane, pair = forces.gaps(self, q, params)
        return pair if plane is None else plane

    def pair_gaps(self, q, params):
        """The pairs' gaps `|c_j − c_i| − r_i − r_j`, shape `(P,)` (negative: overlap)."""
        pair = forces.gaps(self, q, params)[1]
        return jnp.zeros((0,), jnp.result_type(q, float)) if pair is None else pair

    def point_velocities(self, q, v, params):
        """`(velocities, centres)`: the velocities of the spheres' contact points with
        the plane, `c_i − r_i n`, `ċ_i + ω_i × (−r_i n)`, and their centres, both
        `(S, d)`; linear in the velocities `v`."""
        c, c_dot, w = forces.motion(self, q, v, params)
        normal = jnp.asarray(self.plane.normal, c.dtype)
        r = forces.radii(self, c.dtype)
        return c_dot + pairs.turn(w, -r[:, None] * normal[None, :]), c

    # ------------------------------------------------------------ coefficients
    def coefficients(self, params, dtype=float) -> Coefficients:
        """The contact's coefficients at `params` (functions of `params` evaluated,
        defaults scaled from the scene), and whether they are valid."""

        return scale.coefficients(self, params, dtype)

    # ------------------------------------------------------------ forces
    def contact_state(self, q, v, params):
        """The contact at one state: a dict of `gap` `(S,)`, `normal_force` `f_n`
        `(S,)`, `elastic_force` `k δ₊^p` `(S,)`, `force` (on each contact point, world
        frame, `(S, d)`), `velocity` (of each contact point, `(S, d)`) and `normal`
        `(S, d)` for the plane's contacts (absent without a plane); the same, prefixed
        `pair_`, for the pairs (`pair_force`: on sphere `j` of pair `(i, j)`, `−` that
        on `i`; `pair_velocity`: `j`'s contact point's relative to `i`'s; `pair_normal`:
        from `i` to `j`; absent without pairs); the generalized force `generalized`
        `Q = Σ J_iᵀ F_i` `(n_dof,)`, the elastic `energy` `V_c` and the
        `coefficients`."""
        return forces.contact_state(self, q, v, params)

    def normal_forces(self, q, qd, params):
        """The normal forces `f_n` on the spheres from the plane at one state, shape
        `(S,)`."""
        return self.contact_state(jnp.asarray(q), jnp.asarray(qd), params)["normal_force"]

    def contact_energy(self, q, params):
        """The elastic energy stored in the contacts (the plane's and the pairs'),
        `V_c = Σ k δ₊^{p+1}/(p+1)`."""
        return forces.elastic_energy(self, q, params)

    # ------------------------------------------------------------ the dynamics
    def accelerations(self, t, q, qd, params, tau):
        """The wrapped system's accelerations with the contact's generalized force added
        to `tau`; NaN where a coefficient is invalid (so `simulate` reports it)."""
        contact = self.contact_state(q, qd, params)
        force = contact["generalized"]
        tau = self.generalized_input(q, qd, tau)
        force = force if tau is None else force + tau
        if self.force is not None:
            force = force + self.force(t, q, qd, params)
        qdd = self.system.accelerations(t, q, qd, params, force)
        return jnp.where(contact["coefficients"].ok, qdd, jnp.nan)

    def forward_dynamics(self, q, qd, params, tau=None, t=0.0):
        """Accelerations with the contact forces, every input checked.

        **Raises:** as the wrapped system's `forward_dynamics`, and the errors of
        [`check_state`][lagrax.contact.ContactSystem.check_state].
        """
        q = coords(q, "q", self.n_configuration, self.name)
        qd = coords(qd, "qd", self.n_dof, self.name)
        if tau is not None:
            size = "degrees of freedom" if self.actuation is None else "actuators (ctrl)"
            tau = coords(tau, "tau", self.n_input, self.name, size=size)
        if not traced(self, q, qd, tau, params, t):
            self.check_state(q, qd, params, t=t)
        qdd = self.accelerations(t, q, qd, params, tau)
        return eqx.error_if(
            qdd,
            ~jnp.all(jnp.isfinite(qdd)),
            f"forward_dynamics of {self.name} produced non-finite accelerations: a state, "
            "a parameter or a contact coefficient is not finite or not valid. Outside jit "
            "the message names which.",
        )

    def check_state(self, q, qd, params, *, t=0.0) -> None:
        """Validate a state eagerly: the wrapped system's checks, the spheres' shapes and
        the contact's coefficients (those read from `params` and the defaults).

        **Raises:** the wrapped system's errors; `ShapeError` for a sphere position of
        the wrong shape; `ConfigurationError` for a coefficient that is negative or not
        finite, `static_friction < friction`, or default coefficients in a scene with no
        weight on the plane (pass `stiffness=` and `dissipation=`); `ContactError` for a
        sphere that starts deeper inside the ground or another sphere than
        `max_penetration` allows.
        """
        eager_only(f"check_state of {self.name}", self, q, qd, params, t)
        self.system.check_state(q, qd, params, t=t)
        q, qd = jnp.asarray(q, float), jnp.asarray(qd, float)
        forces.gaps(self, q, params)
        co = self.coefficients(params, q.dtype)
        named = (
            ("stiffness", co.stiffness, "> 0"),
            ("dissipation", co.dissipation, ">= 0"),
            ("friction", co.friction, ">= 0"),
            ("static_friction", co.static_friction, ">= friction"),
            ("stiction_velocity", co.stiction_velocity, "> 0"),
        )
        arguments.check_limit_coefficients(self, co)
        for label, value, rule in named:
            # (a friction read from params may be one coefficient per sphere, `(S,)`)
            values = np.broadcast_to(np.asarray(value, float), (len(self.spheres),))
            floors = np.broadcast_to(np.asarray(co.friction, float), values.shape)
            for x, floor in zip(values.tolist(), floors.tolist(), strict=True):
                bad = not math.isfinite(x) or x < 0 or (rule == "> 0" and x == 0)
                if bad or (label == "static_friction" and x < floor):
                    raise ConfigurationError(
                        f"the contact of {self.name} has {label}={x!r}; it must be finite "
                        f"and {rule} (check the value or the params entry it is read from)"
                    )
        if not bool(co.ok):
            raise ConfigurationError(
                f"the contact of {self.name} scales its default stiffness, dissipation and "
                "stiction velocity by the weight on the plane, and this scene has none at "
                "its reference configuration (no gravity towards the plane, or constraints "
                "that carry it there): pass stiffness=, dissipation= and "
                "stiction_velocity= explicitly, or a reference= where the spheres bear weight"
            )
        start.check(self, self.system.initial_state(q, qd, params)[0], params)

    # ------------------------------------------------------------ the energy balance
    def energy(self, q, qd, params, *, t=0.0):
        """The wrapped system's energy plus the contacts' elastic energy `V_c`."""
        return self.system.energy(q, qd, params, t=t) + self.contact_energy(q, params)

    def jacobi_integral(self, t, q, qd, params):
        """The wrapped system's `h` plus `V_c`."""
        return self.system.jacobi_integral(t, q, qd, params) + self.contact_energy(q, params)

    def explicit_power(self, t, q, qd, params):
        """The wrapped system's `−∂L/∂t`."""
        return self.system.explicit_power(t, q, qd, params)

    def input_power(self, t, q, qd, params, tau):
        """The wrapped system's input power plus the contacts' dissipation and friction,
        `Σ (F_i − f_el,i n_i)·v_i` over the plane's contacts and the pairs, the joint
        limits' `Σ (f_n − f_el) ġ` (the elastic parts' power is `−dV_c/dt`, in `h`),
        and the applied `force`'s `F·v`."""
        power = forces.dissipated_power(self.contact_state(q, qd, params))
        if self.force is not None:
            power = power + jnp.dot(self.force(t, q, qd, params), qd)
        inner = self.system.input_power(t, q, qd, params, self.generalized_input(q, qd, tau))
        return power if inner is None else inner + power

    def energy_and_magnitude(self, t, q, qd, params):
        """The wrapped system's `(h, |T| + |V|)` with `V_c` added to both."""
        h, magnitude = self.system.energy_and_magnitude(t, q, qd, params)
        stored = self.contact_energy(q, params)
        return h + stored, magnitude + jnp.abs(stored)

    def components(self, t, q, qd, params):
        """The wrapped system's components, the gaps and the contact forces."""
        out = dict(self.system.components(t, q, qd, params))
        contact = self.contact_state(q, qd, params)
        for key, label in _OUTPUTS:
            if key in contact:
                out[f"the contact {label}"] = contact[key]
        return out

    def observables(self, t, q, qd, params, tau):
        """The wrapped system's observables, and `contact_gap` `(S,)` and
        `contact_force` `(S, d)` (on each contact point, in the world frame; with a
        plane), `pair_gap` `(P,)` and `pair_force` `(P, d)` (on sphere `j` of each pair
        `(i, j)`; with pairs), `limit_gap` `(K,)` and `limit_force` `(K,)` (each joint
        limit's stop: its gap, and its generalized force on its joint; with limits)."""
        out = dict(self.system.observables(t, q, qd, params, self.generalized_input(q, qd, tau)))
        contact = self.contact_state(q, qd, params)
        for key, _ in _OUTPUTS:
            if key in contact:
                out[key if key.startswith(("pair_", "limit_")) else f"contact_{key}"] = contact[key]
        return out

    def observable_dims(self):
        """The wrapped system's, and `("contact",)` for `contact_gap`, `("contact",
        "axis")` for `contact_force`, `("pair",)` and `("pair", "axis")` for
        `pair_gap` and `pair_force` (`axis`: the world frame's `x, y[, z]`)."""
        return {
            **self.system.observable_dims(),
            "contact_gap": ("contact",),
            "contact_force": ("contact", "axis"),
            "pair_gap": ("pair",),
            "pair_force": ("pair", "axis"),
            "limit_gap": ("stop",),
            "limit_force": ("stop",),
        }

    # ------------------------------------------------------------ events
    def events(self, max_events: int = 100) -> tuple[Event, ...]:
        """One [`Event`][lagrax.Event] per sphere on its gap to the plane, then one per
        pair on its gap, then one per joint limit's stop (each finite bound, lower
        before upper, in the order of `limits`) on its gap, for `simulate(...,
        events=)`: each contact's onset and release is located on the dense output and
        the step is cut there (an identity reset), so the adaptive steps keep their
        order across the switch. `Solution.events[i]`
        records sphere `i`'s crossings (with a plane), then pair `k`'s at
        `Solution.events[S + k]` (`S`: the number of spheres; `k` without a plane), then
        the stops'.

        **Arguments:** `max_events`: the most crossings recorded per contact (a solve
        with more ends with `RESULTS.event_cascade`).

        **Returns:** a tuple of `Event`s, one per contact.
        """

        def gap_of(i, which):
            return lambda t, q, qd, p: forces.gaps(self, q, p)[which][i]

        conditions = []
        if self.plane is not None:
            conditions += [gap_of(i, 0) for i in range(len(self.spheres))]
        conditions += [gap_of(k, 1) for k in range(len(self.pairs))]
        stops = joint_limits.stops(self.limits)
        conditions += [
            (lambda t, q, qd, p, k=k: joint_limits.gaps(self, q)[k]) for k in range(len(stops.q))
        ]
        return tuple(Event(c, reset=keep, max_events=max_events) for c in conditions)


_OUTPUTS = (
    ("gap", "gaps"),
    ("force", "forces"),
    ("pair_gap", "pair gaps"),
    ("pair_force", "pair forces"),
    ("limit_gap", "joint limits' gaps"),
    ("limit_force", "joint limits' forces"),
)
