"""Robots written for lagrax as URDF files (`lagrax/models/urdf`, installed with the
package): a 7-DOF arm and a torso with two 3-link arms. Their masses and inertias are
those of solid aluminium cylinders and boxes (`tools/make_urdf_models.py` writes them
and says how)."""

from pathlib import Path

from .._core.errors import ConfigurationError
from .._systems.lagrangian import LagrangianSystem

_DIR = Path(__file__).resolve().parent / "urdf"
_NAMES = ("arm7", "torso_two_arms")


def urdf_path(name: str) -> Path:
    """The path of one of lagrax's URDF models: `"arm7"` or `"torso_two_arms"`.

    **Example:** `tree, params = lagrax.chains.from_urdf(lagrax.models.urdf_path("arm7"))`

    **Raises:** `ValueError` for another name.
    """
    if name not in _NAMES:
        raise ConfigurationError(f"no URDF model {name!r}; lagrax has {_NAMES}")
    return _DIR / f"{name}.urdf"


def _load(name: str) -> tuple[LagrangianSystem, dict]:
    from .._multibody.formats.urdf import from_urdf

    tree, params = from_urdf(urdf_path(name))
    return tree.system(), params


def arm7() -> tuple[LagrangianSystem, dict]:
    """A 7-DOF arm (`arm7.urdf`): seven revolute joints alternating about z and y, links
    of solid aluminium cylinders (6.1 kg at the shoulder to 0.5 kg at the flange), a 1.3 kg
    gripper on a fixed joint (merged into link 7), joint damping 0.05–0.5 N m s/rad.
    Gravity along −z. For the tree (joint names, limits, the Newton–Euler oracle) use
    `lagrax.chains.from_urdf(urdf_path("arm7"))`.

    **Returns:** `(system, params)`.
    """
    return _load("arm7")


def torso_two_arms() -> tuple[LagrangianSystem, dict]:
    """A small kinematic tree (`torso_two_arms.urdf`): a prismatic lift, a torso yaw
    joint, a head on a fixed joint, and two arms of three revolute joints each (shoulder
    pitch, shoulder roll, elbow; the right elbow is continuous): 8 coordinates.

    **Returns:** `(system, params)`.
    """
    return _load("torso_two_arms")
