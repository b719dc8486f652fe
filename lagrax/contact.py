"""Contact: spheres on a system's bodies against a ground plane, as energies.

A [`ContactSystem`][lagrax.contact.ContactSystem] wraps any lagrax system with
[`Sphere`][lagrax.contact.Sphere]s fixed to its bodies and a ground
[`Plane`][lagrax.contact.Plane]: a compliant Hunt–Crossley normal force (its elastic part a
potential energy, its damping a dissipation) and regularized Coulomb friction with stiction.
It is an [`AbstractSystem`][lagrax.AbstractSystem], so `simulate`, `sweep`, events and
`jax.grad` take it as they take the system:

```python
from lagrax.contact import ContactSystem, Plane, Sphere
ball = lx.LagrangianSystem(lambda q, qd, p: 0.5 * p["m"] * qd @ qd,
                           lambda q, p: p["m"] * 9.81 * q[1], n_dof=2)
scene = ContactSystem(ball, Sphere(0.1, lambda q, p: q), Plane([0.0, 1.0]), friction=0.3)
sol = lx.simulate(scene, [0.0, 1.0], [1.0, 0.0], {"m": 1.0}, t1=2.0)
sol.contact_force[:, 0]   # the force on the ball's contact point along the way
```

A [`Capsule`][lagrax.contact.Capsule] is its two end spheres and a
[`Box`][lagrax.contact.Box] its corners (exact against a plane); `pairs=` makes spheres
touch each other (billiards, Newton's cradle), with the same law.
[`body_sphere`][lagrax.contact.body_sphere] fixes a sphere to a tree's body by name (a
robot's foot), from the tree's own kinematics. `limits=` enforces joint limits as
compliant stops of the same law ([`JointLimit`][lagrax.contact.JointLimit]).
"""

from ._contact.geometry import AbstractSphereSource as AbstractSphereSource
from ._contact.geometry import Plane as Plane
from ._contact.geometry import Sphere as Sphere
from ._contact.limits import JointLimit as JointLimit
from ._contact.shapes import Box as Box
from ._contact.shapes import Capsule as Capsule
from ._contact.system import ContactSystem as ContactSystem
from ._multibody.spheres import body_sphere as body_sphere

__all__ = [
    "AbstractSphereSource",
    "Box",
    "Capsule",
    "ContactSystem",
    "JointLimit",
    "Plane",
    "Sphere",
    "body_sphere",
]
