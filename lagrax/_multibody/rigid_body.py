"""A rigid body rotating about its centre of mass: Euler's equations on unit quaternions,
and the attitude maps (Euler angles, quaternions, rotation matrices) they need."""

from collections.abc import Callable

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float, Int

from .._core.checks import is_traced
from .._core.custom_types import Matrix3, Quaternion, Vector3
from .._core.errors import (
    ConfigurationError,
    MassMatrixError,
    NonFiniteError,
    ShapeError,
    SimulationError,
)
from .._core.results import RESULTS
from .._solve.methods import resolve_solver

TorqueFn = Callable[[Array, Quaternion, Vector3], Vector3]


# ------------------------------------------------------------------ attitude maps
def hat(w: Float[ArrayLike, "3"]) -> Matrix3:
    """The skew-symmetric matrix `[w]×` with `[w]× v = w × v`."""
    w = jnp.asarray(w)
    zero = jnp.zeros_like(w[0])
    return jnp.stack(
        [
            jnp.stack([zero, -w[2], w[1]]),
            jnp.stack([w[2], zero, -w[0]]),
            jnp.stack([-w[1], w[0], zero]),
        ]
    )


def vee(s: Float[ArrayLike, "3 3"]) -> Vector3:
    """Inverse of [`hat`][lagrax.rigid_body.hat]: the vector of the skew part of `s`."""
    s = jnp.asarray(s)
    return 0.5 * jnp.stack([s[2, 1] - s[1, 2], s[0, 2] - s[2, 0], s[1, 0] - s[0, 1]])


def quaternion_product(p: Float[ArrayLike, "4"], q: Float[ArrayLike, "4"]) -> Quaternion:
    """Hamilton product `p ⊗ q` of quaternions `(w, x, y, z)` (scalar first)."""
    p, q = jnp.asarray(p), jnp.asarray(q)
    pw, pv, qw, qv = p[0], p[1:], q[0], q[1:]
    return jnp.concatenate(
        [jnp.stack([pw * qw - jnp.dot(pv, qv)]), pw * qv + qw * pv + jnp.cross(pv, qv)]
    )


def quaternion_to_matrix(quat: Float[ArrayLike, "4"]) -> Matrix3:
    """Rotation matrix `R` (body → space: `x_space = R x_body`) of the quaternion
    `(w, x, y, z)`, normalized first (so a slightly drifted norm still gives an exactly
    orthogonal `R`): `R = I + 2w[v]× + 2[v]×²` for the unit quaternion `(w, v)`."""
    quat = jnp.asarray(quat)
    quat = quat / jnp.sqrt(jnp.sum(quat**2))
    v = hat(quat[1:])
    return jnp.eye(3, dtype=quat.dtype) + 2.0 * quat[0] * v + 2.0 * v @ v


def _axis_rotation(angle, axis: int):
    c, s = jnp.cos(angle), jnp.sin(angle)
    one, zero = jnp.ones_like(c), jnp.zeros_like(c)
    if axis == 0:
        rows = [[one, zero, zero], [zero, c, -s], [zero, s, c]]
    elif axis == 1:
        rows = [[c, zero, s], [zero, one, zero], [-s, zero, c]]
    else:
        rows = [[c, -s, zero], [s, c, zero], [zero, zero, one]]
    return jnp.stack([jnp.stack(r) for r in rows])


def euler_angles_to_matrix(angles: Float[ArrayLike, "3"]) -> Matrix3:
    """`R = R_z(ψ) R_y(θ) R_x(φ)` for ZYX (yaw–pitch–roll, intrinsic) Euler angles
    `angles = (ψ, θ, φ)`: rotate about the body z axis by ψ, then about the new y axis by
    θ, then about the newest x axis by φ. Body → space. Gimbal lock at `θ = ±π/2`."""
    a = jnp.asarray(angles)
    return _axis_rotation(a[0], 2) @ _axis_rotation(a[1], 1) @ _axis_rotation(a[2], 0)


def euler_angles_to_quaternion(angles: Float[ArrayLike, "3"]) -> Quaternion:
    """The unit quaternion of [`euler_angles_to_matrix`][lagrax.rigid_body.euler_angles_to_matrix]:
    `q_z(ψ) ⊗ q_y(θ) ⊗ q_x(φ)` with `q_axis(a) = (cos a/2, sin a/2 · axis)`."""
    a = jnp.asarray(angles)

    def about(angle, axis):
        vec = [jnp.zeros_like(angle)] * 3
        vec[axis] = jnp.sin(0.5 * angle)
        return jnp.stack([jnp.cos(0.5 * angle), *vec])

    return quaternion_product(quaternion_product(about(a[0], 2), about(a[1], 1)), about(a[2], 0))


def body_angular_velocity(angles: Float[ArrayLike, "3"], rates: Float[ArrayLike, "3"]) -> Vector3:
    """Body-frame angular velocity `ω` (`[ω]× = Rᵀ Ṙ`) of ZYX Euler angles `(ψ, θ, φ)`
    and their rates: each rate turns the body about its own axis, carried to the body
    frame by the rotations that follow it,

        ω = ψ̇ (R_y(θ) R_x(φ))ᵀ e_z + θ̇ R_x(φ)ᵀ e_y + φ̇ e_x = E(θ, φ) (ψ̇, θ̇, φ̇),

    linear in the rates with `det E = −cos θ` (singular at gimbal lock `θ = ±π/2`).
    """
    a = jnp.asarray(angles)
    r = jnp.asarray(rates)
    rx, ry = _axis_rotation(a[2], 0), _axis_rotation(a[1], 1)
    zero = jnp.zeros_like(r[2])
    return r[0] * (ry @ rx)[2] + r[1] * rx[1] + jnp.stack([r[2], zero, zero])


def euler_angle_rates(angles: Float[ArrayLike, "3"], omega: Float[ArrayLike, "3"]) -> Vector3:
    """Euler-angle rates that produce the body angular velocity `omega`: the solution of
    `E(angles) rates = ω` (inverse of
    [`body_angular_velocity`][lagrax.rigid_body.body_angular_velocity]). Not finite at gimbal
    lock (`θ = ±π/2`), where `E` is singular."""
    angles = jnp.asarray(angles)
    omega = jnp.asarray(omega, angles.dtype)
    e = jax.jacfwd(lambda r: body_angular_velocity(angles, r))(jnp.zeros_like(angles))
    return jnp.linalg.solve(e, omega)


# ------------------------------------------------------------------ Euler's equations
def _inertia_matrix(inertia) -> Matrix3:
    inertia = jnp.asarray(inertia)
    if not jnp.issubdtype(inertia.dtype, jnp.floating):
        inertia = inertia.astype(jnp.result_type(float))
    if inertia.shape == (3,):
        return jnp.diag(inertia)
    if inertia.shape == (3, 3):
        return inertia
    raise ShapeError(
        f"inertia must be the 3 principal moments, shape (3,), or a 3x3 body-frame inertia "
        f"matrix; got shape {inertia.shape}"
    )


def euler_equations(
    omega: Float[ArrayLike, "3"],
    inertia: Float[ArrayLike, "3"] | Float[ArrayLike, "3 3"],
    torque: Float[ArrayLike, "3"] | None = None,
) -> Vector3:
    r"""Euler's equations of a rigid body about its centre of mass, in the body frame:

    $$
    I ω̇ + ω × (I ω) = M   ⇒   ω̇ = I⁻¹ (M − ω × I ω)
    $$

    **Arguments:**

    - `omega`: body-frame angular velocity, shape `(3,)`.
    - `inertia`: principal moments `(I1, I2, I3)` (body axes = principal axes) or the
      3×3 inertia matrix about the centre of mass in the body frame.
    - `torque`: body-frame moment `M` about the centre of mass (default zero).

    **Returns:** `ω̇`, shape `(3,)`.
    """
    omega = jnp.asarray(omega)
    principal = jnp.shape(inertia) == (3,)
    inertia = _inertia_matrix(inertia)
    rhs = -jnp.cross(omega, inertia @ omega)
    if torque is not None:
        rhs = rhs + jnp.asarray(torque)
    if principal:
        return rhs / jnp.diagonal(inertia)
    return jnp.linalg.solve(inertia, rhs)


class RigidBodySolution(eqx.Module):
    """A rigid-body rotation at the saved times.

    **Fields:**

    - `ts`: saved times `(T,)`.
    - `quat`: attitude quaternions `(w, x, y, z)` (body → space), shape `(T, 4)`.
    - `omega`: body-frame angular velocity, shape `(T, 3)`.
    - `energy`: rotational kinetic energy `½ ωᵀ I ω`, shape `(T,)`.
    - `angular_momentum`: space-frame angular momentum `R I ω`, shape `(T, 3)`
      (constant without torque).
    - `result`, `stats`: the result code (`lagrax.RESULTS`) and counters (`ok`
      tells success).

    Properties: `rotation` (`(T, 3, 3)`), `body_angular_momentum` (`I ω`, whose
    magnitude is conserved without torque), `ok`.
    """

    ts: Float[Array, " T"]
    quat: Float[Array, "T 4"]
    omega: Float[Array, "T 3"]
    energy: Float[Array, " T"]
    angular_momentum: Float[Array, "T 3"]
    inertia: Float[Array, "3 3"]
    result: RESULTS
    stats: dict[str, Int[Array, ""]]

    @property
    def ok(self) -> Array:
        return self.result == RESULTS.successful

    @property
    def rotation(self) -> Float[Array, "T 3 3"]:
        return jax.vmap(quaternion_to_matrix)(self.quat)

    @property
    def body_angular_momentum(self) -> Float[Array, "T 3"]:
        return self.omega @ self.inertia.T


def _field(t, y, args):
    quat, omega = y
    inertia, torque_fn, torque_const = args
    torque = torque_const
    if torque_fn is not None:
        torque = jnp.asarray(torque_fn(t, quat, omega), omega.dtype)
        if torque_const is not None:
            torque = torque + torque_const
    zero = jnp.zeros_like(omega[:1])
    quat_dot = 0.5 * quaternion_product(quat, jnp.concatenate([zero, omega]))
    return quat_dot, euler_equations(omega, inertia, torque)


@eqx.filter_jit
def _solve_euler(
    solver, y0, moments, torque_fn, torque_const, t0, t1, ts, rtol, atol, max_steps: int
):
    inertia = _inertia_matrix(moments)
    sol = dfx.diffeqsolve(
        dfx.ODETerm(_field),
        solver,
        t0,
        t1,
        None,
        y0,
        args=(moments, torque_fn, torque_const),
        saveat=dfx.SaveAt(ts=ts),
        stepsize_controller=dfx.PIDController(rtol=rtol, atol=atol),
        max_steps=max_steps,
        throw=False,
    )
    quat, omega = sol.ys
    energy = 0.5 * jnp.einsum("ti,ij,tj->t", omega, inertia, omega)
    rot = jax.vmap(quaternion_to_matrix)(quat)
    momentum = jnp.einsum("tij,jk,tk->ti", rot, inertia, omega)
    return RigidBodySolution(
        sol.ts, quat, omega, energy, momentum, inertia, RESULTS.promote(sol.result), dict(sol.stats)
    )


def simulate_euler(
    inertia: Float[ArrayLike, "3"] | Float[ArrayLike, "3 3"],
    omega0: Float[ArrayLike, "3"],
    *,
    t1: float,
    quat0: Float[ArrayLike, "4"] | None = None,
    t0: float = 0.0,
    ts: Float[ArrayLike, " T"] | None = None,
    n_save: int = 501,
    torque: Float[ArrayLike, "3"] | TorqueFn | None = None,
    solver: str | dfx.AbstractSolver | None = None,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    max_steps: int = 100_000,
    throw: bool = True,
) -> RigidBodySolution:
    r"""Rotation of a rigid body about its centre of mass by Euler's equations, with the
    attitude as a unit quaternion (no singular configuration, unlike Euler angles).

    The state `(q, ω)` (attitude quaternion body → space, body angular velocity) obeys

    $$
    q̇ = ½ q ⊗ (0, ω),    I ω̇ = M − ω × I ω,
    $$

    integrated with diffrax (default Tsit5, adaptive). The quaternion's norm is preserved
    by the exact flow and drifts only by the integration error; rotations are formed from
    the normalized quaternion. Without torque, the kinetic energy `½ ωᵀ I ω`, the
    magnitude `|I ω|` and the space-frame angular momentum `R I ω` are conserved
    (reported along the solution to check the integration).

    **Arguments:**

    - `inertia`: principal moments `(I1, I2, I3)` or the 3×3 body-frame inertia about
      the centre of mass (symmetric positive-definite).
    - `omega0`: initial body angular velocity `(3,)`.
    - `t1`, `t0`: time interval; `ts` the save times (default `n_save` evenly
      spaced).
    - `quat0`: initial attitude `(w, x, y, z)` (default identity); normalized.
    - `torque`: body-frame moment about the centre of mass: a constant `(3,)` or a
      function `torque(t, quat, omega) -> (3,)`. Default none (free body).
    - `solver`, `rtol`, `atol`, `max_steps`: as for `lagrax.simulate` (adaptive
      methods only).
    - `throw`: raise `SimulationError` on failure (default) or report it in `result`.

    **Returns:** a [`RigidBodySolution`][lagrax.rigid_body.RigidBodySolution].

    **Raises:** `ShapeError`, `NonFiniteError` for bad inputs, `MassMatrixError`
    for an inertia that is not symmetric positive-definite, `SimulationError` when the
    solve fails.

    **Example:** the intermediate-axis (tennis-racket) instability:

    ```python
    sol = lagrax.rigid_body.simulate_euler([1.0, 2.0, 3.0], [1e-3, 1.0, 1e-3], t1=30.0)
    sol.omega[:, 1].min() < 0   # the spin about axis 2 has flipped
    ```
    """
    omega0 = jnp.asarray(omega0)
    if not jnp.issubdtype(omega0.dtype, jnp.floating):
        omega0 = omega0.astype(jnp.result_type(float))
    dtype = omega0.dtype
    moments = jnp.asarray(inertia, dtype)  # (3,) principal moments or (3, 3), for the field
    inertia = _inertia_matrix(moments)
    if omega0.shape != (3,):
        raise ShapeError(f"omega0 must have shape (3,), got {omega0.shape}")
    if quat0 is None:
        quat0 = jnp.array([1.0, 0.0, 0.0, 0.0], dtype)
    quat0 = jnp.asarray(quat0, dtype)
    if quat0.shape != (4,):
        raise ShapeError(f"quat0 must be a quaternion (w, x, y, z), shape (4,); got {quat0.shape}")
    torque_fn = torque if callable(torque) else None
    torque_const = None if torque is None or callable(torque) else jnp.asarray(torque, dtype)
    if torque_const is not None and torque_const.shape != (3,):
        raise ShapeError(f"torque must have shape (3,), got {torque_const.shape}")
    if not is_traced(inertia, omega0, quat0, torque_const):
        for name, x in (("inertia", inertia), ("omega0", omega0), ("quat0", quat0)):
            if not np.all(np.isfinite(np.asarray(x))):
                raise NonFiniteError(f"{name} contains non-finite values: {np.asarray(x)}")
        inert = np.asarray(inertia)
        eigs = np.linalg.eigvalsh(0.5 * (inert + inert.T))
        if not np.allclose(inert, inert.T, rtol=0, atol=1e-12 * np.max(np.abs(inert))) or not (
            eigs[0] > 0
        ):
            raise MassMatrixError(
                f"the inertia must be symmetric positive-definite; got {inert} (eigenvalues {eigs})"
            )
        if not float(np.linalg.norm(np.asarray(quat0))) > 0:
            raise ConfigurationError("quat0 must be a non-zero quaternion")
    quat0 = quat0 / jnp.sqrt(jnp.sum(quat0**2))
    if ts is None:
        ts = jnp.linspace(t0, t1, n_save, dtype=dtype)
    solver, may_adapt = resolve_solver(solver)
    if not may_adapt:
        raise ConfigurationError(
            "simulate_euler runs adaptive methods only (e.g. 'tsit5', 'dopri8')"
        )
    tdt = jnp.asarray(0.0, dtype).dtype
    sol = _solve_euler(
        solver,
        (quat0, omega0),
        moments,
        torque_fn,
        torque_const,
        jnp.asarray(t0, tdt),
        jnp.asarray(t1, tdt),
        jnp.asarray(ts, tdt),
        jnp.asarray(rtol, tdt),
        jnp.asarray(atol, tdt),
        int(max_steps),
    )
    if throw and not is_traced(sol.omega) and not bool(sol.ok):
        raise SimulationError(
            f"simulate_euler failed: {RESULTS[sol.result]} (omega0={np.asarray(omega0)}, "
            f"rtol={rtol}, atol={atol}, max_steps={max_steps}); try a larger max_steps or "
            "looser tolerances, or pass throw=False for the partial solution"
        )
    return sol
