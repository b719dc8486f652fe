"""Many trajectories: `sweep` over parameter sets, with `grid` and `samples`.

One concept a module:

- `driver`: `sweep` itself, in named steps;
- `options`: its own option checks (and `Kept`, what `keep=` asks for);
- `grid`: the batch (`Grid`, `grid`, `samples`) and `Members` (a sweep's parameters
  and initial states);
- `chunk`: the compiled chunk (`solve_chunk`: the solves on lanes or in lock-step, then
  the solve's post-processing from `lagrax._solve.postprocess`);
- `result`: `ChunkResult`, what a chunk gives, the unit of checkpoints and of the
  Dataset;
- `checkpoint`: fingerprints, verified chunk files, the checkpoint directory;
- `store`: a zarr store as the result and its checkpoint (`SweepStore`, `open_sweep`);
- `cluster`: chunks as tasks on a Dask cluster (`client=`);
- `dataset`: the `xarray.Dataset` from the chunks' results;
- `devices` (mesh, transfers), `defaults` (chunk size and lanes for the device),
  `progress`, `io` (`save_sweep`, `load_sweep`) and `unused` (swept parameters
  nothing reads).

A chunk's result flows `chunk.solve_chunk` → `ChunkResult` → `checkpoint.write_chunk`
(its `arrays()`, checksummed) and, on resume, `checkpoint.prepare` (`from_arrays`) →
`dataset.dataset` (`result.concatenate`, then the labelled variables).
"""

from .driver import sweep as sweep
from .grid import Grid as Grid
from .grid import grid as grid
from .grid import samples as samples
from .io import load_sweep as load_sweep
from .io import save_sweep as save_sweep
from .store import open_sweep as open_sweep
