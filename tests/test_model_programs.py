"""A model's compiled programs: reused while the model lives, freed when it is dropped.

The model is a particle in polar coordinates, `T = ½ m (ṙ² + r² θ̇²)` with `m` a NumPy
array the kinetic energy closes over: the closed forms are `M = diag(m, m r²)`, the
inverse dynamics `τ = (m r̈ − m r θ̇², m r² θ̈ + 2 m r ṙ θ̇)` and the forward dynamics
`q̈ = M⁻¹ (τ + (m r θ̇², −2 m r ṙ θ̇))`. The kinetic energy counts its traces, so a
second call that compiled again would show; and a weak reference to `m` tells whether
anything (a compiled program, a cache key) still holds the model once it is deleted.
"""

import gc
import weakref

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax._core import model_programs

R, THETA, RD, THETAD = 1.5, 0.3, 0.4, -0.7
RDD, THETADD = 0.2, 0.9


def _particle(mass: float):
    """`(system, m, traces)`: the polar particle of mass `m` (an array it closes over),
    and a list its kinetic energy appends to each time JAX traces it."""
    m = np.array(mass)
    traces: list[int] = []

    def kinetic(q, qd, p):
        traces.append(1)
        return 0.5 * m * (qd[0] ** 2 + q[0] ** 2 * qd[1] ** 2)

    return lx.LagrangianSystem(kinetic, n_dof=2, name="polar particle"), m, traces


def _inputs():
    q, qd, qdd = (jnp.array(x) for x in ((R, THETA), (RD, THETAD), (RDD, THETADD)))
    return q, qd, qdd


def test_eager_calls_match_closed_forms_and_compile_once():
    system, m, traces = _particle(2.0)
    q, qd, qdd = _inputs()
    m = float(m)
    tau_ref = np.array([m * RDD - m * R * THETAD**2, m * R**2 * THETADD + 2 * m * R * RD * THETAD])
    calls = {
        "M": (lambda: system.mass_matrix(q, {}), np.diag([m, m * R**2])),
        "ID": (lambda: system.inverse_dynamics(q, qd, qdd, {}), tau_ref),
        "FD": (lambda: system.forward_dynamics(q, qd, {}, jnp.asarray(tau_ref)), [RDD, THETADD]),
    }
    for name, (call, expected) in calls.items():
        np.testing.assert_allclose(call(), expected, rtol=1e-13, err_msg=name)
        traced = len(traces)
        assert traced > 0, name
        np.testing.assert_allclose(call(), expected, rtol=1e-13, err_msg=name)
        assert len(traces) == traced, f"{name}: a second call with the same model traced again"


def test_eager_derivatives_compile_once():
    system, _, traces = _particle(2.0)
    q, qd, _ = _inputs()
    first = system.forward_dynamics_derivatives(q, qd, {})
    traced = len(traces)
    second = system.forward_dynamics_derivatives(q + 0.1, qd, {})
    assert len(traces) == traced
    # ∂r̈/∂θ̇ = 2 r θ̇ (from r̈ = r θ̇²): the second state's value, not the first's
    np.testing.assert_allclose(second.dqd[0, 1], 2 * (R + 0.1) * THETAD, rtol=1e-13)
    np.testing.assert_allclose(first.dqd[0, 1], 2 * R * THETAD, rtol=1e-13)


@pytest.mark.parametrize(
    "use",
    [
        lambda s, q, qd, qdd: s.mass_matrix(q, {}),
        lambda s, q, qd, qdd: s.inverse_dynamics(q, qd, qdd, {}),
        lambda s, q, qd, qdd: s.forward_dynamics(q, qd, {}),
        lambda s, q, qd, qdd: s.forward_dynamics_derivatives(q, qd, {}),
        lambda s, q, qd, qdd: s.linearize(q, qd, {}),
        lambda s, q, qd, qdd: s.check_state(q, qd, {}),
    ],
    ids=[
        "mass_matrix",
        "inverse_dynamics",
        "forward_dynamics",
        "derivatives",
        "linearize",
        "check",
    ],
)
def test_a_deleted_model_is_collected_with_its_programs(use):
    system, m, _ = _particle(3.0)
    use(system, *_inputs())
    programs = list(model_programs._OWNED[id(system)][1].values())
    assert programs
    alive = [weakref.ref(system), weakref.ref(m), *map(weakref.ref, programs)]
    del system, m, programs
    gc.collect()
    assert [r() is None for r in alive] == [True] * len(alive)


def test_equal_models_do_not_share_or_keep_each_other():
    first, _, first_traces = _particle(2.0)
    second, _, second_traces = _particle(2.0)
    q, _, _ = _inputs()
    np.testing.assert_array_equal(first.mass_matrix(q, {}), second.mass_matrix(q, {}))
    assert first_traces and second_traces  # each compiled its own program
    ref = weakref.ref(first)
    del first
    gc.collect()
    assert ref() is None
    assert second.mass_matrix(q, {})[1, 1] == pytest.approx(2.0 * R**2, rel=1e-14)


def test_at_most_max_models_keep_programs(monkeypatch):
    monkeypatch.setattr(model_programs, "MAX_MODELS", 2)
    model_programs.clear()
    systems = [_particle(1.0 + k)[0] for k in range(3)]
    q, _, _ = _inputs()
    for s in systems:
        s.mass_matrix(q, {})
    assert list(model_programs._OWNED) == [id(s) for s in systems[1:]]
