"""A zarr store as a sweep's output and its checkpoint: `SweepStore` and `open_sweep`.

`sweep(..., store="study.zarr")` writes each finished chunk into the store as it
completes and returns the result opened lazily (dask-backed), so memory is bounded by a
chunk, not by the sweep. The store is the checkpoint: it keeps every guarantee of the
`.npz` checkpoint directory (`checkpoint`), through the same fingerprint and checksum:

- the group's attrs hold `lagrax_store`: the format version, the sweep's fingerprint,
  its chunk size and member count, the sweep's dimensions and shape, the `dof` labels,
  and whether every chunk is done (`complete`); a store of another sweep (or chunk
  size) or of a newer format is refused with a `CheckpointError`;
- every variable of the Dataset but `status` is an array with one flat `"member"`
  dimension (zarr chunks of the sweep's chunk size along it, so a chunk's region is
  whole zarr chunks of its own: chunks never share a file), created with the full
  sweep's shape when the first chunk is written, then written region by region;
- a subgroup `lagrax/` holds, per chunk, its lane-step counters (`lane_steps`) and its
  done marker: the SHA-256 (`digest`, 32 bytes, zero while not done) of the chunk's
  identity (fingerprint, chunk size, index, member range) and of the arrays it wrote,
  written after them, so a chunk killed mid-write is not done;
- on resume a done chunk is read back and its digest checked: one that does not match
  (or cannot be read) is recomputed, with a `CheckpointWarning`; a path that cannot be
  written while work is left is refused before any chunk is computed.

`open_sweep` reads the store back as the Dataset `sweep` returns in memory (the grid's
dimensions from the flat member axis, `status` from `result`), lazily.
"""

import os
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from .._core.errors import CheckpointError, CheckpointWarning, MissingFileError
from .._core.results import messages
from .checkpoint import checksum, probe_writable
from .dataset import attrs_of, labels, statuses, variables
from .grid import Members
from .options import Kept
from .result import ChunkResult

# 1: flat member axis, per-chunk digest and lane steps in the `lagrax/` subgroup
STORE_VERSION = 1
STORE_KIND = "lagrax.sweep.store"
ATTR = "lagrax_store"
MEMBER = "member"


def _zarr():
    try:
        import zarr
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise CheckpointError(
            "store= needs the zarr package: pip install 'lagrax[zarr]' (or pip install zarr dask)"
        ) from err
    return zarr


class SweepStore:
    """A sweep's zarr store: its checks before any work (`prepare`), the chunks done
    (`done`), a finished chunk written (`write`) and the result opened (`finish`)."""

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        self._has_arrays = False
        self._done: set[int] = set()

    # ----------------------------------------------------------------- before any work

    def stored_chunk_size(self) -> int | None:
        """The chunk size the store was written with, or `None`."""
        meta = _meta_or_none(self.path)
        size = None if meta is None else meta.get("chunk_size")
        return size if isinstance(size, int) and size > 0 else None

    def prepare(
        self,
        fp: str,
        chunk_size: int,
        members: Members,
        n_chunks: int,
        dof: np.ndarray,
        q_dof: np.ndarray | None = None,
    ) -> set[int]:
        """Check the store before any work and find the chunks it holds that verify.

        - A path that is a file, a directory that is not a lagrax sweep store, a store of
          another sweep (by its fingerprint or chunk size) or of a newer format:
          `CheckpointError`.
        - A done chunk whose digest does not match what it holds, or that cannot be read:
          a `CheckpointWarning`, and it is computed again.
        - A path that cannot be written while a chunk is left to compute:
          `CheckpointError`.

        **Returns:** the indices of the chunks that are done and verified.
        """
        zarr = _zarr()
        path = self.path
        if path.exists() and not path.is_dir():
            raise CheckpointError(
                f"store={str(path)!r} is a file, not a zarr store (a directory); pass a "
                "directory path such as 'study.zarr' (it is created if missing)"
            )
        self.fp, self.chunk_size, self.n_chunks = fp, chunk_size, n_chunks
        self.members = members
        fresh = not path.exists() or not any(path.iterdir())
        if not fresh:
            meta = _meta(path)
            self._check_is_ours(meta, fp, chunk_size)
            group: Any = zarr.open_group(str(path), mode="r")
            self._has_arrays = "ok" in group.array_keys()
            self._done = self._verified(group)
        if len(self._done) < n_chunks:
            probe_writable(path, what="store")
        if fresh:
            group: Any = zarr.open_group(str(path), mode="w")
            shape = members.shape
            meta = dict(
                kind=STORE_KIND,
                version=STORE_VERSION,
                fingerprint=fp,
                chunk_size=chunk_size,
                n_members=members.size,
                n_chunks=n_chunks,
                dims=list(members.dims),
                shape=list(shape),
                dof=dof.tolist(),
                **({} if q_dof is None else {"q_dof": q_dof.tolist()}),
                complete=False,
            )
            group.attrs.update({ATTR: meta})
            sub = group.create_group("lagrax")
            sub.create_array(
                "digest",
                shape=(n_chunks, 32),
                chunks=(1, 32),
                dtype="uint8",
                fill_value=0,
                dimension_names=("chunk", "sha256"),
            )
            sub.create_array(
                "lane_steps",
                shape=(n_chunks, 2),
                chunks=(1, 2),
                dtype="int64",
                fill_value=0,
                dimension_names=("chunk", "busy_all"),
            )
        return set(self._done)

    def _check_is_ours(self, meta: Mapping[str, Any], fp: str, chunk_size: int) -> None:
        path = self.path
        if meta.get("version", 0) > STORE_VERSION:
            raise CheckpointError(
                f"the sweep store {path} was written in store format {meta.get('version')!r} "
                f"by a newer lagrax; this lagrax reads format {STORE_VERSION}. Update lagrax, "
                "or pass another store path."
            )
        if meta.get("version") != STORE_VERSION:
            raise CheckpointError(
                f"the sweep store {path} was written in store format {meta.get('version')!r}; "
                f"this lagrax reads format {STORE_VERSION}. Delete it to compute the sweep "
                "again, or pass another store path."
            )
        if meta.get("fingerprint") != fp or meta.get("chunk_size") != chunk_size:
            what = (
                f"chunk_size {meta.get('chunk_size')} there, {chunk_size} here"
                if meta.get("fingerprint") == fp
                else "model, parameters, initial states, solver settings or keep= differ"
            )
            raise CheckpointError(
                f"the sweep store {path} belongs to a different sweep definition ({what}: "
                f"its fingerprint is {str(meta.get('fingerprint'))[:12]}…, this sweep's "
                f"{fp[:12]}…); refusing to mix results. Use another store path, or delete "
                "this one to start over."
            )

    def _verified(self, group: Any) -> set[int]:
        """The chunks marked done whose digest matches what the store holds; a
        `CheckpointWarning` for each that does not."""
        try:
            digests = np.asarray(group["lagrax/digest"][:])
        except Exception as err:  # noqa: BLE001 - a damaged marker array: nothing is done
            _warn(
                f"the done markers of the sweep store {self.path} cannot be read "
                f"({type(err).__name__}: {err}); every chunk is computed again"
            )
            return set()
        done = set()
        for c in np.flatnonzero(digests.any(axis=1)):
            c = int(c)
            if c >= self.n_chunks:
                continue
            try:
                ok = bytes(digests[c]).hex() == self._digest_of(group, c)
                why = "its SHA-256 does not match what the store holds for it"
            except Exception as err:  # noqa: BLE001 - whatever the reader trips on, say so
                ok, why = False, f"it cannot be read ({type(err).__name__}: {err})"
            if ok:
                done.add(c)
            else:
                a, b = self._range(c)
                _warn(
                    f"chunk {c} (members {a}:{b}) of the sweep store {self.path} is not "
                    f"loaded: {why} (modified or damaged after it was written). Its members "
                    "are computed again."
                )
        return done

    # ----------------------------------------------------------------- chunks

    def _range(self, c: int) -> tuple[int, int]:
        return c * self.chunk_size, min((c + 1) * self.chunk_size, self.members.size)

    def _identity(self, c: int) -> dict[str, Any]:
        a, b = self._range(c)
        return dict(
            kind=STORE_KIND,
            version=STORE_VERSION,
            fingerprint=self.fp,
            chunk_size=self.chunk_size,
            chunk=c,
            start=a,
            stop=b,
        )

    def _digest_of(self, group: Any, c: int) -> str:
        """The SHA-256 of chunk `c` as the store holds it (its arrays' regions and
        lane-step counters, with its identity)."""
        a, b = self._range(c)
        names = dict(group.attrs)[ATTR]["variables"]
        arrays = {name: np.asarray(group[name][a:b]) for name in names}
        arrays["lagrax/lane_steps"] = np.asarray(group["lagrax/lane_steps"][c])
        return checksum(arrays, self._identity(c))

    def write(self, c: int, chunk: ChunkResult, kept: Kept) -> None:
        """Write chunk `c` into its region: its arrays, its lane-step counters, then its
        done marker (the digest of both)."""
        import xarray as xr

        zarr = _zarr()
        a, b = self._range(c)
        data = variables(chunk, kept, [MEMBER], lambda x: x, status=False)
        if not self._has_arrays:
            self._create_arrays(data, kept)
        region = xr.Dataset({k: (v[0], v[1]) for k, v in data.items()})
        region.to_zarr(str(self.path), region={MEMBER: slice(a, b)}, consolidated=False)
        group: Any = zarr.open_group(str(self.path), mode="r+")
        lanes = np.asarray([chunk.busy_lane_steps.sum(), chunk.lane_steps.sum()], np.int64)
        group["lagrax/lane_steps"][c] = lanes
        arrays = {k: np.asarray(v[1]) for k, v in data.items()}
        arrays["lagrax/lane_steps"] = lanes
        digest = bytes.fromhex(checksum(arrays, self._identity(c)))
        group["lagrax/digest"][c] = np.frombuffer(digest, np.uint8)
        self._done.add(c)

    def _create_arrays(self, data: Mapping[str, Any], kept: Kept) -> None:
        """Every variable with the full sweep's shape (no data written), and the
        coordinates but `dof` (its labels may be strings: they are in the attrs)."""
        import dask.array as da
        import xarray as xr

        zarr = _zarr()
        n, size = self.members.size, self.chunk_size
        template = {}
        for k, (dims, x, *rest) in data.items():
            full = da.zeros((n, *x.shape[1:]), dtype=x.dtype, chunks=(size, *x.shape[1:]))
            template[k] = (dims, full, *rest)
        attrs = dict(zarr.open_group(str(self.path), mode="r").attrs)
        # the variables a chunk writes (and its digest covers)
        attrs[ATTR] = {**attrs[ATTR], "variables": sorted(data)}  # type: ignore[dict-item]
        coords = labels(self.members, kept)
        ds = xr.Dataset(template, coords=coords, attrs=attrs)
        # uncompressed: trajectories of floats barely compress, and the chunks are
        # written while the cores solve the next ones (compression would take from them)
        encoding = {k: {"compressors": None} for k in template}
        ds.to_zarr(str(self.path), mode="a", compute=False, consolidated=False, encoding=encoding)
        self._has_arrays = True

    def finish(self, run: Mapping[str, Any]):
        """Mark the store complete, with the result's attrs (the failure counts, how
        it ran, the idle lane-steps), and open it lazily (`open_sweep`)."""
        zarr = _zarr()
        group: Any = zarr.open_group(str(self.path), mode="r+")
        result = np.asarray(group["result"][:])
        ok = np.asarray(group["ok"][:])
        lanes = np.asarray(group["lagrax/lane_steps"][:])
        stats = attrs_of(result, ok, lanes[:, 0], lanes[:, 1], self.members.size, run)
        meta = dict(group.attrs[ATTR])
        if meta.get("complete") is not True or any(
            group.attrs.get(k) != v for k, v in stats.items()
        ):
            meta["complete"] = True
            group.attrs.update({ATTR: meta, **stats})
        return open_sweep(self.path)


def _warn(message: str) -> None:
    # stacklevel: _warn < _verified < prepare < sweep < the user's call
    warnings.warn(message, CheckpointWarning, stacklevel=5)


def is_sweep_store(path: str | os.PathLike) -> bool:
    """Whether `path` is a zarr group that `sweep(..., store=path)` wrote (finished
    or not), not some other zarr store such as `save_sweep`'s."""
    return _meta_or_none(Path(path)) is not None


def _meta_or_none(path: Path) -> dict[str, Any] | None:
    try:
        return _meta(path)
    except CheckpointError:
        return None


def _meta(path: Path) -> dict[str, Any]:
    """The store's `lagrax_store` attrs, or a `CheckpointError` for a path that is not
    a lagrax sweep store."""
    zarr = _zarr()
    try:
        attrs = dict(zarr.open_group(str(path), mode="r").attrs)
    except Exception as err:  # noqa: BLE001 - not a zarr group, or damaged metadata
        raise CheckpointError(
            f"{path} is not a lagrax sweep store: it cannot be opened as a zarr group "
            f"({type(err).__name__}: {err}). Pass a new path or one a sweep wrote."
        ) from err
    meta = attrs.get(ATTR)
    if not isinstance(meta, dict) or meta.get("kind") != STORE_KIND:
        raise CheckpointError(
            f"{path} is a zarr store but not a lagrax sweep's (it has no {ATTR!r} attrs); "
            "refusing to write into it. Pass a new path or one a sweep wrote."
        )
    return meta


def open_sweep(path: str | os.PathLike):
    """Open a sweep's zarr store (written by `sweep(..., store=path)`) lazily: the
    Dataset `sweep` returns, its variables dask arrays read chunk by chunk on demand.
    A `.zarr` result that `save_sweep` wrote is opened lazily too.

    Reduce it with xarray as usual (`ds.q.mean("member").compute()`); only the chunks
    a computation needs are read.

    **Arguments:**

    - `path`: the store's path.

    **Returns:** the `xarray.Dataset`, dask-backed, with the same dimensions,
    coordinates, variables and attrs as the in-memory result of the same sweep.

    **Raises:** [`lagrax.MissingFileError`][] (a `FileNotFoundError`) for a missing path;
    `CheckpointError` for a path that is not a lagrax sweep store, one of a newer format, or
    one whose sweep has not finished (run the same `sweep` call again to resume it).

    **Example:**

    ```python
    ds = lagrax.open_sweep("study.zarr")
    ds.energy_error.max().compute()
    ```
    """
    import dask.array as da
    import xarray as xr

    path = Path(path)
    if not path.exists():
        raise MissingFileError(f"no sweep store at {path}")
    if path.is_dir() and not is_sweep_store(path) and _saved_result(path):
        return _open_saved(xr, path)
    meta = _meta(path)
    if meta.get("version", 0) > STORE_VERSION:
        raise CheckpointError(
            f"the sweep store {path} was written in store format {meta.get('version')!r} by "
            f"a newer lagrax; this lagrax reads format {STORE_VERSION}. Update lagrax."
        )
    if meta.get("complete") is not True:
        raise CheckpointError(
            f"the sweep store {path} is not complete: its sweep was interrupted before every "
            "chunk was written. Run the same sweep call with store= again to finish it "
            "(finished chunks are not recomputed)."
        )
    try:
        ds = xr.open_zarr(str(path), consolidated=False)
    except Exception as err:  # noqa: BLE001 - every backend fails its own way
        raise CheckpointError(
            f"{path} cannot be read as a sweep store ({type(err).__name__}: {err})"
        ) from err
    ds.attrs.pop(ATTR, None)
    for k in ds.variables:
        ds[k].encoding = {}
    dims, shape = tuple(meta["dims"]), tuple(meta["shape"])
    # each member's status from its result code, lazily: a table of the codes' messages
    # (Python strings, shared: 8 bytes a member once computed)
    table = statuses(np.arange(len(messages()), dtype=np.int32)).astype(object)
    result = ds["result"]
    text = result.data.map_blocks(lambda r: table[r], dtype=object)
    ds["status"] = (result.dims, text)
    if dims != (MEMBER,):  # a grid: its dimensions from the flat member axis
        data = {}
        for k, v in ds.data_vars.items():
            rest = v.dims[1:]
            x = da.reshape(v.data, shape + v.shape[1:])
            data[k] = (dims + rest, x, v.attrs)
        coords = {k: c for k, c in ds.coords.items() if MEMBER not in c.dims}
        ds = xr.Dataset(data, coords=coords, attrs=ds.attrs)
    dof = np.asarray(meta["dof"])
    ds = ds.assign_coords(dof=dof)
    if "q_dof" in meta and "q_dof" in ds.dims:  # a floating base's q
        ds = ds.assign_coords(q_dof=np.asarray(meta["q_dof"]))
    return ds


def _saved_result(path: Path) -> bool:
    """Whether `path` is a zarr group holding a sweep result (`ok` and `result`), as
    `save_sweep` writes it."""
    zarr = _zarr()
    try:
        group = zarr.open_group(str(path), mode="r")
        return all(k in group for k in ("ok", "result"))
    except Exception:  # noqa: BLE001 - not a zarr group: `_meta` names the fault
        return False


def _open_saved(xr: Any, path: Path):
    """`save_sweep`'s `.zarr` result, opened lazily."""
    try:
        return xr.open_zarr(str(path), consolidated=False)
    except Exception as err:  # noqa: BLE001 - every backend fails its own way
        raise CheckpointError(
            f"{path} cannot be read as a sweep result ({type(err).__name__}: {err})"
        ) from err
