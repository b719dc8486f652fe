r"""The contact forces of a `ContactSystem` at one state: the spheres' motion, the gaps
to the plane and between the paired spheres, the normal and friction forces, and their
generalized force `Q = Σ J_iᵀ F_i`.

Every function here is traced (never raises on values) and takes the `ContactSystem`
as its first argument; the system's methods delegate to them.
"""

import jax
import jax.numpy as jnp
import numpy as np

from .._core.errors import ShapeError
from . import laws, pairs
from . import limits as joint_limits


def _checked(contact, c):
    """A sphere's centre `c`, checked: `(d,)` with `d` the scene's dimension."""
    dim = contact.dim
    good = c.ndim == 1 and c.shape[0] in (2, 3) and (dim is None or c.shape[0] == dim)
    if not good:
        want = f"({dim},)" if dim is not None else "(2,) or (3,)"
        raise ShapeError(
            f"a Sphere's position(q, params) of {contact.name} returned shape {c.shape}; "
            f"it must return {want}"
        )
    return c


def _placed(contact, q, params, turning):
    """`(c, R)`: the spheres' centres `(S, d)` and the rotations of the spheres
    `turning` (indices, in order) `(T, 3, 3)` (`None` with none): the spheres that share a
    source placed as one batch (one pass of their model's kinematics), each other
    sphere by its own functions."""
    spheres = contact.spheres
    blocks, order, rot_blocks = [], [], []
    for group in contact.groups:
        members = [spheres[i] for i in group]
        bodies = np.asarray([s.body for s in members], int)
        offsets = np.asarray([s.offset for s in members], float)
        c, r = members[0].source.poses(q, params, bodies, offsets)
        blocks.append(c)
        rot_blocks.append(r)
        order.extend(group)
    rot_order = list(order)  # the groups' rotations come in the groups' order
    grouped = set(order)
    alone = [i for i in range(len(spheres)) if i not in grouped]
    if alone:
        cs = [_checked(contact, jnp.asarray(spheres[i].position(q, params))) for i in alone]
        if len({c.shape for c in cs} | {b.shape[1:] for b in blocks}) > 1:
            raise ShapeError(
                f"the Spheres of {contact.name} return centres of different sizes "
                f"{[tuple(b.shape[1:]) for b in blocks] + [c.shape for c in cs]}: all planar "
                "(2) or all spatial (3)"
            )
        blocks.append(jnp.stack(cs))
        order.extend(alone)
    dtype = jnp.result_type(q, float)
    c = _in_order(blocks, order, range(len(spheres)))
    if not turning:
        return c.astype(dtype), None
    lone = [i for i in turning if i not in grouped]
    if lone:
        rot_blocks.append(jnp.stack([jnp.asarray(spheres[i].rotation(q, params)) for i in lone]))
        rot_order.extend(lone)
    return c.astype(dtype), _in_order(rot_blocks, rot_order, turning).astype(dtype)


def _in_order(blocks, order, wanted):
    """The rows of the concatenated `blocks` (row `k` is item `order[k]`) for the items
    `wanted`, in their order: a static gather, none where they already are."""
    x = jnp.concatenate(blocks) if len(blocks) > 1 else blocks[0]
    wanted = list(wanted)
    if order == wanted:
        return x
    row = {item: k for k, item in enumerate(order)}
    return x[np.asarray([row[i] for i in wanted], int)]


def centres(contact, q, params):
    """The spheres' centres `(S, d)`."""
    return _placed(contact, q, params, ())[0]


def motion(contact, q, v, params):
    """`(c, ċ, ω)`: the spheres' centres and their rates `(S, d)`, and their bodies'
    angular velocities, `(S,)` planar or `(S, 3)` spatial (zero for a sphere without
    orientation or of radius 0); the rates linear in the velocities `v`."""
    rate = contact.system.configuration_rate(q, v)
    # the centres and the spatial bodies' rotations, with their rates, in one pass (the
    # spheres that share a source, a robot's, share its kinematics)
    spheres = contact.spheres
    turning = tuple(i for i, s in enumerate(spheres) if s.rotation is not None and s.radius > 0)
    (c, rots), (c_dot, rot_dots) = jax.jvp(
        lambda a: _placed(contact, a, params, turning), (q,), (rate,)
    )
    planar = c.shape[1] == 2
    if planar:
        omegas = []
        for s in spheres:
            w = jnp.zeros((), c.dtype)
            if s.angle is not None and s.radius > 0:
                _, w = jax.jvp(lambda a, s=s: jnp.asarray(s.angle(a, params)), (q,), (rate,))
            omegas.append(jnp.asarray(w, c.dtype))
        return c, c_dot, jnp.stack(omegas)
    if not turning:
        return c, c_dot, jnp.zeros(c.shape, c.dtype)
    x = jnp.einsum("kij,klj->kil", rot_dots, rots)  # [ω]× in the world frame, (T, 3, 3)
    w = 0.5 * jnp.stack(
        [x[:, 2, 1] - x[:, 1, 2], x[:, 0, 2] - x[:, 2, 0], x[:, 1, 0] - x[:, 0, 1]], axis=-1
    )
    if len(turning) == len(spheres):
        return c, c_dot, w
    return c, c_dot, jnp.zeros(c.shape, c.dtype).at[np.asarray(turning)].set(w)


def radii(contact, dtype):
    """The spheres' radii `(S,)`."""
    return jnp.asarray([s.radius for s in contact.spheres], dtype)


def plane_gaps(contact, c, dtype):
    """`g_i = n·c_i − offset − r_i` `(S,)` for the centres `c` (negative: penetration)."""
    normal = jnp.asarray(contact.plane.normal, dtype)
    return c @ normal - contact.plane.offset - radii(contact, dtype)


def gaps(contact, q, params):
    """`(plane, pair)`: the gaps to the plane `(S,)` and between the paired spheres
    `(P,)` (`None` where there is no plane or no pair)."""
    c = centres(contact, q, params)
    plane = None if contact.plane is None else plane_gaps(contact, c, c.dtype)
    pair = None
    if contact.pairs:
        pair = pairs.pair_geometry(c, radii(contact, c.dtype), contact.pairs)[1]
    return plane, pair


def elastic_energy(contact, q, params):
    """`V_c = Σ k δ₊^{p+1}/(p+1)` over the plane's contacts, the pairs and the joint
    limits' stops."""
    q = jnp.asarray(q)
    co = contact.coefficients(params, jnp.result_type(q, float))
    total = jnp.zeros((), jnp.result_type(q, float))
    for g in gaps(contact, q, params):
        if g is not None:
            total = total + jnp.sum(laws.elastic_energy(-g, co.stiffness, contact.exponent))
    if contact.limits:
        total = total + joint_limits.elastic_energy(contact, q, co.limit_stiffness)
    return total


def _forces(velocity, normal, gap, co, exponent):
    """`(f_n, f_el, F)` of contacts with velocities `(K, d)`, unit normals `(K, d)` and
    gaps `(K,)`: the normal force, its elastic part and the whole force along `n` plus
    friction."""
    rate = jnp.sum(velocity * normal, axis=-1)
    f_n, f_el = laws.normal_force(-gap, -rate, co.stiffness, co.dissipation, exponent)
    v_t = velocity - rate[:, None] * normal
    f_t = laws.friction_force(v_t, f_n, co.friction, co.static_friction, co.stiction_velocity)
    return f_n, f_el, f_n[:, None] * normal + f_t


def velocity_map(contact, q, params, dtype):
    """`v ↦ ({"plane": (S, d), "pair": (P, d)}, c)`: the velocities of the contact points
    (with the plane; the pairs' relative ones), linear in the velocities `v`, and the
    centres `(S, d)` (the keys present where there is a plane, pairs)."""
    r = radii(contact, dtype)
    plane = contact.plane

    def velocities(b):
        c, c_dot, w = motion(contact, q, b, params)
        out = {}
        if plane is not None:
            normal = jnp.asarray(plane.normal, dtype)
            out["plane"] = c_dot + pairs.turn(w, -r[:, None] * normal[None, :])
        if contact.pairs:
            n_ij = pairs.pair_geometry(c, r, contact.pairs)[0]
            out["pair"] = pairs.relative_velocity(c_dot, w, r, n_ij, contact.pairs)
        return out, c

    return velocities


def contact_state(contact, q, v, params):
    """The contact at one state, see `ContactSystem.contact_state`."""
    dtype = jnp.result_type(q, v, float)
    co = contact.coefficients(params, dtype)
    r = radii(contact, dtype)
    plane = contact.plane
    velocities = velocity_map(contact, q, params, dtype)
    velocity, pullback, c = jax.vjp(velocities, v, has_aux=True)
    out = {"coefficients": co}
    cotangent = {}
    energy = jnp.zeros((), dtype)
    if plane is not None:
        normal = jnp.broadcast_to(jnp.asarray(plane.normal, dtype), c.shape)
        gap = plane_gaps(contact, c, dtype)
        f_n, f_el, force = _forces(velocity["plane"], normal, gap, co, contact.exponent)
        out.update(gap=gap, normal_force=f_n, elastic_force=f_el, force=force)
        out.update(velocity=velocity["plane"], normal=normal)
        cotangent["plane"] = force.astype(dtype)
        energy = energy + jnp.sum(laws.elastic_energy(-gap, co.stiffness, contact.exponent))
    if contact.pairs:
        n_ij, gap = pairs.pair_geometry(c, r, contact.pairs)
        f_n, f_el, force = _forces(velocity["pair"], n_ij, gap, co, contact.exponent)
        out.update(pair_gap=gap, pair_normal_force=f_n, pair_elastic_force=f_el)
        out.update(pair_force=force, pair_velocity=velocity["pair"], pair_normal=n_ij)
        cotangent["pair"] = force.astype(dtype)
        energy = energy + jnp.sum(laws.elastic_energy(-gap, co.stiffness, contact.exponent))
    (generalized,) = pullback(cotangent)
    if contact.limits:
        gap, rate, f_n, f_el, force = joint_limits.state(
            contact, q, v, co.limit_stiffness, co.limit_dissipation
        )
        sign = jnp.asarray(joint_limits.stops(contact.limits).sign, dtype)
        out.update(limit_gap=gap, limit_rate=rate, limit_normal_force=f_n)
        out.update(limit_elastic_force=f_el, limit_force=sign * f_n)
        generalized = generalized + force
        energy = energy + joint_limits.elastic_energy(contact, q, co.limit_stiffness)
    out.update(generalized=generalized, energy=energy)
    return out


def dissipated_power(state):
    """`Σ (F − f_el n)·v` over the plane's contacts and the pairs, and `Σ (f_n − f_el)
    ġ` over the joint limits' stops: the power of the dissipation and the friction (the
    elastic part's is `−dV_c/dt`)."""
    power = jnp.zeros((), state["generalized"].dtype)
    for prefix in ("", "pair_"):
        if prefix + "force" in state:
            elastic = state[prefix + "elastic_force"][:, None] * state[prefix + "normal"]
            power = power + jnp.sum(
                (state[prefix + "force"] - elastic) * state[prefix + "velocity"]
            )
    if "limit_gap" in state:
        damping = state["limit_normal_force"] - state["limit_elastic_force"]
        power = power + jnp.sum(damping * state["limit_rate"])
    return power
