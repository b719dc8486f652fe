r"""A kinematic tree on a floating base: [`FloatingTree`][lagrax.chains.FloatingTree] and its
system, [`FloatingBaseSystem`][lagrax.chains.FloatingBaseSystem].

The base is a free rigid body (a 6-DOF root joint) carrying a [`Tree`][lagrax.chains.Tree] of
joints. Its coordinates are exactly Pinocchio's free-flyer convention
(`pin.JointModelFreeFlyer`), so states move between the two libraries unchanged:

- `q = (x, y, z, q_x, q_y, q_z, q_w, joints…)`, size `7 + n`: the base origin in the world
  frame and the unit quaternion of the base's rotation `R` (world from base), scalar last;
- `v = (v_b, ω_b, joint rates…)`, size `6 + n`: the velocity of the base origin and the
  base's angular velocity, both in the base frame.

The configuration's rate is then not the velocity but `q̇ = N(q) v`:
`ṗ = R v_b`, `q̇_quat = ½ q_quat ⊗ (ω_b, 0)`, joint angles' rates the joint rates
([`configuration_rate`][lagrax.AbstractSystem.configuration_rate]). The equations are
Featherstone's recursions with a free root (`lagrax._multibody.algorithms.floating_recursions`).
"""

from typing import Any

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..._core.blocking import blocked
from ..._core.checks import (
    configuration_size,
    coords,
    eager_only,
    finite,
    finite_params,
    param_shapes,
    physical,
    traced,
)
from ..._core.custom_types import Params
from ..._core.errors import MassMatrixError, NonFiniteError, ShapeError
from ..._core.linalg import cholesky_solve
from .. import joint_space as js
from ..algorithms import floating_recursions as fr
from ..articulated import balls
from ..articulated.trees import Tree
from ..common import broadcast, float_dtype
from ..inertia import check_inertia
from . import derivatives as floating_derivatives
from .derivatives import FloatingDerivatives

BASE_VELOCITY_NAMES = ("base_vx", "base_vy", "base_vz", "base_wx", "base_wy", "base_wz")
BASE_POSE_NAMES = ("base_x", "base_y", "base_z", "base_qx", "base_qy", "base_qz", "base_qw")


class FloatingTree(eqx.Module):
    r"""A [`Tree`][lagrax.chains.Tree] of joints on a free-floating base body: a robot
    that is not bolted to the world (a quadruped, a humanoid, a satellite with an arm).

    The base is body `−1` of the tree (the bodies with parent `−1` hang from it; their
    joint `offset` and `rotations` are in the base frame). Its pose and velocity are
    Pinocchio's free-flyer coordinates (see `lagrax._multibody.floating.system`): `q` of size
    `7 + n` (position, quaternion `(x, y, z, w)`, joints) and `v` of size `6 + n` (base
    linear and angular velocity in the base frame, joint rates).

    **Arguments:**

    - `tree`: the joints, a [`Tree`][lagrax.chains.Tree] whose bodies with parent `−1` hang
      from the base; `Tree("", ())`, with no joints, makes the base a single free rigid
      body (`n = 0`: a quadrotor, a satellite), `q` of size 7 and `v` of size 6.
    - `base_name`: a label for the base body (a URDF's root link).

    **Example:** a satellite with a two-joint arm, in zero gravity:

    ```python
    arm = lagrax.chains.Tree("RR", parents=(-1, 0), axes=[(0, 0, 1), (0, 1, 0)])
    robot = lagrax.chains.FloatingTree(arm)
    params = robot.params(base_m=50.0, base_inertia=np.eye(3), g=0.0,
                          offset=[(0.5, 0, 0), (0, 0, 0.4)], com=(0, 0, 0.2))
    system = robot.system()
    q = jnp.array([0, 0, 0, 0, 0, 0, 1.0, 0.3, -0.5])   # identity quaternion
    system.forward_dynamics(q, jnp.zeros(8), params)
    ```
    """

    tree: Tree
    base_name: str = eqx.field(default="base", static=True)

    @property
    def n(self) -> int:
        """Number of joints below the base (the velocity has `6 + n` entries)."""
        return self.tree.n

    @property
    def joint_names(self) -> tuple[str, ...]:
        """The joints' names (the tree's)."""
        return self.tree.joint_names

    def params(
        self,
        *,
        base_m: Any = 1.0,
        base_com: Any = 0.0,
        base_inertia: Any = None,
        dtype: Any = None,
        **joints: Any,
    ) -> dict[str, jnp.ndarray]:
        """The tree's [`params`][lagrax.chains.Tree.params] (the keyword arguments `m`,
        `offset`, `com`, `inertia`, `damping`, `g`) and the base body's.

        **Arguments:** `base_m` (scalar, positive), `base_com` (`(3,)`, in the base frame),
        `base_inertia` (`(3, 3)` about the base's centre of mass in the base frame; default
        a solid sphere of radius 0.1 m, `0.004 base_m 1`), `dtype`, and the tree's.

        **Returns:** the tree's dict plus `{"base_m": (), "base_com": (3,),
        "base_inertia": (3, 3)}`.

        **Raises:** as [`Tree.params`][lagrax.chains.Tree.params]; `ParameterError` for a base
        mass that is not positive or an inertia that is not physical.
        """
        dtype = float_dtype(dtype)
        out = self.tree.params(dtype=dtype, **joints)
        m = broadcast("base_m", base_m, (), dtype)
        m = physical(m, f"FloatingTree.params base_m (base {self.base_name!r})", positive=True)
        inertia = 0.004 * m * jnp.eye(3, dtype=dtype) if base_inertia is None else base_inertia
        inertia = broadcast("base_inertia", inertia, (3, 3), dtype)
        inertia = check_inertia(
            inertia[None], name="FloatingTree.params base_inertia", semidefinite=True
        )[0]
        out["base_m"] = m
        out["base_com"] = broadcast("base_com", base_com, (3,), dtype)
        out["base_inertia"] = inertia
        return out

    def system(self) -> "FloatingBaseSystem":
        """The robot's [`FloatingBaseSystem`][lagrax.chains.FloatingBaseSystem]."""
        return FloatingBaseSystem(self)


def _aba(system: Any, q: Any, v: Any, params: Params, force: Any) -> jnp.ndarray:
    """`v̇` by the articulated-body algorithm with a free root (`force`: the generalized
    force, damping included; the joint springs' force is taken off here)."""
    if system.robot.tree.balls:  # the lanes' `v̇ − P δ`, with the armature's `A P δ`
        fc = system._at(q, params)
        product = balls.joint_product(system.robot.tree, v)
        springs = js.spring_force(params, fc.theta)
        force = force if springs is None else force.at[6:].add(-springs)
        return fr.aba(fc, v, force - balls.armature_product(params, product)) + product
    springs = js.spring_force(params, q[7:])
    if springs is not None:
        force = force.at[6:].add(-springs)
    return fr.aba(system._at(q, params), v, force)


def _joint_damping(tree: Tree, params: Params, v: Any) -> jnp.ndarray:
    """`∂D/∂v` of `D = ½ Σ b_j θ̇_j²` over the tree's joints (`θ̇ = J v_joints`, mimic
    joints included: `Jᵀ (b θ̇)`; the base is free), with the fixed tendons' damping and
    the joints' friction loss where `params` has them."""
    param_shapes(
        params,
        {"damping": (tree.n_bodies,)},
        f"the joint damping of {tree.n_bodies} joints (mimic ones included)",
        ("damping",),
    )
    b = jnp.asarray(params["damping"], v.dtype)
    theta_d = tree.joint_rates(v[6:])
    rates = b * theta_d
    if params.get("tendon") is not None:  # fixed tendons: ½ Σ b_t (C θ̇)²
        c = jnp.asarray(params["tendon"], v.dtype)
        rates = rates + c.T @ (jnp.asarray(params["tendon_damping"], v.dtype) * (c @ theta_d))
    friction = js.friction_force(params, theta_d)  # friction loss: f μ̂(s) sign(θ̇)
    if friction is not None:
        rates = rates + friction
    if tree.mimic:
        rates = jnp.asarray(tree.coupling_matrix(), v.dtype).T @ rates
    return jnp.concatenate([jnp.zeros(6, v.dtype), rates])


class FloatingBaseSystem(FloatingDerivatives):
    r"""The equations of motion of a [`FloatingTree`][lagrax.chains.FloatingTree]:

    $$
    M(q) v̇ + b(q, v) = τ − ∂D/∂v, \qquad q̇ = N(q) v,
    $$

    with `q` (size `7 + n`) and `v` (size `6 + n`) in Pinocchio's free-flyer convention,
    `M` the `(6 + n) × (6 + n)` mass matrix (Pinocchio's `crba`), `b` the bias
    (`nonLinearEffects`: Coriolis, centrifugal and gravity terms), and `τ = (f_b, n_b,
    τ_joints)`: the force and the torque about the base origin applied to the base, in
    the base frame (zero for a free robot), then the joint torques. `v̇` comes from the
    articulated-body algorithm with a free root (Pinocchio's `aba`), `M` from the
    composite-rigid-body algorithm, `M v̇ + b` from recursive Newton–Euler. Joint damping
    `D = ½ Σ b_j q̇_j²` acts on the joints.

    A tree with mimic joints (see [`Tree`][lagrax.chains.Tree]) has the joint angles
    `θ = J q_joints + b` of all its bodies: the recursions run over all of them and are
    reduced by `J_B = blockdiag(I_6, J)`, `M = J_Bᵀ M_θ J_B`, `b = J_Bᵀ b_θ` (a mimic
    joint's torque, times its multiplier, adds to its master's), and `v̇` comes from a
    Cholesky solve of the reduced equations (the articulated-body algorithm needs
    independent joints).

    The mechanical energy `T + V` (`T = ½ vᵀ M v`, `V = m g up·c` with `c` the centre of
    mass) is conserved by an unforced, undamped motion; in zero gravity so is the spatial
    [`momentum`][lagrax.chains.FloatingBaseSystem.momentum].

    `simulate` integrates `(q, v)` with `q̇ = N(q) v`
    ([`configuration_rate`][lagrax.chains.FloatingBaseSystem.configuration_rate]) and puts
    the quaternion back on the unit sphere after every accepted step
    ([`project_configuration`][lagrax.chains.FloatingBaseSystem.project_configuration]);
    `Solution.constraint_violation` reports `|q_quat| − 1` at the saves (the norm drift:
    the saves are interpolated between projected steps).

    Build it with [`FloatingTree.system`][lagrax.chains.FloatingTree.system]; the dynamics
    work under `jax.jit`, `jax.vmap` and `jax.grad`.
    """

    robot: FloatingTree
    name: str = eqx.field(default="floating-base tree", static=True)

    @property
    def n_dof(self) -> int:
        """The number of velocities, `6 + n`."""
        return 6 + self.robot.n

    @property
    def n_configuration(self) -> int:
        """The size of `q`, `7 + n` (a ball joint: 4 entries, against its 3 velocities)."""
        return 7 + self.robot.tree.n_configuration

    @property
    def final_maxima(self) -> tuple[str, ...]:
        """`constraint_violation`: the quaternion's norm drift `|q_quat| − 1`."""
        return ("constraint_violation",)

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """The velocities' names: the base's six, then the joints' (the coordinates':
        mimic joints are not among them)."""
        return BASE_VELOCITY_NAMES + self.robot.tree.coordinate_names()

    @property
    def configuration_names(self) -> tuple[str, ...]:
        """The configuration's names: the base position and quaternion
        (`base_x, base_y, base_z, base_qx, base_qy, base_qz, base_qw`), then the joints'
        (the coordinates'). `sweep` labels `q`'s `q_dof` axis with them."""
        tree = self.robot.tree
        return BASE_POSE_NAMES + (
            balls.configuration_names(tree) if tree.balls else tree.coordinate_names()
        )

    # ------------------------------------------------------------------ inputs
    def _inputs(self, q: Any, q_name: str = "q", **velocities: Any) -> list[Any]:
        """`q` (size `7 + n`) and the velocity-sized arrays (`qd`, `tau`, …: size
        `6 + n`; `None` kept) as arrays of one dtype; the messages name `q_name` and the
        keys."""
        size = configuration_size(self.n_configuration, self.n_dof)
        q = coords(q, q_name, self.n_configuration, self.name, size=size)
        out = [q]
        for key, value in velocities.items():
            if value is None:
                out.append(None)
                continue
            x = coords(value, key, self.n_dof, self.name)
            out.append(x)
        dtype = jnp.result_type(*(x for x in out if x is not None))
        return [None if x is None else x.astype(dtype) for x in out]

    def _at(self, q: Any, params: Params) -> fr.FloatingChain:
        tree = self.robot.tree
        if tree.balls:  # the lanes at angle zero, the balls' rotations in `A`
            return fr.floating_chain(tree, q, params, lanes=balls.lane_state(tree, q[7:]))
        return fr.floating_chain(tree, q, params)

    # ------------------------------------------------------------------ mimic joints
    def _full(self, v: Any) -> Any:
        """A velocity-sized vector `(base 6, coordinates n)` as every body's:
        `(base 6, J v_joints)` (itself without mimic joints; `None` kept)."""
        if v is None or not self.robot.tree.mimic:
            return v
        return jnp.concatenate([v[:6], self.robot.tree.joint_rates(v[6:])])

    def _reduce(self, f: Any) -> jnp.ndarray:
        """A generalized force of every body reduced to the coordinates: `J_Bᵀ f`."""
        tree = self.robot.tree
        if not tree.mimic:
            return f
        j = jnp.asarray(tree.coupling_matrix(), f.dtype)
        return jnp.concatenate([f[:6], j.T @ f[6:]])

    def _mass(self, fc: fr.FloatingChain) -> tuple[jnp.ndarray, jnp.ndarray]:
        """`(M, I^c_B)` with `M = J_Bᵀ M_θ J_B` (`M_θ` itself without mimic joints)."""
        mass, total = fr.crba(fc)
        mass = js.with_armature(mass, fc.params, offset=6)
        if not self.robot.tree.mimic:
            return mass, total
        j_b = self._coupling(mass.dtype)
        return j_b.T @ mass @ j_b, total

    def _coupling(self, dtype: Any) -> jnp.ndarray:
        """`J_B = diag(1_6, J)`, every body's velocities from the coordinates' (`J` the
        mimic map, `θ̇ = J q̇`)."""
        tree = self.robot.tree
        j = jnp.asarray(tree.coupling_matrix(), dtype)
        return jnp.block(
            [
                [jnp.eye(6, dtype=dtype), jnp.zeros((6, tree.n), dtype)],
                [jnp.zeros((tree.n_bodies, 6), dtype), j],
            ]
        )

    def _rnea(self, fc: fr.FloatingChain, v: Any, vdot: Any) -> jnp.ndarray:
        """`M v̇ + b` (`vdot` `None`: `b`) in the coordinates, armature and joint
        springs included."""
        vdot = self._full(vdot)
        if self.robot.tree.balls:  # the lanes' accelerations `v̇ − P δ`
            lanes = -balls.joint_product(self.robot.tree, v)
            tau = fr.rnea(fc, v, lanes if vdot is None else vdot + lanes)
        else:
            tau = fr.rnea(fc, self._full(v), vdot)
        if fc.theta is not None:
            joints = js.joint_inverse(fc.params, fc.theta, None if vdot is None else vdot[6:])
            tau = tau.at[6:].add(joints)
        return self._reduce(tau)

    # ------------------------------------------------------------------ configuration
    def configuration_rate(self, q: Any, v: Any) -> jnp.ndarray:
        r"""`q̇ = N(q) v`: `ṗ = R v_b` (the base origin's velocity in the world frame),
        `q̇_quat = ½ q_quat ⊗ (ω_b, 0)` (the Hamilton product, scalar last), and the
        joint rates. Sizes: `q` `7 + n`, `v` `6 + n`, the result `7 + n`."""
        rot = fr.quaternion_rotation(q[3:7])
        quat_rate = fr.quaternion_rate(q[3:7], v[3:6])
        if self.robot.tree.balls:  # a ball's quaternion moves as the base's does
            joints = balls.configuration_rate(self.robot.tree, q[7:], v[6:])
            return jnp.concatenate([rot @ v[:3], quat_rate, joints])
        return jnp.concatenate([rot @ v[:3], quat_rate, v[6:]])

    def project_configuration(self, q: Any) -> jnp.ndarray:
        """`q` with its quaternion divided by its norm (back on the unit sphere)."""
        quat = q[3:7]
        if self.robot.tree.balls:  # and every ball joint's
            joints = balls.normalized(self.robot.tree, q[7:])
            return jnp.concatenate([q[:3], quat / jnp.linalg.norm(quat), joints])
        return jnp.concatenate([q[:3], quat / jnp.linalg.norm(quat), q[7:]])

    def initial_state(self, q: Any, qd: Any, params: Params) -> tuple[Any, Any, Any]:
        """The initial state with its quaternion normalized (`ok` false for a zero
        quaternion)."""
        if self.robot.tree.balls:  # and every ball joint's
            ok = jnp.all(balls.quaternion_norms(self.robot.tree, q[7:]) > 0)
            return self.project_configuration(q), qd, ok & (jnp.linalg.norm(q[3:7]) > 0)
        return self.project_configuration(q), qd, jnp.linalg.norm(q[3:7]) > 0

    def observables(self, t: Any, q: Any, qd: Any, params: Params, tau: Any) -> dict[str, Any]:
        """`constraint_violation`: `|q_quat| − 1`, shape `(1,)` (the norm drift)."""
        if self.robot.tree.balls:  # and every ball joint's
            norms = jnp.linalg.norm(q[3:7])[None]
            norms = jnp.concatenate([norms, balls.quaternion_norms(self.robot.tree, q[7:])])
            return {"constraint_violation": norms - 1.0}
        return {"constraint_violation": (jnp.linalg.norm(q[3:7]) - 1.0)[None]}

    # ------------------------------------------------------------------ dynamics
    def mass_matrix(self, q: Any, params: Params, qd: Any = None, *, t: Any = 0.0) -> jnp.ndarray:
        """`M(q)`, shape `(6 + n, 6 + n)`, by the composite-rigid-body algorithm (equal to
        Pinocchio's `crba` on the free-flyer model, both triangles filled)."""
        (q,) = self._inputs(q)
        return self._mass(self._at(q, params))[0]

    def bias(self, q: Any, v: Any, params: Params) -> jnp.ndarray:
        """`b(q, v)`: Coriolis, centrifugal and gravity terms, shape `(6 + n,)`
        (Pinocchio's `nonLinearEffects`), by recursive Newton–Euler."""
        q, v = self._inputs(q, qd=v)
        return self._rnea(self._at(q, params), v, None)

    def inverse_dynamics(
        self, q: Any, qd: Any, qdd: Any, params: Params, t: Any = 0.0
    ) -> jnp.ndarray:
        """`τ = M v̇ + b + ∂D/∂v` (Pinocchio's `rnea` plus joint damping): the first six
        entries are the force and the torque about the base origin on the base, in the
        base frame. **Arguments:** `q` `(7 + n,)`, `qd` = `v` and `qdd` = `v̇`
        `(6 + n,)`, `params`."""
        q, v, vdot = self._inputs(q, qd=qd, qdd=qdd)
        return self._inverse(q, v, vdot, params)

    def _inverse(self, q: Any, v: Any, vdot: Any, params: Params) -> jnp.ndarray:
        """`inverse_dynamics` of checked arrays."""
        return self._rnea(self._at(q, params), v, vdot) + self._damping(params, v)

    def _damping(self, params: Params, v: Any) -> jnp.ndarray:
        """`∂D/∂v`, the joint damping's generalized force (zero on the base)."""
        return _joint_damping(self.robot.tree, params, v)

    def accelerations(self, t: Any, q: Any, qd: Any, params: Params, tau: Any) -> jnp.ndarray:
        """`v̇` of checked arrays by the articulated-body algorithm with a free root
        (a Cholesky solve of the reduced equations for a tree with mimic joints), never
        raising (NaN where an articulated inertia or `M` is not positive)."""
        force = -_joint_damping(self.robot.tree, params, qd)
        if tau is not None:
            force = force + jnp.asarray(tau, qd.dtype)
        if not self.robot.tree.mimic:
            return blocked(_aba)(self, q, qd, params, force)
        fc = self._at(q, params)
        return cholesky_solve(self._mass(fc)[0], force - self._rnea(fc, qd, None))

    def forward_dynamics(
        self, q: Any, qd: Any, params: Params, tau: Any = None, t: Any = 0.0
    ) -> jnp.ndarray:
        """`v̇ = M⁻¹ (τ − b − ∂D/∂v)` (Pinocchio's `aba`), shape `(6 + n,)`.

        **Arguments:** `q` `(7 + n,)`, `qd` = `v` `(6 + n,)`, `params`, `tau`
        `(6 + n,)` (default zero; its first six entries act on the base).

        **Raises:** `ShapeError` for wrong sizes; `NonFiniteError` for NaN/inf inputs
        (the base's position included, which the accelerations do not depend on) and for
        non-finite accelerations (a massless subtree); under `jit` through
        `equinox.error_if`.
        """
        q, v, tau = self._inputs(q, qd=qd, tau=tau)
        if not traced(self, q, v, tau, params):
            # the inputs first: a NaN in the base's position, which the dynamics do not
            # read, would otherwise pass unnoticed
            floating_derivatives.finite_inputs(self, ("q", "qd", "tau"), q, v, tau)
            vdot = self.accelerations(t, q, v, params, tau)
            if not np.all(np.isfinite(np.asarray(vdot))):
                self.check_state(q, v, params)
                raise NonFiniteError(
                    f"forward_dynamics of {self.name} gave non-finite accelerations "
                    f"{np.asarray(vdot)} at q={np.asarray(q)}: check tau and that every "
                    "subtree has a positive mass"
                )
            return vdot
        vdot = self.accelerations(t, q, v, params, tau)
        return eqx.error_if(
            vdot,
            ~(jnp.all(jnp.isfinite(vdot)) & jnp.all(jnp.isfinite(q))),
            f"forward_dynamics of {self.name} produced non-finite accelerations, or its "
            "configuration q is not finite",
        )

    # ------------------------------------------------------------------ energies, momentum
    def center_of_mass(self, q: Any, params: Params) -> jnp.ndarray:
        """The whole robot's centre of mass in the world frame, shape `(3,)`."""
        (q,) = self._inputs(q)
        return _com(fr.crba(self._at(q, params))[1]) + q[:3]

    def momentum(self, q: Any, v: Any, params: Params) -> jnp.ndarray:
        r"""The spatial momentum `h = Σ_i I_i v_i = (L_O, p)` in the world frame: the
        angular momentum about the world origin, then the linear momentum, shape `(6,)`.
        From the mass matrix's base rows: `h = S_B⁻ᵀ (M v)_{1:6}` (`S_B` the base's
        motion subspace in world coordinates). Conserved by a free motion in zero
        gravity; the angular momentum about the centre of mass `c` is `L_O − c × p`
        (Pinocchio's `computeCentroidalMomentum`)."""
        q, v = self._inputs(q, qd=v)
        fc = self._at(q, params)
        mass, _ = self._mass(fc)
        h = fc.force_from_base(mass[:6] @ v)  # about the base origin (world axes)
        return jnp.concatenate([h[:3] + jnp.cross(fc.position, h[3:]), h[3:]])

    def kinetic_energy(self, q: Any, v: Any, params: Params) -> jnp.ndarray:
        """`T = ½ vᵀ M v`."""
        q, v = self._inputs(q, qd=v)
        return 0.5 * v @ (self._mass(self._at(q, params))[0] @ v)

    def potential_energy(self, q: Any, params: Params) -> jnp.ndarray:
        """`V = m g up·c`: gravity on the whole robot's mass `m` at its centre of mass."""
        (q,) = self._inputs(q)
        springs = js.spring_energy(params, self._angles(q))
        return _potential(self.robot, fr.crba(self._at(q, params))[1], params, q[:3]) + springs

    def _angles(self, q: Any) -> jnp.ndarray:
        """Every body's joint angle (a ball's lanes: zero)."""
        tree = self.robot.tree
        return balls.lane_state(tree, q[7:])[0] if tree.balls else tree.joint_angles(q[7:])

    def _energies(self, q: Any, v: Any, params: Params) -> tuple[jnp.ndarray, jnp.ndarray]:
        mass, total = self._mass(self._at(q, params))
        springs = js.spring_energy(params, self._angles(q))
        return 0.5 * v @ (mass @ v), _potential(self.robot, total, params, q[:3]) + springs

    def energy(self, q: Any, qd: Any, params: Params, *, t: Any = 0.0) -> jnp.ndarray:
        """The mechanical energy `T + V`."""
        q, v = self._inputs(q, qd=qd)
        kinetic, potential = self._energies(q, v, params)
        return kinetic + potential

    def jacobi_integral(self, t: Any, q: Any, qd: Any, params: Params) -> jnp.ndarray:
        """`T + V` (`T` is quadratic in `v`)."""
        kinetic, potential = self._energies(q, qd, params)
        return kinetic + potential

    def explicit_power(self, t: Any, q: Any, qd: Any, params: Params) -> None:
        """`None`: the energies do not depend on time."""
        return None

    def input_power(self, t: Any, q: Any, qd: Any, params: Params, tau: Any) -> jnp.ndarray:
        """`v·(τ − ∂D/∂v)`: the power of the inputs and of the joint damping."""
        force = -_joint_damping(self.robot.tree, params, qd)
        if tau is not None:
            force = force + tau
        return qd @ force

    def energy_and_magnitude(
        self, t: Any, q: Any, qd: Any, params: Params
    ) -> tuple[jnp.ndarray, jnp.ndarray]:
        """`(T + V, |T| + |V|)`."""
        kinetic, potential = self._energies(q, qd, params)
        return kinetic + potential, jnp.abs(kinetic) + jnp.abs(potential)

    def components(self, t: Any, q: Any, qd: Any, params: Params) -> dict[str, Any]:
        """The base pose's rotation, the mass matrix and the bias at one state."""
        fc = self._at(q, params)
        return {
            "the base rotation (from the quaternion q[3:7])": fc.rot,
            "the mass matrix M (CRBA)": self._mass(fc)[0],
            "the bias b = C v + G (RNEA)": self._rnea(fc, qd, None),
        }

    def check_state(self, q: Any, qd: Any, params: Params, *, t: Any = 0.0) -> None:
        """Validate a state eagerly: sizes `7 + n` and `6 + n`, finite values, a
        quaternion that is not zero, finite params and a positive-definite `M(q)`.

        **Raises:** `ShapeError`, `NonFiniteError`, `MassMatrixError`;
        `ConfigurationError` for traced values (inside `jax.jit`).
        """
        eager_only(f"check_state of {self.name}", self, q, qd, params, t)
        q, v = self._inputs(q, qd=qd)
        finite(q, "q")
        finite(v, "qd")
        finite_params(params)
        norm = float(jnp.linalg.norm(q[3:7]))
        if not norm > 0:
            raise ShapeError(
                f"the base quaternion q[3:7] = {np.asarray(q[3:7])} is zero: a rotation "
                "needs a unit quaternion (x, y, z, w), e.g. (0, 0, 0, 1)"
            )
        if self.robot.tree.balls:
            balls.check_quaternions(self.robot.tree, q[7:], offset=7)
        mass = np.asarray(self.mass_matrix(q, params))
        eigs = np.linalg.eigvalsh(0.5 * (mass + mass.T))
        if not (np.all(np.isfinite(eigs)) and eigs[0] > 0):
            raise MassMatrixError(
                f"the mass matrix of {self.name} is not positive-definite at q={np.asarray(q)} "
                f"(smallest eigenvalue {eigs[0]:.3g}): check that every body and subtree "
                "has a positive mass"
            )


def _com(total: jnp.ndarray) -> jnp.ndarray:
    """The centre of mass from a spatial inertia at the origin (`m [c]×` in its upper
    right block)."""
    return jnp.stack([total[2, 4], total[0, 5], total[1, 3]]) / total[3, 3]


def _potential(
    robot: FloatingTree, total: jnp.ndarray, params: Params, position: Any
) -> jnp.ndarray:
    """`m g up·c` from the whole robot's spatial inertia about the base origin (`c` is
    its centre of mass relative to it, plus the base `position`)."""
    up = jnp.asarray(robot.tree.up, total.dtype)
    g = jnp.asarray(params["g"], total.dtype)
    return g * total[3, 3] * (up @ (_com(total) + position))
