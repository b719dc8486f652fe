"""Sweep results on disk: ``save_sweep`` and ``load_sweep``."""

import itertools
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from ._checkpoint import atomic_write


def save_sweep(ds: Any, path: str | os.PathLike) -> Path:
    """Save a sweep result: ``.nc`` (netCDF), ``.zarr`` or ``.npz``, by the file suffix.

    netCDF needs ``netCDF4``, ``h5netcdf`` or SciPy; zarr needs ``zarr``; ``.npz`` needs
    nothing beyond NumPy and is read back by :func:`load_sweep`. The file is written atomically.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        arrays = {f"var/{k}": np.asarray(v.values) for k, v in ds.data_vars.items()}
        arrays.update({f"coord/{k}": np.asarray(v.values) for k, v in ds.coords.items()})
        meta = dict(
            dims={
                k: list(v.dims) for k, v in itertools.chain(ds.data_vars.items(), ds.coords.items())
            },
            attrs=dict(ds.attrs),
        )
        arrays["meta"] = np.asarray(json.dumps(meta))
        atomic_write(path, lambda f: np.savez(f, **arrays))
    elif suffix in (".nc", ".nc4", ".netcdf"):
        ds.to_netcdf(path)
    elif suffix == ".zarr":
        ds.to_zarr(path, mode="w")
    else:
        raise ValueError(f"unknown format {suffix!r}: use .nc, .zarr or .npz")
    return path


def load_sweep(path: str | os.PathLike):
    """Read a sweep result written by :func:`save_sweep` (any of its formats)."""
    import xarray as xr

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            data = {k[4:]: (meta["dims"][k[4:]], z[k]) for k in z.files if k.startswith("var/")}
            coords = {k[6:]: (meta["dims"][k[6:]], z[k]) for k in z.files if k.startswith("coord/")}
        return xr.Dataset(data, coords=coords, attrs=meta["attrs"])
    if suffix == ".zarr":
        return xr.open_zarr(path).load()
    return xr.load_dataset(path)
