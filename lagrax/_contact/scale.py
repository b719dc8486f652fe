r"""The default contact parameters, scaled from the scene.

With no `stiffness`, `dissipation` or `stiction_velocity` given, a
[`ContactSystem`][lagrax.contact.ContactSystem] takes them from its scene at a reference
configuration `q_ref` (zero coordinates; a floating base upright, `base_qw = 1`; or the
`reference=` the system was given), at rest:

- the **weight** the spheres carry: the generalized force that holds the system at
  rest, `h = −M(q_ref) q̈_free` (`q̈_free`: the accelerations at rest without
  contact), shared out among the spheres as the minimum-norm normal forces `f` with
  `J_nᵀ f = h` (`J_n`: the spheres' normal velocity Jacobian), `L = mean |f_i|` (a ball
  on an incline: `m g cos θ`);
- the **normal acceleration** of free fall, `g_n = max_i |n·J_i q̈_free|`;
- the **size** `ℓ`: the largest radius or distance of a sphere's centre from the
  spheres' centroid (one point alone: `ℓ = 1`).

Then `δ_ref = 10⁻⁴ ℓ` is the static penetration under the load `L`:

$$
k = L/δ_{ref}^p, \qquad c = \tfrac43 \sqrt{p/(g_n δ_{ref})}, \qquad
v_s = 10^{-4}\sqrt{g_n ℓ},
$$

`c` making a resting contact critically damped (its linearization about `δ_ref`, with
the mass `L/g_n`), `v_s` the stiction velocity. They are functions of `params` only (not
of the state), so the contact's elastic energy is a true potential, and derivatives with
respect to `params` include theirs.

**Joint limits** (`limits=`) are scaled the same way, per joint `j`, with the joint's
effective inertia `I_j = 1/(M(q_ref)⁻¹)_{jj}` (the inertia a push on joint `j` alone
meets) as the resting contact's mass and `λ_j` the length one unit of the joint moves
(a hinge: `λ_j = ℓ`, per radian; a slide: `λ_j = 1`): the stop's static penetration is
`δ_j = 10⁻⁴ ℓ/λ_j` (`10⁻⁴` rad on a hinge) under the load `L_j = I_j g_n/λ_j` (the
torque that turns the joint's inertia at the angular acceleration `g_n/ℓ`), so

$$
k_j = L_j/δ_j^p, \qquad c_j = 	frac43 \sqrt{p I_j/(L_j δ_j)} = λ_j\,c_{ground},
$$

a critically damped stop whose rate `√(p g_n λ_j/(ℓ δ_j λ_j))` is the ground contact's,
`√(p g_n/δ_ref)`: the limits make the equations no stiffer than the ground does.
"""

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

PENETRATION = 1e-4  # δ_ref/ℓ: the static penetration, relative to the scene's size
STICTION = 1e-4  # v_s/sqrt(g_n ℓ): the stiction velocity, relative to the scene's speed
DAMPING_RATIO = 1.0  # of a resting contact, linearized


def reference_configuration(system, reference, dtype):
    """`q_ref`: the given `reference`, or zeros with a floating base's `base_qw = 1`."""
    if reference is not None:
        return jnp.asarray(reference, dtype)
    q = jnp.zeros((system.n_configuration,), dtype)
    names = system.configuration_names or ()
    if "base_qw" in names:
        q = q.at[names.index("base_qw")].set(1.0)
    return q


def scene_size(contact, params, dtype):
    """`ℓ`: the largest radius or distance of a sphere's centre from the spheres'
    centroid at the reference configuration (one point alone: 1)."""
    q_ref = reference_configuration(contact.system, contact.reference, dtype)
    centres = contact.centres(q_ref, params)
    radii = jnp.asarray([s.radius for s in contact.spheres], dtype)
    spread = jnp.max(jnp.linalg.norm(centres - jnp.mean(centres, axis=0, keepdims=True), axis=-1))
    size = jnp.maximum(jnp.max(radii), spread)
    return jnp.where(size > 0, size, 1.0)


def scene_scale(contact, params, dtype):
    """`(k, c, v_s, k_j, c_j, ok)`: the default stiffness, dissipation and stiction
    velocity of `contact` (a `ContactSystem`) at `params`, its joint limits' stiffness
    and dissipation `(J,)`, and whether the scene has a weight on the plane to scale them
    by (`ok` false: no gravity towards it)."""
    system, p = contact.system, contact.exponent
    if contact.plane is None:  # pairs alone: no weight on a plane to scale by
        one = jnp.ones((), dtype)
        ones = jnp.ones((len(contact.limits),), dtype)
        return one, one, one, ones, ones, jnp.asarray(False)
    q_ref = reference_configuration(system, contact.reference, dtype)
    v0 = jnp.zeros((system.n_dof,), dtype)
    free = system.accelerations(jnp.zeros((), dtype), q_ref, v0, params, None)
    mass = system.mass_matrix(q_ref, params)
    normal = jnp.asarray(contact.plane.normal, dtype)

    def normal_rates(v):
        return contact.point_velocities(q_ref, v, params)[0] @ normal

    jac = jax.jacfwd(normal_rates)(v0)  # (S, n_dof)
    gram = jac @ jac.T
    ridge = 1e-12 * jnp.trace(gram) + jnp.finfo(dtype).tiny
    loads = jnp.linalg.solve(
        gram + ridge * jnp.eye(gram.shape[0], dtype=dtype), jac @ (-mass @ free)
    )
    load = jnp.mean(jnp.abs(loads))
    g_n = jnp.max(jnp.abs(jac @ free))
    size = scene_size(contact, params, dtype)
    ok = jnp.isfinite(load) & (load > 0) & jnp.isfinite(g_n) & (g_n > 0)
    load, g_n = jnp.where(ok, load, 1.0), jnp.where(ok, g_n, 1.0)
    delta = PENETRATION * size
    stiffness = load / delta**p
    dissipation = 4.0 / 3.0 * DAMPING_RATIO * jnp.sqrt(p / (g_n * delta))
    stiction = STICTION * jnp.sqrt(g_n * size)
    limit_k, limit_c = _limit_scale(contact, mass, g_n, size, dtype)
    return stiffness, dissipation, stiction, limit_k, limit_c, ok


def _limit_scale(contact, mass, g_n, size, dtype):
    """`(k_j, c_j)` `(J,)` of the joint limits (the module docstring) from the mass
    matrix at `q_ref`, the normal acceleration `g_n` and the size `ℓ`."""
    if not contact.limits:
        return jnp.zeros((0,), dtype), jnp.zeros((0,), dtype)
    p = contact.exponent
    rates = np.asarray([lim.rate for lim in contact.limits], int)
    lever = jnp.where(jnp.asarray([lim.angular for lim in contact.limits]), size, 1.0)
    basis = jnp.eye(mass.shape[0], dtype=dtype)[:, rates]
    inertia = 1.0 / jnp.sum(basis * jnp.linalg.solve(mass, basis), axis=0)
    delta = PENETRATION * size / lever
    load = inertia * g_n / lever
    stiffness = load / delta**p
    dissipation = 4.0 / 3.0 * DAMPING_RATIO * jnp.sqrt(p * inertia / (load * delta))
    return stiffness, dissipation


class Coefficients(NamedTuple):
    """The contact's coefficients at one `params`: stiffness `k`, dissipation `c`,
    kinetic and static friction `μ`, `μ_s`, stiction velocity `v_s`, `ok`: all valid
    (and, for defaults, the scene has a weight to scale them by), and the joint limits'
    stiffness and dissipation, one per limit `(J,)`."""

    stiffness: Any
    dissipation: Any
    friction: Any
    static_friction: Any
    stiction_velocity: Any
    ok: Any
    limit_stiffness: Any = None
    limit_dissipation: Any = None


def coefficients(contact, params, dtype) -> Coefficients:
    """`ContactSystem.coefficients`: the contact's coefficients at `params` (functions of
    `params` evaluated, defaults scaled from the scene), and whether they are valid."""

    def value(c):
        return jnp.asarray(c(params) if callable(c) else c, dtype)

    ok = jnp.asarray(True)
    stiction = contact.stiction_velocity
    if stiction is None and contact.friction == 0.0 and contact.static_friction in (None, 0.0):
        stiction = 1.0  # frictionless: v_s plays no part
    own = (contact.stiffness, contact.dissipation, stiction)
    limited = (contact.limit_stiffness, contact.limit_dissipation) if contact.limits else (0.0, 0.0)
    if None in own + limited:
        k0, c0, v0, kj0, cj0, ok = scene_scale(contact, params, dtype)
    k = k0 if contact.stiffness is None else value(contact.stiffness)
    c = c0 if contact.dissipation is None else value(contact.dissipation)
    vs = v0 if stiction is None else value(stiction)
    mu = value(contact.friction)
    mus = mu if contact.static_friction is None else value(contact.static_friction)
    n_lim = (len(contact.limits),)
    kj = kj0 if limited[0] is None else jnp.broadcast_to(value(limited[0]), n_lim)
    cj = cj0 if limited[1] is None else jnp.broadcast_to(value(limited[1]), n_lim)
    good = [jnp.isfinite(x) for x in (k, c, vs, mu, mus)]
    good += [k > 0, c >= 0, vs > 0, mu >= 0, mus >= mu]
    if contact.limits:
        good += [jnp.isfinite(kj), jnp.isfinite(cj), kj > 0, cj >= 0]
    # (a friction read from params may be one coefficient per sphere, `(S,)`)
    valid = jnp.all(jnp.stack([jnp.all(x) for x in good]))
    return Coefficients(k, c, mu, mus, vs, ok & valid, kj, cj)
