r"""MuJoCo's inertia-box fluid model (`opt.density`, `opt.viscosity`, `opt.wind`) as an
applied generalized force: [`mjcf_fluid`][lagrax.chains.mjcf_fluid] and
[`MJCFFluid`][lagrax.chains.MJCFFluid].

MuJoCo (`mj_inertiaBoxFluidModel`) gives each body of mass `m` and principal inertia
`I` the box of the same inertia, `b_k = √(6 (I_1 + I_2 + I_3 − 2 I_k)/m)`, and, with the
body's angular velocity `ω` and its centre of mass's velocity less the wind `v`, both in
its inertia frame, the force and torque at the centre of mass (`ρ` the density, `μ` the
viscosity, `d = (b_1 + b_2 + b_3)/3`):

$$
f_k = −3π d μ\, v_k − \tfrac12 ρ\, b_{k+1} b_{k+2}\, |v_k| v_k, \qquad
t_k = −π d^3 μ\, ω_k − \tfrac{ρ}{64} b_k (b_{k+1}^4 + b_{k+2}^4)\, |ω_k| ω_k,
$$

(indices mod 3): linear (Stokes) viscous drag and quadratic form drag. The generalized
force is `Σ J_pᵀ f + J_ωᵀ t` over the bodies, `J` their velocity Jacobians (MuJoCo's
`qfrc_fluid`).
"""

import warnings
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..._core.errors import MJCFError
from ..algorithms.floating_recursions import quaternion_rotation
from ..common import float_dtype
from ..floating.system import FloatingTree
from .mjcf import from_mjcf, load_model, placements, quat_matrix

_MIN = 1e-15  # mjMINVAL


class MJCFFluid(eqx.Module):
    r"""A MuJoCo model's fluid forces (the inertia-box model) on
    [`lagrax.chains.from_mjcf`][]'s robot: `fluid(q, qd, params)` is the generalized
    force, `fluid.tau(...)` the `tau(t, q, q̇)` for [`lagrax.simulate`][]
    (see [`mjcf_fluid`][lagrax.chains.mjcf_fluid]).

    **Fields:** `robot` (the `Tree` or `FloatingTree`); `body` (static: each fluid
    body's tree body, −1 the floating base); `rotation` `(B, 3, 3)` and `centre`
    `(B, 3)`: each body's inertia frame in its tree body's frame; `box` `(B, 3)`;
    `density`, `viscosity`, `wind` `(3,)`.
    """

    robot: Any
    body: tuple[int, ...] = eqx.field(static=True)
    rotation: jnp.ndarray
    centre: jnp.ndarray
    box: jnp.ndarray
    density: jnp.ndarray
    viscosity: jnp.ndarray
    wind: jnp.ndarray

    def _poses(self, q, params) -> tuple[jnp.ndarray, jnp.ndarray]:
        """Each fluid body's centre of mass `(B, 3)` and inertia frame `(B, 3, 3)` in
        the world."""
        floating = isinstance(self.robot, FloatingTree)
        tree = self.robot.tree if floating else self.robot
        joints = q[7:] if floating else q
        if tree.n_bodies:
            origins, rots = tree.frames(joints, params)
        else:
            origins, rots = jnp.zeros((0, 3), q.dtype), jnp.zeros((0, 3, 3), q.dtype)
        # the floating base (tree body −1) last; without one, the world's frame
        origins = jnp.concatenate([origins, jnp.zeros((1, 3), q.dtype)])
        rots = jnp.concatenate([rots, jnp.eye(3, dtype=q.dtype)[None]])
        idx = jnp.asarray(self.body)
        r_body, o_body = rots[idx], origins[idx]
        centres = o_body + jnp.einsum("bij,bj->bi", r_body, self.centre)
        frames = r_body @ self.rotation
        if floating:
            base = quaternion_rotation(q[3:7])
            centres = q[None, :3] + centres @ base.T
            frames = base[None] @ frames
        return centres, frames

    def _rates(self, q, qd) -> jnp.ndarray:
        """`q̇` from the velocities (a floating base: `N(q) v`)."""
        if not isinstance(self.robot, FloatingTree):
            return qd
        return self.robot.system().configuration_rate(q, qd)

    def _velocities(self, q, qd, params):
        """Each fluid body's centre-of-mass velocity and angular velocity `(B, 3)` in
        the world and its inertia frame `(B, 3, 3)`: linear in `qd`."""
        (_, frames), (vel, frames_dot) = jax.jvp(
            lambda x: self._poses(x, params), (q,), (self._rates(q, qd),)
        )
        w = frames_dot @ jnp.swapaxes(frames, 1, 2)  # ω× in the world
        omega = jnp.stack([w[:, 2, 1], w[:, 0, 2], w[:, 1, 0]], axis=1)
        return vel, omega, frames

    def _local(self, vel, omega, frames):
        """The velocity less the wind and the angular velocity in the inertia frames."""
        local_v = jnp.einsum("bji,bj->bi", frames, vel - self.wind[None])
        return local_v, jnp.einsum("bji,bj->bi", frames, omega)

    def _force(self, q, qd, params) -> jnp.ndarray:
        """`Σ J_pᵀ f + J_ωᵀ t`, by the pullback of the velocities."""
        (vel, omega, frames), pullback = jax.vjp(lambda v: self._velocities(q, v, params), qd)
        local_v, local_w = self._local(vel, omega, frames)
        force, torque = _box_forces(self.box, self.density, self.viscosity, local_v, local_w)
        world_f = jnp.einsum("bij,bj->bi", frames, force)
        world_t = jnp.einsum("bij,bj->bi", frames, torque)
        return pullback((world_f, world_t, jnp.zeros_like(frames)))[0]

    def _local_jacobians(self, q, qd, params):
        """`((R_bᵀ J_p, R_bᵀ J_ω), (local_v, local_w))`: the local velocity Jacobians,
        `(B, 3, n_v)` each (the wind is constant in `q̇`), and the local velocities
        themselves (`_local`'s) from the same pass."""

        def local(v):
            both = self._local(*self._velocities(q, v, params))
            return both, both

        return jax.jacfwd(local, has_aux=True)(qd)

    def _gains(self, local_v, local_w):
        """The diagonal `∂f/∂v` and `∂t/∂ω` of each box `(B, 3)` at its local velocities."""
        box = self.box
        d = jnp.mean(box, axis=1, keepdims=True)
        b1, b2 = jnp.roll(box, -1, axis=1), jnp.roll(box, -2, axis=1)
        gain_v = -3.0 * jnp.pi * d * self.viscosity - self.density * b1 * b2 * jnp.abs(local_v)
        gain_w = -jnp.pi * d**3 * self.viscosity
        gain_w = gain_w - self.density * box * (b1**4 + b2**4) * jnp.abs(local_w) / 32.0
        return gain_v, gain_w

    def __call__(self, q, qd, params) -> jnp.ndarray:
        """The generalized force `Σ J_pᵀ f + J_ωᵀ t` (MuJoCo's `qfrc_fluid`); its
        Jacobians are [`derivatives`][lagrax.chains.MJCFFluid.derivatives]."""
        return self._force(jnp.asarray(q), jnp.asarray(qd), params)

    def derivatives(self, q, qd, params) -> tuple[jnp.ndarray, jnp.ndarray]:
        r"""`(∂τ/∂q, ∂τ/∂q̇)` of the force at a state. `∂τ/∂q̇` analytically: with `J_b`
        each body's local velocity Jacobian (`R_bᵀ J_p` and `R_bᵀ J_ω`, from one
        forward-mode pass) and each box's force a function of its own local velocity,
        component by component,

        $$
        \frac{∂τ}{∂q̇} = \sum_b J_bᵀ\, \mathrm{diag}\Bigl(\frac{∂f}{∂v}, \frac{∂t}{∂ω}\Bigr)\, J_b,
        \qquad \frac{∂f_k}{∂v_k} = −3π d μ − ρ\, b_{k+1} b_{k+2} |v_k|,
        \quad \frac{∂t_k}{∂ω_k} = −π d^3 μ − \tfrac{ρ}{32} b_k (b_{k+1}^4 + b_{k+2}^4) |ω_k|
        $$

        (symmetric; negative semi-definite): about half the cost of `jax.jacfwd`
        through the force, which pulls every column back through the velocity map.
        `∂τ/∂q` (which needs the Jacobians' own derivatives, second-order kinematics) by
        forward mode through the force. Automatic differentiation of `fluid(...)` itself
        (`jax.jacfwd`, `jax.grad`, a closed loop's Jacobian through
        [`lagrax.LagrangianSystem.forward_dynamics`][]) stays plain: as a tangent rule this
        Jacobian costs more than it saves where `q` and `q̇` move together, and for one
        tangent or a gradient.

        **Arguments:** `q`, `qd`, `params` as for the force.

        **Returns:** `(∂τ/∂q, ∂τ/∂q̇)`, `(n_v, n_q)` and `(n_v, n_v)` (`n_q = n_v + 1`
        on a floating base: the derivative in the quaternion's four entries).
        """
        q, qd = jnp.asarray(q), jnp.asarray(qd)
        (jac_v, jac_w), local = self._local_jacobians(q, qd, params)
        gain_v, gain_w = self._gains(*local)
        dqd = jnp.einsum("bik,bi,bil->kl", jac_v, gain_v, jac_v)
        dqd = dqd + jnp.einsum("bik,bi,bil->kl", jac_w, gain_w, jac_w)
        return jax.jacfwd(lambda x: self._force(x, qd, params))(q), dqd

    def tau(self, params):
        """`tau(t, q, q̇)` for [`lagrax.simulate`][]'s `tau=` (add the actuators'
        force to it where there are any)."""
        return lambda t, q, qd: self(q, qd, params)


def _box_forces(box, density, viscosity, v, w):
    """The inertia box's force and torque in its frame (see the module docstring)."""
    d = jnp.mean(box, axis=1, keepdims=True)
    b1, b2 = jnp.roll(box, -1, axis=1), jnp.roll(box, -2, axis=1)
    force = -3.0 * jnp.pi * d * viscosity * v - 0.5 * density * b1 * b2 * jnp.abs(v) * v
    torque = -jnp.pi * d**3 * viscosity * w
    torque = torque - density * box * (b1**4 + b2**4) * jnp.abs(w) * w / 64.0
    return force, torque


def mjcf_fluid(source: Any, *, dtype: Any = None) -> tuple[Any, dict, MJCFFluid]:
    r"""A MuJoCo model with fluid forces: `(robot, params, fluid)`, the robot and params
    [`lagrax.chains.from_mjcf`][] gives for the model without its fluid, and the
    [`MJCFFluid`][lagrax.chains.MJCFFluid] force, MuJoCo's inertia-box model: each
    body's box of equal inertia dragged through a medium of `opt.density` (quadratic
    form drag) and `opt.viscosity` (Stokes drag) moving at `opt.wind` (the module
    docstring has the formulas). Pass `tau=fluid.tau(params)`
    to [`lagrax.simulate`][] (plus the actuators' force where the model has them).

    **Arguments:**

    - `source`: a path to an MJCF file, the XML text, or a compiled `mujoco.MjModel`.
    - `dtype`: of the params and the force's constants (default float64 with x64).

    **Returns:** `(robot, params, fluid)`.

    **Raises:** `MJCFError` for a model with a geom on MuJoCo's ellipsoid fluid model
    (`fluidshape="ellipsoid"`), or for what `from_mjcf` refuses other than the fluid
    (named as `from_mjcf` names it).

    **Example:**

    ```python
    robot, params, fluid = lagrax.chains.mjcf_fluid("swimmer.xml")
    sol = lagrax.simulate(robot.system(), q0, qd0, params, t1=1.0, tau=fluid.tau(params))
    ```

    The drag of a dense fluid on light bodies can make the equations stiff for an
    explicit solver: the fish's first 0.2 s (density 5000) took minutes with the
    default solver on a loaded 2-core machine, compilation included.
    """
    mujoco, model = load_model(source)
    if np.any(np.asarray(model.geom_fluid)[:, 0] > 0):
        raise MJCFError(
            "the model has a geom on MuJoCo's ellipsoid fluid model (fluidshape), which "
            "mjcf_fluid does not read (the inertia-box model only)"
        )
    density, viscosity = float(model.opt.density), float(model.opt.viscosity)
    saved = (density, viscosity)
    model.opt.density, model.opt.viscosity = 0.0, 0.0
    try:
        robot, params = from_mjcf(model, dtype=dtype)
    finally:
        model.opt.density, model.opt.viscosity = saved
    place = placements(model)
    body, rotation, centre, box = [], [], [], []
    for b in range(1, model.nbody):
        mass = float(model.body_mass[b])
        tb, rot, pos = place[b]
        if mass < _MIN or tb == -2 or (tb == -1 and not isinstance(robot, FloatingTree)):
            continue  # massless, or welded to the world: no velocity
        inertia = np.asarray(model.body_inertia[b], float)
        box.append(np.sqrt(np.maximum(_MIN, inertia.sum() - 2 * inertia) / mass * 6.0))
        body.append(int(tb))
        rotation.append(rot @ quat_matrix(model.body_iquat[b]))
        centre.append(pos + rot @ model.body_ipos[b])
    if not (density > 0 or viscosity > 0):
        warnings.warn("the model has no fluid (density and viscosity 0)", UserWarning, stacklevel=2)
    dt = float_dtype(dtype)
    fluid = MJCFFluid(
        robot,
        tuple(body),
        jnp.asarray(np.reshape(rotation, (-1, 3, 3)), dt),
        jnp.asarray(np.reshape(centre, (-1, 3)), dt),
        jnp.asarray(np.reshape(box, (-1, 3)), dt),
        jnp.asarray(density, dt),
        jnp.asarray(viscosity, dt),
        jnp.asarray(np.asarray(model.opt.wind, float), dt),
    )
    return robot, params, fluid
