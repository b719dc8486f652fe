"""The lean single-trajectory loop (``lagrax._solve.integrate``) against ``diffrax.diffeqsolve``,
forward-mode derivatives through ``adjoint=``, and the XLA:CPU flag set on import.

(Reverse mode through the lean loop: ``test_simulate.py``, against finite differences.)"""

import os
import subprocess
import sys

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import central_difference
from lagrax._core.linalg import lu_factor_small, lu_solve_small

Q0 = jnp.array([-np.pi / 2 + 1.4, 0.8])
QD0 = jnp.zeros(2)
DIFFRAX = dfx.RecursiveCheckpointAdjoint()  # any adjoint runs diffeqsolve itself


@pytest.fixture(scope="module")
def arm():
    return lx.models.planar_2r()


@pytest.mark.parametrize(
    "kw",
    [
        dict(solver="tsit5", rtol=1e-9, atol=1e-9),
        dict(solver="dopri8", rtol=1e-9, atol=1e-9),
        dict(solver="rk4", dt=0.01),
        dict(solver="variational", dt=0.01),
        dict(solver="kvaerno5", rtol=1e-6, atol=1e-6),
    ],
    ids=lambda kw: kw["solver"],
)
def test_lean_loop_takes_diffeqsolves_steps(arm, kw):
    system, params = arm
    lean = lx.simulate(system, Q0, QD0, params, t1=3.0, n_save=31, **kw)
    ref = lx.simulate(system, Q0, QD0, params, t1=3.0, n_save=31, adjoint=DIFFRAX, **kw)
    for key in ("num_steps", "num_accepted_steps", "num_rejected_steps"):
        assert int(lean.stats[key]) == int(ref.stats[key]), key
    # the same arithmetic in the same order: equal up to the last few bits
    np.testing.assert_allclose(lean.ts, ref.ts, rtol=0, atol=1e-15)
    np.testing.assert_allclose(lean.q, ref.q, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(lean.qd, ref.qd, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(lean.qd_end, ref.qd_end, rtol=1e-12, atol=1e-12)
    assert float(lean.t_end) == float(ref.t_end) == 3.0


def test_simulate_runs_the_lean_loop_unless_given_an_adjoint(monkeypatch):
    import lagrax._solve.integrate as integrate_module

    calls = []
    original = integrate_module.integrate
    monkeypatch.setattr(
        integrate_module, "integrate", lambda *a, **k: calls.append(1) or original(*a, **k)
    )
    # a system of its own, so nothing is reused from the compilation cache
    pendulum = lx.LagrangianSystem(
        kinetic=lambda q, qd, p: 0.5 * qd[0] ** 2, potential=lambda q, p: -jnp.cos(q[0])
    )
    lx.simulate(pendulum, [0.5], [0.0], {}, t1=1.0, n_save=3)
    assert len(calls) == 1
    lx.simulate(pendulum, [0.5], [0.0], {}, t1=1.0, n_save=3, adjoint=DIFFRAX)
    lx.simulate(pendulum, [0.5], [0.0], {}, t1=1.0, n_save=3, saveat=dfx.SaveAt(t1=True))
    assert len(calls) == 1


def test_lean_loop_failure_matches_diffeqsolve(arm):
    system, params = arm
    kw = dict(t1=5.0, n_save=11, max_steps=200, throw=False)
    lean = lx.simulate(system, Q0, QD0, params, **kw)
    ref = lx.simulate(system, Q0, QD0, params, adjoint=DIFFRAX, **kw)
    assert lean.result == ref.result == lx.RESULTS.max_steps_reached
    assert int(lean.stats["num_steps"]) == int(ref.stats["num_steps"]) == 200
    np.testing.assert_allclose(lean.t_end, ref.t_end, rtol=1e-13)
    np.testing.assert_allclose(lean.q_end, ref.q_end, rtol=1e-12)
    # saves past the failure are inf in both, never NaN
    reached = np.isfinite(np.asarray(ref.ts))
    np.testing.assert_array_equal(np.isfinite(np.asarray(lean.ts)), reached)
    assert np.all(np.isinf(np.asarray(lean.q)[~reached]))


def test_lean_loop_flags_a_blow_up(arm):
    system, params = arm
    stiff = lx.LagrangianSystem(
        kinetic=system.kinetic,
        potential=lambda q, p: system.potential(q, p) + 0.5e7 * q[1] ** 2,
        name="stiff arm",
    )
    sol = lx.simulate(stiff, Q0, QD0, params, t1=1.0, solver="rk4", dt=0.01, throw=False)
    assert sol.result == lx.RESULTS.non_finite_state
    assert float(sol.t_end) < 1.0  # stopped at the blow-up, not carried on to t1
    with pytest.raises(lx.SimulationError, match="blew up"):
        lx.simulate(stiff, Q0, QD0, params, t1=1.0, solver="rk4", dt=0.01)


def test_forward_mode_adjoint_gives_jacfwd(arm):
    system, params = arm

    def final(m2):
        p = dict(params, m2=m2)
        sol = lx.simulate(system, Q0, QD0, p, t1=1.0, n_save=2, adjoint=dfx.ForwardMode())
        return sol.q_end

    jac = jax.jacfwd(final)(jnp.asarray(params["m2"]))
    eps = 1e-6
    fd = central_difference(final, params["m2"], eps)
    np.testing.assert_allclose(jac, fd, rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 9])
def test_small_lu_solves_general_systems(n):
    rng = np.random.default_rng(n)
    solve = jax.jit(lambda a, b: lu_solve_small(lu_factor_small(a), b))
    for _ in range(10):
        a, b = rng.normal(size=(n, n)), rng.normal(size=n)
        np.testing.assert_allclose(solve(a, b), np.linalg.solve(a, b), rtol=1e-9, atol=1e-12)
    if n >= 2:  # a zero leading pivot needs the row exchange
        a = np.roll(np.eye(n), 1, axis=0) + 0.1 * rng.normal(size=(n, n))
        a[0, 0] = 0.0
        np.testing.assert_allclose(solve(a, b), np.linalg.solve(a, b), rtol=1e-9, atol=1e-12)


def _run(code, extra_env):
    env = {k: v for k, v in os.environ.items() if k not in ("XLA_FLAGS", "LAGRAX_XLA_FLAGS")}
    env.update(extra_env)
    out = subprocess.run(
        [sys.executable, "-W", "always", "-c", code],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    return out


SHOW = "import os, lagrax; print(os.environ.get('XLA_FLAGS', ''))"


def test_import_sets_the_small_loop_flag_unless_told_not_to():
    key = "xla_cpu_small_while_loop_byte_threshold"
    assert key in _run(SHOW, {}).stdout
    assert key not in _run(SHOW, {"LAGRAX_XLA_FLAGS": "0"}).stdout
    own = "--xla_backend_extra_options=xla_cpu_enable_fast_min_max=true"
    assert _run(SHOW, {"XLA_FLAGS": own}).stdout.strip() == own  # the user's flags win
    late = _run("import jax.numpy as jnp; jnp.ones(1); import lagrax", {})
    assert "imported after JAX had started" in late.stderr


@pytest.mark.parametrize("ts", [[0.0, 0.5, 0.2], [0.0, 0.5, 2.0], [-0.1, 0.5]])
def test_save_times_must_be_sorted_and_inside_the_interval(arm, ts):
    system, params = arm
    with pytest.raises(ValueError, match="ts must be non-decreasing and inside"):
        lx.simulate(system, Q0, QD0, params, t1=1.0, ts=ts)

    @jax.jit
    def traced(ts):
        return lx.simulate(system, Q0, QD0, params, t1=1.0, ts=ts, throw=False).q

    with pytest.raises(Exception, match="ts must be non-decreasing and inside"):
        jax.block_until_ready(traced(jnp.asarray(ts)))
