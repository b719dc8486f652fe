"""Result codes: diffrax's, plus the failures lagrax detects itself."""

import diffrax as dfx
import jax.tree_util as jtu
import numpy as np


class RESULTS(dfx.RESULTS):
    """diffrax's result codes, plus the failures lagrax detects itself."""

    non_finite_state = (
        "The state became non-finite (NaN or inf): the solve blew up, typically a fixed "
        "step past the method's stability limit, or a force that diverges."
    )
    constraint_projection_failed = (
        "The initial state is not admissible: it could not be projected onto the constraint "
        "manifold phi(q) = 0 (no admissible configuration nearby, or a rank-deficient "
        "constraint Jacobian), or a contact's sphere starts deeper inside the ground or "
        "another sphere than its max_penetration; the solve ran from it all the same. "
        "Call simulate outside jit for the values."
    )
    invalid_input = (
        "This member was not solved: its parameters or initial state are non-finite, or "
        "its mass matrix is not positive-definite at the initial state."
    )
    # (new codes go last: codes are stored in sweep files and checkpoints)
    event_cascade = (
        "An event cascade: an event occurred more than its max_events times, or a reset "
        "event recurred at the time of the previous one (events accumulating at a point, "
        "a Zeno-like cascade such as a ball bouncing infinitely often in finite time); "
        "the solve stopped there."
    )
    orbit_not_converged = (
        "The Newton iteration for a periodic orbit did not converge within max_iter "
        "iterations: there may be no periodic orbit near the guess (or it is too far)."
    )
    orbit_no_return = (
        "The motion from a Newton iterate did not return to the Poincare section before "
        "t_max (it left the section's neighbourhood: a walker that fell, an orbit that "
        "escaped): no periodic orbit near this guess, or t_max is too short."
    )
    orbit_singular = (
        "The Newton iteration for a periodic orbit stopped at a singular or non-finite "
        "Jacobian DP - I: a Floquet multiplier at 1 (a fold, or a family of orbits such "
        "as a conservative system's), or a non-finite return map."
    )
    orbit_bad_section = (
        "The Poincare section cannot serve from the guess: its condition is constant there "
        "(grad g = 0, a guard) and it has no reset, or the guess is on the section while "
        "the reset's image is not (pass the post-reset state). Call periodic_orbit outside "
        "jit for the values."
    )
    step_past_stability_limit = (
        "A fixed step past the stability limit of a stiff force (a contact's spring or its "
        "stiction): h * lambda > 2, lambda the magnitude of the fastest eigenvalue there "
        "(a contact's omega = sqrt(k_eff/m)); the solve stopped there, before the state "
        "could blow up. Use a step below 2/lambda (simulate's error names it), an adaptive "
        "step, an implicit method (rodas4, kvaerno5), or a softer contact."
    )


def code_of(result: RESULTS):
    """The integer code of a result (an `int32` array, batched under `vmap`): a result
    is a pytree whose one leaf is its code."""
    (value,) = jtu.tree_leaves(result)
    return value


def from_code(code) -> RESULTS:
    """The `RESULTS` item with integer code `code` (e.g. one read back from a file)."""
    return jtu.tree_unflatten(jtu.tree_structure(RESULTS.successful), [code])


def messages() -> list[str]:
    """Every result's message, indexed by its integer code."""
    return [RESULTS[from_code(np.asarray(i, np.int32))] for i in range(len(RESULTS))]
