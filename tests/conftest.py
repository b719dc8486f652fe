"""Shared configuration and fixtures for the lagrax test suite.

64-bit mode is switched on before anything else imports JAX (lagrax does it too, but the
tests must not depend on that), and implicit rank promotion is an error so that a
broadcasting slip in the library (or in a test) fails loudly.
"""

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_rank_promotion", "raise")

import gc  # noqa: E402
import os  # noqa: E402

import pytest  # noqa: E402
from hypothesis import HealthCheck, settings  # noqa: E402

import lagrax  # noqa: E402
from lagrax._core import model_programs  # noqa: E402
from lagrax._solve import compiled  # noqa: E402

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


@pytest.fixture(scope="module", autouse=True)
def _release_programs_after_module():
    """After each test file, once its own fixtures are gone: release what it compiled,
    so that a worker's memory does not grow with every file it runs (programs of robots
    and models that no later file uses; 8-9.5 GB a worker before)."""
    yield
    release_compiled_programs()
