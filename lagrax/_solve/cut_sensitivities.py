r"""Forward mode through a solve whose events only cut the steps (a contact scene's
onsets and releases, [`ContactSystem.events`][lagrax.contact.ContactSystem.events]).

`jax.jvp` of the events loop differentiates the steps the state's error chose, which do
not resolve the tangents where the vector field's Jacobian is rough (a compliant
contact's onset and release: see `sensitivities`). Events whose reset is the identity
(`events.keep`) or absent, none terminal, leave the motion as it is: the trajectory is
that of the solve without them. So here

1. the events loop runs undifferentiated, for the saves, the final state and the
   records (the crossing times and states): the primal values, those of `simulate`
   without a derivative;
2. the solve without events runs by forward sensitivities (`sensitivities.integrate`,
   the tangents under the error control), saving at the save times and at the recorded
   crossings: the tangents `s(t)`;
3. each crossing time's tangent is the implicit function's, `δt* = −(∂g/∂y s + ∂g/∂θ
   δθ)/ġ` at the crossing (a Newton step of `g` on the differentiated state, whose primal
   is dropped), and the recorded state's `s(t*) + f δt*`.

The cost: one solve more than the forward sensitivities alone, without tangents.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu

from . import events as _events
from . import sensitivities


def applies(events, system) -> bool:
    """Whether the events only cut the steps (resets `events.keep` or none, none
    terminal) on a system whose Jacobian is rough
    ([`rough_jacobian`][lagrax.AbstractSystem.rough_jacobian])."""
    cuts_only = all(not ev.terminal and ev.reset in (None, _events.keep) for ev in events)
    return cuts_only and system.rough_jacobian


def _frozen(tree):
    """`tree` with every inexact array's derivative stopped (functions kept)."""
    return jtu.tree_map(lambda x: jax.lax.stop_gradient(x) if eqx.is_inexact_array(x) else x, tree)


def _tangent_only(value, differentiated):
    """`value` (the primal), carrying the tangent of `differentiated`."""
    return jtu.tree_map(lambda v, d: v + (d - jax.lax.stop_gradient(d)), value, differentiated)


def integrate(term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, events, field):
    """`events.integrate_events(..., kind="lax")` for events that only cut the steps
    (`applies`), differentiated as the module says: `(ys, state, records)`."""
    frozen = _frozen((term, y0, args, t0, t1, dt0, ts, field))
    f_term, f_y0, f_args, f_t0, f_t1, f_dt0, f_ts, f_field = frozen
    ys, state, records = _events.integrate_events(
        f_term, solver, controller, f_y0, f_args, f_t0, f_t1, f_dt0, f_ts, max_steps, events,
        f_field, "lax",
    )  # fmt: skip
    n_save = ts.shape[0]
    valid = [jnp.arange(rec.times.shape[0]) < rec.count for rec in records]
    crossings = jnp.concatenate(
        [jnp.where(v, rec.times, f_t0) for v, rec in zip(valid, records, strict=True)]
    )
    at = jnp.concatenate([f_ts, crossings])
    order = jnp.argsort(at)
    (q_all, qd_all), end = sensitivities.integrate(
        term, solver, controller, y0, args, t0, t1, dt0, at[order], max_steps, "lax"
    )
    back = jnp.argsort(order)
    q_all, qd_all = q_all[back], qd_all[back]
    ys = _tangent_only(ys, (q_all[:n_save], qd_all[:n_save]))
    y_end = _tangent_only(state.y, end.y)
    state = eqx.tree_at(lambda s: s.y, state, y_end)
    out, start = [], n_save
    for ev, rec, v in zip(events, records, valid, strict=True):
        k = rec.times.shape[0]
        q_k, qd_k = q_all[start : start + k], qd_all[start : start + k]
        start += k
        out.append(_polished(ev, rec, v, (q_k, qd_k), field, args))
    return ys, state, tuple(out)


def _polished(ev, rec, valid, y_k, field, args):
    """The record `rec` of `ev` with the tangents of its crossings: a Newton step of
    the condition on the differentiated states `y_k` at the recorded times, whose primal
    (about the tolerance) is dropped."""

    def one(t, q, qd):
        (g, rate), (q_rate, qdd) = (
            _events.along(ev, t, (q, qd), field, args),
            field(t, (q, qd), args),
        )
        dt = jnp.where(rate != 0, -g / jnp.where(rate != 0, rate, 1.0), 0.0)
        return dt, q + q_rate * dt, qd + qdd * dt

    dt, q, qd = jax.vmap(one)(jax.lax.stop_gradient(jnp.where(valid, rec.times, 0.0)), *y_k)
    vq, vt = valid[:, None], valid
    times = jnp.where(vt, _tangent_only(rec.times, rec.times + dt), rec.times)
    qs = jnp.where(vq, _tangent_only(rec.q, q), rec.q)
    qds = jnp.where(vq, _tangent_only(rec.qd, qd), rec.qd)
    return eqx.tree_at(lambda r: (r.times, r.q, r.qd), rec, (times, qs, qds))
