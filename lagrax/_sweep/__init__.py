"""Many trajectories: `sweep` over parameter sets, with `grid` and `samples`.

One concept a module: `_grid` (the batch), `_chunk` (the compiled chunk), `_checkpoint`
(fingerprints, verified chunk files, the checkpoint directory), `_devices` (mesh,
transfers), `_defaults` (chunk size and lanes for the device), `_progress`,
`_dataset` (the xarray result), `_io` (files), `_unused` (swept parameters nothing
reads) and `_driver` (`sweep` itself).
"""

from .driver import sweep as sweep
from .grid import Grid as Grid
from .grid import grid as grid
from .grid import samples as samples
from .io import load_sweep as load_sweep
from .io import save_sweep as save_sweep
