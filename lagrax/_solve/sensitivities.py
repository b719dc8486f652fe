r"""Forward mode through the lean loop: the tangents carried as state.

`jax.jvp` of a `lax.while_loop` differentiates every operation of the loop body: the
solver's stages and their combinations, its error estimate, the accept/reject selects,
the dense output. Under `jax.vmap` over `k` tangents (`jax.jacfwd`, and `jax.grad` by
forward sensitivities, `transposed`), XLA:CPU then spent about 1 µs a step per tangent
on that bookkeeping alone: seven harmonic oscillators (the solve 0.43 ms) took 3.0 ms
with seven tangents.

`integrate` here is `integrate.integrate` with a custom JVP whose rule solves the
*augmented* system instead,

$$
\frac{d}{dt}\begin{pmatrix} y \\ s \end{pmatrix}
= \begin{pmatrix} f(t, y, a) \\ \frac{∂f}{∂y} s + \frac{∂f}{∂a} δa \end{pmatrix},
\qquad s(t_0) = δy_0,
$$

(`Sensitivities`, the second row one JVP of the vector field along `(s, δa)`), with the
same explicit Runge–Kutta method and the steps the primal's error alone chooses (the
controller's norm sees `y` only, and its step sizes are not differentiated: diffrax's
`PIDController` stops their gradient). An explicit Runge–Kutta step of the augmented
system is the JVP of the step of `y` (the method commutes with linearization for fixed
steps), so the numbers are those of `jax.jvp` of the loop to the last bit (tested), for
about a third of the per-tangent cost.

For a system whose Jacobian is rough where the motion goes
([`rough_jacobian`][lagrax.AbstractSystem.rough_jacobian]: a compliant contact, whose
force `k δ^{3/2}` has a slope of infinite rate at each onset and release), the norm sees
the tangents too, held to `1/TANGENT_TOLERANCE_RATIO` of the tolerances
(`1/ROSENBROCK_TANGENT_TOLERANCE_RATIO` for `Rodas4`): the state's
error alone does not see the roughness, and its steps leave the derivatives that move an
onset wrong (even in sign at the default tolerances). The steps then differ from the
primal's own (more of them), and the derivative is that of this finer solve. There the
linearly implicit [`Rodas4`][lagrax.integrators.Rodas4] (a contact scene's default where
something can stick) solves the augmented system too: its step is not the JVP of the
step of `y` (its Jacobian is the augmented system's), but the tangents are integrated
under the same error control, where the JVP of its loop left a billiard shot's
derivative 6.8e-3 off at the default tolerances (4e-9 now, `tests/test_contact_pairs.py`);
at tolerances below `ROSENBROCK_TANGENT_TOLERANCE` the state's error alone chooses its
steps. The augmented system's Jacobian is block lower triangular (`TangentLinearField`),
so `Rodas4` forms and factorizes only the state's `∂f/∂y` for it: its columns along `y`
alone, `n + 1` of them where the augmented state has `n (1 + k) + 1` (the billiard shot's
`jax.grad`, four tangents: 322 → 231 ms at the same steps).

The rule covers what `simulate`'s forward-mode loops differentiate in practice: the
initial state, `params`, a constant `tau` and the values a `tau` function closes over
(`simulate` hoists them into its fields, `closures.hoisted`, so they are the vector
field's own perturbed arrays here). Any other perturbed input (the times, the
tolerances, a tracer still hidden in a closure) takes `jax.jvp` of the loop itself. A
system that projects its configuration after each step (a floating base's quaternion
normalized) has its tangents carried by the projection's derivative
(`integrate.project`), which is the JVP of the projected step.
"""

import contextlib
from typing import Any

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import jax.tree_util as jtu
from jax.custom_batching import custom_vmap

from .._core.closures import closes_over_tracers
from .._core.results import code_of, from_code
from .._systems.abstract import AbstractSystem
from .._systems.implicit import along_given, switched_off
from ..integrators import Rodas4
from ..integrators._rosenbrock import TangentLinearField
from . import integrate as _integrate

_RULE = {"on": True}

# Where the tangents are under the error control (`AbstractSystem.rough_jacobian`), they
# are held to this fraction of the state's tolerances: a derivative that moves an impact's
# onset is the small difference of large terms (at a fixed time, the tangent during the
# impact is the shift of the whole impact, about 10³ times the derivative after it for the
# contact guide's ball). Measured on that ball at the default tolerances (1e-8): the
# height's derivative with respect to the drop height is wrong by 1.9e-5 with a ratio of
# 1, 1.7e-6 with 10, 3.5e-9 with 100; 231, 309 and 405 steps, against 89 for the state.
TANGENT_TOLERANCE_RATIO = 100.0
# The same for `Rodas4`, whose steps are shorter on that ball (its error estimate is of
# order 3): the drop height's derivative is wrong by 1.9e-6 with a ratio of 1, 7.9e-7
# with 3, 2.8e-7 with 10, 4.9e-8 with 100, in 657, 818, 1,050 and 1,725 steps; a
# billiard shot's (`tests/test_contact_pairs.py`) by 4e-9 with any of them, in 1,021
# to 2,521 steps. 10 keeps a margin of 3.5 under 1e-6 at two thirds of the cost of 100.
ROSENBROCK_TANGENT_TOLERANCE_RATIO = 10.0


def plain_jvp() -> contextlib.AbstractContextManager[None]:
    """Within this context, solves traced take `jax.jvp` of the loop itself (the
    definition the tests hold the augmented system to). Trace-time only."""
    return switched_off(_RULE)


class Sensitivities(TangentLinearField):
    """The augmented vector field `(y, s) ↦ (f(t, y, a), ∂f/∂y s + ∂f/∂a δa)` of
    `field`, for arguments `(a, δa)` (`δa`: `None` where not perturbed); with
    `tangents=True`, `s` and `δa` carry `k` tangents on a leading axis (one JVP each,
    vmapped: the primal and the Jacobians the rule forms are shared)."""

    field: Any
    tangents: bool = eqx.field(default=False, static=True)
    # the field's own arrays come in the arguments, `a = (a', arrays)`, `field` holding
    # the rest (a system whose arrays are traced: a contact's coefficients at `params`)
    own: bool = eqx.field(default=False, static=True)

    # `integrate.advance` checks only the primal part for non-finite values: a tangent
    # that overflows must not fail the solve that the primal alone would have finished
    augmented = True

    def __call__(self, t, ys, args):
        y, s = ys
        a, da = args
        if self.own:

            def f(yy, aa):
                inner, arrays = aa
                return eqx.combine(arrays, self.field)(t, yy, inner)

        else:

            def f(yy, aa):
                return self.field(t, yy, aa)

        along, values, directions = along_given(f, (y, a), (s, da))

        def one(*direction):
            return jax.jvp(along, values, direction)

        if not self.tangents:
            return one(*directions)
        return jax.vmap(one, out_axes=(None, 0))(*directions)


def _rough(field) -> bool:
    """Whether `field`'s system asks for its sensitivities under the error control
    ([`rough_jacobian`][lagrax.AbstractSystem.rough_jacobian])."""
    system = getattr(field, "system", None)
    return isinstance(system, AbstractSystem) and system.rough_jacobian


def _field_of(term):
    """The vector field inside `term` (`None` if it is not an `ODETerm`)."""
    return term.vector_field if isinstance(term, dfx.ODETerm) else None


def _projects(field) -> bool:
    """Whether `field`'s system projects its configuration after each step."""
    system = getattr(field, "system", None)
    return isinstance(system, AbstractSystem) and system.projects


def _end(state: _integrate.StepState, y, result) -> _integrate.StepState:
    """The final state as `integrate` reports it, without the solver's and
    controller's internals (nothing downstream reads them), with `y` and `result` (as
    its code inside the custom JVP, which returns arrays)."""
    return _integrate.StepState(
        state.t,
        state.tnext,
        y,
        None,
        None,
        state.num_steps,
        state.num_accepted_steps,
        state.save_index,
        result,
    )


def integrate(term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps: int, kind: str):
    """`integrate.integrate(...)`: `(ys, end)`, `end` without the solver's and
    controller's states; differentiated in forward mode by the augmented system, except
    where the system's functions or `tau` close over a traced value (a custom JVP cannot
    see a tangent hidden there: the loop's own JVP takes it)."""
    field = _field_of(term)
    hidden = (getattr(field, "system", None), getattr(field, "tau_fn", None))
    if field is None or closes_over_tracers(*hidden):
        ys, state = _integrate.integrate(
            term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, kind
        )
        return ys, _end(state, state.y, state.result)
    ys, end = _integrate_rule(term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, kind)
    return ys, _end(end, end.y, from_code(end.result))


@eqx.filter_custom_jvp
def _integrate_rule(term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, kind):
    return _plain(term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, kind)


@_integrate_rule.def_jvp
def _integrate_jvp(primals, tangents):
    term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, kind = primals
    d_term, d_solver, d_controller, dy0, dargs, *d_times, _, _ = tangents
    if not _augmentable(term, solver, (d_solver, d_controller, *d_times)):
        return eqx.filter_jvp(_plain, primals, tangents)
    if dy0 is None:
        dy0 = jtu.tree_map(lambda _: None, y0)
    s0 = jtu.tree_map(lambda y, d: jnp.zeros_like(y) if d is None else d, y0, dy0, is_leaf=_is_none)
    if dargs is None:
        dargs = jtu.tree_map(lambda _: None, args)
    own = d_term is not None and bool(jtu.tree_leaves(d_term))
    if own:  # the field's perturbed arrays (a controller's gains, say) join the arguments
        field, d_field = term.vector_field, d_term.vector_field
        if _projects(field) and jtu.tree_leaves(getattr(d_field, "system", None)):
            # (the projection after each step needs the system's arrays in the field)
            return eqx.filter_jvp(_plain, primals, tangents)
        perturbed = jtu.tree_map(lambda _, d: d is not None, field, d_field)
        arrays, rest = eqx.partition(field, perturbed)
        term = dfx.ODETerm(rest)
        args, dargs = (args, arrays), (dargs, d_field)
    loop = (term, solver, controller, t0, t1, dt0, ts, max_steps, kind, own)
    ys, d_ys, end, d_end_y = _augmented(loop, y0, s0, args, dargs)
    d_end = _integrate.StepState(None, None, d_end_y, None, None, None, None, None, None)
    return (ys, end), (d_ys, d_end)


def _is_none(x) -> bool:
    return x is None


# `Rodas4`'s tangents go under the error control only down to these tolerances: its error
# estimate comes from linear solves whose round-off the tangents' error at `1e-12` does
# not clear (a slide's derivative ran out of steps there, even held to the state's own
# tolerances); below them the state's error alone chooses the steps, which are then
# fine enough for the tangents (the slide's derivative to 1e-6).
ROSENBROCK_TANGENT_TOLERANCE = 1e-10


def _rosenbrock_gate(controller):
    """1 where `controller`'s tolerances (traced) are at least
    `ROSENBROCK_TANGENT_TOLERANCE`, else 0 (`None` for a controller without them)."""
    rtol, atol = getattr(controller, "rtol", None), getattr(controller, "atol", None)
    if rtol is None or atol is None:
        return None
    tight = jnp.minimum(jnp.asarray(rtol), jnp.asarray(atol)) < ROSENBROCK_TANGENT_TOLERANCE
    return jnp.where(tight, 0.0, 1.0)


def _augmentable(term, solver, other_tangents) -> bool:
    """Whether the augmented system gives the loop's JVP: the rule on, an explicit
    Runge–Kutta method (a variational step treats its state as `(q, v)`, an implicit
    one iterates on it) or, on a rough system, `Rodas4` (its tangents under the error
    control at tolerances of at least `ROSENBROCK_TANGENT_TOLERANCE`), only the initial
    state, the arguments and the vector field's arrays perturbed (not the times or the
    tolerances; a projecting system's arrays perturbed take the loop's JVP too)."""
    field = _field_of(term)
    return (
        _RULE["on"]
        and field is not None
        and (isinstance(solver, dfx.AbstractERK) or (isinstance(solver, Rodas4) and _rough(field)))
        and not jtu.tree_leaves(other_tangents)
    )


def _augmented_solve(loop, y0, s0, args, dargs, tangents: bool):
    """`(ys, δys, end, δy_end)` of the augmented system (`tangents`: `s0` and `dargs`
    hold a leading axis of tangents)."""
    term, solver, controller, t0, t1, dt0, ts, max_steps, kind, own = loop
    field = _field_of(term)
    aug = dfx.ODETerm(Sensitivities(field, tangents, own))
    rosenbrock = isinstance(solver, Rodas4)
    ratio = None
    if _rough(field):
        ratio = ROSENBROCK_TANGENT_TOLERANCE_RATIO if rosenbrock else TANGENT_TOLERANCE_RATIO
    gate = _rosenbrock_gate(controller) if rosenbrock else None
    (ys, d_ys), state = _integrate.integrate(
        aug,
        solver,
        _integrate.primal_controller(controller, ratio, tangents, gate),
        (y0, s0),
        (args, dargs),
        t0,
        t1,
        dt0,
        ts,
        max_steps,
        kind,
    )
    if tangents:  # the saves' tangents as (k, S, ...), as a vmap over tangents has them
        d_ys = jtu.tree_map(lambda x: jnp.moveaxis(x, 1, 0), d_ys)
    y_end, s_end = state.y
    return ys, d_ys, _end(state, y_end, code_of(state.result)), s_end


def _augmented(loop, y0, s0, args, dargs):
    """`_augmented_solve` for one tangent; vmapped over tangents (`jax.jacfwd`, the
    forward sensitivities of `jax.grad`) with the primal unbatched, the tangents as one
    array state with a leading axis (a custom batching rule: the loop's bookkeeping on
    them is vectorized code, where the plain vmap's ran at about a third of the speed)."""
    dynamic, static = eqx.partition((loop, y0, s0, args, dargs), eqx.is_array)

    def call(dyn, tangents=False):
        return _augmented_solve(*eqx.combine(dyn, static), tangents=tangents)

    @custom_vmap
    def run(dyn):
        return call(dyn)

    @run.def_vmap
    def _rule(axis_size, in_batched, dyn):
        (batched,) = in_batched
        loop_b, y0_b, s0_b, args_b, dargs_b = batched
        if any(jtu.tree_leaves((loop_b, y0_b, args_b))):  # a batch of primals: plain vmap
            axes = jtu.tree_map(lambda b: 0 if b else None, batched)
            out = jax.vmap(call, in_axes=(axes,))(dyn)
            return out, jtu.tree_map(lambda _: True, out)
        loop_, y0_, s0_, args_, dargs_ = dyn

        def spread(x, b):
            return x if b else jnp.broadcast_to(x, (axis_size, *jnp.shape(x)))

        s0_ = jtu.tree_map(spread, s0_, s0_b)
        dargs_ = jtu.tree_map(spread, dargs_, dargs_b)
        out = call((loop_, y0_, s0_, args_, dargs_), tangents=True)
        ys, d_ys, end, d_end = out
        flags = (
            jtu.tree_map(lambda _: False, ys),
            jtu.tree_map(lambda _: True, d_ys),
            jtu.tree_map(lambda _: False, end),
            jtu.tree_map(lambda _: True, d_end),
        )
        return out, flags

    @jax.custom_jvp
    def primal(dyn):
        return run(dyn)

    @primal.defjvp
    def _jvp(primals, tangents):  # (a second derivative: through the plain loop)
        return jax.jvp(call, primals, tangents)

    return primal(dynamic)


def _plain(term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, kind):
    ys, state = _integrate.integrate(
        term, solver, controller, y0, args, t0, t1, dt0, ts, max_steps, kind
    )
    return ys, _end(state, state.y, code_of(state.result))
