"""Sweep results on disk: `save_sweep` and `load_sweep`."""

import itertools
import json
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from .._core.errors import CheckpointError, ConfigurationError, MissingFileError
from .checkpoint import atomic_write, checksum


def save_sweep(ds: Any, path: str | os.PathLike) -> Path:
    """Save a sweep result: `.nc` (netCDF), `.zarr` or `.npz`, by the file suffix.

    netCDF needs `netCDF4`, `h5netcdf` or SciPy; zarr needs `zarr`; `.npz` needs
    nothing beyond NumPy and is read back by `load_sweep`; it carries a SHA-256
    checksum of its arrays, which `load_sweep` verifies. The file is written atomically.
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
            # per-variable attrs (units, long names) of the variables and coordinates
            var_attrs={
                k: dict(v.attrs)
                for k, v in itertools.chain(ds.data_vars.items(), ds.coords.items())
                if v.attrs
            },
        )
        meta["sha256"] = checksum(arrays, {})
        arrays["meta"] = np.asarray(json.dumps(meta))
        atomic_write(path, lambda f: np.savez(f, **arrays))
    elif suffix in (".nc", ".nc4", ".netcdf"):
        ds.to_netcdf(path)
    elif suffix == ".zarr":
        with warnings.catch_warnings():
            # the members' `status` strings: zarr 3 stores fixed-width Unicode before
            # the format specifies it, and says so; xarray (and lagrax) read it back
            warnings.filterwarnings("ignore", message=".*does not have a Zarr V3 specification")
            ds.to_zarr(path, mode="w", consolidated=False)
    else:
        raise ConfigurationError(f"unknown format {suffix!r}: use .nc, .zarr or .npz")
    return path


def load_sweep(path: str | os.PathLike):
    """Read a sweep result written by `save_sweep` (any of its formats) into memory.

    A `.zarr` store that `sweep(..., store=path)` wrote is read as `open_sweep` reads
    it (the same dimensions, labels and checks), then loaded; to keep a store larger
    than memory on disk and read only what a computation needs, use `open_sweep`.

    **Raises:** [`lagrax.MissingFileError`][] (a `FileNotFoundError`) for a missing file;
    `CheckpointError` (naming the path and what is wrong) for a file that is truncated,
    damaged, fails its checksum, or is not a sweep result, and for a sweep store that is
    not complete or of a newer format; `ConfigurationError` for an unknown suffix.
    """
    import xarray as xr

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".npz", ".zarr", ".nc", ".nc4", ".netcdf"):
        raise ConfigurationError(f"unknown format {suffix!r} of {path}: use .nc, .zarr or .npz")
    if not path.exists():
        raise MissingFileError(f"no sweep result at {path}")
    if suffix == ".npz":
        return _load_npz(xr, path)
    if suffix == ".zarr" and path.is_dir():
        from .store import is_sweep_store, open_sweep

        if is_sweep_store(path):
            return open_sweep(path).load()
    try:
        ds = (
            xr.open_zarr(path, consolidated=False).load()
            if suffix == ".zarr"
            else xr.load_dataset(path)
        )
    except Exception as err:  # noqa: BLE001 - every backend fails its own way
        raise CheckpointError(
            f"{path} cannot be read as a sweep result ({type(err).__name__}: {err}): the "
            "file is damaged, truncated or not a netCDF/zarr store"
        ) from err
    _is_sweep(ds, path)
    return ds


def _bad(path: Path, what: str) -> CheckpointError:
    return CheckpointError(
        f"{path} is not a usable sweep result: {what}. Save it again with lagrax.save_sweep "
        "(or run the sweep again)."
    )


def _load_npz(xr, path: Path):
    if path.stat().st_size == 0:
        raise _bad(path, "the file is empty (0 bytes)")
    try:
        # our own file handle: NumPy leaves its own open when the archive is damaged
        with open(path, "rb") as fh:
            z = np.load(fh, allow_pickle=False)
            if not isinstance(z, np.lib.npyio.NpzFile):
                raise _bad(path, "it is a bare .npy array, not the .npz archive save_sweep writes")
            with z:
                if "meta" not in z.files:
                    raise _bad(path, "it has no 'meta' entry, so save_sweep did not write it")
                arrays = {k: np.asarray(z[k]) for k in z.files}
    except CheckpointError:
        raise
    except Exception as err:  # noqa: BLE001
        raise _bad(
            path, f"it cannot be read ({type(err).__name__}: {err}); truncated or damaged"
        ) from err
    try:
        meta = json.loads(str(arrays.pop("meta")))
        dims, attrs = meta["dims"], meta["attrs"]
    except (ValueError, KeyError, TypeError) as err:
        raise _bad(path, f"its 'meta' entry is damaged ({type(err).__name__}: {err})") from err
    if "sha256" in meta and checksum(arrays, {}) != meta["sha256"]:
        raise _bad(path, "its SHA-256 checksum does not match its arrays (modified or damaged)")
    try:
        var_attrs = meta.get("var_attrs", {})

        def entry(k, v):
            return (dims[k], v, var_attrs.get(k, {}))

        data = {k[4:]: entry(k[4:], v) for k, v in arrays.items() if k.startswith("var/")}
        coords = {k[6:]: entry(k[6:], v) for k, v in arrays.items() if k.startswith("coord/")}
        ds = xr.Dataset(data, coords=coords, attrs=attrs)
    except Exception as err:  # noqa: BLE001
        raise _bad(
            path, f"its arrays do not fit its metadata ({type(err).__name__}: {err})"
        ) from err
    _is_sweep(ds, path)
    return ds


def _is_sweep(ds, path: Path) -> None:
    missing = [k for k in ("ok", "result") if k not in ds.data_vars]
    if missing:
        raise _bad(path, f"it has no {missing} variable(s), which every sweep result has")
