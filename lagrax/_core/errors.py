"""Exception types raised by lagrax.  All derive from the built-in they refine."""


class LagraxError(Exception):
    """Base class of every error lagrax raises on purpose."""


class ShapeError(LagraxError, ValueError):
    """An array has the wrong shape for the system (e.g. `q` of length 3 for a 2-DOF arm)."""


class NonFiniteError(LagraxError, ValueError):
    """An input or a state contains NaN or infinity."""


class ParameterError(LagraxError, KeyError):
    """`params` lacks an entry that an energy or force function reads."""

    def __str__(self) -> str:  # KeyError would quote the whole message
        return str(self.args[0])


class MassMatrixError(LagraxError, ValueError):
    """The mass matrix `M(q) = ∂²T/∂q̇²` is singular or not positive-definite."""


class SimulationError(LagraxError, RuntimeError):
    """A solve failed (step budget exhausted, non-finite state, singular mass matrix)."""


class ConstraintError(LagraxError, ValueError):
    """Holonomic constraints cannot be enforced: their Jacobian `J = ∂φ/∂q` is
    rank-deficient (redundant constraints or a singular configuration, so the KKT matrix
    `[[M, Jᵀ], [J, 0]]` is singular), or a state cannot be projected onto `φ(q) = 0`."""


class ContactError(LagraxError, ValueError):
    """A contact cannot start: a sphere of a `lagrax.contact.ContactSystem` starts deeper
    inside the ground (or another sphere) than its `max_penetration` allows. The message
    names the sphere, its depth and the limit."""


class ConfigurationError(LagraxError, ValueError):
    """An option has a value lagrax cannot use (`t1 <= t0`, an unknown method name,
    `dt` together with `stepsize_controller`, ...): the message names the option, the
    value and the fix."""


class ArgumentTypeError(ConfigurationError, TypeError):
    """An argument is the wrong kind of object (an energy function where a system goes,
    a solver that is neither a method name nor a diffrax solver, ...)."""


class MissingFileError(LagraxError, FileNotFoundError):
    """A file or directory lagrax was asked to read is not there (an MJCF file, a saved
    sweep, a sweep store). The message names the path."""


class MissingDependencyError(LagraxError, ImportError):
    """An optional package a feature needs is not installed (meshcat for
    `lagrax.plot.show3d`). The message names the feature and the `pip install` command."""


class CheckpointError(LagraxError, ValueError):
    """A sweep's checkpoint directory or a saved sweep file cannot be used: it holds
    another sweep's results, was written in an older format, cannot be written, or is
    damaged or not a lagrax file. The message names the path, what is wrong and the fix."""


class CheckpointWarning(UserWarning):
    """A chunk file in a checkpoint directory cannot be trusted (unreadable, truncated,
    its checksum or fingerprint does not match, an older format): it is not loaded, and
    its members are computed again. The message names the file and the reason."""


class URDFError(LagraxError, ValueError):
    """A URDF model cannot be read into a tree: malformed XML, a missing or unphysical
    `<inertial>`, a link with two parents or a loop, an unknown or unsupported joint
    type. The message names the link or joint and says what to fix."""


class MJCFError(LagraxError, ValueError):
    """An MJCF model (or another file MuJoCo reads) cannot be made a tree: MuJoCo refuses
    the file, or it holds a construct lagrax does not model (a free or ball joint, a
    tendon, an equality constraint, armature, a joint spring, friction loss, gravity
    compensation, fluid forces). The message names the construct, its name and value,
    and what to do."""


class URDFWarning(UserWarning):
    """A URDF model was loaded, but something in it is doubtful: an `<inertia>` whose
    principal moments violate the triangle inequality `I1 + I2 ≥ I3` (no rigid body has
    them; the dynamics stay defined). The message names the link and the amount;
    `from_urdf(..., strict_inertia=True)` refuses such a file instead."""


class PeriodicOrbitError(LagraxError, ValueError):
    """A periodic-orbit search cannot start: the motion from the guess never reaches the
    Poincaré section (within `t_max`), the section or the period is not usable, or an
    option is invalid. The message names the section, the values seen and what to do.
    (A Newton iteration that does not converge is reported in `PeriodicOrbit.result`.)"""
