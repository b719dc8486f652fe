"""JAX's persistent compilation cache, on by default in a user cache directory.

Compiling a solve costs seconds (3 s for the 7-DOF arm's first `simulate`), and every new
Python process, every notebook restart, pays it again. JAX can keep what XLA compiled on
disk and load it in the next process instead (`jax_compilation_cache_dir`); the entries
are keyed on the program, the JAX and XLA versions, the device and the compile options,
so a stale entry is never loaded. What remains of a first call is tracing, which no cache
saves.

`import lagrax` turns it on, unless:

- `LAGRAX_COMPILATION_CACHE=0` (or `false`, `no`, `off`) is set: off;
- `LAGRAX_COMPILATION_CACHE=/some/path` is set: that directory instead;
- you already set `jax_compilation_cache_dir` yourself (`JAX_COMPILATION_CACHE_DIR` or
  `jax.config.update`): yours is kept.

The default directory is `$XDG_CACHE_HOME/lagrax/jax` (`~/.cache/lagrax/jax`). Only
programs that took at least `MIN_COMPILE_SECONDS` to compile are written, so the
many small helper programs do not fill it. Delete the directory to clear it.
"""

import os
from pathlib import Path

import jax

MIN_COMPILE_SECONDS = 0.1
_OFF = ("0", "false", "no", "off")
_ON = ("", "1", "true", "yes", "on")


def default_directory() -> Path:
    """`$XDG_CACHE_HOME/lagrax/jax`, or `~/.cache/lagrax/jax`."""
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "lagrax" / "jax"


def configure() -> Path | None:
    """Turn the persistent cache on as the module docstring says; return its directory
    (`None` where lagrax left it off or the directory cannot be made)."""
    setting = os.environ.get("LAGRAX_COMPILATION_CACHE", "").strip()
    if setting.lower() in _OFF:
        return None
    if jax.config.jax_compilation_cache_dir:  # the user's own choice
        return Path(jax.config.jax_compilation_cache_dir)
    path = default_directory() if setting.lower() in _ON else Path(setting).expanduser()
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:  # a read-only home: run without the cache
        return None
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_SECONDS)
    return path
