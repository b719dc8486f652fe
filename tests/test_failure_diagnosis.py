"""A failed solve is reported with its cause and where it happened, never as silent NaN."""

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx


def _degenerate_T(q, qd, p):  # M(q) = q0², singular at q0 = 0
    return 0.5 * q[0] ** 2 * qd[0] ** 2


def _spring_V(q, p):
    return 0.5 * p["k"] * q[0] ** 2


def test_mass_matrix_collapsing_during_the_solve_is_named():
    system = lx.LagrangianSystem(_degenerate_T, _spring_V, n_dof=1, name="degenerate")
    with pytest.raises(lx.SimulationError) as info:
        lx.simulate(system, [1.0], [0.0], {"k": 1.0}, t1=5.0, max_steps=2000)
    msg = str(info.value)
    assert "singular" in msg and "eigenvalues" in msg
    # the reported stopping time is where the coordinate reaches the singularity:
    # q̈ = -k/q - q̇²/q, energy ½ q² q̇² + ½ q² = ½  =>  q² = 1 - t² ... q → 0 at t = 1
    t_stop = float(msg.split("stopped at t=")[1].split()[0])
    assert abs(t_stop - 1.0) < 1e-3


def test_partial_solution_keeps_finished_part_and_marks_the_rest():
    system, params = lx.models.planar_2r()
    full = lx.simulate(system, [0.3, 0.2], [0.0, 0.0], params, t1=2.0, n_save=41)
    part = lx.simulate(
        system, [0.3, 0.2], [0.0, 0.0], params, t1=2.0, n_save=41, max_steps=30, throw=False
    )
    assert not bool(part.ok)
    reached = np.isfinite(np.asarray(part.ts))
    assert 0 < reached.sum() < 41
    assert not np.any(np.isnan(np.asarray(part.q)))  # unreached entries are inf, not NaN
    assert np.all(np.isinf(np.asarray(part.q)[~reached]))
    assert not np.any(np.isnan(np.asarray(part.energy)))
    assert np.all(np.isinf(np.asarray(part.energy)[~reached]))
    np.testing.assert_allclose(part.q[reached], full.q[reached], rtol=1e-6, atol=1e-8)
    assert 0.0 < float(part.t_end) < 2.0
    assert float(full.t_end) == 2.0
    # the save at t1 is the dense output at its step's end: the end state, to round-off
    np.testing.assert_allclose(full.q_end, full.q[-1], rtol=1e-15, atol=0)


def test_blow_up_reports_max_steps_and_remedies():
    def force(t, q, qd, p):
        return jnp.array([1.0 / (1.0 - t) ** 3])

    system = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd[0] ** 2, force=force, n_dof=1)
    with pytest.raises(lx.SimulationError, match="max_steps=500") as info:
        lx.simulate(system, [0.0], [0.0], {}, t1=2.0, max_steps=500)
    assert "solver='rodas4' or 'kvaerno5'" in str(info.value)
