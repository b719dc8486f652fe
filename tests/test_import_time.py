"""`import lagrax` loads only what a simulation needs; the rest loads on first use.

Each check runs `import lagrax` in a fresh interpreter (this process has imported
everything already) and reads that interpreter's `sys.modules`: an eager import of a heavy
package, or of a lazily loaded wing, added anywhere under `lagrax/__init__.py` fails here.
"""

import json
import subprocess
import sys

import pytest

import lagrax

# Third-party packages lagrax uses for one feature each (symbolic derivation, sweeps'
# stores, plots, MJCF checks, SciPy baselines, progress bars, file formats).
HEAVY = (
    "sympy",
    "xarray",
    "matplotlib",
    "dask",
    "zarr",
    "mujoco",
    "scipy",
    "tqdm",
    "pandas",
    "numba",
    "pinocchio",
    "trimesh",
    "lxml",
)
# lagrax's own modules that `lagrax.__getattr__` imports on first use.
DEFERRED = (
    "lagrax.bench",
    "lagrax.bodies",
    "lagrax.chains",
    "lagrax.models",
    "lagrax.plot",
    "lagrax.symbolic",
    "lagrax._periodic",
    "lagrax._sweep",
    "lagrax._symbolic",
    "lagrax._multibody",
)


def _loaded_after(code: str) -> set[str]:
    """Top names and lagrax modules in `sys.modules` of a fresh interpreter running `code`."""
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=120
    )
    names = json.loads(out.stdout.strip().splitlines()[-1])
    return set(names) | {name.split(".")[0] for name in names}


def test_import_lagrax_loads_no_heavy_package_nor_deferred_wing():
    loaded = _loaded_after("import lagrax")
    assert "lagrax._solve.simulate" in loaded  # the probe sees lagrax's own modules
    assert sorted(loaded & set(HEAVY)) == []
    assert sorted(loaded & set(DEFERRED)) == []


def test_a_deferred_name_loads_its_module_on_first_use():
    loaded = _loaded_after("import lagrax\nlagrax.sweep")
    assert "lagrax._sweep" in loaded
    assert "lagrax.symbolic" not in loaded  # only what was asked for
    assert "sympy" not in loaded


def test_every_public_name_resolves_to_its_defining_object():
    from lagrax import _periodic, _sweep, plot, symbolic

    for name in lagrax.__all__:
        assert getattr(lagrax, name) is not None, name
        assert name in dir(lagrax), name
    assert lagrax.sweep is _sweep.sweep
    assert lagrax.periodic_orbit is _periodic.periodic_orbit
    assert lagrax.plot is plot
    assert lagrax.symbolic is symbolic
    assert lagrax.simulate.__module__ == "lagrax._solve.simulate"


def test_unknown_attribute_raises_attribute_error():
    with pytest.raises(AttributeError, match="no_such_name"):
        lagrax.no_such_name  # noqa: B018
