"""Bad input to lagrax.sweep: every kind is a LagraxError whose message names the problem
and the value, raised on the host before anything is compiled or written."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx

SHARED = dict(t1=0.5)


@pytest.fixture(scope="module")
def oscillator():
    return lx.models.mass_spring_damper()


def batched(params, n=2, **changes):
    """Batched params: every leaf with a leading axis of ``n`` members."""
    out = {k: np.full(n, float(v)) for k, v in params.items()}
    out.update({k: np.asarray(v) for k, v in changes.items()})
    return out


# (id, sweep keyword arguments over SHARED, params maker, exception, substrings of message)
CASES = [
    ("chunk_size zero", dict(chunk_size=0), None, lx.ConfigurationError, ["chunk_size", "0"]),
    ("chunk_size negative", dict(chunk_size=-3), None, lx.ConfigurationError, ["-3"]),
    ("chunk_size fraction", dict(chunk_size=2.5), None, lx.ConfigurationError, ["2.5"]),
    ("chunk_size string", dict(chunk_size="8"), None, lx.ArgumentTypeError, ["'8'", "str"]),
    ("chunk_size bool", dict(chunk_size=True), None, lx.ArgumentTypeError, ["chunk_size"]),
    ("n_lanes zero", dict(n_lanes=0), None, lx.ConfigurationError, ["n_lanes", "0"]),
    (
        "n_lanes above chunk",
        dict(n_lanes=8, chunk_size=2),
        None,
        lx.ConfigurationError,
        ["n_lanes=8", "chunk_size=2"],
    ),
    ("t1 infinite", dict(t1=np.inf), None, lx.ConfigurationError, ["t1", "inf"]),
    ("t1 nan", dict(t1=np.nan), None, lx.ConfigurationError, ["t1", "nan"]),
    ("t1 before t0", dict(t1=-1.0), None, lx.ConfigurationError, ["t1", "-1.0"]),
    ("t0 nan", dict(t0=np.nan), None, lx.ConfigurationError, ["t0", "nan"]),
    ("t1 string", dict(t1="10"), None, lx.ArgumentTypeError, ["t1", "'10'"]),
    ("rtol negative", dict(rtol=-1e-6), None, lx.ConfigurationError, ["rtol", "-1e-06"]),
    ("atol nan", dict(atol=np.nan), None, lx.ConfigurationError, ["atol", "nan"]),
    ("rtol atol zero", dict(rtol=0.0, atol=0.0), None, lx.ConfigurationError, ["both 0"]),
    ("max_steps zero", dict(max_steps=0), None, lx.ConfigurationError, ["max_steps", "0"]),
    (
        "negative fixed step",
        dict(solver="rk4", dt=-0.01),
        None,
        lx.ConfigurationError,
        ["dt", "-0.01", "positive"],
    ),
    ("zero fixed step", dict(solver="rk4", dt=0.0), None, lx.ConfigurationError, ["dt=0.0"]),
    ("infinite step", dict(solver="rk4", dt=np.inf), None, lx.ConfigurationError, ["dt", "inf"]),
    ("negative dt0", dict(dt0=-0.1), None, lx.ConfigurationError, ["dt0", "-0.1"]),
    (
        "keep misspelt",
        dict(keep="finale"),
        None,
        lx.ConfigurationError,
        ["'finale'", "did you mean 'final'"],
    ),
    ("keep nan time", dict(keep=[0.0, np.nan]), None, lx.ConfigurationError, ["keep", "nan"]),
    ("keep words", dict(keep=["q", "qd"]), None, lx.ArgumentTypeError, ["keep", "'q'"]),
    ("keep time outside", dict(keep=[0.0, 2.0]), None, lx.ConfigurationError, ["keep", "2."]),
    ("n_save zero", dict(keep="trajectory", n_save=0), None, lx.ConfigurationError, ["n_save"]),
    ("schedule unknown", dict(schedule="fast"), None, lx.ConfigurationError, ["'fast'"]),
    ("devices zero", dict(devices=0), None, lx.ConfigurationError, ["devices=0"]),
    ("devices too many", dict(devices=10_000), None, lx.ConfigurationError, ["devices=10000"]),
    ("devices string", dict(devices="gpu"), None, lx.ArgumentTypeError, ["'gpu'"]),
    ("checkpoint number", dict(checkpoint=123), None, lx.ArgumentTypeError, ["checkpoint", "123"]),
    (
        "controller string",
        dict(stepsize_controller="pid"),
        None,
        lx.ArgumentTypeError,
        ["stepsize_controller", "'pid'"],
    ),
    ("progress string", dict(progress="yes"), None, lx.ArgumentTypeError, ["progress", "'yes'"]),
    (
        "empty batch",
        {},
        lambda p: batched(p, n=0),
        lx.ShapeError,
        ["0 members"],
    ),
    (
        "batch axes disagree",
        {},
        lambda p: batched(p, k=[1.0, 2.0, 3.0]),
        lx.ShapeError,
        ["different batch sizes", "['k']", "3"],
    ),
    ("no leaves", {}, lambda p: {}, lx.ShapeError, ["no array leaves"]),
    (
        "string leaf",
        {},
        lambda p: batched(p, k=np.array(["a", "b"])),
        lx.ArgumentTypeError,
        ["params['k']", "numeric"],
    ),
    (
        "grid over a misspelt name",
        {},
        lambda p: lx.grid(p, kk=[1.0, 2.0]),
        lx.ConfigurationError,
        ["kk", "reads", "k,", "allow_unused"],
    ),
    (
        "samples over an unread name",
        {},
        lambda p: lx.samples(p, mass=[1.0, 2.0], k=[1.0, 2.0]),
        lx.ConfigurationError,
        ["mass", "allow_unused"],
    ),
    (
        "batch varies an unread leaf",
        {},
        lambda p: batched(p, zeta=[0.1, 0.2]),
        lx.ConfigurationError,
        ["params['zeta']"],
    ),
]


@pytest.mark.parametrize(
    "kwargs, make, exc, words", [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_bad_sweep_input(oscillator, kwargs, make, exc, words):
    system, params = oscillator
    batch = make(params) if make is not None else lx.samples(params, k=[1.0, 2.0])
    with pytest.raises(exc) as info:
        lx.sweep(system, [1.0], [0.0], batch, **{**SHARED, **kwargs})
    assert isinstance(info.value, lx.LagraxError)
    message = str(info.value)
    for word in words:
        assert word in message, (word, message)


def test_options_are_checked_before_anything_is_computed(oscillator, monkeypatch, tmp_path):
    """A bad option costs no compilation and writes nothing to a checkpoint directory."""
    from lagrax._sweep import driver as _driver

    def never(*a, **k):
        raise AssertionError("a chunk was computed")

    monkeypatch.setattr(_driver, "solve_chunk", never)
    system, params = oscillator
    ckpt = tmp_path / "ckpt"
    with pytest.raises(lx.ConfigurationError):
        lx.sweep(
            system, [1.0], [0.0], lx.samples(params, k=[1.0, 2.0]), t1=0.5, dt=-0.1,
            solver="rk4", checkpoint=ckpt,
        )  # fmt: skip
    assert not ckpt.exists()


def test_allow_unused_sweeps_a_label(oscillator):
    system, params = oscillator
    ds = lx.sweep(
        system, [1.0], [0.0], lx.samples(params, trial=[0.0, 1.0]), t1=0.5, allow_unused=True
    )
    assert bool(ds.ok.all())
    np.testing.assert_array_equal(ds.q.values[0], ds.q.values[1])


def test_parameters_read_by_force_or_a_branch_count_as_read(oscillator):
    """Structural detection: a parameter read only by the force, or only inside one
    branch of ``lax.cond`` / ``jnp.where``, is read, whichever branch member 0 takes."""
    system, params = oscillator
    ds = lx.sweep(system, [1.0], [0.0], lx.samples(params, omega=[1.0, 2.0], f0=[0.5, 0.5]), t1=0.5)
    assert bool(ds.ok.all())

    def T(q, qd, p):
        m = jax.lax.cond(p["heavy"] > 0, lambda: p["m_heavy"], lambda: p["m_light"])
        return 0.5 * m * qd[0] ** 2

    def V(q, p):
        return 0.5 * jnp.where(q[0] > 10.0, p["k_far"], p["k"]) * q[0] ** 2

    branchy = lx.LagrangianSystem(T, V)
    base = dict(heavy=0.0, m_heavy=2.0, m_light=1.0, k=1.0, k_far=5.0)
    ds = lx.sweep(branchy, [1.0], [0.0], lx.grid(base, m_heavy=[2.0, 3.0], k_far=[4.0]), t1=0.5)
    assert bool(ds.ok.all())
