"""Checkpoints of a sweep: fingerprints of its definition and atomic files."""

import hashlib
import json
import os
import re
import tempfile
import types
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import equinox as eqx
import jax.tree_util as jtu
import numpy as np

FORMAT_VERSION = 1

_ADDRESS = re.compile(r" at 0x[0-9a-fA-F]+")


def stable_repr(obj: Any) -> str:
    """``repr`` without memory addresses (they change from one process to the next)."""
    return _ADDRESS.sub("", repr(obj))


def code_fingerprint(obj: Any, h: "hashlib._Hash") -> None:
    """Feed what identifies a function (name, bytecode, constants) into ``h``."""
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
