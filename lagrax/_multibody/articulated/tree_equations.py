"""Chains' and trees' structure-aware equations: what the recursions need of a chain
or a tree (`AbstractArticulated`), their kinematics as a `recursions.Chain`, and
`ChainEquations`, which their `LagrangianSystem` evaluates instead of differentiating
its energies (see `lagrax._multibody.algorithms.recursions`)."""

import abc
from typing import Any, Protocol

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..._core.blocking import BLOCK
from ..._core.checks import param_shapes
from ..._core.custom_types import Params
from ..._core.errors import ShapeError
from ..._core.linalg import cholesky_solve
from ..._systems.derivatives import AbstractEquations
from .. import joint_space as js
from ..algorithms import recursions as a
from ..algorithms.derivative_recursions import rnea_derivatives
from ..algorithms.links import UNROLL_MAX_SPATIAL, joint_trig, spatial_link
from ..joints import revolute_flags


class TreeStructure(Protocol):
    """What the equations read of a spatial chain or tree (an
    [`AbstractTree`][lagrax.chains.AbstractTree], which is defined above this module):
    its structure, all static, and the parameter check."""

    n: int
    joint_types: str
    parents: tuple[int, ...]
    axes: tuple[tuple[float, float, float], ...]
    up: tuple[float, float, float]

    @property
    def n_bodies(self) -> int: ...

    def joint_constants(self) -> Any: ...

    def coupling_matrix(self) -> np.ndarray: ...

    def joint_angles(self, q) -> Any: ...

    def joint_rates(self, qd) -> Any: ...

    def _check_params(self, params: Params) -> None: ...


class AbstractArticulated(eqx.Module):
    """Bodies joined by one-coordinate joints, as the recursions see them: a planar chain
    ([`PlanarChain`][lagrax.chains.PlanarChain]) or a spatial tree
    ([`AbstractTree`][lagrax.chains.AbstractTree]: a spatial chain or a
    [`Tree`][lagrax.chains.Tree]). Structure only (static fields); the numbers are in
    `params`."""

    n: eqx.AbstractVar[int]  # the number of joints (and bodies)

    @property
    def n_bodies(self) -> int:
        """The number of bodies: one per joint (a tree with mimic joints has more
        bodies than coordinates, and says so)."""
        return self.n

    parents: eqx.AbstractVar[tuple[int, ...]]  # each body's parent (−1: the base)

    @abc.abstractmethod
    def articulated(self, q, params: Params, scan: bool | None = None) -> a.Chain:
        """The motion subspaces and body inertias at `q`, for the recursions
        (`scan=None`: unrolled for short chains, a `lax.scan` for long ones)."""

    @abc.abstractmethod
    def link_energies(self, q, qd, params: Params) -> tuple[jnp.ndarray, jnp.ndarray] | None:
        """`(T, V)` by a pass over the bodies, or `None` where the pose maps are the
        cheaper route."""

    @abc.abstractmethod
    def _param_shapes(self) -> dict[str, tuple[int, ...]]:
        """The shapes of the `params` entries its kinematics reads (as `params()`
        returns them)."""

    def _check_params(self, params: Params) -> None:
        """`ShapeError` for an entry of `params` of the wrong shape (at trace time)."""
        param_shapes(params, self._param_shapes(), f"the {type(self).__name__} of {self.n} joints")


def _check(n: int, q) -> None:
    if q.shape != (n,):
        raise ShapeError(f"q has shape {q.shape}, expected ({n},) for this chain")


# Chains up to these lengths are written out link by link (straight-line code that skips
# structural zeros: fastest to run); longer ones loop over the links with ``lax.scan``,
# whose compile time does not grow with n.
UNROLL_MAX_PLANAR = 3


def _planar_link(carry, x):
    phi, px, py = carry
    q, m, length, r, inertia = x
    phi = a.add(phi, q)
    c, sn = jnp.cos(phi), jnp.sin(phi)
    s = (1.0, py, -px)
    com = (a.add(px, r * c), a.add(py, r * sn))
    inertia = a.planar_inertia(m, inertia, com)
    return (phi, a.add(px, length * c), a.add(py, length * sn)), (s, inertia)


def planar_chain(n: int, q, params: Params, scan: bool | None = None) -> a.Chain:
    """A planar chain (joint `i` at `p_i`, link angle `φ_i = q_1 + … + q_i`): motion
    subspaces `S_i = (1, p_iy, −p_ix)` and link inertias at the origin."""
    _check(n, q)
    scan = n > UNROLL_MAX_PLANAR if scan is None else scan
    passes = a.Passes(n, scan, q.dtype)
    per_link = (q, *(jnp.asarray(params[k], q.dtype) for k in ("m", "l", "r", "I")))
    _, ys = passes.run(_planar_link, (0.0, 0.0, 0.0), passes.links(per_link))
    s, inertia = passes.split(ys)
    g = jnp.asarray(params["g"], q.dtype)
    return a.Chain(passes, a.PLANAR, s, inertia, (0.0, 0.0, g))


def _energy_link(carry, x):
    # In link frames: the angular velocity w, the velocity v of the link origin and the
    # `up` direction, each carried from the parent through the joint rotation J (`Jᵀ`),
    # and the origin's height h. No world rotation is formed.
    w, v, up, h = carry
    q, qd, big_a, big_b, big_c, slide, axis, rev, offset, com, inertia, m, lift = x
    step = offset + slide * q  # parent origin -> this origin, in the parent's axes
    v = v + jnp.cross(w, step) + slide * qd
    h = h + up @ step
    joint_t = (big_a + jnp.sin(q) * big_b + (1 - jnp.cos(q)) * big_c).T
    w = joint_t @ w + axis * (rev * qd)
    v, up = joint_t @ v, joint_t @ up
    v_com = v + jnp.cross(w, com)
    kinetic = 0.5 * (m * (v_com @ v_com) + w @ (inertia @ w))
    return (w, v, up, h), (kinetic, m * lift * (h + up @ com))


def spatial_energies(
    chain: TreeStructure, q, qd, params: Params, big_a=None
) -> tuple[jnp.ndarray, jnp.ndarray]:
    """`(T, V)` of a spatial chain or tree by one outward pass in link frames:
    `ω_i = J_iᵀ ω_p + a_i q̇_i`, the origin's velocity `v_i = J_iᵀ (v_p + ω_p × d_i +
    s_i q̇_i)` (`d_i` the step from the parent's origin, `p` the parent), `T_i = ½ m_i
    |v_i + ω_i × c_i|² + ½ ω_iᵀ Ī_i ω_i` and `V_i = m_i g (h_i + up_i·c_i)`, with the height
    `h_i` of the origin and `up` carried into link axes.

    About a quarter of the work of the pose maps' JVP (no world rotations, no derivative).
    Written as a `lax.scan` of small array operations, not in scalars like the
    recursions: `simulate` evaluates it under `vmap` over the saved states inside its
    one-kernel program, where scalar code for every link would cost about a second of
    compilation for a 7-link arm. `big_a`: the constants `A` in place of the
    tree's (a tree with ball joints: `balls.lane_state`).
    """
    n, dtype = chain.n_bodies, q.dtype
    _check(n, q)
    chain._check_params(params)
    constant_a, big_b, big_c, slide = (jnp.asarray(x, dtype) for x in chain.joint_constants())
    big_a = constant_a if big_a is None else big_a
    axes = jnp.asarray(np.asarray(chain.axes, float), dtype)
    rev = jnp.asarray(revolute_flags(chain.joint_types), dtype)
    values = [jnp.asarray(params[k], dtype) for k in ("offset", "com", "inertia", "m")]
    lift = jnp.broadcast_to(jnp.asarray(params["g"], dtype), (n,))
    xs = (q, qd.astype(dtype), big_a, big_b, big_c, slide, axes, rev, *values, lift)
    zero = jnp.zeros(3, dtype)
    init = (zero, zero, jnp.asarray(chain.up, dtype), jnp.zeros((), dtype))
    parents = a.Passes(n, True, dtype, chain.parents).parents
    if parents is None:  # a chain (a tree whose parents form one is one too)
        _, (kinetic, potential) = jax.lax.scan(_energy_link, init, xs)
    else:  # a tree: every body's carry in a buffer (slot n: the base), read by parent
        slot = jnp.asarray([p if p >= 0 else n for p in parents])
        buffers = jax.tree_util.tree_map(lambda v: jnp.broadcast_to(v, (n + 1, *v.shape)), init)

        def body(bufs, x):
            i, p, xi = x
            carry, y = _energy_link(jax.tree_util.tree_map(lambda b: b[p], bufs), xi)
            return jax.tree_util.tree_map(lambda b, c: b.at[i].set(c), bufs, carry), y

        _, (kinetic, potential) = jax.lax.scan(body, buffers, (jnp.arange(n), slot, xs))
    return jnp.sum(kinetic), jnp.sum(potential)


def spatial_chain(
    chain: TreeStructure, q, params: Params, scan: bool | None = None, big_a=None
) -> a.Chain:
    """A spatial chain or tree (a [`Tree`][lagrax.chains.Tree]: body `i` hangs from
    body `parents[i]`, and every pass runs over parents): world joint axes
    `z_i = R_i axis_i` through the joint origins `o_i`, `S_i = (z_i, o_i × z_i)`
    (revolute) or `(0, z_i)` (prismatic), and link inertias at the origin,
    `R_i Ī_i R_iᵀ` about the centre of mass `o_i + R_i com_i`. `big_a`: the joint
    constants `A` in place of the tree's (a tree with ball joints, whose rotations
    come from their quaternions: `balls.lane_state`)."""
    n = chain.n_bodies
    _check(n, q)
    chain._check_params(params)
    scan = n > UNROLL_MAX_SPATIAL if scan is None else scan
    passes = a.Passes(n, scan, q.dtype, chain.parents)
    constant_a, big_b, big_c, slide = chain.joint_constants()
    big_a = constant_a if big_a is None else big_a
    axes = np.asarray(chain.axes, float)
    rev = revolute_flags(chain.joint_types)
    values = (jnp.asarray(params[k], q.dtype) for k in ("offset", "com", "inertia", "m"))
    per_link = (joint_trig(q), big_a, big_b, big_c, slide, axes, rev, *values)
    eye = tuple(tuple(1.0 if i == j else 0.0 for j in range(3)) for i in range(3))
    _, ys = passes.run(spatial_link, (eye, (0.0, 0.0, 0.0)), passes.links(per_link))
    s, inertia = passes.split(ys)
    g = jnp.asarray(params["g"], q.dtype)
    a0 = (0.0, 0.0, 0.0) + tuple(a.mul(g, u) for u in chain.up)
    rotor = js.armature(params, q.dtype)
    rotor = None if rotor is None else passes.links(rotor)
    return a.Chain(passes, a.SPATIAL, s, inertia, a0, rotor)


class ChainEquations(AbstractEquations):
    """The equations of a chain's or a tree's `LagrangianSystem` from Featherstone's recursions:
    `q̈` by the articulated-body algorithm (O(n)), `M` by the composite-rigid-body
    algorithm, `M q̈ + C q̇ + G` by recursive Newton–Euler. They equal the autodiff
    Lagrangian of the chain's energies to round-off (tested against it and against
    [`lagrax.newton_euler.rnea`][])."""

    chain: AbstractArticulated  # structure only (static fields)

    scan: bool | None = eqx.field(default=None, static=True)

    def at(self, q, params: Params) -> a.Chain:
        """The chain's motion subspaces and inertias at `q` (and its armature)."""
        js.check(params, self.chain.n_bodies)
        return self.chain.articulated(q, params, self.scan)

    def blocks(self) -> tuple[int | None, int | None]:
        """Blocks of `BLOCK` states for the articulated-body algorithm and for the
        derivatives, planar chains' included: over 4,096 states, `PlanarChain(20)`'s
        derivatives call 22 → 16 µs a state and its `jacfwd` 38 → 30 µs in blocks,
        `PlanarChain(7)`'s 2.4–4.0 → 2.2–2.3 µs (the whole batch at once ran at either
        speed from run to run)."""
        return BLOCK, BLOCK

    def accelerations(self, q, qd, params: Params, force) -> jnp.ndarray:
        """`q̈` solving `M q̈ + C q̇ + G = force` (`force` `None` means zero); NaN
        where the chain's articulated inertias are not positive."""
        return _accelerations_of(self.at(q, params), q, qd, _less_springs(force, q, params))

    def energies(self, q, qd, params: Params) -> tuple[jnp.ndarray, jnp.ndarray] | None:
        """`(T, V)` of a spatial chain or tree by one outward pass in link frames
        (`spatial_energies`: about half the cost of the pose maps' JVP per saved state
        in `simulate`), or `None` for a planar chain, whose vectorized pose maps are
        already the cheaper route (0.2 against 0.8 µs a state at n = 7 for a recursion)."""
        out = self.chain.link_energies(q, qd, params)
        if out is None:
            return None
        kinetic, potential = out
        rotor = js.armature(params, q.dtype)
        if rotor is not None:
            kinetic = kinetic + 0.5 * jnp.sum(rotor * qd.astype(q.dtype) ** 2)
        return kinetic, potential + js.spring_energy(params, q)

    def mass_matrix(self, q, params: Params) -> jnp.ndarray:
        return js.with_armature(a.crba(self.at(q, params)), params)

    def mass_and_bias(self, q, qd, params: Params) -> tuple[jnp.ndarray, jnp.ndarray]:
        """`M` and the bias `C q̇ + G` from one evaluation of the kinematics."""
        chain = self.at(q, params)
        bias = a.rnea(chain, chain.passes.links(qd.astype(q.dtype)), None)
        bias = chain.passes.vector(bias, q) + js.joint_inverse(params, q, None)
        return js.with_armature(a.crba(chain), params), bias

    def inverse_dynamics(self, q, qd, qdd, params: Params) -> jnp.ndarray:
        """`M q̈ + C q̇ + G` (`qdd=None`: the bias `C q̇ + G`), armature and springs
        included."""
        chain = self.at(q, params)
        links = chain.passes.links
        qdd = None if qdd is None else qdd.astype(q.dtype)
        tau = a.rnea(chain, links(qd.astype(q.dtype)), None if qdd is None else links(qdd))
        return chain.passes.vector(tau, q) + js.joint_inverse(params, q, qdd)

    def derivatives(self, q, qd, qdd, params: Params) -> tuple[jnp.ndarray, ...]:
        """`(∂τ/∂q, ∂τ/∂q̇, M)` of `τ = M q̈ + C q̇ + G` at `(q, q̇, q̈)`, analytically in
        `O(n²)` (see `lagrax._multibody.algorithms.derivative_recursions`)."""
        return _derivatives_of(self.at(q, params), q, qd, qdd, params)

    def accelerations_and_derivatives(self, q, qd, params: Params, force):
        """`(q̈, ∂τ/∂q, ∂τ/∂q̇, M)` from one evaluation of the kinematics."""
        chain = self.at(q, params)
        qdd = _accelerations_of(chain, q, qd, _less_springs(force, q, params))
        return (qdd, *_derivatives_of(chain, q, qd, qdd, params))


def _accelerations_of(chain: a.Chain, q, qd, force) -> jnp.ndarray:
    """`ChainEquations.accelerations` of the chain at `q`: the articulated-body algorithm."""
    links = chain.passes.links
    f = None if force is None else links(jnp.asarray(force, q.dtype))
    return chain.passes.vector(a.aba(chain, links(qd.astype(q.dtype)), f), q)


def _less_springs(force, q, params: Params):
    """The generalized force less the joint springs' `∂V_s/∂θ` (`force` `None`: zero)."""
    springs = js.spring_force(params, q)
    if springs is None:
        return force
    return -springs if force is None else jnp.asarray(force, q.dtype) - springs


def _derivatives_of(chain: a.Chain, q, qd, qdd, params: Params) -> tuple[jnp.ndarray, ...]:
    """`ChainEquations.derivatives` of the chain at `q`: the RNEA derivatives, with the
    armature on `M`'s diagonal and the springs' stiffness `K_s` in `∂τ/∂q`."""
    links = chain.passes.links
    _, dq, dqd, mass = rnea_derivatives(
        chain, links(qd.astype(q.dtype)), links(qdd.astype(q.dtype))
    )
    stiffness = js.stiffness_matrix(params, q.shape[0], q.dtype)
    dq = dq if stiffness is None else dq + stiffness
    return dq, dqd, js.with_armature(mass, params)


class CoupledEquations(AbstractEquations):
    """The equations of a tree with mimic joints (see [`Tree`][lagrax.chains.Tree]): the
    recursions of all its bodies at the joint angles `θ = J q + b`, `θ̇ = J q̇`,
    `θ̈ = J q̈` (`J` constant), reduced to the coordinates by the virtual work of the
    mimic map: `M = Jᵀ M_θ J`, `τ = Jᵀ τ_θ` (a mimic joint's torque, times its
    multiplier, adds to its master's), `∂τ/∂q = Jᵀ (∂τ_θ/∂θ) J` and likewise in
    `q̇`. `q̈` by a Cholesky solve of the reduced `M` (NaN where it is not positive),
    since the articulated-body algorithm needs independent joints."""

    chain: TreeStructure  # structure only (static fields)

    scan: bool | None = eqx.field(default=None, static=True)

    def _full(self) -> ChainEquations:
        return ChainEquations(self.chain, self.scan)

    def blocks(self) -> tuple[int | None, int | None]:
        """As the full tree's (see `ChainEquations.blocks`)."""
        return self._full().blocks()

    def _j(self, dtype) -> jnp.ndarray:
        return jnp.asarray(self.chain.coupling_matrix(), dtype)

    def _reduce(self, tau_theta, dtype) -> jnp.ndarray:
        return self._j(dtype).T @ tau_theta

    def _congruent(self, mat, dtype) -> jnp.ndarray:
        j = self._j(dtype)
        return j.T @ mat @ j

    def _angles(self, q, qd):
        return self.chain.joint_angles(q), self.chain.joint_rates(qd.astype(q.dtype))

    def mass_matrix(self, q, params: Params) -> jnp.ndarray:
        _check(self.chain.n, q)
        mass = self._full().mass_matrix(self.chain.joint_angles(q), params)
        return self._congruent(mass, q.dtype)

    def mass_and_bias(self, q, qd, params: Params) -> tuple[jnp.ndarray, jnp.ndarray]:
        _check(self.chain.n, q)
        mass, bias = self._full().mass_and_bias(*self._angles(q, qd), params)
        return self._congruent(mass, q.dtype), self._reduce(bias, q.dtype)

    def accelerations(self, q, qd, params: Params, force) -> jnp.ndarray:
        """`q̈` solving `M q̈ + C q̇ + G = force` by Cholesky (NaN where `M` is not
        positive-definite)."""
        mass, bias = self.mass_and_bias(q, qd, params)
        rhs = -bias if force is None else jnp.asarray(force, q.dtype) - bias
        return cholesky_solve(mass, rhs)

    def energies(self, q, qd, params: Params) -> tuple[jnp.ndarray, jnp.ndarray] | None:
        _check(self.chain.n, q)
        return self._full().energies(*self._angles(q, qd), params)

    def inverse_dynamics(self, q, qd, qdd, params: Params) -> jnp.ndarray:
        _check(self.chain.n, q)
        theta, theta_d = self._angles(q, qd)
        theta_dd = None if qdd is None else self.chain.joint_rates(qdd.astype(q.dtype))
        tau = self._full().inverse_dynamics(theta, theta_d, theta_dd, params)
        return self._reduce(tau, q.dtype)

    def derivatives(self, q, qd, qdd, params: Params) -> tuple[jnp.ndarray, ...]:
        _check(self.chain.n, q)
        theta, theta_d = self._angles(q, qd)
        theta_dd = self.chain.joint_rates(qdd.astype(q.dtype))
        dq, dqd, mass = self._full().derivatives(theta, theta_d, theta_dd, params)
        return tuple(self._congruent(x, q.dtype) for x in (dq, dqd, mass))
