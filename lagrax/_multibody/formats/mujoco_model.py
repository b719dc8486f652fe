r"""A MuJoCo model with everything on that lagrax simulates:
[`from_mujoco`][lagrax.chains.from_mujoco], the door a MuJoCo user walks through.

`from_mjcf` stays the building block; this module turns on, in one call, what MuJoCo's
`mj_step` simulates and lagrax has: the ground contact (`contact=True`), the joint
limits enforced as compliant stops (`limits="contact"`), the actuators driven by the
scene's input, MuJoCo's `ctrl` (`mjcf_actuation`), and the fluid forces (`mjcf_fluid`), and names in
one warning what it leaves out.
"""

import warnings
from typing import Any

import jax
import numpy as np

from ..._contact.system import ContactSystem
from ..._core.errors import ConfigurationError, MJCFError
from .mjcf import Names, from_mjcf, load_model
from .mjcf_actuators import actuation
from .mjcf_fluid import mjcf_fluid
from .mjcf_support import unsupported

_HFIELD, _MESH = 1, 7  # mujoco.mjtGeom


def _colliding(model) -> np.ndarray:
    """The geoms MuJoCo lets collide (`contype` or `conaffinity` nonzero)."""
    return (np.asarray(model.geom_contype) != 0) | (np.asarray(model.geom_conaffinity) != 0)


def _body_contacts(mujoco, model, names) -> list[str]:
    """The pairs of moving bodies whose geoms MuJoCo lets collide (by `contype` and
    `conaffinity`, not parent and child unless that filter is off, not excluded), and
    the explicit `<pair>`s: lagrax's ground contact does not model them."""
    found = []
    collide = _colliding(model)
    filter_parent = not int(model.opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)
    excluded = {
        frozenset((int(x) >> 16, int(x) & 0xFFFF)) for x in np.asarray(model.exclude_signature)
    }
    geoms = [g for g in range(model.ngeom) if collide[g] and int(model.geom_bodyid[g]) != 0]
    for i, a in enumerate(geoms):
        for b in geoms[i + 1 :]:
            ba, bb = int(model.geom_bodyid[a]), int(model.geom_bodyid[b])
            if ba == bb or frozenset((ba, bb)) in excluded:
                continue
            if (
                filter_parent
                and bb in (ba, int(model.body_parentid[ba]))
                or (filter_parent and ba == int(model.body_parentid[bb]))
            ):
                continue
            ta, ca = int(model.geom_contype[a]), int(model.geom_conaffinity[a])
            tb, cb = int(model.geom_contype[b]), int(model.geom_conaffinity[b])
            if ta & cb or tb & ca:
                found.append(
                    f"contact between bodies (the first: {names('body', ba)!r} and "
                    f"{names('body', bb)!r}; lagrax's contact is with the ground only)"
                )
                break
        if found:
            break
    if model.npair:
        found.append(f"{int(model.npair)} explicit contact pair(s) (<contact><pair>)")
    return found


def _not_simulated(mujoco, model, names) -> list[str]:
    """What MuJoCo simulates in `model` and `from_mujoco`'s scene does not, each a
    sentence naming it (beside `mjcf_support.unsupported`'s, fluid aside)."""
    found = []
    collide = _colliding(model)
    kinds = np.asarray(model.geom_type)
    hfields = [g for g in range(model.ngeom) if kinds[g] == _HFIELD and collide[g]]
    if hfields:
        found.append(f"a height field (geom {names('geom', hfields[0])!r}; the ground is a plane)")
    meshes = [g for g in range(model.ngeom) if kinds[g] == _MESH and collide[g]]
    if meshes:
        found.append(
            f"mesh collision (geom {names('geom', meshes[0])!r} and {len(meshes) - 1} more: "
            "each mesh touches the ground as its bounding sphere)"
        )
    condim = np.asarray(model.geom_condim)
    friction = np.asarray(model.geom_friction)
    for k, (dim, what) in enumerate(((4, "torsional"), (6, "rolling"))):
        rows = [g for g in range(model.ngeom) if collide[g] and condim[g] >= dim]
        rows = [g for g in rows if friction[g, k + 1] > 0]
        if rows:
            found.append(
                f"MuJoCo's {what} friction (geom {names('geom', rows[0])!r}, condim "
                f"{int(condim[rows[0]])}, coefficient {friction[rows[0], k + 1]:g})"
            )
    gaps = [g for g in range(model.ngeom) if collide[g] and model.geom_gap[g] > 0]
    if gaps:
        found.append(
            f"a contact gap (geom {names('geom', gaps[0])!r}, gap {model.geom_gap[gaps[0]]:g}: "
            "lagrax's contact acts from the margin)"
        )
    found += _body_contacts(mujoco, model, names)
    for i in range(model.nu):
        if int(model.actuator_dyntype[i]) != 0:
            found.append(
                f"the activation dynamics of actuator {names('actuator', i)!r} (dyntype "
                f"{int(model.actuator_dyntype[i])}, time constant "
                f"{float(model.actuator_dynprm[i, 0]):g} s): its activation follows ctrl at "
                "once"
            )
    return found


def from_mujoco(source: Any, *, dtype: Any = None) -> tuple[Any, dict]:
    r"""A MuJoCo model as MuJoCo runs it, in one call: the robot on its ground with its
    joint limits enforced, its actuators and its fluid, as one
    [`ContactSystem`][lagrax.contact.ContactSystem].

    It turns on what lagrax simulates of what `mj_step` does:

    - **ground contact** from every geom MuJoCo lets collide (`contype`/`conaffinity`)
      on a moving body, against the model's floor plane, each geom's friction, each
      sphere grown by MuJoCo's contact margin (`from_mjcf(..., contact=True,
      margin=True)`);
    - **joint limits, enforced** as compliant stops of the same normal law
      (`limits="contact"`: their stored energy and dissipation in the energy balance);
    - **actuators**, the scene's input: the `tau=` of `simulate`, `sweep` and
      `forward_dynamics` is MuJoCo's `ctrl`, `(n_u,)` (`scene.n_input`; a constant, or
      a function `ctrl(t, q, v)`), and with no `tau=`, `ctrl = 0` (the servos' bias
      acts, as in `mj_step`). Each control is clamped to its `ctrlrange` where MuJoCo's
      `ctrllimited` says (unless the model disables clamping), as MuJoCo clamps it, and
      each force to its `forcerange` ([`mjcf_actuation`][lagrax.chains.mjcf_actuation],
      the scene's `actuation`);
    - **fluid forces** where the model has `density` or `viscosity`
      ([`mjcf_fluid`][lagrax.chains.mjcf_fluid]), applied the same way;
    - and what `from_mjcf` reads of the model's joints (damping, armature, springs,
      friction loss, fixed tendons).

    Whatever MuJoCo simulates and this scene does not (a height field, mesh geoms
    touching as bounding spheres, torsional or rolling friction, contact between bodies,
    actuators' activation dynamics, which are taken as following `ctrl` at once, what
    `from_mjcf` refuses, and combinations it refuses, such as equality constraints
    beside contact, which are then dropped) is named in **one** `UserWarning` at load
    and listed in `scene.unsupported`; nothing is dropped silently.

    A state from MuJoCo: [`from_mujoco_state`][lagrax.chains.from_mujoco_state]`(qpos,
    qvel, scene.system)`; `simulate` then takes the linearly implicit `"rodas4"` by default
    (the scene's `default_method`: contact and limits are stiff).

    **Arguments:**

    - `source`: a path to an MJCF file, the XML text (a string starting with `<`) or a
      compiled `mujoco.MjModel`.
    - `dtype`: of the params (default float64 with x64).

    **Returns:** `(scene, params)`: the `ContactSystem` (`scene.system` the robot's
    system, `scene.limits` the enforced limits, `scene.actuation` the actuators,
    `scene.unsupported` what is left out) and the params of `from_mjcf` plus
    `"contact_friction"`.

    **Raises:** [`lagrax.MJCFError`][] (a [`lagrax.LagraxError`][]) when MuJoCo
    cannot compile the model, with MuJoCo's message; when the model cannot be put on
    the ground at all (several free bodies, ball joints beside contact, no collision
    geometry on a moving body, no weight on the ground to scale the contact by), naming
    why; as `from_mjcf` for a model with no joint. A `ctrl` (`tau=`) of the wrong length
    is a [`lagrax.ShapeError`][] naming `tau`, its length and the number of actuators.

    **Example:**

    ```python
    scene, params = lagrax.chains.from_mujoco("ant.xml")
    q0, v0 = lagrax.chains.from_mujoco_state(data.qpos, data.qvel, scene.system)
    sol = lagrax.simulate(scene, q0, v0, params, t1=1.0)  # ctrl = 0
    sol = lagrax.simulate(scene, q0, v0, params, t1=1.0, tau=ctrl)  # MuJoCo's ctrl
    ```
    """
    mujoco, model = load_model(source)
    names = Names(mujoco, model)
    notes = _not_simulated(mujoco, model, names)
    fluid = None
    saved = (float(model.opt.density), float(model.opt.viscosity), int(model.opt.disableflags))
    if saved[0] > 0 or saved[1] > 0:
        try:
            fluid = mjcf_fluid(model, dtype=dtype)[2]
        except MJCFError as err:
            notes.append(f"fluid forces ({err})")
    try:
        model.opt.density, model.opt.viscosity = 0.0, 0.0
        notes += unsupported(mujoco, model, names)
        if model.neq and not saved[2] & int(mujoco.mjtDisableBit.mjDSBL_EQUALITY):
            notes.append(f"{int(model.neq)} equality constraint(s) (not taken beside contact yet)")
            model.opt.disableflags = saved[2] | int(mujoco.mjtDisableBit.mjDSBL_EQUALITY)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # named in this call's warning
            scene, params = from_mjcf(
                model,
                contact=True,
                limits="contact",
                ignore_unsupported=True,
                dtype=dtype,
                margin=True,
            )
    except (MJCFError, ConfigurationError) as err:
        raise MJCFError(f"from_mujoco cannot put this model on the ground: {err}") from None
    finally:
        model.opt.density, model.opt.viscosity = saved[:2]
        model.opt.disableflags = saved[2]
    # one compiled program, not the scaling's few hundred small eager ones (12 s for the ant)
    co = jax.jit(scene.coefficients)(params)
    if not bool(co.ok):
        raise MJCFError(
            "from_mujoco cannot scale the contact's defaults: the model bears no weight on its "
            "ground at qpos0 (a robot fixed to the world, or no gravity); load it with "
            "from_mjcf(..., contact=True, limits='contact') and pass the contact's "
            "coefficients"
        )
    try:
        drive = actuation(mujoco, model, dtype=dtype, instant=True) if model.nu else None
    except MJCFError as err:
        notes.append(f"the actuators ({err})")
        drive = None
    force = None if fluid is None else _fluid_force(fluid)
    if notes:
        warnings.warn(
            "from_mujoco: lagrax does not simulate, in this model: " + "; ".join(notes),
            UserWarning,
            stacklevel=2,
        )
    scene = ContactSystem(
        scene.system,
        scene.spheres,
        scene.plane,
        friction=scene.friction,
        limits=scene.limits,
        force=force,
        actuation=drive,
        unsupported=notes,
        name=scene.name,
    )
    return scene, params


def _fluid_force(fluid):
    """The fluid's applied force `F(t, q, v, params)`."""

    def force(t, q, v, params):
        return fluid(q, v, params)

    return force
