"""Bodies, springs and dampers as energy terms, and inertia tools.

Describe *where* things are as functions of the generalized coordinates `q`; lagrax
differentiates them (`jax.jvp`) for the velocities, sums the energies and hands them to
[`lagrax.LagrangianSystem`][]:

```python
import jax.numpy as jnp
import lagrax as lx
from lagrax.bodies import Param, PointMass, Scene

def bob(q, p):                        # a pendulum bob hanging from the origin
    return p["l"] * jnp.stack([jnp.sin(q[0]), -jnp.cos(q[0])])

system = Scene([PointMass(Param("m"), bob)], gravity=Param("g"), n_dof=1).system()
system.forward_dynamics(jnp.array([0.3]), jnp.array([0.0]), {"m": 1.0, "l": 2.0, "g": 9.81})
```

**Parameters.** Every mass, inertia, stiffness, coefficient and gravity field is a
[`ParamLike`][lagrax.bodies.ParamLike]: a constant, or a callable `params -> value` evaluated with
the `params` the system is called with. [`Param`][lagrax.bodies.Param] (`Param("m")` reads
`params["m"]`) is the usual choice, so that sweeps can vary the value; a `lambda p: p["m"] * p["l"]
** 2` derives one. Positions, angles and rotations are functions `(q, params) -> ...`.

**Bodies.**

- [`PointMass`][lagrax.bodies.PointMass] `(mass, position)`: `T = ½ m ‖ẋ‖²`, in 1, 2 or 3
  dimensions.
- [`PlanarBody`][lagrax.bodies.PlanarBody] `(mass, inertia, position, angle)`: `T = ½ m ‖v_c‖² + ½
  I_c θ̇²`.
- [`SpatialBody`][lagrax.bodies.SpatialBody] `(mass, inertia, position, rotation)`:
  `T = ½ m ‖v_c‖² + ½ ω_Bᵀ I_c ω_B` with `ω̂_B = Rᵀ Ṙ` from the JVP of `R(q)`.

Gravity (`Scene(gravity=...)`) is a magnitude acting along the negative last axis of each
body's position (−y in the plane, −z in space) or a full vector. A body may stand for `k`
bodies at once: parameters of shape `(k,)` (or shared) and kinematics returning a *list*
of `k` poses (fastest for a few bodies: the energy stays straight-line scalar code that
XLA fuses) or arrays with the bodies along axis 0 (for many bodies).

**Planar or spatial?** Use the smallest description the motion needs. A mechanism that
moves in a plane is exactly described by [`PlanarBody`][lagrax.bodies.PlanarBody] (2 position
components and one angle per body); the same mechanism built from
[`SpatialBody`][lagrax.bodies.SpatialBody] (3 components and a 3×3 rotation matrix) gives identical
equations, but its energy differentiates rotation matrices where the planar one differentiates one
angle. Measured on the 2R arm (`benchmarks/bench_planar_vs_spatial.py`, one run on a shared 2-core
CPU): vmapped forward dynamics ~11× slower, compile ~3× longer, a short `simulate` ~3× slower; at 5
links ~10× and ~4× slower to run. Reach for [`SpatialBody`][lagrax.bodies.SpatialBody] when bodies
leave the plane or spin about in-plane axes; [`PointMass`][lagrax.bodies.PointMass] when rotational
inertia is negligible. Scenes with spatial bodies default to forward-over-reverse derivatives
(`Scene(scalar_derivatives=...)`), which compile much faster for them.

**Springs and dampers.** [`LinearSpring`][lagrax.bodies.LinearSpring] (between two points, with a
rest length), [`TorsionalSpring`][lagrax.bodies.TorsionalSpring] (on a coordinate or a scalar
function of `q`), [`LinearDamper`][lagrax.bodies.LinearDamper] (relative velocity of two points, or
axial dashpot), [`TorsionalDamper`][lagrax.bodies.TorsionalDamper] (on a coordinate). A
[`Scene`][lagrax.bodies.Scene] sums them with any hand-written
`kinetic`/`potential`/`dissipation`/`force` and `.system()` builds the
[`lagrax.LagrangianSystem`][].

**Inertia tools** (the lecture's conventions, `I = ∫ −[r]² ρ dV`):
[`rod_inertia`][lagrax.bodies.rod_inertia], [`box_inertia`][lagrax.bodies.box_inertia],
[`cylinder_inertia`][lagrax.bodies.cylinder_inertia],
[`sphere_inertia`][lagrax.bodies.sphere_inertia], [`parallel_axis`][lagrax.bodies.parallel_axis]
(`I_P = I_C + m(‖d‖² 1 − d dᵀ)`), [`rotate_inertia`][lagrax.bodies.rotate_inertia] (`ᴬI = ᴬR_B ᴮI
ᴬR_Bᵀ`), [`principal_axes`][lagrax.bodies.principal_axes] (eigen-decomposition) and
[`check_inertia`][lagrax.bodies.check_inertia] (symmetric, positive-definite, `I1 + I2 ≥ I3`).
"""

from ._multibody.energies.bodies import AbstractBody as AbstractBody
from ._multibody.energies.bodies import Param as Param
from ._multibody.energies.bodies import ParamLike as ParamLike
from ._multibody.energies.bodies import PlanarBody as PlanarBody
from ._multibody.energies.bodies import PointFn as PointFn
from ._multibody.energies.bodies import PointMass as PointMass
from ._multibody.energies.bodies import SpatialBody as SpatialBody
from ._multibody.energies.forces import AbstractDamper as AbstractDamper
from ._multibody.energies.forces import AbstractSpring as AbstractSpring
from ._multibody.energies.forces import LinearDamper as LinearDamper
from ._multibody.energies.forces import LinearSpring as LinearSpring
from ._multibody.energies.forces import TorsionalDamper as TorsionalDamper
from ._multibody.energies.forces import TorsionalSpring as TorsionalSpring
from ._multibody.energies.scene import Scene as Scene
from ._multibody.inertia import PrincipalAxes as PrincipalAxes
from ._multibody.inertia import box_inertia as box_inertia
from ._multibody.inertia import check_inertia as check_inertia
from ._multibody.inertia import cylinder_inertia as cylinder_inertia
from ._multibody.inertia import parallel_axis as parallel_axis
from ._multibody.inertia import principal_axes as principal_axes
from ._multibody.inertia import rod_inertia as rod_inertia
from ._multibody.inertia import rotate_inertia as rotate_inertia
from ._multibody.inertia import sphere_inertia as sphere_inertia

__all__ = [
    "Scene",
    "PointMass",
    "PlanarBody",
    "SpatialBody",
    "LinearSpring",
    "TorsionalSpring",
    "LinearDamper",
    "TorsionalDamper",
    "Param",
    "ParamLike",
    "PointFn",
    "AbstractBody",
    "AbstractSpring",
    "AbstractDamper",
    "rod_inertia",
    "box_inertia",
    "cylinder_inertia",
    "sphere_inertia",
    "parallel_axis",
    "rotate_inertia",
    "principal_axes",
    "PrincipalAxes",
    "check_inertia",
]
