r"""Joint limits as compliant contacts in joint space: a `ContactSystem`'s `limits=`.

A joint with the coordinate `q_i` (its rate `v_k`) and limits `[lo, hi]` has a stop at
each finite bound, each a contact of the scene's normal law (`laws.normal_force`, the
same exponent `p`) whose gap is the joint's distance to the bound,

$$
g_{lo} = q_i − lo, \qquad g_{hi} = hi − q_i
$$

(so the joint's gap is `min(q_i − lo, hi − q_i)`: at most one stop touches), and whose
force `f_n = k δ₊^p max(0, 1 + (3/2) c δ̇)` (`δ = −g`) is a generalized force on joint
`i` alone, `+f_n` at the lower stop and `−f_n` at the upper one. Its elastic part
derives from `k δ₊^{p+1}/(p+1)`, which is part of the scene's stored contact energy; the
rest is a dissipation whose power `(f_n − f_el) ġ` is part of the scene's dissipated
power, exactly as the ground's contacts are. `k` and `c` are per joint (a torque per
`rad^p` and a time per radian for a hinge, a force per `m^p` and a time per metre for a
slide); their defaults are scaled from the scene (`scale.py`).
"""

import math
from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from .._core.errors import ConfigurationError
from . import laws


class JointLimit(NamedTuple):
    """A joint's limits, enforced by a [`ContactSystem`][lagrax.contact.ContactSystem]
    as compliant stops (see its `limits=`).

    **Fields:**

    - `index`: the joint's coordinate, its place in `q`.
    - `lower`, `upper`: the limits (`±inf`: no stop on that side).
    - `rate`: its rate's place in the velocities `v` (default `None`: `index`; a
      floating base's joints sit 7 into `q` and 6 into `v`).
    - `angular`: `True` for a hinge (the limits in radians), `False` for a slide
      (metres): how the default coefficients are scaled.
    - `name`: the joint's name, for messages and events.
    """

    index: int
    lower: float
    upper: float
    rate: int | None = None
    angular: bool = True
    name: str = ""


def checked(limits) -> tuple[JointLimit, ...]:
    """`limits=` as a tuple of `JointLimit`s, each with a lower bound below its upper
    one and at least one finite; `ConfigurationError` otherwise."""
    if limits is None:
        return ()
    items = (limits,) if isinstance(limits, JointLimit) else tuple(limits)
    out = []
    for x in items:
        if not isinstance(x, JointLimit):
            raise ConfigurationError(
                f"ContactSystem's limits= takes lagrax.contact.JointLimit entries, got {x!r}"
            )
        lo, hi = float(x.lower), float(x.upper)
        if (
            not (lo < hi)
            or math.isnan(lo)
            or math.isnan(hi)
            or not (math.isfinite(lo) or math.isfinite(hi))
        ):
            raise ConfigurationError(
                f"the JointLimit of joint {x.name or x.index!r} has lower={x.lower!r}, "
                f"upper={x.upper!r}: it needs lower < upper, one of them finite"
            )
        rate = int(x.index if x.rate is None else x.rate)
        out.append(JointLimit(int(x.index), lo, hi, rate, bool(x.angular), str(x.name)))
    return tuple(out)


class Stops(NamedTuple):
    """The limits' finite bounds, one stop each (static arrays): the coordinate `q`
    `(K,)`, the rate `v` `(K,)`, the side `sign` (`+1` lower, `−1` upper), the `bound`,
    and the `joint` each belongs to (its place in `limits`)."""

    q: np.ndarray
    v: np.ndarray
    sign: np.ndarray
    bound: np.ndarray
    joint: np.ndarray


def clipped(limits: tuple[JointLimit, ...], q):
    """`q` with each joint of `limits` that is past one of its bounds moved onto it."""
    if not limits:
        return q
    index = np.asarray([lim.index for lim in limits], int)
    lower = jnp.asarray([lim.lower for lim in limits], q.dtype)
    upper = jnp.asarray([lim.upper for lim in limits], q.dtype)
    q = jnp.asarray(q)
    return q.at[index].set(jnp.clip(q[index], lower, upper))


def stops(limits: tuple[JointLimit, ...]) -> Stops:
    """The `Stops` of `limits`, lower bounds before upper ones within each joint."""
    rows = [
        (lim.index, lim.rate, side, bound, j)
        for j, lim in enumerate(limits)
        for side, bound in ((1.0, lim.lower), (-1.0, lim.upper))
        if math.isfinite(bound)
    ]
    cols = list(zip(*rows, strict=True)) if rows else [()] * 5
    q, v, sign, bound, joint = (np.asarray(c) for c in cols)
    return Stops(q.astype(int), v.astype(int), sign.astype(float), bound.astype(float), joint)


def gaps(contact, q):
    """The stops' gaps `s (q_i − bound)` `(K,)` (negative: past the limit)."""
    st = stops(contact.limits)
    dtype = jnp.result_type(q, float)
    return jnp.asarray(st.sign, dtype) * (q[st.q] - jnp.asarray(st.bound, dtype))


def state(contact, q, v, stiffness, dissipation):
    """`(gap, rate, f_n, f_el, Q)` of the stops at `(q, v)`: the gaps and their rates
    `ġ = s v_k` `(K,)`, the normal force and its elastic part `(K,)` (the joint's
    per-joint `stiffness` and `dissipation`, `(J,)`), and their generalized force `Q`
    `(n_dof,)`."""
    st = stops(contact.limits)
    dtype = jnp.result_type(q, v, float)
    sign = jnp.asarray(st.sign, dtype)
    gap = gaps(contact, q)
    rate = sign * v[st.v]
    k = jnp.broadcast_to(stiffness, (len(contact.limits),))[st.joint]
    c = jnp.broadcast_to(dissipation, (len(contact.limits),))[st.joint]
    f_n, f_el = laws.normal_force(-gap, -rate, k, c, contact.exponent)
    force = jnp.zeros(v.shape, dtype).at[st.v].add(sign * f_n)
    return gap, rate, f_n, f_el, force


def elastic_energy(contact, q, stiffness):
    """`Σ k δ₊^{p+1}/(p+1)` over the stops at `q`."""
    st = stops(contact.limits)
    k = jnp.broadcast_to(stiffness, (len(contact.limits),))[st.joint]
    return jnp.sum(laws.elastic_energy(-gaps(contact, q), k, contact.exponent))
