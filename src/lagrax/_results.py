"""Result codes: diffrax's, plus the failures lagrax detects itself."""

import diffrax as dfx


class RESULTS(dfx.RESULTS):
    """diffrax's result codes, plus the failures lagrax detects itself."""

    non_finite_state = (
        "The state became non-finite (NaN or inf): the solve blew up, typically a fixed "
        "step past the method's stability limit, or a force that diverges."
    )
    constraint_projection_failed = (
        "The initial state could not be projected onto the constraint manifold phi(q) = 0 "
        "(no admissible configuration nearby, or a rank-deficient constraint Jacobian); the "
        "solve ran from the unprojected state."
    )
    invalid_input = (
        "This member was not solved: its parameters or initial state are non-finite, or "
        "its mass matrix is not positive-definite at the initial state."
    )
