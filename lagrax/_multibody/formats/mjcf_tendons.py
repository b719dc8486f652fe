"""MuJoCo tendons for [`lagrax.chains.from_mjcf`][]: fixed tendons' springs and dampers
as joint-space params (`lagrax._multibody.joint_space`), and the tendon constructs lagrax
refuses, each named.

A **fixed** tendon (every wrap a joint) has the length `L = Σ c_i qpos_i`, linear in the
joint angles: its stiffness about its spring length and its damping are a potential
`½ k (L − L_0)²` and a Rayleigh dissipation `½ b L̇²` on the coordinates. A **spatial**
tendon (a path through sites, perhaps wrapping around geoms) that has neither stiffness
nor damping carries only a length limit and actuators' paths: its limit is a MuJoCo
constraint, inactive as joint limits are (lagrax does not enforce it), so it is loaded
without a term. One that has either is refused: lagrax does not compute site paths.
"""

from typing import Any

import numpy as np

_JOINT_WRAP = 1  # mujoco.mjtWrap.mjWRAP_JOINT


def _wraps(model, t: int) -> range:
    first = int(model.tendon_adr[t])
    return range(first, first + int(model.tendon_num[t]))


def is_fixed(model, t: int) -> bool:
    """Whether tendon `t` is a fixed tendon (all its wraps are joints)."""
    return all(int(model.wrap_type[w]) == _JOINT_WRAP for w in _wraps(model, t))


def _active(mujoco, model) -> tuple[np.ndarray, np.ndarray]:
    """The tendons' stiffness and damping, zero where MuJoCo's flags disable them."""
    disabled, off = int(model.opt.disableflags), mujoco.mjtDisableBit
    stiffness = np.array(model.tendon_stiffness, float)
    damping = np.array(model.tendon_damping, float)
    if disabled & int(off.mjDSBL_SPRING):
        stiffness[:] = 0.0
    if disabled & int(off.mjDSBL_DAMPER):
        damping[:] = 0.0
    return stiffness, damping


def tendons_unsupported(mujoco, model, names) -> list[str]:
    """What lagrax does not model of `model`'s tendons, each a sentence naming the
    tendon and the value: a spatial tendon with stiffness or damping, a dead-band spring
    length, tendon armature, friction loss, polynomial stiffness or damping, yield."""
    found: list[str] = []
    stiffness, damping = _active(mujoco, model)
    off = mujoco.mjtDisableBit
    friction_off = int(model.opt.disableflags) & int(off.mjDSBL_FRICTIONLOSS)
    for t in range(model.ntendon):
        who = f"tendon {names('tendon', t)!r}"
        if not is_fixed(model, t) and (stiffness[t] or damping[t]):
            found.append(
                f"a spatial {who} (a path through sites) with stiffness {stiffness[t]:g} and "
                f"damping {damping[t]:g}; lagrax models fixed tendons only (a spatial tendon "
                "without either, a limit only, is loaded)"
            )
        low, high = (float(x) for x in model.tendon_lengthspring[t])
        if stiffness[t] and low != high:
            found.append(f"a dead-band spring length [{low:g}, {high:g}] on {who}")
        checks = [
            ("tendon_armature", "armature (inertia added to M along the tendon)"),
            ("tendon_frictionloss", "friction loss (a constraint)"),
            ("tendon_stiffnesspoly", "nonlinear stiffness"),
            ("tendon_dampingpoly", "nonlinear damping"),
            ("tendon_springyield", "spring yield (plasticity)"),
        ]
        for field, what in checks:
            # a field an older MuJoCo lacks is read as None (its construct cannot be there)
            values = getattr(model, field, None)
            if values is None or (field == "tendon_frictionloss" and friction_off):
                continue
            value = np.asarray(values[t], float)
            if np.any(value):
                shown = f"{float(value.flat[0]):g}" if value.size == 1 else str(value.tolist())
                found.append(f"{what} {shown} on {who}")
    return found


def fixed_tendons(mujoco, model, joint_ids: list[int]) -> dict[str, Any]:
    """The fixed tendons with stiffness or damping as joint-space params: `tendon`
    `(n_t, n_bodies)` (each tendon's coefficients on the tree bodies' joint angles,
    `joint_ids` giving each tree body's MuJoCo joint), `tendon_stiffness`,
    `tendon_length` (the spring length, MuJoCo's `tendon_lengthspring`) and
    `tendon_damping`; empty without any."""
    stiffness, damping = _active(mujoco, model)
    body_of = {j: i for i, j in enumerate(joint_ids)}
    rows, kept = [], []
    for t in range(model.ntendon):
        if not is_fixed(model, t) or not (stiffness[t] or damping[t]):
            continue  # no force outside constraints (a limit) and actuators
        row = np.zeros(len(joint_ids))
        for w in _wraps(model, t):
            row[body_of[int(model.wrap_objid[w])]] += float(model.wrap_prm[w])
        rows.append(row)
        kept.append(t)
    if not kept:
        return {}
    return {
        "tendon": np.array(rows),
        "tendon_stiffness": stiffness[kept],
        "tendon_length": np.array([model.tendon_lengthspring[t][0] for t in kept], float),
        "tendon_damping": damping[kept],
    }
