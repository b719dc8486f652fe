r"""The lecture's three derivations of the 2R arm's equations, compared symbolically.

- **Lagrange** from the energies of [`lagrax.models.planar_2r`][]:
  [`equations`][lagrax.symbolic.equations].
- **Newton–Euler** from the free-body diagrams: [`lagrax.newton_euler.planar_2r`][] (each
  link cut free, `m a_c = Σ f` and `I α = Σ M`, the joint reaction eliminated),
  interpreted on the same symbols.
- **Kane's method**: the arm built from two [`PlanarBody`][lagrax.bodies.PlanarBody]s, and
  the equations its scene evaluates from the bodies' pose maps (`Scene(equations="poses")`),
  interpreted on the symbols: `M = Σ_b m_b J_{v,b}ᵀ J_{v,b} + I_b J_{ω,b}ᵀ J_{ω,b}` and
  `C q̇ = Σ_b m_b J_{v,b}ᵀ J̇_{v,b} q̇ + I_b J_{ω,b}ᵀ J̇_{ω,b} q̇`, plus `G = ∂V/∂q`.
  The columns of `J_{v,b} = ∂v_b/∂q̇` and `J_{ω,b} = ∂ω_b/∂q̇` are Kane's partial
  velocities; `F*_r = −Σ_b (m_b a_b·∂v_b/∂q̇_r + I_b α_b ∂ω_b/∂q̇_r)` (with
  `a_b = J_{v,b} q̈ + J̇_{v,b} q̇`, `α_b = J_{ω,b} q̈ + J̇_{ω,b} q̇`) are the generalized
  inertia forces, and `F_r = Σ_b m_b g⃗·∂v_b/∂q̇_r + τ_r = −∂V/∂q_r + τ_r` the generalized
  active forces; Kane's equations `F_r + F*_r = 0` are `τ = M q̈ + C q̇ + G`, which is
  what the scene computes (its `G` as the gradient of `V`, the same active forces).

All three must equal the slide's equations (the lecture's notation, `c12 = cos(θ1 + θ2)`):

    τ1 = (I1 + I2 + m1 r1² + m2 r2² + m2 l1² + 2 m2 l1 r2 c2) θ̈1 + (I2 + m2 r2² + m2 l1 r2 c2) θ̈2
         − m2 l1 r2 s2 (2 θ̇1 + θ̇2) θ̇2 + m2 g (l1 c1 + r2 c12) + m1 g r1 c1
    τ2 = (I2 + m2 r2² + m2 l1 r2 c2) θ̈1 + (I2 + m2 r2²) θ̈2 + m2 l1 r2 s2 θ̇1² + m2 g r2 c12
"""

from __future__ import annotations

import dataclasses
from typing import Any

import jax.numpy as jnp
import numpy as np

from ..bodies import Param, PlanarBody, Scene
from ..models import planar_2r
from ..newton_euler import planar_2r as newton_euler_planar_2r
from .conversions import load_sympy
from .equations import Equations, equations
from .interpreter import interpret
from .simplification import canonical


def _unit(angle):
    return jnp.stack([jnp.cos(angle), jnp.sin(angle)])


def _link1(q, p):
    return p["r1"] * _unit(q[0])


def _link2(q, p):
    return p["l1"] * _unit(q[0]) + p["r2"] * _unit(q[0] + q[1])


def _angle1(q, p):
    return q[0]


def _angle2(q, p):
    return q[0] + q[1]


def planar_2r_scene() -> Any:
    """The 2R arm as a [`lagrax.bodies.Scene`][] of two
    [`PlanarBody`][lagrax.bodies.PlanarBody]s (same parameters as
    [`lagrax.models.planar_2r`][]), evaluated from the bodies' pose maps
    (`equations="poses"`): Kane's method (see the module docstring)."""

    links = [
        PlanarBody(Param("m1"), Param("I1"), _link1, _angle1),
        PlanarBody(Param("m2"), Param("I2"), _link2, _angle2),
    ]
    return Scene(links, gravity=Param("g"), n_dof=2, name="2R arm of bodies", equations="poses")


def slide_2r(eq: Equations) -> Any:
    """The slide's `τ` of the 2R arm (module docstring), in the symbols of `eq` (the
    equations of [`lagrax.models.planar_2r`][] or a system with its parameter names)."""
    sp = load_sympy()
    s = eq.symbols
    m1, m2, l1, r1, r2, i1, i2, g = (s[k] for k in ("m1", "m2", "l1", "r1", "r2", "I1", "I2", "g"))
    th1, th2 = eq.q
    w1, w2 = eq.qd
    a1, a2 = eq.qdd
    c1, c2, s2, c12 = sp.cos(th1), sp.cos(th2), sp.sin(th2), sp.cos(th1 + th2)
    tau1 = (
        (i1 + i2 + m1 * r1**2 + m2 * r2**2 + m2 * l1**2 + 2 * m2 * l1 * r2 * c2) * a1
        + (i2 + m2 * r2**2 + m2 * l1 * r2 * c2) * a2
        - m2 * l1 * r2 * s2 * (2 * w1 + w2) * w2
        + m2 * g * (l1 * c1 + r2 * c12)
        + m1 * g * r1 * c1
    )
    tau2 = (
        (i2 + m2 * r2**2 + m2 * l1 * r2 * c2) * a1
        + (i2 + m2 * r2**2) * a2
        + m2 * l1 * r2 * s2 * w1**2
        + m2 * g * r2 * c12
    )
    return sp.Matrix([tau1, tau2])


def _state(eq: Equations) -> tuple[Any, ...]:
    params = {key: eq.symbols[key] for key, _ in eq.parameter_keys}
    arrays = tuple(np.array(list(v), dtype=object) for v in (eq.q, eq.qd, eq.qdd))
    return (*arrays, params)


def newton_euler_2r(eq: Equations) -> Any:
    """`τ` of the 2R arm by the free-body Newton–Euler method
    ([`lagrax.newton_euler.planar_2r`][], interpreted), simplified, in `eq`'s symbols."""
    tau = interpret(newton_euler_planar_2r, *_state(eq))
    return tau.applyfunc(canonical)


def kane_2r(eq: Equations) -> Any:
    """`τ = M q̈ + (C q̇ + G)` of the 2R arm by Kane's method: the pose-map equations of
    [`planar_2r_scene`][lagrax.symbolic.planar_2r_scene], interpreted and simplified, in
    `eq`'s symbols."""
    q, qd, _, params = _state(eq)
    system = planar_2r_scene().system()
    mass, bias = interpret(system.equations.mass_and_bias, q, qd, params)
    return mass.applyfunc(canonical) * eq.qdd + bias.applyfunc(canonical)


@dataclasses.dataclass(frozen=True)
class Derivations2R:
    """The 2R arm's `τ` by the lecture's three methods and on its slide (columns
    `Matrix`es in the symbols of `equations`)."""

    equations: Equations
    """Lagrange's equations from the energies ([`equations`][lagrax.symbolic.equations])."""
    lagrange: Any
    """`τ` from the energies."""
    newton_euler: Any
    """`τ` from the free-body diagrams."""
    kane: Any
    """`τ` from the partial velocities (the scene's pose-map equations)."""
    slide: Any
    """`τ` as on the lecture's slide."""

    def differences(self) -> dict[str, Any]:
        """Each derivation minus the slide, simplified entry by entry (`sympy.simplify`):
        zero matrices when they agree."""
        sp = load_sympy()
        return {
            name: (value - self.slide).applyfunc(sp.simplify)
            for name, value in (
                ("lagrange", self.lagrange),
                ("newton_euler", self.newton_euler),
                ("kane", self.kane),
            )
        }

    def agree(self) -> bool:
        """Whether all three equal the slide: `simplify(τ − τ_slide) == 0` entry by entry."""
        return all(all(e == 0 for e in diff) for diff in self.differences().values())


def derivations_2r(**overrides: float) -> Derivations2R:
    """The lecture's 2R arm derived three ways (Lagrange, Newton–Euler, Kane) and on its
    slide, symbolically, in the symbols `θ1, θ2` and `m1 m2 l1 l2 r1 r2 I1 I2 g`.

    **Arguments:** `overrides`: parameter values for [`lagrax.models.planar_2r`][] (they
    only decide the symbols' assumptions: every default is positive).

    **Returns:** a [`Derivations2R`][lagrax.symbolic.Derivations2R];
    `derivations_2r().agree()` is `True`.

    **Example:**

    ```python
    d = lx.symbolic.derivations_2r()
    d.differences()   # {'lagrange': Matrix([[0], [0]]), 'newton_euler': ..., 'kane': ...}
    ```
    """
    system, params = planar_2r(**overrides)
    eq = equations(system, params, coordinates=("theta1", "theta2"))
    return Derivations2R(
        equations=eq,
        lagrange=eq.tau,
        newton_euler=newton_euler_2r(eq),
        kane=kane_2r(eq),
        slide=slide_2r(eq),
    )
