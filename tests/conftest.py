"""Shared configuration and fixtures for the lagrax test suite.

64-bit mode is switched on before anything else imports JAX (lagrax does it too, but the
tests must not depend on that), and implicit rank promotion is an error so that a
broadcasting slip in the library (or in a test) fails loudly.
"""

import os

# The suite's programs mostly run once (an oracle, a check at a few states), so the time
# goes to compiling them, not to running them. For the suite:
# - LLVM's backend optimizations are off: about a fifth of its CPU time off (a quarter to
#   a third on the compile-bound files; measured file by file);
# - XLA:CPU's newer fusion emitters are off (its loop emitter instead): a fusion of many
#   small ops (the transposes of a second-order derivative: ~170 pads and adds) compiled
#   in 35 s with them, 5 s without; `test_contact.py` 90 → 69 CPU s, 2.1 → 1.4 GB.
# XLA's HLO optimizations and the programs are unchanged; the machine code may round
# differently, within the tests' tolerances. `LAGRAX_TEST_XLA_DEFAULTS=1` tests with
# XLA's defaults, as the benchmarks and the documentation build run. Set before JAX
# starts its backend; the notebooks' kernels inherit it.
if os.environ.get("LAGRAX_TEST_XLA_DEFAULTS", "") in ("", "0"):
    os.environ["XLA_FLAGS"] = " ".join(
        (
            os.environ.get("XLA_FLAGS", ""),
            "--xla_backend_optimization_level=0",
            "--xla_llvm_disable_expensive_passes=true",
            "--xla_cpu_use_fusion_emitters=false",
        )
    ).strip()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")

import ctypes  # noqa: E402
import ctypes.util  # noqa: E402
import gc  # noqa: E402

import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

import lagrax  # noqa: E402
from _helpers import GC_THRESHOLD  # noqa: E402  (tests/_helpers.py)
from lagrax._core import model_programs  # noqa: E402
from lagrax._solve import compiled  # noqa: E402

# the cyclic collector tuned for tracing (`_helpers.GC_THRESHOLD`); each test file ends
# with a full collection (`_release_programs_after_module`)
gc.freeze()
gc.set_threshold(*GC_THRESHOLD)

settings.register_profile(
    "lagrax",
    max_examples=30,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile(
    "thorough",
    max_examples=500,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "lagrax"))


@pytest.fixture(scope="session")
def arm():
    """``(system, params)`` of the default planar 2R arm (shared, so compiled code is reused)."""
    return lagrax.models.planar_2r()


@pytest.fixture(scope="session")
def arm_system(arm):
    return arm[0]


@pytest.fixture(scope="session")
def arm_params(arm):
    return arm[1]


@pytest.fixture(scope="session")
def msd():
    """``(system, params)`` of the default mass–spring–damper."""
    return lagrax.models.mass_spring_damper()


@pytest.fixture
def chunk_calls(monkeypatch):
    """The chunks a sweep computes (not loads from a checkpoint) from here on: a list
    that a spy on the sweep driver's `solve_chunk` appends to once per chunk."""
    from lagrax._sweep import driver

    calls = []
    real = driver.solve_chunk

    def counting(*a, **k):
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(driver, "solve_chunk", counting)
    return calls


def release_compiled_programs() -> None:
    """Drop every compiled program the process holds: lagrax's caches (the models'
    programs, `simulate`'s per-configuration programs and front cache, the sweep's
    read-parameters cache), then JAX's, then collect. The next use compiles again, or
    loads from the persistent compilation cache."""
    from lagrax._sweep import unused

    model_programs.clear()
    compiled.compiled.cache_clear()
    compiled._FRONT.clear()
    unused._cache.clear()
    jax.clear_caches()
    gc.collect()
    _return_freed_memory()


def _return_freed_memory() -> None:
    """Hand the heap's free pages back to the system (glibc's `malloc_trim`). The
    released programs' memory is free in the process but stays resident otherwise: a
    worker's resident size grew with every file it ran (0.6 GB instead of 1.4 GB after
    four compile-heavy files in one process). A no-op without glibc."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError):
        return
    trim(0)


# a worker past this resident size at the end of a test file releases its compiled programs
RELEASE_AFTER_FILE_ABOVE_BYTES = 5 * 1024**3 // 2
# a worker past this resident size releases its compiled programs after the test it is on
RELEASE_ABOVE_BYTES = 3 * 1024**3


@pytest.fixture(scope="module", autouse=True)
def _release_programs_after_module():
    """After a test file, once its own fixtures are gone, in a worker above 2.5 GB resident:
    release what it compiled, so that a worker's memory does not grow with every file it
    runs (programs of robots and models that no later file uses; 8-9.5 GB a worker
    before). Below that, the next file keeps the programs it shares (the 2R arm's
    solves, JAX's single-operation programs), instead of tracing and compiling them
    again."""
    yield
    if _resident_bytes() > RELEASE_AFTER_FILE_ABOVE_BYTES:
        release_compiled_programs()  # a full collection included
    else:
        gc.collect()


def _resident_bytes() -> int:
    """The process's resident size (Linux's `/proc/self/statm`; 0 elsewhere)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


@pytest.fixture(autouse=True)
def _release_programs_when_large():
    """After a test that leaves the worker above 3 GB resident: release the compiled
    programs then, not at the end of its file. A file that compiles many large programs
    (`test_derivatives.py`: eight systems' Jacobians, then Pinocchio's robots) grew one
    worker to 5.4 GB; what the next tests need again is compiled again, or read back from
    the persistent compilation cache."""
    yield
    if _resident_bytes() > RELEASE_ABOVE_BYTES:
        release_compiled_programs()
