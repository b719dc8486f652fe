"""A `Scene`: the sum of bodies, springs, dampers and hand-written terms, as a system."""

import equinox as eqx
import jax.numpy as jnp

from ..._core.custom_types import Params, Scalar, Vector
from ..._core.errors import ArgumentTypeError, ConfigurationError
from ..._systems.lagrangian import DissipationFn, ForceFn, KineticFn, LagrangianSystem, PotentialFn
from ..common import value
from .bodies import AbstractBody, ParamLike, PlanarBody, PointMass, SpatialBody
from .forces import (
    AbstractDamper,
    AbstractSpring,
    LinearDamper,
    LinearSpring,
    TorsionalDamper,
    TorsionalSpring,
)
from .scene_equations import SceneEquations


def _check_members(items, kind, name: str) -> None:
    for i, item in enumerate(items):
        if not isinstance(item, kind):
            raise ArgumentTypeError(
                f"Scene.{name}[{i}] is a {type(item).__name__}; expected a {kind.__name__} "
                f"subclass (e.g. {', '.join(c.__name__ for c in _EXAMPLES[kind])})"
            )


class Scene(eqx.Module):
    r"""A mechanical scene: the sum of its bodies, springs, dampers and hand-written terms.

    $$
    T = Σ_{bodies} T_b + T_{extra},\qquad
    V = Σ_{bodies} (−m_b g⃗·x_b) + Σ_{springs} V_s + V_{extra},\qquad
    D = Σ_{dampers} D_d + D_{extra}
    $$

    [`system`][lagrax.bodies.Scene.system] turns it into a [`lagrax.LagrangianSystem`][] with these
    energies.

    **Arguments:**

    - `bodies`: [`PointMass`][lagrax.bodies.PointMass], [`PlanarBody`][lagrax.bodies.PlanarBody],
      [`SpatialBody`][lagrax.bodies.SpatialBody] (any mix).
    - `springs`: [`LinearSpring`][lagrax.bodies.LinearSpring],
      [`TorsionalSpring`][lagrax.bodies.TorsionalSpring] (potential terms).
    - `dampers`: [`LinearDamper`][lagrax.bodies.LinearDamper],
      [`TorsionalDamper`][lagrax.bodies.TorsionalDamper] (Rayleigh terms).
    - `gravity`: the gravitational acceleration: a magnitude `g` (default 9.81 m/s²)
      acting along each body's negative last axis (−y for planar positions, −z for spatial
      ones), or a vector `g⃗` of the bodies' dimension; a constant or a callable of
      `params` (e.g. `Param("g")`, so sweeps can vary it); `None` for none.
    - `kinetic`, `potential`, `dissipation`: hand-written extra terms with the
      signatures of [`lagrax.LagrangianSystem`][] (`T(q, qd, params)`,
      `V(q, params)`, `D(q, qd, params)`).
    - `force`: applied generalized force `F(t, q, qd, params)`, passed on to the system.
    - `n_dof`: number of generalized coordinates (recommended: shapes are then checked).
    - `name`: a label for messages and plots.
    - `equations`: how [`system`][lagrax.bodies.Scene.system] evaluates the equations of motion.
      `"poses"`: from the bodies' pose maps (`M = Σ m J_vᵀJ_v + J_ωᵀ I J_ω` from one forward-mode
      Jacobian of the poses, the velocity products from one second-order derivative
      along `q̇`, Newton's and Euler's equations of each body projected on the
      coordinates; no second derivatives of `T`). `"energies"`: by differentiating
      `T` and `V` (the definition; both agree to round-off). `"auto"` (default):
      `"poses"` when the scene has a [`SpatialBody`][lagrax.bodies.SpatialBody] or `n_dof >= 4` and
      no hand-written `kinetic` term, else `"energies"`.
    - `scalar_derivatives`: passed to [`lagrax.LagrangianSystem`][]. Default `None`:
      `False` when the scene has a [`SpatialBody`][lagrax.bodies.SpatialBody] (the energy of
      rotation matrices is large; forward-over-reverse derivatives compiled 2–10× faster and ran
      about as fast or faster in `benchmarks/bench_planar_vs_spatial.py`), else the system's
      default.

    **Example:** a damped pendulum on a torsional spring:

    ```python
    import jax.numpy as jnp
    from lagrax.bodies import Param, PlanarBody, Scene, TorsionalDamper, TorsionalSpring

    rod = PlanarBody(
        mass=Param("m"), inertia=lambda p: p["m"] * p["l"] ** 2 / 12,
        position=lambda q, p: 0.5 * p["l"] * jnp.stack([jnp.sin(q[0]), -jnp.cos(q[0])]),
        angle=lambda q, p: q[0],
    )
    scene = Scene([rod], springs=[TorsionalSpring(Param("k"), 0)],
                  dampers=[TorsionalDamper(Param("c"), 0)], gravity=Param("g"), n_dof=1)
    system = scene.system()
    ```
    """

    bodies: tuple[AbstractBody, ...] = eqx.field(default=(), converter=tuple)
    springs: tuple[AbstractSpring, ...] = eqx.field(default=(), converter=tuple)
    dampers: tuple[AbstractDamper, ...] = eqx.field(default=(), converter=tuple)
    gravity: ParamLike | None = 9.81
    kinetic: KineticFn | None = None
    potential: PotentialFn | None = None
    dissipation: DissipationFn | None = None
    force: ForceFn | None = None
    n_dof: int | None = eqx.field(default=None, static=True)
    name: str = eqx.field(default="scene", static=True)
    scalar_derivatives: bool | None = eqx.field(default=None, static=True)
    equations: str = eqx.field(default="auto", static=True)

    def __check_init__(self):
        if self.equations not in _EQUATIONS:
            raise ConfigurationError(
                f"Scene equations must be one of {sorted(_EQUATIONS)}, got {self.equations!r}"
            )
        _check_members(self.bodies, AbstractBody, "bodies")
        _check_members(self.springs, AbstractSpring, "springs")
        _check_members(self.dampers, AbstractDamper, "dampers")
        if not self.bodies and self.kinetic is None:
            raise ConfigurationError(
                "a Scene needs at least one body or a hand-written kinetic energy"
            )

    def kinetic_energy(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        """`T = Σ T_b + T_extra`."""
        total = sum(b.kinetic_energy(q, qd, params) for b in self.bodies)
        if self.kinetic is not None:
            total = total + self.kinetic(q, qd, params)
        return jnp.asarray(total)

    def potential_energy(self, q: Vector, params: Params) -> Scalar:
        """`V = Σ gravity of bodies + Σ springs + V_extra`."""
        total = jnp.zeros((), jnp.result_type(q))
        if self.gravity is not None and self.bodies:
            g = value(self.gravity, params)
            for body in self.bodies:
                total = total + body.potential_energy(q, params, g)
        for spring in self.springs:
            total = total + spring.potential_energy(q, params)
        if self.potential is not None:
            total = total + self.potential(q, params)
        return total

    def dissipation_function(self, q: Vector, qd: Vector, params: Params) -> Scalar:
        """`D = Σ D_d + D_extra`."""
        total = jnp.zeros((), jnp.result_type(q))
        for damper in self.dampers:
            total = total + damper.dissipation(q, qd, params)
        if self.dissipation is not None:
            total = total + self.dissipation(q, qd, params)
        return total

    def system(self) -> LagrangianSystem:
        """The [`lagrax.LagrangianSystem`][] of this scene.

        Terms the scene does not have are left out (no potential without gravity, springs
        or an extra potential; no dissipation without dampers), so they cost nothing.
        """
        has_v = bool(self.springs) or self.potential is not None
        has_v = has_v or (self.gravity is not None and bool(self.bodies))
        has_d = bool(self.dampers) or self.dissipation is not None
        scalar = self.scalar_derivatives
        if scalar is None and any(isinstance(b, SpatialBody) for b in self.bodies):
            scalar = False
        equations = None
        if self._use_poses():
            equations = SceneEquations(self)
        return LagrangianSystem(
            self.kinetic_energy,
            self.potential_energy if has_v else None,
            dissipation=self.dissipation_function if has_d else None,
            force=self.force,
            n_dof=self.n_dof,
            name=self.name,
            scalar_derivatives=scalar,
            equations=equations,
        )

    def _use_poses(self) -> bool:
        """Whether [`system`][lagrax.bodies.Scene.system] evaluates the equations from the
        bodies' pose maps."""
        if self.equations == "energies" or not self.bodies:
            return False
        if self.kinetic is not None:
            if self.equations == "poses":
                raise ConfigurationError(
                    "Scene(equations='poses') needs every kinetic term to come from bodies; "
                    "this scene has a hand-written kinetic energy"
                )
            return False
        if self.equations == "poses":
            return True
        spatial = any(isinstance(b, SpatialBody) for b in self.bodies)
        return spatial or (self.n_dof is not None and self.n_dof >= _POSES_MIN_PLANAR)


_EQUATIONS = ("auto", "poses", "energies")
# Scenes without spatial bodies use the pose-map equations from this many coordinates: a
# planar chain of bodies ran 1.7x / 3x / 9x faster than autodiff of its energy at n = 4 /
# 6 / 8 (and compiled 2-7x faster); at n = 2 scalar autodiff is 4x faster.
_POSES_MIN_PLANAR = 4

_EXAMPLES = {
    AbstractBody: (PointMass, PlanarBody, SpatialBody),
    AbstractSpring: (LinearSpring, TorsionalSpring),
    AbstractDamper: (LinearDamper, TorsionalDamper),
}
