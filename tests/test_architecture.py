"""The system interface and the defects the architecture change fixed.

Each defect test would have failed before the change: a constrained system that ignored
its system's ``scalar_derivatives``; a ``keep=`` reduction of a constrained sweep that got
a ``Solution`` without ``constraint_violation`` / ``multipliers``; ``check_state`` that
re-ran the energies eagerly on every call instead of one compiled call.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx


def _counting_pendulum(scalar_derivatives):
    """A Cartesian pendulum whose ``T`` counts how often it is called (traced or run)."""
    calls = []

    def kinetic(q, qd, p):
        calls.append(1)
        return 0.5 * p["m"] * jnp.sum(qd**2)

    free = lx.LagrangianSystem(
        kinetic,
        lambda q, p: p["m"] * p["g"] * q[1],
        n_dof=2,
        scalar_derivatives=scalar_derivatives,
    )
    rod = lambda q, p: jnp.stack([q @ q - p["l"] ** 2])  # noqa: E731
    return free, lx.ConstrainedSystem(free, rod), calls


PARAMS = {"m": 1.0, "g": 9.81, "l": 1.0}
Q = jnp.array([0.6, -0.8])
QD = jnp.array([0.8, 0.6])


@pytest.mark.parametrize("scalar", [True, False])
def test_constrained_system_differentiates_as_its_system_says(scalar):
    free, constrained, calls = _counting_pendulum(scalar)
    # warm up: the first trace of T also runs lagrax's one-off (cached) check of its
    # indexing, which would count once for whichever system comes first
    jax.make_jaxpr(lambda q, qd: free.accelerations(0.0, q, qd, PARAMS, None))(Q, QD)
    calls.clear()
    jax.make_jaxpr(lambda q, qd: free.accelerations(0.0, q, qd, PARAMS, None))(Q, QD)
    n_free = len(calls)
    calls.clear()
    jax.make_jaxpr(lambda q, qd: constrained.accelerations(0.0, q, qd, PARAMS, None))(Q, QD)
    # the same derivative path traces T the same number of times (the two paths differ:
    # see the next test)
    assert n_free > 0 and len(calls) == n_free


def test_scalar_and_vector_paths_trace_differently():
    counts = {}
    for scalar in (True, False):
        free, _, calls = _counting_pendulum(scalar)
        jax.make_jaxpr(lambda q, qd, f=free: f.accelerations(0.0, q, qd, PARAMS, None))(Q, QD)
        counts[scalar] = len(calls)
    assert counts[True] > counts[False]


def test_constrained_sweep_reduction_sees_violation_and_multipliers():
    system, params = lx.models.cartesian_pendulum()
    lengths = np.array([1.0, 1.5])
    q0 = np.array([[0.6, -0.8], [0.9, -1.2]])

    def reduce(sol):
        return {
            "violation": jnp.max(jnp.abs(sol.constraint_violation)),
            "lam_end": sol.multipliers[-1, 0],
        }

    kw = dict(t1=1.0, rtol=1e-10, atol=1e-10)
    ds = lx.sweep(
        system, q0, [0.0, 0.0], lx.samples(params, l=lengths), keep=reduce, n_save=11, **kw
    )
    for i, l in enumerate(lengths):
        sol = lx.simulate(system, q0[i], [0.0, 0.0], dict(params, l=l), n_save=11, **kw)
        np.testing.assert_allclose(ds.lam_end.values[i], sol.multipliers[-1, 0], rtol=1e-8)
        np.testing.assert_allclose(
            ds.violation.values[i], np.max(np.abs(sol.constraint_violation)), atol=1e-12
        )
        assert ds.violation.values[i] < 1e-9


def test_check_state_is_one_compiled_call():
    calls = []

    def kinetic(q, qd, p):
        calls.append(1)
        return 0.5 * p["m"] * jnp.sum(qd**2)

    system = lx.LagrangianSystem(kinetic, n_dof=2)
    system.check_state(jnp.array([0.1, 0.2]), jnp.array([0.3, 0.4]), {"m": 1.0})
    first = len(calls)
    assert first > 0
    # new values, same shapes: the compiled call is reused, T is not run again
    system.check_state(jnp.array([0.5, 0.6]), jnp.array([0.7, 0.8]), {"m": 2.0})
    assert len(calls) == first


def test_system_kinds_share_one_interface():
    system, params = lx.models.planar_2r()
    pendulum, _ = lx.models.cartesian_pendulum()
    pendulum_params = lx.models.cartesian_pendulum()[1]
    for kind, p, q in (
        (system, params, jnp.array([0.1, 0.2])),
        (pendulum, pendulum_params, jnp.array([0.6, -0.8])),
    ):
        # the energy-balance hooks every kind implements agree with each other
        qd = jnp.array([0.3, -0.2]) if kind is system else jnp.array([0.8, 0.6])
        h, magnitude = kind.energy_and_magnitude(0.0, q, qd, p)
        np.testing.assert_allclose(h, kind.jacobi_integral(0.0, q, qd, p), rtol=1e-12)
        np.testing.assert_allclose(h, kind.energy(q, qd, p), rtol=1e-12)
        assert magnitude >= abs(h)
        assert kind.explicit_power(0.0, q, qd, p) is None
        assert kind.input_power(0.0, q, qd, p, None) is None
    with pytest.raises(TypeError):
        lx.AbstractSystem()  # abstract: never instantiated
    q, qd, ok = system.initial_state(jnp.array([0.1, 0.2]), jnp.zeros(2), params)
    assert bool(ok) and system.observables(0.0, q, qd, params, None) == {}


def test_final_maxima_are_observables_the_system_reports():
    """What a sweep reports as a maximum at the final state is the system's to say (not
    keys the sweep knows of one kind): observables it has, only those of its constraints."""
    system, params = lx.models.planar_2r()
    assert system.final_maxima == ()
    pendulum, p = lx.models.cartesian_pendulum()
    knife = lx.ConstrainedSystem(
        pendulum.system, None, velocity_constraints=lambda q, p: jnp.stack([q[1], -q[0]])
    )
    q, qd = jnp.array([0.6, -0.8]), jnp.array([0.8, 0.6])
    for kind, names in (
        (pendulum, ("constraint_violation",)),
        (knife, ("velocity_constraint_violation",)),
    ):
        assert kind.final_maxima == names
        assert set(names) <= set(kind.observables(0.0, q, qd, p, None))


def test_simulate_under_jit_raises_the_failures_own_message(arm):
    system, params = arm
    run = jax.jit(lambda q0: lx.simulate(system, q0, jnp.zeros(2), params, t1=1.0, max_steps=10).q)
    with pytest.raises(Exception, match="maximum number of solver steps"):
        jax.block_until_ready(run(jnp.array([0.3, 0.8])))


def test_simulate_euler_reports_lagrax_results():
    sol = lx.rigid_body.simulate_euler([1.0, 2.0, 3.0], [0.1, 1.0, 0.1], t1=0.5, n_save=3)
    assert isinstance(sol.result, lx.RESULTS)
    assert bool(sol.ok)
    bad = lx.rigid_body.simulate_euler(
        [1.0, 2.0, 3.0], [0.1, 1.0, 0.1], t1=50.0, n_save=3, max_steps=5, throw=False
    )
    assert bad.result == lx.RESULTS.max_steps_reached


def test_sweep_accepts_the_old_argument_order_with_a_warning(arm):
    system, params = arm
    batch = lx.samples(params, m2=[1.0, 1.5])
    new = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, t1=0.5, progress=False)
    with pytest.warns(DeprecationWarning, match="simulate's order"):
        old = lx.sweep(system, batch, [0.3, 0.8], [0.0, 0.0], t1=0.5, progress=False)
    np.testing.assert_array_equal(old.q.values, new.q.values)


def test_wrong_objects_raise_lagrax_errors(arm):
    system, params = arm
    with pytest.raises(lx.ArgumentTypeError, match="system"):
        lx.simulate(system.kinetic, [0.3, 0.8], [0.0, 0.0], params, t1=1.0)
    with pytest.raises(lx.ConfigurationError, match="t1 must be greater"):
        lx.simulate(system, [0.3, 0.8], [0.0, 0.0], params, t1=-1.0)
    with pytest.raises(lx.ConfigurationError, match="unknown method"):
        lx.simulate(system, [0.3, 0.8], [0.0, 0.0], params, t1=1.0, solver="euler2")
