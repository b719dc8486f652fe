"""lagrax: equations of motion of mechanical systems from their energies, with JAX.

Write a kinetic energy `T(q, qd, params)` and a potential `V(q, params)`; lagrax forms
`M(q) q̈ + C(q, q̇) q̇ + G(q) = τ` by automatic differentiation and integrates it with
diffrax.

lagrax enables JAX's 64-bit mode on import (`jax_enable_x64`): float64 is the default
for accuracy. Arrays you pass in float32 stay float32. It also lets XLA:CPU compile small
solver loops into single kernels (an `XLA_FLAGS` entry, added only if JAX has not
started yet and you have not set `xla_backend_extra_options`; `LAGRAX_XLA_FLAGS=0`
opts out): see `lagrax/_core/xla_flags.py`. And it keeps what XLA compiles on disk, so
that a new process (a notebook restart) loads instead of recompiling: JAX's persistent
compilation cache in `~/.cache/lagrax/jax` (`LAGRAX_COMPILATION_CACHE=0` turns it off, a
path moves it): see `lagrax/_core/compilation_cache.py`.

`import lagrax` loads the systems and `simulate`; the sweeps, periodic orbits and the
submodules (`lagrax.symbolic`, `lagrax.plot`, `lagrax.chains`, ...) load on first use.
"""

import importlib
import importlib.metadata
from typing import TYPE_CHECKING, Any

from ._core import xla_flags as _xla_flags

_xla_flags.configure()  # before JAX starts its backend: see lagrax/_core/xla_flags.py

import jax as _jax  # noqa: E402

_jax.config.update("jax_enable_x64", True)

from ._core import compilation_cache as _compilation_cache  # noqa: E402

_compilation_cache.configure()  # compiled programs kept on disk: see its docstring

from . import integrators as integrators  # noqa: E402
from ._core.errors import ArgumentTypeError as ArgumentTypeError  # noqa: E402
from ._core.errors import CheckpointError as CheckpointError  # noqa: E402
from ._core.errors import CheckpointWarning as CheckpointWarning  # noqa: E402
from ._core.errors import ConfigurationError as ConfigurationError  # noqa: E402
from ._core.errors import ConstraintError as ConstraintError  # noqa: E402
from ._core.errors import ContactError as ContactError  # noqa: E402
from ._core.errors import LagraxError as LagraxError  # noqa: E402
from ._core.errors import MassMatrixError as MassMatrixError  # noqa: E402
from ._core.errors import MissingDependencyError as MissingDependencyError  # noqa: E402
from ._core.errors import MissingFileError as MissingFileError  # noqa: E402
from ._core.errors import MJCFError as MJCFError  # noqa: E402
from ._core.errors import NonFiniteError as NonFiniteError  # noqa: E402
from ._core.errors import ParameterError as ParameterError  # noqa: E402
from ._core.errors import PeriodicOrbitError as PeriodicOrbitError  # noqa: E402
from ._core.errors import ShapeError as ShapeError  # noqa: E402
from ._core.errors import SimulationError as SimulationError  # noqa: E402
from ._core.errors import URDFError as URDFError  # noqa: E402
from ._core.errors import URDFWarning as URDFWarning  # noqa: E402
from ._core.results import RESULTS as RESULTS  # noqa: E402
from ._solve.events import Event as Event  # noqa: E402
from ._solve.methods import METHODS as METHODS  # noqa: E402
from ._solve.simulate import simulate as simulate  # noqa: E402
from ._solve.solution import EventRecord as EventRecord  # noqa: E402
from ._solve.solution import Solution as Solution  # noqa: E402
from ._systems.abstract import AbstractSystem as AbstractSystem  # noqa: E402
from ._systems.constrained import ConstrainedSystem as ConstrainedSystem  # noqa: E402
from ._systems.lagrangian import LagrangianSystem as LagrangianSystem  # noqa: E402
from ._systems.sensitivity import ForwardDynamicsDerivatives as ForwardDynamicsDerivatives  # noqa: E402
from ._systems.sensitivity import InverseDynamicsDerivatives as InverseDynamicsDerivatives  # noqa: E402

if TYPE_CHECKING:  # imported on first use at run time: see `__getattr__` below
    from . import bench as bench
    from . import bodies as bodies
    from . import chains as chains
    from . import contact as contact
    from . import models as models
    from . import newton_euler as newton_euler
    from . import plot as plot
    from . import rigid_body as rigid_body
    from . import symbolic as symbolic
    from ._periodic import Bifurcation as Bifurcation
    from ._periodic import OrbitBranch as OrbitBranch
    from ._periodic import PeriodicOrbit as PeriodicOrbit
    from ._periodic import continue_orbits as continue_orbits
    from ._periodic import orbit_map as orbit_map
    from ._periodic import periodic_orbit as periodic_orbit
    from ._sweep import Grid as Grid
    from ._sweep import grid as grid
    from ._sweep import load_sweep as load_sweep
    from ._sweep import open_sweep as open_sweep
    from ._sweep import samples as samples
    from ._sweep import save_sweep as save_sweep
    from ._sweep import sweep as sweep

# Public names whose modules load on first use, so that `import lagrax` costs little
# more than `import jax, diffrax, equinox` (tests/test_import_time.py): name -> (module,
# attribute), attribute None for a public submodule.
_SUBMODULES = (
    "bench",
    "bodies",
    "chains",
    "contact",
    "models",
    "newton_euler",
    "plot",
    "rigid_body",
    "symbolic",
)
_PERIODIC = (
    "Bifurcation",
    "OrbitBranch",
    "PeriodicOrbit",
    "continue_orbits",
    "orbit_map",
    "periodic_orbit",
)
_SWEEP = ("Grid", "grid", "load_sweep", "open_sweep", "samples", "save_sweep", "sweep")
_LAZY: dict[str, tuple[str, str | None]] = {
    **{name: (f".{name}", None) for name in _SUBMODULES},
    **{name: ("._periodic", name) for name in _PERIODIC},
    **{name: ("._sweep", name) for name in _SWEEP},
}


def __getattr__(name: str) -> Any:
    """Import a public name of `_LAZY` on first use and keep it in the package."""
    if name not in _LAZY:
        raise AttributeError(f"module 'lagrax' has no attribute {name!r}")
    module_name, attribute = _LAZY[name]
    module = importlib.import_module(module_name, __name__)
    value = module if attribute is None else getattr(module, attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


try:
    __version__ = importlib.metadata.version("lagrax")
except importlib.metadata.PackageNotFoundError:  # pragma: no cover - source tree
    __version__ = "0.0.0"

__all__ = [
    "AbstractSystem",
    "LagrangianSystem",
    "ConstrainedSystem",
    "ForwardDynamicsDerivatives",
    "InverseDynamicsDerivatives",
    "rigid_body",
    "ConstraintError",
    "ContactError",
    "simulate",
    "Event",
    "EventRecord",
    "periodic_orbit",
    "PeriodicOrbit",
    "continue_orbits",
    "orbit_map",
    "OrbitBranch",
    "Bifurcation",
    "sweep",
    "grid",
    "samples",
    "Grid",
    "save_sweep",
    "load_sweep",
    "open_sweep",
    "METHODS",
    "integrators",
    "bench",
    "Solution",
    "RESULTS",
    "models",
    "bodies",
    "chains",
    "contact",
    "newton_euler",
    "plot",
    "symbolic",
    "LagraxError",
    "ArgumentTypeError",
    "CheckpointError",
    "CheckpointWarning",
    "ConfigurationError",
    "MassMatrixError",
    "NonFiniteError",
    "ParameterError",
    "PeriodicOrbitError",
    "ShapeError",
    "SimulationError",
    "URDFError",
    "MJCFError",
    "MissingFileError",
    "MissingDependencyError",
    "URDFWarning",
]
