"""Checkpoints of a sweep: fingerprints of its definition, atomic files, and chunk files
that carry their sweep's fingerprint and a checksum of their arrays.

A checkpoint directory holds `manifest.json` (the sweep's fingerprint, chunk size and
format version) and one `chunk_NNNNNN.npz` per finished chunk: its `ChunkResult` as
named arrays (`ChunkResult.arrays`: each field by its name, the final maxima and the
`keep=` reduction's outputs and the kept observables as `final_maxima/<name>`,
`reduced/<pytree path>` and `observed/<name>`).
Beside its arrays, each chunk file stores a JSON header `__lagrax__`: the format
version, the sweep fingerprint, the chunk size, the chunk's index and member range, and a
SHA-256 of the header's other fields and of every array (name, dtype, shape, bytes). On
resume a chunk is loaded only if its header parses, its checksum matches and it belongs
to this sweep at this index; any other chunk file is never loaded (see `prepare`).
"""

import hashlib
import json
import os
import re
import tempfile
import types
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import equinox as eqx
import jax.tree_util as jtu
import numpy as np

from .._core.errors import CheckpointError, CheckpointWarning
from .result import ChunkResult

# 2: chunk files carry the sweep fingerprint and a SHA-256 of their arrays;
# 3: and the energy balance and scale (energy_balance, energy_scale);
# 4: the arrays of a ChunkResult: final maxima and reduce outputs under "final_maxima/"
#    and "reduced/" (no "__reduce_paths__" entry)
FORMAT_VERSION = 4

CHUNK_KIND = "lagrax.sweep.chunk"
HEADER_KEY = "__lagrax__"
MANIFEST = "manifest.json"
_CHUNK_NAME = re.compile(r"chunk_(\d{6})\.npz")

_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def stable_repr(obj: Any) -> str:
    """`repr` without memory addresses (they change from one process to the next)."""
    return _ADDRESS.sub("", repr(obj))


def code_fingerprint(obj: Any, h: "hashlib._Hash") -> None:
    """Feed what identifies a function (name, bytecode, constants) into `h`."""
    h.update(repr(getattr(obj, "__qualname__", type(obj).__name__)).encode())
    code = obj if isinstance(obj, types.CodeType) else getattr(obj, "__code__", None)
    if code is None:
        h.update(stable_repr(obj).encode())
        return
    h.update(code.co_code)
    h.update(repr(code.co_names).encode())
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            code_fingerprint(const, h)
        else:
            h.update(stable_repr(const).encode())


def fingerprint(setup: Any, arrays: Sequence[Any], settings: Mapping[str, Any]) -> str:
    """A hash of everything that defines a sweep's results, stable across processes."""
    h = hashlib.sha256()
    h.update(str(FORMAT_VERSION).encode())
    for leaf in jtu.tree_leaves(setup, is_leaf=callable):
        if callable(leaf) and not eqx.is_array(leaf):
            code_fingerprint(leaf, h)
            for cell in getattr(leaf, "__closure__", None) or ():
                try:
                    val = cell.cell_contents
                except ValueError:
                    continue
                if callable(val):
                    code_fingerprint(val, h)
                elif eqx.is_array_like(val):
                    h.update(np.asarray(val).tobytes())
        elif eqx.is_array_like(leaf):
            h.update(np.asarray(leaf).tobytes())
        else:
            h.update(stable_repr(leaf).encode())
    h.update(stable_repr(eqx.tree_pformat(setup, short_arrays=False)).encode())
    for a in jtu.tree_leaves(arrays):
        a = np.ascontiguousarray(np.asarray(a))
        h.update(str((a.shape, a.dtype)).encode())
        h.update(a.tobytes())
    h.update(json.dumps(settings, sort_keys=True, default=stable_repr).encode())
    return h.hexdigest()


def atomic_write(path: Path, write: Callable[[Any], None]) -> None:
    """Write via a temporary file in the same directory, then rename (atomic on POSIX)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


# --------------------------------------------------------------------------- chunk files


def chunk_path(directory: Path, index: int) -> Path:
    return directory / f"chunk_{index:06d}.npz"


def checksum(arrays: Mapping[str, Any], header: Mapping[str, Any]) -> str:
    """SHA-256 of a header (without its `sha256` field) and of named arrays: every
    array's name, dtype, shape and bytes, in name order."""
    h = hashlib.sha256()
    fields = {k: v for k, v in header.items() if k != "sha256"}
    h.update(json.dumps(fields, sort_keys=True).encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(np.asarray(arrays[name]))
        h.update(json.dumps([name, a.dtype.str, list(a.shape)]).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def write_chunk(path: Path, result: ChunkResult, /, **identity: Any) -> None:
    """Write a chunk file atomically: the chunk's arrays (`ChunkResult.arrays`) and a
    header with `identity` (the sweep fingerprint, chunk size, index `chunk`, member
    range `start`, `stop`) and the checksum of both."""
    arrays = result.arrays()
    if HEADER_KEY in arrays:  # pragma: no cover - internal
        raise CheckpointError(f"{HEADER_KEY} is reserved for the chunk file's header")
    header = dict(kind=CHUNK_KIND, version=FORMAT_VERSION, **identity)
    header["sha256"] = checksum(arrays, header)
    payload = {**arrays, HEADER_KEY: np.asarray(json.dumps(header, sort_keys=True))}
    atomic_write(path, lambda f: np.savez(f, **payload))


class UntrustedChunk(CheckpointError):
    """A chunk file that must not be loaded; `str(err)` says why (`prepare` turns it
    into a `CheckpointWarning` and computes the chunk again)."""


def _header(z: Any) -> dict[str, Any]:
    if HEADER_KEY not in z.files:
        raise UntrustedChunk(
            "it has no lagrax header: written by lagrax before checkpoint format "
            f"{FORMAT_VERSION}, or not by lagrax, so it cannot be verified"
        )
    try:
        header = json.loads(str(z[HEADER_KEY]))
    except ValueError as err:
        raise UntrustedChunk(f"its header is not valid JSON ({err})") from err
    if not isinstance(header, dict) or header.get("kind") != CHUNK_KIND:
        raise UntrustedChunk("its header is not a lagrax sweep chunk's")
    if header.get("version") != FORMAT_VERSION:
        raise UntrustedChunk(
            f"it was written in checkpoint format {header.get('version')!r}; this lagrax "
            f"reads format {FORMAT_VERSION}"
        )
    return header


def read_header(path: Path) -> dict[str, Any] | None:
    """A chunk file's header without reading (or verifying) its arrays; `None` when it
    has none that can be read."""
    try:
        with open(path, "rb") as fh, np.load(fh, allow_pickle=False) as z:
            return _header(z)
    except Exception:  # noqa: BLE001 - any unreadable file simply has no header
        return None


def _unreadable(path: Path, err: BaseException) -> str:
    if path.is_file() and path.stat().st_size == 0:
        return "it is empty (0 bytes)"
    return f"it cannot be read ({type(err).__name__}: {err}): truncated or damaged"


def read_chunk(path: Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """`(header, arrays)` of a chunk file whose checksum matches, or `UntrustedChunk`
    saying why it cannot be loaded (unreadable, truncated, no header, bad checksum)."""
    try:
        # our own file handle: NumPy leaves its own open when the archive is damaged
        with open(path, "rb") as fh:
            z = np.load(fh, allow_pickle=False)
            if not isinstance(z, np.lib.npyio.NpzFile):
                raise UntrustedChunk("it is a bare .npy array, not a lagrax .npz chunk")
            with z:
                header = _header(z)
                arrays = {k: np.asarray(z[k]) for k in z.files if k != HEADER_KEY}
    except UntrustedChunk:
        raise
    except Exception as err:  # noqa: BLE001 - whatever the reader trips on, say so
        raise UntrustedChunk(_unreadable(path, err)) from err
    if checksum(arrays, header) != header.get("sha256"):
        raise UntrustedChunk(
            "its SHA-256 checksum does not match its contents (the file was modified or "
            "damaged after it was written)"
        )
    return header, arrays


def stored_chunk_size(directory: Path) -> int | None:
    """The chunk size a checkpoint directory was written with (from its manifest, else
    from the first chunk file with a readable header), or `None`."""
    try:
        size = json.loads((directory / MANIFEST).read_text()).get("chunk_size")
        if isinstance(size, int) and size > 0:
            return size
    except (OSError, ValueError, AttributeError):
        pass
    if not directory.is_dir():
        return None
    for path in sorted(directory.glob("chunk_*.npz")):
        header = read_header(path)
        if header is not None and isinstance(header.get("chunk_size"), int):
            return header["chunk_size"]
    return None


# --------------------------------------------------------------------------- the directory


def _warn(message: str) -> None:
    # stacklevel: _warn < prepare < sweep < the user's call
    warnings.warn(message, CheckpointWarning, stacklevel=4)


def probe_writable(directory: Path, what: str = "checkpoint") -> None:
    """Create and remove a file in `directory` (a checkpoint directory, or with
    `what="store"` a sweep's zarr store), or raise `CheckpointError`."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=directory, prefix=".lagrax-probe.", suffix=".tmp")
        os.close(fd)
        os.unlink(tmp)
    except OSError as err:
        kind = "checkpoint directory" if what == "checkpoint" else "sweep store"
        raise CheckpointError(
            f"the {kind} {directory} cannot be written ({type(err).__name__}: "
            f"{err.strerror or err}); a sweep with {what}= writes each finished chunk "
            f"there. Pass a writable path, fix its permissions, or drop {what}=."
        ) from err


def prepare(
    directory: Path, fp: str, chunk_size: int, n_members: int, n_chunks: int
) -> dict[int, ChunkResult]:
    """Check a checkpoint directory before any work and read the chunks it can trust.

    - A `manifest.json` of another sweep (or chunk size) or of another format: refused
      (`CheckpointError`). An unreadable manifest: a `CheckpointWarning`, then the
      chunk files decide.
    - Chunk files of another sweep (a valid checksum, another fingerprint or chunk size)
      with no manifest of this sweep: the directory is refused (`CheckpointError`). With
      this sweep's manifest they are strays: recomputed, with a warning.
    - A chunk file that cannot be read, is truncated or empty, has no header (older
      format) or whose checksum or index does not match: never loaded; a
      `CheckpointWarning` names it and the reason, and its chunk is computed again
      (the file is replaced when it is written).
    - A directory that cannot be written while something is left to write:
      `CheckpointError` (before any chunk is computed).

    **Returns:** chunk index → its `ChunkResult`, for the chunks that can be loaded.
    """
    if directory.exists() and not directory.is_dir():
        raise CheckpointError(
            f"checkpoint={str(directory)!r} is a file, not a directory; pass a directory "
            "path (it is created if missing)"
        )
    ours, notes = _manifest_is_ours(directory, fp, chunk_size)
    loaded, foreign, untrusted = _read_chunks(directory, fp, chunk_size, n_members, n_chunks)
    for message in notes + untrusted:
        _warn(message)
    if foreign and not ours:
        raise _foreign_directory(directory, foreign)
    for path, why in foreign:
        _warn(
            f"checkpoint chunk {path} is not loaded: it belongs to another sweep ({why}), "
            "although the directory's manifest is this sweep's. Its members are computed "
            "again."
        )
    if not ours or len(loaded) < n_chunks:
        probe_writable(directory)
    if not ours:
        info = dict(
            fingerprint=fp,
            chunk_size=chunk_size,
            n_members=n_members,
            n_chunks=n_chunks,
            version=FORMAT_VERSION,
        )
        atomic_write(directory / MANIFEST, lambda f: f.write(json.dumps(info, indent=1).encode()))
    return loaded


def _manifest_is_ours(directory: Path, fp: str, chunk_size: int) -> tuple[bool, list[str]]:
    """Whether the directory's `manifest.json` is this sweep's (`False`: there is none
    or it cannot be read, with a warning to give), or a `CheckpointError` for another
    sweep's or another format's."""
    manifest = directory / MANIFEST
    if not manifest.exists():
        return False, []
    try:
        old = json.loads(manifest.read_text())
        if not isinstance(old, dict):
            raise CheckpointError("not a JSON object")
    except (OSError, ValueError) as err:
        return False, [
            f"{manifest} cannot be read ({err}); it is ignored and rewritten, and each "
            "chunk file is checked on its own"
        ]
    if old.get("version") != FORMAT_VERSION:
        raise CheckpointError(
            f"the checkpoint at {directory} was written in checkpoint format "
            f"{old.get('version', 1)!r} (this lagrax reads and writes format "
            f"{FORMAT_VERSION}); its chunk files cannot be verified as this format's, so "
            "they are not reused. Delete the directory to compute the sweep again, or pass "
            "another checkpoint directory."
        )
    if old.get("fingerprint") != fp or old.get("chunk_size") != chunk_size:
        what = (
            f"chunk_size {old.get('chunk_size')} there, {chunk_size} here"
            if old.get("fingerprint") == fp
            else "model, parameters, initial states, solver settings or keep= differ"
        )
        raise CheckpointError(
            f"the checkpoint at {directory} belongs to a different sweep definition "
            f"({what}: its manifest has fingerprint {str(old.get('fingerprint'))[:12]}…, "
            f"this sweep {fp[:12]}…); refusing to mix results. Use another checkpoint "
            "directory, or delete this one to start over."
        )
    return True, []


def _read_chunks(directory: Path, fp: str, chunk_size: int, n_members: int, n_chunks: int):
    """`(loaded, foreign, untrusted)`: the chunk files of this sweep that can be
    trusted (index → `ChunkResult`), those of another sweep (`(path, why)`), and a
    warning for each that cannot be trusted (unreadable, bad checksum, wrong index)."""
    loaded: dict[int, ChunkResult] = {}
    foreign: list[tuple[Path, str]] = []
    untrusted: list[str] = []
    files = sorted(directory.glob("chunk_*.npz")) if directory.is_dir() else []
    for path in files:
        m = _CHUNK_NAME.fullmatch(path.name)
        if m is None:
            continue  # not a name this sweep writes: left alone
        index = int(m.group(1))
        try:
            header, arrays = read_chunk(path)
            chunk = _chunk_of(arrays)
        except UntrustedChunk as err:
            untrusted.append(
                f"checkpoint chunk {path} is not loaded: {err}. Its members are computed again."
            )
            continue
        a, b = index * chunk_size, min((index + 1) * chunk_size, n_members)
        if header.get("fingerprint") != fp or header.get("chunk_size") != chunk_size:
            why = (
                f"chunk_size {header.get('chunk_size')} (this sweep: {chunk_size})"
                if header.get("fingerprint") == fp
                else f"sweep fingerprint {str(header.get('fingerprint'))[:12]}… (this "
                f"sweep: {fp[:12]}…)"
            )
            foreign.append((path, why))
            continue
        if (header.get("chunk"), header.get("start"), header.get("stop")) != (index, a, b) or (
            index >= n_chunks
        ):
            untrusted.append(
                f"checkpoint chunk {path} is not loaded: it holds chunk {header.get('chunk')} "
                f"(members {header.get('start')}:{header.get('stop')}), not chunk {index} "
                f"(members {a}:{b}) of this sweep. Its members are computed again."
            )
            continue
        loaded[index] = chunk
    return loaded, foreign, untrusted


def _chunk_of(arrays: Mapping[str, np.ndarray]) -> ChunkResult:
    """The `ChunkResult` of a verified chunk file's arrays, or `UntrustedChunk`."""
    try:
        return ChunkResult.from_arrays(arrays)
    except (TypeError, KeyError) as err:
        raise UntrustedChunk(
            f"its arrays are not a sweep chunk's ({type(err).__name__}: {err})"
        ) from err


def _foreign_directory(directory: Path, foreign: list[tuple[Path, str]]) -> CheckpointError:
    """The refusal of a directory that holds another sweep's chunk files."""
    by_reason: dict[str, list[str]] = {}
    for path, why in foreign:
        by_reason.setdefault(why, []).append(path.name)
    listing = "; ".join(
        f"{', '.join(names[:3])}{f' and {len(names) - 3} more' if len(names) > 3 else ''}: {why}"
        for why, names in by_reason.items()
    )
    return CheckpointError(
        f"the checkpoint directory {directory} holds chunk files of a different sweep "
        f"({listing}). The fingerprint hashes what defines a sweep's results (model, "
        "parameters, initial states, solver settings, keep=); a mismatch means those "
        "files are another sweep's results, and reusing them would be wrong. Use "
        "another checkpoint directory, or delete this one to start over."
    )
