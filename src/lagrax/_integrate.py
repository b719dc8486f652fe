"""A lean stepping loop for one trajectory, on diffrax's own steps.

``diffrax.diffeqsolve`` is general: events, jump times, several kinds of saving, progress
meters, SDEs. Each of those costs a little on every step, and for the small systems
mechanics produces (n = 1 … 10 coordinates) the step itself is cheap, so the machinery
dominates: about 4 µs a step for the 2R arm against well under 1 µs for the stepping alone.

``integrate`` keeps only what ``simulate`` needs: ``solver.step``, the step-size
controller's ``adapt_step_size``, diffrax's clipping of the last step to ``t1``, and
dense output at the save times (``solver.interpolation_cls``). Each step is therefore the
one ``diffeqsolve`` would take. The loops are ``equinox.internal.while_loop`` with
``kind="checkpointed"`` (as diffrax's default adjoint), so reverse-mode ``jax.grad``
works through them with recursive checkpointing, and the saved outputs are written in
place (``buffers``).

``step`` is shared with the sweep's lane queue (``_lanes.run_lanes``), which runs it
under ``vmap``.
"""

import diffrax as dfx
import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
import numpy as np

from ._results import RESULTS

DEFAULT_DT0 = 0.01


def tree_where(pred, a, b):
    """``where`` over matching pytrees, broadcasting a (batched) scalar ``pred``."""

    def pick(x, y):
        if not (eqx.is_array(x) or eqx.is_array(y)):
            return x  # static (Python) leaves, e.g. a solver's flags
        x, y = jnp.asarray(x), jnp.asarray(y)
        p = pred.reshape(pred.shape + (1,) * (x.ndim - pred.ndim))
        return jnp.where(p, x, y)

    return jtu.tree_map(pick, a, b)


def t1_floor(t1):
    """diffrax snaps a step end within ~100 ulps of ``t1`` to ``t1``."""
    return t1 - 100 * jnp.finfo(t1.dtype).eps * jnp.maximum(jnp.abs(t1), 1.0)


def init(term, solver, controller, t0, t1, y0, dt0, args):
    """``(tnext, solver_state, controller_state)`` at the start of a solve."""
    if dt0 is None:
        # What diffeqsolve ends up doing: it wraps the terms (diffrax.WrapTerm), and its
        # PID controller's initial-step heuristic then falls back to 0.01. Matching it
        # keeps the step sequence that of diffeqsolve.
        dt0 = jnp.asarray(DEFAULT_DT0, t0.dtype)
    error_order = solver.error_order(term)
    tnext, cstate = controller.init(term, t0, t1, y0, dt0, args, solver.func, error_order)
    tnext = jnp.minimum(tnext, t1)
    sstate = solver.init(term, t0, tnext, y0, args)
    return tnext, sstate, cstate


def step(term, solver, controller, t, tnext, y, args, sstate, cstate, t1):
    """One attempted step ``[t, tnext]``, accepted or rejected by the controller.

    **Returns:** ``(keep, tprev, tnew, y, solver_state, controller_state, result, dense)``:
    whether the step was accepted, the new current time (``tnext`` if accepted, else
    ``t``), the end of the next attempt (clipped to ``t1``), the state at ``tprev``, the
    new solver/controller states, a ``RESULTS`` code and the dense-output information of
    the attempt.
    """
    error_order = solver.error_order(term)
    y1, y_err, dense, sstate1, sres = solver.step(term, t, tnext, y, args, sstate, False)
    if y_err is not None:  # a NaN error would be accepted by nothing: reject, shrink
        y_err = jtu.tree_map(lambda e: jnp.where(jnp.isnan(e), jnp.inf, e), y_err)
    keep, tprev, tnew, _, cstate1, cres = controller.adapt_step_size(
        t, tnext, y, y1, args, y_err, error_order, cstate
    )
    keep = jnp.asarray(keep)
    tprev = jnp.minimum(tprev, t1)
    clip = jnp.where(keep, t1, tprev + 0.5 * (t1 - tprev))
    tnew = jnp.where(tnew > t1_floor(t1), clip, tnew)
    # explicit methods report a constant success: skip the eager ops on constants (each
    # would compile a tiny kernel during tracing, ~0.1 s in all on the first call)
    sres, cres = _promote(sres), _promote(cres)
    if _known_success(sres):
        res = cres
    else:
        sres = RESULTS.where(keep, sres, RESULTS.successful)
        res = RESULTS.where(sres == RESULTS.successful, cres, sres)
    y_next = tree_where(keep, y1, y)
    sstate_next = tree_where(keep, sstate1, sstate)
    return keep, tprev, tnew, y_next, sstate_next, cstate1, res, dense


def _known_success(result) -> bool:
    """Whether ``result`` is the constant ``RESULTS.successful`` (known at trace time)."""
    value = result._value
    if isinstance(value, jax.core.Tracer):
        return False
    return bool(np.all(np.asarray(value) == np.asarray(RESULTS.successful._value)))


def _promote(result):
    """``RESULTS.promote``, without eager ops when ``result`` is a constant success."""
    return RESULTS.successful if _known_success(result) else RESULTS.promote(result)


def all_finite(y) -> jax.Array:
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(v)) for v in jtu.tree_leaves(y)]))


def integrate(term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps: int):
    """Solve ``y' = f(t, y, args)`` on ``[t0, t1]`` and save at ``ts``.

    **Arguments:** as ``diffrax.diffeqsolve``; ``ts`` are sorted save times inside
    ``[t0, t1]``, ``max_steps`` the budget of attempted steps.

    **Returns:** ``(ys, t_end, y_end, result, num_steps, num_accepted_steps, n_saved)``:
    the states at ``ts`` (``inf`` where not reached), the last time and state reached
    (``t1`` on success), a ``RESULTS`` code (``max_steps_reached``, ``non_finite_state``
    as soon as an accepted state is not finite, or the solver's own failure), the step
    counts, and how many of ``ts`` were reached.
    """
    n_save = ts.shape[0]
    tnext, sstate, cstate = init(term, solver, controller, t0, t1, y0, dt0, args)
    ys = jtu.tree_map(lambda a: jnp.full((n_save,) + jnp.shape(a), jnp.inf, a.dtype), y0)
    zero = jnp.asarray(0, jnp.int32)
    state = (t0, tnext, y0, sstate, cstate, zero, zero, zero, RESULTS.successful, ys)

    def cond(s):
        t, result = s[0], s[8]
        return (t < t1) & (result == RESULTS.successful)

    def body(s):
        t, tnext, y, sstate, cstate, steps, accepted, save_i, _, ys = s
        keep, tprev, tnew, y_next, sstate, cstate, res, dense = step(
            term, solver, controller, t, tnext, y, args, sstate, cstate, t1
        )
        if n_save:
            interp = solver.interpolation_cls(t0=t, t1=tnext, **dense)

            def save_cond(c):
                i, _ = c
                return keep & (i < n_save) & (ts[jnp.minimum(i, n_save - 1)] <= tnext)

            def save_body(c):
                i, out = c
                y_t = interp.evaluate(ts[i])
                out = jtu.tree_map(lambda v, o: o.at[i].set(v), y_t, out)
                return i + 1, out

            save_i, ys = eqxi.while_loop(
                save_cond,
                save_body,
                (save_i, ys),
                max_steps=n_save,
                buffers=lambda c: c[1],
                kind="checkpointed",
                checkpoints=n_save,
            )
        steps = steps + 1
        accepted = accepted + keep
        result = RESULTS.where(all_finite(y_next), res, RESULTS.non_finite_state)
        out_of_steps = (steps >= max_steps) & (tprev < t1) & (result == RESULTS.successful)
        result = RESULTS.where(out_of_steps, RESULTS.max_steps_reached, result)
        return (tprev, tnew, y_next, sstate, cstate, steps, accepted, save_i, result, ys)

    s = eqxi.while_loop(
        cond, body, state, max_steps=max_steps, buffers=lambda s: s[9], kind="checkpointed"
    )
    t_end, _, y_end, _, _, steps, accepted, n_saved, result, ys = s
    return ys, t_end, y_end, result, steps, accepted, n_saved


def is_lean(controller: dfx.AbstractStepSizeController | None) -> bool:
    """Whether ``integrate`` reproduces ``diffeqsolve`` with this controller."""
    # (diffrax's step_ts / jump_ts live in ClipStepSizeController, which is not lean)
    return controller is None or type(controller) in (dfx.ConstantStepSize, dfx.PIDController)
