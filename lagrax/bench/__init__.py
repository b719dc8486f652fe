"""Accuracy–cost studies: work–precision diagrams and the stability atlas.

- [`work_precision`][lagrax.bench.work_precision] runs methods over ladders of tolerances/steps
  against a reference solution; [`write_csv`][lagrax.bench.write_csv] and
  [`plot_work_precision`][lagrax.bench.plot_work_precision] report it.
- `stability` cases: [`long_horizon`][lagrax.bench.long_horizon], [`stiff`][lagrax.bench.stiff],
  [`chaos`][lagrax.bench.chaos], [`singular`][lagrax.bench.singular], collected by `lagrax bench
  stability`.
"""

from .precision import DEFAULT_LADDERS as DEFAULT_LADDERS
from .precision import WorkPrecisionPoint as WorkPrecisionPoint
from .precision import plot_work_precision as plot_work_precision
from .precision import reference_solution as reference_solution
from .precision import work_precision as work_precision
from .precision import write_csv as write_csv
from .stability import AtlasRow as AtlasRow
from .stability import chaos as chaos
from .stability import long_horizon as long_horizon
from .stability import plot_chaos as plot_chaos
from .stability import plot_long_horizon as plot_long_horizon
from .stability import singular as singular
from .stability import spherical_pendulum as spherical_pendulum
from .stability import stiff as stiff
from .stability import stiff_arm as stiff_arm
from .stability import write_table as write_table

__all__ = [
    "work_precision",
    "reference_solution",
    "WorkPrecisionPoint",
    "DEFAULT_LADDERS",
    "write_csv",
    "plot_work_precision",
    "long_horizon",
    "stiff",
    "stiff_arm",
    "chaos",
    "singular",
    "spherical_pendulum",
    "AtlasRow",
    "write_table",
    "plot_long_horizon",
    "plot_chaos",
]
