"""Serial chains, kinematic trees and URDF robots.

Planar n-link arms and spatial revolute/prismatic chains; [`Tree`][lagrax.chains.Tree], a kinematic
tree (a parent index per body: a torso with two arms, a hand). A spatial chain is a tree whose
parents are `(−1, 0, 1, …)`: [`SpatialChain`][lagrax.chains.SpatialChain] and `Tree` share
[`AbstractTree`][lagrax.chains.AbstractTree] (kinematics, `frames`, `scene`, `system`);
[`from_urdf`][lagrax.chains.from_urdf], a URDF robot as a tree (fixed joints merged into their
bodies) with its joint names, limits and damping; [`from_mjcf`][lagrax.chains.from_mjcf], a
MuJoCo model through MuJoCo's own compiler (a free joint: a floating base, whose state
[`from_mujoco_state`][lagrax.chains.from_mujoco_state] converts, and its `qacc`
[`from_mujoco_acceleration`][lagrax.chains.from_mujoco_acceleration]; several free bodies: a
[`Forest`][lagrax.chains.Forest]; equality constraints: a
[`ConstrainedRobot`][lagrax.chains.ConstrainedRobot]);
[`from_mujoco`][lagrax.chains.from_mujoco], a MuJoCo model as MuJoCo runs it (ground contact,
enforced limits, actuators, fluid: one call, what it leaves out named in one warning);
[`limit_events`][lagrax.chains.limit_events], the events that stop a robot's joints at their
limits:

```python
tree, params = lx.chains.from_urdf("arm.urdf")        # or root=..., tip=... for a chain
system = tree.system()                                # Featherstone's recursions, O(n)
system.coordinate_names                               # the URDF's joint names
tau_ne = lx.newton_euler.rnea(tree, q, qd, qdd, params)   # the independent oracle
tree, params = lx.chains.from_mjcf("robot.xml")       # q is MuJoCo's qpos
tree, params = lx.chains.from_urdf("arm.urdf", limits="impact", restitution=0.5)
sol = lx.simulate(tree.system(), q0, qd0, params, t1=3.0, events=lx.chains.limit_events(tree))
```

Each chain builder returns `(system, params)` with `params` a dict of arrays (leading axis
`n`: one entry per link), so a sweep can vary masses, lengths, offsets and inertias
with `jax.vmap`. The chain object ([`PlanarChain`][lagrax.chains.PlanarChain],
[`SpatialChain`][lagrax.chains.SpatialChain]) holds the structure and is what
[`lagrax.newton_euler.rnea`][] consumes:

```python
import lagrax as lx

chain = lx.chains.PlanarChain(4)                  # relative angles, gravity along -y
system, params = chain.system(), chain.params(m=[1.0, 1.0, 0.5, 0.5])
tau = system.inverse_dynamics(q, qd, qdd, params)
tau_ne = lx.newton_euler.rnea(chain, q, qd, qdd, params)   # independent oracle
```

The energies come from [`lagrax.bodies`][]: a planar chain is one batched
[`PlanarBody`][lagrax.bodies.PlanarBody] (`bodies="spatial"` builds the same links from
[`SpatialBody`][lagrax.bodies.SpatialBody], for comparison), a spatial chain one batched
[`SpatialBody`][lagrax.bodies.SpatialBody].

**Which to use.** A chain whose joint axes are all parallel moves in a plane: use
[`PlanarChain`][lagrax.chains.PlanarChain] — its forward kinematics is a running sum of angles and
its energy differentiates `n` angles, not `n` rotation matrices. For identical equations it ran
~16× faster than the same 2R arm as a [`SpatialChain`][lagrax.chains.SpatialChain] (vmapped forward
dynamics; ~5× in a short `simulate`) and compiled ~3× faster, and as fast as the hand-written
[`lagrax.models.planar_2r`][] (`benchmarks/bench_planar_vs_spatial.py`, one run on a
shared 2-core CPU). Use [`SpatialChain`][lagrax.chains.SpatialChain] for anything that leaves the
plane; [`PlanarChain.to_spatial`][lagrax.chains.PlanarChain.to_spatial] converts for comparison.
"""

from ._multibody.articulated.ball_system import BallTreeSystem as BallTreeSystem
from ._multibody.articulated.chains import BodyKind as BodyKind
from ._multibody.articulated.chains import PlanarChain as PlanarChain
from ._multibody.articulated.chains import SpatialChain as SpatialChain
from ._multibody.articulated.chains import axis_angle_rotation as axis_angle_rotation
from ._multibody.articulated.chains import planar_chain as planar_chain
from ._multibody.articulated.chains import spatial_chain as spatial_chain
from ._multibody.articulated.trees import AbstractTree as AbstractTree
from ._multibody.articulated.trees import Tree as Tree
from ._multibody.floating.forest import Forest as Forest
from ._multibody.floating.forest import ForestSystem as ForestSystem
from ._multibody.floating.system import FloatingBaseSystem as FloatingBaseSystem
from ._multibody.floating.system import FloatingTree as FloatingTree
from ._multibody.formats.mjcf import from_mjcf as from_mjcf
from ._multibody.formats.mjcf_actuators import MJCFActuation as MJCFActuation
from ._multibody.formats.mjcf_actuators import mjcf_actuation as mjcf_actuation
from ._multibody.formats.mjcf_equality import ConstrainedRobot as ConstrainedRobot
from ._multibody.formats.mjcf_fluid import MJCFFluid as MJCFFluid
from ._multibody.formats.mjcf_fluid import mjcf_fluid as mjcf_fluid
from ._multibody.formats.mujoco_model import from_mujoco as from_mujoco
from ._multibody.formats.mujoco_state import (
    from_mujoco_acceleration as from_mujoco_acceleration,
)
from ._multibody.formats.mujoco_state import from_mujoco_state as from_mujoco_state
from ._multibody.formats.mujoco_state import to_mujoco_acceleration as to_mujoco_acceleration
from ._multibody.formats.mujoco_state import to_mujoco_state as to_mujoco_state
from ._multibody.formats.urdf import from_urdf as from_urdf
from ._multibody.limits import limit_events as limit_events

__all__ = [
    "PlanarChain",
    "SpatialChain",
    "planar_chain",
    "spatial_chain",
    "AbstractTree",
    "Tree",
    "BallTreeSystem",
    "FloatingTree",
    "FloatingBaseSystem",
    "Forest",
    "ForestSystem",
    "ConstrainedRobot",
    "from_urdf",
    "from_mjcf",
    "mjcf_actuation",
    "MJCFActuation",
    "mjcf_fluid",
    "MJCFFluid",
    "from_mujoco",
    "from_mujoco_state",
    "to_mujoco_state",
    "from_mujoco_acceleration",
    "to_mujoco_acceleration",
    "limit_events",
    "axis_angle_rotation",
    "BodyKind",
]
