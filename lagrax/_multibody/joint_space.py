r"""Joint-space terms of a tree: armature, joint springs and fixed tendons (MuJoCo's).

They act on the joint angles `θ` of all bodies (the coordinates themselves without mimic
joints; a floating base's joints, not its six base coordinates), read from optional
entries of `params` (absent: the term is not there and costs nothing):

- `"armature"` `(n_bodies,)`: a rotor's reflected inertia, `T ⊃ ½ Σ a_i θ̇_i²`, so
  `M ⊃ diag(a)`: the articulated-body algorithm's `D_i = S_iᵀ I^A_i S_i + a_i`,
  recursive Newton–Euler's `τ_i ⊃ a_i θ̈_i` (`∂τ/∂q̈ = M` gains `diag(a)`; `∂τ/∂q` and
  `∂τ/∂q̇` do not change: `a` is constant);
- `"stiffness"`, `"springref"` `(n_bodies,)`: joint springs, `V ⊃ ½ Σ k_i (θ_i −
  θ_ref,i)²` (MuJoCo's joint `stiffness` about `springref`, its `qpos_spring`);
- fixed tendons, `L = C θ` (`"tendon"` `(n_t, n_bodies)`: each tendon's coefficients on
  the joints): `"tendon_stiffness"` `(n_t,)` about `"tendon_length"` `(n_t,)`,
  `V ⊃ ½ Σ k_t (L_t − L_0,t)²`, and `"tendon_damping"` `(n_t,)`, Rayleigh `D ⊃ ½ Σ b_t
  L̇_t²`;
- `"frictionloss"` `(n_bodies,)` with `"friction_velocity"` `()`: MuJoCo's joint friction
  loss, regularized Coulomb friction with stiction (`lagrax._core.friction`, the law the
  contacts use): the dissipation `D ⊃ Σ f_i v_s Φ(|θ̇_i|/v_s)`, whose force
  `−f_i μ̂(|θ̇_i|/v_s) sign(θ̇_i)` is `−f_i sign(θ̇_i)` above `3 v_s` and holds a load
  below `f_i` by a creep below `v_s` (`"frictionloss_static"` `(n_bodies,)`, optional: a
  stiction peak `f_s ≥ f` at `v_s`; MuJoCo has none, `f_s = f`).

The springs' generalized force is `∂V_s/∂θ = K_s θ − f_0` with the constant stiffness
matrix `K_s = diag(k) + Cᵀ diag(k_t) C`: `∂τ/∂q ⊃ K_s` in the derivatives.
"""

from collections.abc import Mapping
from typing import Any

import equinox as eqx
import jax.numpy as jnp

from .._core.checks import param_shapes
from .._core.custom_types import Params
from .._core.friction import joint_friction, joint_friction_dissipation

# the default stiction velocity `v_s` of joint friction loss (rad/s or m/s): the creep
# that holds a load below the friction loss is below it
FRICTION_VELOCITY = 0.01

JOINT_KEYS = ("armature", "stiffness", "springref", "frictionloss", "frictionloss_static")
TENDON_KEYS = ("tendon", "tendon_stiffness", "tendon_length", "tendon_damping")


def _get(params: Params, key: str, dtype: Any) -> jnp.ndarray | None:
    if not isinstance(params, Mapping) or params.get(key) is None:
        return None
    return jnp.asarray(params[key], dtype)


def check(params: Params, n_bodies: int) -> None:
    """`ShapeError`/`ParameterError` for a joint-space entry of the wrong shape, or a
    spring or tendon entry without its partners (at trace time)."""
    if not isinstance(params, Mapping):
        return
    shapes: dict[str, tuple[int, ...]] = {
        k: (n_bodies,) for k in JOINT_KEYS if params.get(k) is not None
    }
    if params.get("stiffness") is not None:
        shapes["springref"] = (n_bodies,)
    if params.get("frictionloss") is not None:
        shapes["friction_velocity"] = ()
    if params.get("tendon") is not None:
        n_t = int(jnp.shape(params["tendon"])[0])
        shapes["tendon"] = (n_t, n_bodies)
        for key in TENDON_KEYS[1:]:
            shapes[key] = (n_t,)
    param_shapes(params, shapes, f"the joint-space terms of {n_bodies} joints")


def armature(params: Params, dtype: Any) -> jnp.ndarray | None:
    """`a` `(n_bodies,)`, or `None` without armature."""
    return _get(params, "armature", dtype)


def spring_force(params: Params, theta: Any) -> jnp.ndarray | None:
    """`∂V_s/∂θ = k (θ − θ_ref) + Cᵀ k_t (C θ − L_0)`, or `None` without springs."""
    out = None
    k = _get(params, "stiffness", theta.dtype)
    if k is not None:
        out = k * (theta - jnp.asarray(params["springref"], theta.dtype))
    c = _get(params, "tendon", theta.dtype)
    if c is not None:
        k_t = jnp.asarray(params["tendon_stiffness"], theta.dtype)
        f = c.T @ (k_t * (c @ theta - jnp.asarray(params["tendon_length"], theta.dtype)))
        out = f if out is None else out + f
    return out


def spring_energy(params: Params, theta: Any) -> Any:
    """`V_s = ½ Σ k (θ − θ_ref)² + ½ Σ k_t (C θ − L_0)²` (`0.0` without springs)."""
    out: Any = 0.0
    k = _get(params, "stiffness", theta.dtype)
    if k is not None:
        out = 0.5 * jnp.sum(k * (theta - jnp.asarray(params["springref"], theta.dtype)) ** 2)
    c = _get(params, "tendon", theta.dtype)
    if c is not None:
        k_t = jnp.asarray(params["tendon_stiffness"], theta.dtype)
        stretch = c @ theta - jnp.asarray(params["tendon_length"], theta.dtype)
        out = out + 0.5 * jnp.sum(k_t * stretch**2)
    return out


def stiffness_matrix(params: Params, n_bodies: int, dtype: Any) -> jnp.ndarray | None:
    """`K_s = ∂²V_s/∂θ² = diag(k) + Cᵀ diag(k_t) C`, or `None` without springs."""
    out = None
    k = _get(params, "stiffness", dtype)
    if k is not None:
        out = jnp.diag(k)
    c = _get(params, "tendon", dtype)
    if c is not None:
        kc = c.T @ (jnp.asarray(params["tendon_stiffness"], dtype)[:, None] * c)
        out = kc if out is None else out + kc
    return out


def tendon_dissipation(params: Params, theta_d: Any) -> Any:
    """`½ Σ b_t (C θ̇)²` (`0.0` without tendon damping)."""
    c = _get(params, "tendon", theta_d.dtype)
    b = _get(params, "tendon_damping", theta_d.dtype)
    if c is None or b is None:
        return 0.0
    return 0.5 * jnp.sum(b * (c @ theta_d) ** 2)


def _friction_laws(params: Params, dtype: Any):
    """`(f, f_s, v_s)` of the joints' friction loss, or `None` without it."""
    f = _get(params, "frictionloss", dtype)
    if f is None:
        return None
    static = _get(params, "frictionloss_static", dtype)
    return f, f if static is None else static, jnp.asarray(params["friction_velocity"], dtype)


def friction_dissipation(params: Params, theta_d: Any) -> Any:
    """`Σ f_i v_s Φ(|θ̇_i|/v_s)`, the friction loss's dissipation (`0.0` without)."""
    laws = _friction_laws(params, theta_d.dtype)
    if laws is None:
        return 0.0
    return jnp.sum(joint_friction_dissipation(theta_d, *laws))


def friction_force(params: Params, theta_d: Any) -> jnp.ndarray | None:
    """`∂D_f/∂θ̇ = f μ̂(s) sign(θ̇)` (the friction loss's force is its negative), with
    its analytic derivative as its JVP; `None` without friction loss."""
    laws = _friction_laws(params, theta_d.dtype)
    return None if laws is None else joint_friction(theta_d, *laws)


def with_armature(mass: Any, params: Params, offset: int = 0) -> Any:
    """`M + diag(a)` on the joints' block (from row `offset`: 6 for a floating base)."""
    a = armature(params, mass.dtype)
    if a is None:
        return mass
    idx = jnp.arange(a.shape[0]) + offset
    return mass.at[idx, idx].add(a)


def joint_inverse(params: Params, theta: Any, theta_dd: Any) -> Any:
    """The joint-space terms of `τ_θ`: `a θ̈ + ∂V_s/∂θ` (`0.0` without any; `theta_dd`
    `None`: the bias, springs only)."""
    out: Any = 0.0
    a = armature(params, theta.dtype)
    if a is not None and theta_dd is not None:
        out = a * theta_dd
    f = spring_force(params, theta)
    if f is not None:
        out = out + f
    return out


class JointKinetic(eqx.Module):
    """The armature's kinetic energy `½ Σ a_i θ̇_i²` of a tree (a `Scene` term)."""

    tree: Any

    def __call__(self, q, qd, params):
        a = armature(params, jnp.result_type(qd))
        if a is None:
            return jnp.zeros((), jnp.result_type(qd))
        rates = self.tree.joint_rates(qd)
        return 0.5 * jnp.sum(a * rates**2)


class JointPotential(eqx.Module):
    """The springs' potential `V_s(θ)` of a tree (a `Scene` term)."""

    tree: Any

    def __call__(self, q, params):
        return jnp.asarray(spring_energy(params, self.tree.joint_angles(q)), jnp.result_type(q))
