r"""MuJoCo's actuators as a map from its `ctrl` vector to the generalized force `τ`:
[`mjcf_actuation`][lagrax.chains.mjcf_actuation] and
[`MJCFActuation`][lagrax.chains.MJCFActuation].

MuJoCo's actuator `i` (`mj_fwdActuation`, without activation dynamics) has the length
`l_i = g_i · L` of its transmission (a hinge or slide joint: its `qpos`; a fixed tendon:
`Σ c_j qpos_j`) scaled by the `gear` `g_i`, the velocity `l̇_i`, and the force

$$
u_i = \mathrm{clamp}(\mathrm{ctrl}_i,\ \mathrm{ctrlrange}_i), \quad
f_i = \mathrm{clamp}\big((a_0 + a_1 l_i + a_2 l̇_i)\, u_i + b_0 + b_1 l_i + b_2 l̇_i,\
\mathrm{forcerange}_i\big),
$$

(`gainprm` `a`, `biasprm` `b`: a motor is `a = (gear-free gain, 0, 0)`, `b = 0`; a
position servo `a_0 = k_p`, `b_1 = −k_p`; a velocity servo `a_0 = k_v`, `b_2 = −k_v`),
and the generalized force `τ = clamp(Σ_i f_i ∂l_i/∂q, actfrcrange)` (MuJoCo's
`qfrc_actuator`, each joint clamped to its `actuatorfrcrange`).
"""

import math
from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._core.errors import MJCFError
from ..common import float_dtype
from .mjcf import load_model
from .mjcf_tendons import is_fixed

# mujoco.mjtTrn: joint, jointinparent, slider-crank, tendon, site, body
_TRN_JOINT, _TRN_JOINT_IN_PARENT, _TRN_TENDON = 0, 1, 3
_JOINT_WRAP = 1
_HINGE_OR_SLIDE = (2, 3)  # mujoco.mjtJoint: slide, hinge
_GAIN = {0: "fixed", 1: "affine"}  # mujoco.mjtGain
_BIAS = {0: "none", 1: "affine"}  # mujoco.mjtBias


class MJCFActuation(eqx.Module):
    r"""A MuJoCo model's actuators: `τ(ctrl, q, q̇)`, MuJoCo's `qfrc_actuator` for the
    control `ctrl` (see the module [`mjcf_actuation`][lagrax.chains.mjcf_actuation]).

    `q` and `q̇` are those of [`lagrax.chains.from_mjcf`][]'s system (MuJoCo's `qpos`,
    `qvel` for a fixed base; a floating base's `(q, v)` in Pinocchio's convention, whose
    joint entries are MuJoCo's), so `τ` is the `tau` that system takes.

    **Fields:** `moment` `(n_u, n_v)`: `∂l/∂q̇` (gear times the transmission's
    coefficients); `index` `(n_v,)`: the entry of `q` each column's coordinate is;
    `gain`, `bias` `(n_u, 3)`: MuJoCo's `gainprm[:3]`, `biasprm[:3]`; `ctrlrange`,
    `forcerange` `(n_u, 2)` and `joint_range` `(n_v, 2)` (`±inf` where not limited);
    `names`: the actuators' names.
    """

    moment: jnp.ndarray
    index: jnp.ndarray
    gain: jnp.ndarray
    bias: jnp.ndarray
    ctrlrange: jnp.ndarray
    forcerange: jnp.ndarray
    joint_range: jnp.ndarray
    names: tuple[str, ...] = eqx.field(static=True)

    @property
    def n_u(self) -> int:
        """The number of actuators (the size of `ctrl`)."""
        return len(self.names)

    def force(self, ctrl: Any, q: Any, qd: Any) -> jnp.ndarray:
        """The actuators' forces `f` `(n_u,)` (MuJoCo's `actuator_force`), clamped."""
        ctrl = jnp.asarray(ctrl, self.moment.dtype)
        u = jnp.clip(ctrl, self.ctrlrange[:, 0], self.ctrlrange[:, 1])
        length = self.moment @ jnp.asarray(q, self.moment.dtype)[self.index]
        rate = self.moment @ jnp.asarray(qd, self.moment.dtype)
        gain = self.gain[:, 0] + self.gain[:, 1] * length + self.gain[:, 2] * rate
        bias = self.bias[:, 0] + self.bias[:, 1] * length + self.bias[:, 2] * rate
        return jnp.clip(gain * u + bias, self.forcerange[:, 0], self.forcerange[:, 1])

    def __call__(self, ctrl: Any, q: Any, qd: Any) -> jnp.ndarray:
        """`τ = clamp(Mᵀ f, joint_range)` `(n_v,)`: MuJoCo's `qfrc_actuator`."""
        tau = self.moment.T @ self.force(ctrl, q, qd)
        return jnp.clip(tau, self.joint_range[:, 0], self.joint_range[:, 1])

    def tau(self, ctrl: Any):
        """`tau(t, q, q̇)` for [`lagrax.simulate`][]'s `tau=`: the actuators' force
        for a constant `ctrl` `(n_u,)`, or for `ctrl(t)` a function of time (an RL
        policy's control sequence, held or interpolated as the function does)."""
        if callable(ctrl):
            return lambda t, q, qd: self(ctrl(t), q, qd)
        ctrl = jnp.asarray(ctrl, self.moment.dtype)
        return lambda t, q, qd: self(ctrl, q, qd)


def _ranges(limited, values, n: int) -> np.ndarray:
    out = np.tile([-math.inf, math.inf], (n, 1))
    for i in range(n):
        if limited[i]:
            out[i] = values[i]
    return out


def _transmission(model, i: int, name: str, row: np.ndarray) -> None:
    """Fill `row` (actuator `i`'s `∂l/∂q̇` over the dofs), or `MJCFError` naming what
    lagrax does not read."""
    kind, target = int(model.actuator_trntype[i]), int(model.actuator_trnid[i, 0])
    gear = float(model.actuator_gear[i, 0])
    if kind in (_TRN_JOINT, _TRN_JOINT_IN_PARENT):
        if int(model.jnt_type[target]) not in _HINGE_OR_SLIDE:
            raise MJCFError(
                f"actuator {name!r} drives a free or ball joint, which mjcf_actuation does "
                "not read (hinge and slide joints and fixed tendons only)"
            )
        row[int(model.jnt_dofadr[target])] += gear
        return
    if kind == _TRN_TENDON and is_fixed(model, target):
        first = int(model.tendon_adr[target])
        for w in range(first, first + int(model.tendon_num[target])):
            dof = int(model.jnt_dofadr[int(model.wrap_objid[w])])
            row[dof] += gear * float(model.wrap_prm[w])
        return
    what = "a spatial tendon" if kind == _TRN_TENDON else f"transmission type {kind}"
    raise MJCFError(
        f"actuator {name!r} acts through {what}, which mjcf_actuation does not read "
        "(hinge and slide joints and fixed tendons only)"
    )


def mjcf_actuation(source: Any, *, dtype: Any = None) -> MJCFActuation:
    r"""A MuJoCo model's actuators as an [`MJCFActuation`][lagrax.chains.MJCFActuation]:
    the map from MuJoCo's control vector `ctrl` to the generalized force `τ(t, q, q̇)`
    that [`lagrax.chains.from_mjcf`][]'s system takes as `tau`, so that a `ctrl`
    sequence (an RL policy's) drives lagrax as it drives MuJoCo.

    For actuator `i` with transmission length `l_i` (gear times a hinge or slide joint's
    `qpos`, or a fixed tendon's length) MuJoCo's force is
    `f_i = clamp(gain_i u_i + bias_i, forcerange)` with `u = clamp(ctrl, ctrlrange)`,
    `gain = a_0 + a_1 l + a_2 l̇` (`gainprm`; fixed gain: `a_0`) and
    `bias = b_0 + b_1 l + b_2 l̇` (`biasprm`): a `motor` (`gear`), a `position` servo
    (`kp`: `f = k_p (u − l)`), a `velocity` servo (`kv`: `f = k_v (u − l̇)`), and any
    `general` actuator of those gain and bias types. `τ = Σ f_i ∂l_i/∂q̇`, each joint's
    clamped to its `actuatorfrcrange`: MuJoCo's `qfrc_actuator`. Ranges apply where
    MuJoCo's `ctrllimited`, `forcelimited` and `actfrclimited` say (and control clamping
    is off where `opt.disableflags` disables it); a model whose actuation is disabled
    gives `τ = 0`.

    **Arguments:**

    - `source`: a path to an MJCF file, the XML text, or a compiled `mujoco.MjModel`
      (as for `from_mjcf`).
    - `dtype`: of the arrays (default float64 with x64).

    **Returns:** the [`MJCFActuation`][lagrax.chains.MJCFActuation]: call it as
    `actuation(ctrl, q, qd)`, or pass `tau=actuation.tau(ctrl)` (`ctrl` an array or a
    function of time) to [`lagrax.simulate`][].

    **Raises:** `MJCFError` for an actuator with activation dynamics (`dyntype`:
    integrator, filter, muscle: a state lagrax does not carry), a muscle or user gain
    or bias, or a transmission other than a hinge or slide joint or a fixed tendon
    (naming the actuator); as `from_mjcf` for a file MuJoCo cannot compile.

    **Example:**

    ```python
    tree, params = lagrax.chains.from_mjcf("cartpole.xml")
    actuation = lagrax.chains.mjcf_actuation("cartpole.xml")
    sol = lagrax.simulate(tree.system(), q0, qd0, params, t1=2.0, tau=actuation.tau(ctrl))
    ```
    """
    return actuation(*load_model(source), dtype=dtype)


def actuation(mujoco, model, *, dtype: Any = None, instant: bool = False) -> MJCFActuation:
    """`mjcf_actuation` of a compiled `model`; `instant=True` reads an actuator with
    activation dynamics as if its activation followed `ctrl` at once (`from_mujoco`,
    which names each such actuator in its warning)."""
    nu, nv = int(model.nu), int(model.nv)
    moment = np.zeros((nu, nv))
    names = []
    for i in range(nu):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) or f"actuator{i}"
        names.append(name)
        if int(model.actuator_dyntype[i]) != 0 and not instant:
            raise MJCFError(
                f"actuator {name!r} has activation dynamics (dyntype "
                f"{int(model.actuator_dyntype[i])}), a state mjcf_actuation does not carry"
            )
        for what, kinds, value in (
            ("gain", _GAIN, int(model.actuator_gaintype[i])),
            ("bias", _BIAS, int(model.actuator_biastype[i])),
        ):
            if value not in kinds:
                raise MJCFError(
                    f"actuator {name!r} has {what} type {value} (muscle or user), which "
                    "mjcf_actuation does not read (fixed or affine only)"
                )
        _transmission(model, i, name, moment[i])
    off = mujoco.mjtDisableBit
    disabled = int(model.opt.disableflags)
    if disabled & int(off.mjDSBL_ACTUATION):
        moment[:] = 0.0
    clamp = not disabled & int(off.mjDSBL_CLAMPCTRL)
    index = np.zeros(nv, int)
    for j in range(model.njnt):
        if int(model.jnt_type[j]) in _HINGE_OR_SLIDE:
            index[int(model.jnt_dofadr[j])] = int(model.jnt_qposadr[j])
    joint_range = np.tile([-math.inf, math.inf], (nv, 1))
    for j in range(model.njnt):
        if bool(model.jnt_actfrclimited[j]) and int(model.jnt_type[j]) in _HINGE_OR_SLIDE:
            joint_range[int(model.jnt_dofadr[j])] = model.jnt_actfrcrange[j]
    dtype = float_dtype(dtype)
    ctrl_limited = np.asarray(model.actuator_ctrllimited) & clamp
    return MJCFActuation(
        jnp.asarray(moment, dtype),
        jnp.asarray(index),
        jnp.asarray(np.array(model.actuator_gainprm[:, :3]), dtype),
        jnp.asarray(np.array(model.actuator_biasprm[:, :3]), dtype),
        jnp.asarray(_ranges(ctrl_limited, model.actuator_ctrlrange, nu), dtype),
        jnp.asarray(_ranges(model.actuator_forcelimited, model.actuator_forcerange, nu), dtype),
        jnp.asarray(joint_range, dtype),
        tuple(names),
    )
