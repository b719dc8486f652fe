"""Optional baselines of the benchmarks: checked up front, skipped with a one-line note.

A benchmark calls ``available(module, what)`` before any timing; when the module cannot
be imported it prints one line naming the baseline it skips and the extra that installs
it, so a long run never dies half-way on a missing package.
"""

import importlib
import importlib.util
import os

EXTRA = 'pip install -e ".[bench]"'


def available(module: str, what: str) -> bool:
    """Whether ``module`` imports; if not, print ``note: <what> skipped ...`` and say no."""
    try:
        importlib.import_module(module)
    except ImportError:
        print(f"note: {what} skipped: {module} is not installed ({EXTRA})", flush=True)
        return False
    return True


def asset(package: str, *parts: str) -> str:
    """A file shipped inside an installed package, found without importing it."""
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        raise FileNotFoundError(f"{package} is not installed ({EXTRA})")
    return os.path.join(spec.submodule_search_locations[0], *parts)
