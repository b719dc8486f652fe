"""A battery of bad input on the simulate / system / bodies / chains / linearize side.

Each case asserts the exception type (a ``LagraxError`` subclass: no raw JAX, equinox or
Python error reaches the user) and that the message names the problem and the value
seen. Where the path supports tracing, the same input is tried under ``jax.jit``: it must
raise (at trace time when the bad value is concrete, at run time through
``equinox.error_if`` when it is traced), never return.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx


def _pend_T(q, qd, p):
    return 0.5 * p["m"] * p["l"] ** 2 * qd[0] ** 2


def _pend_V(q, p):
    return -p["m"] * p["g"] * p["l"] * jnp.cos(q[0])


PEND = lx.LagrangianSystem(_pend_T, _pend_V, n_dof=1, name="pendulum")
P = {"m": 1.0, "l": 1.0, "g": 9.81}
Q0, QD0 = [0.3], [0.0]


def _two_T(q, qd, p):  # reads two coordinates; no n_dof given
    return 0.5 * (qd[0] ** 2 + qd[1] ** 2)


def _two_V(q, p):
    return jnp.cos(q[0]) + 0.5 * q[1] ** 2


TWO = lx.LagrangianSystem(_two_T, _two_V, name="two")


def sim(system=PEND, q0=Q0, qd0=QD0, params=P, **kw):
    kw.setdefault("t1", 1.0)
    return lambda: lx.simulate(system, q0, qd0, params, **kw)


def fwd(system, q=(0.3, 0.1), qd=(0.0, 0.2), params=None, **kw):
    return lambda: system.forward_dynamics(jnp.asarray(q), jnp.asarray(qd), params or {}, **kw)


def sys_with(**energies):
    def make():
        system = lx.LagrangianSystem(
            energies.pop("kinetic", _two_T), energies.pop("potential", None), **energies
        )
        return system.forward_dynamics(jnp.array([0.3, 0.1]), jnp.array([0.0, 0.2]), {})

    return make


def _indefinite():
    return jnp.diag(jnp.array([1.0, -1.0, 1.0]))


def _pose3(q, p):
    return jnp.zeros(3), jnp.eye(3)


Err, Cfg, Typ, Shp, Par = (
    lx.LagraxError,
    lx.ConfigurationError,
    lx.ArgumentTypeError,
    lx.ShapeError,
    lx.ParameterError,
)

CASES = [
    # ------------------------------------------------------------- simulate options
    pytest.param(sim(solver="rk4", dt=-0.01), Cfg, ["dt", "-0.01", "positive"], id="dt-negative"),
    pytest.param(sim(solver="rk4", dt=0.0), Cfg, ["dt=0", "positive"], id="dt-zero"),
    pytest.param(sim(solver="rk4", dt=float("nan")), Cfg, ["dt=nan"], id="dt-nan"),
    pytest.param(sim(solver="rk4", dt=float("inf")), Cfg, ["dt=inf"], id="dt-inf"),
    pytest.param(
        sim(solver="rk4", dt=2.0), Cfg, ["dt=2.0", "longer than the whole interval"], id="dt-long"
    ),
    pytest.param(
        sim(solver="variational", dt=-0.01), Cfg, ["dt", "-0.01"], id="dt-negative-variational"
    ),
    pytest.param(sim(dt=0.01, dt0=0.1), Cfg, ["dt=0.01", "dt0=0.1", "not both"], id="dt-and-dt0"),
    pytest.param(sim(dt0=-0.1), Cfg, ["dt0=-0.1", "positive"], id="dt0-negative"),
    pytest.param(sim(dt0=0.0), Cfg, ["dt0=0"], id="dt0-zero"),
    pytest.param(sim(max_steps=0), Cfg, ["max_steps=0", "positive integer"], id="max-steps-0"),
    pytest.param(sim(max_steps=-5), Cfg, ["max_steps=-5"], id="max-steps-negative"),
    pytest.param(sim(max_steps=2.5), Cfg, ["max_steps=2.5"], id="max-steps-fraction"),
    pytest.param(sim(max_steps="many"), Typ, ["max_steps", "'many'"], id="max-steps-str"),
    pytest.param(sim(rtol=-1e-6), Cfg, ["rtol=-1e-06", "non-negative"], id="rtol-negative"),
    pytest.param(sim(atol=float("nan")), Cfg, ["atol=nan"], id="atol-nan"),
    pytest.param(sim(rtol=0.0, atol=0.0), Cfg, ["rtol", "atol", "both 0"], id="tolerances-zero"),
    pytest.param(sim(rtol=[1e-6]), Typ, ["rtol", "[1e-06]"], id="rtol-list"),
    pytest.param(sim(t1=float("inf")), Cfg, ["t1=inf", "finite"], id="t1-inf"),
    pytest.param(sim(t1=float("nan")), Cfg, ["t1=nan"], id="t1-nan"),
    pytest.param(sim(t0=-float("inf")), Cfg, ["t0=-inf"], id="t0-inf"),
    pytest.param(sim(t0=2.0, t1=1.0), Cfg, ["t1 must be greater than t0", "t0=2.0"], id="t1-lt-t0"),
    pytest.param(sim(t1="10"), Typ, ["t1", "'10'"], id="t1-str"),
    pytest.param(sim(n_save=0), Cfg, ["n_save=0"], id="n-save-0"),
    pytest.param(sim(ts=[0.0, float("nan"), 1.0]), Cfg, ["ts", "nan"], id="ts-nan"),
    pytest.param(sim(solver="euler-ish"), Cfg, ["unknown method", "'euler-ish'"], id="solver"),
    # ------------------------------------------------------------- energies and shapes
    pytest.param(
        sim(lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd**2, n_dof=1)),
        Shp,
        ["kinetic energy", "shape (1,)", "qd[0]"],
        id="T-shape-1",
    ),
    pytest.param(
        sys_with(kinetic=lambda q, qd, p: 0.5 * qd**2),
        Shp,
        ["kinetic energy", "shape (2,)", "scalar"],
        id="T-vector",
    ),
    pytest.param(
        sys_with(kinetic=lambda q, qd, p: 0.5 * (1 + 1j) * jnp.sum(qd**2)),
        Typ,
        ["kinetic energy", "complex"],
        id="T-complex",
    ),
    pytest.param(
        sim(lx.LagrangianSystem(lambda q, qd, p: 0.5 * (1 + 0j) * qd[0] ** 2, n_dof=1)),
        Typ,
        ["kinetic energy", "complex128"],
        id="T-complex-simulate",
    ),
    pytest.param(
        sys_with(potential=lambda q, p: None), Typ, ["potential energy", "None"], id="V-none"
    ),
    pytest.param(
        sys_with(dissipation=lambda q, qd, p: qd**2),
        Shp,
        ["dissipation", "shape (2,)"],
        id="D-vector",
    ),
    pytest.param(
        sys_with(force=lambda t, q, qd, p: 1j * q), Typ, ["force", "complex"], id="force-complex"
    ),
    pytest.param(
        sys_with(force=lambda t, q, qd, p: jnp.zeros(3)),
        Shp,
        ["force", "shape (3,)", "(2,)"],
        id="force-shape",
    ),
    pytest.param(
        sim(tau=lambda t, q, qd: jnp.zeros(2)), Shp, ["tau(t, q, qd)", "(2,)"], id="tau-fn-shape"
    ),
    pytest.param(sim(tau=jnp.array([1j])), Typ, ["tau", "complex"], id="tau-complex"),
    pytest.param(
        sim(TWO, q0=[0.3], qd0=[0.0], params={}),
        Shp,
        ["reads entry 1", "length 1", "n_dof"],
        id="q-shorter-than-energies",
    ),
    pytest.param(
        fwd(lx.LagrangianSystem(_pend_T, _two_V), q=[0.3], qd=[0.0], params=P),
        Shp,
        ["potential energy", "reads entry 1 of an array of length 1"],
        id="V-reads-past-q",
    ),
    pytest.param(
        fwd(
            lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd[0] ** 2 + p["k"][2], n_dof=1),
            [0.1],
            [0.0],
            {"k": jnp.ones(2)},
        ),
        Shp,
        ["reads entry 2 of an array of length 2"],
        id="params-read-past-end",
    ),
    pytest.param(sim(q0=[0.3 + 1j]), Typ, ["q", "complex128"], id="q-complex"),
    pytest.param(sim(qd0=["fast"]), Typ, ["qd", "real numbers"], id="qd-str"),
    pytest.param(sim(q0=[0.1, 0.2]), Shp, ["length 2", "1 degrees of freedom"], id="q-too-long"),
    # ------------------------------------------------------------- containers
    pytest.param(lambda: lx.LagrangianSystem(3.0), Typ, ["kinetic", "3.0"], id="T-not-callable"),
    pytest.param(
        lambda: lx.LagrangianSystem(_pend_T, "gravity"), Typ, ["potential", "'gravity'"], id="V-str"
    ),
    pytest.param(lambda: lx.LagrangianSystem(_pend_T, n_dof=0), Cfg, ["n_dof=0"], id="n-dof-0"),
    pytest.param(
        lambda: lx.LagrangianSystem(PEND), Typ, ["system", "'pendulum'"], id="system-as-energy"
    ),
    pytest.param(
        lambda: lx.simulate(_pend_T, Q0, QD0, P, t1=1.0),
        Typ,
        ["needs a system", "function"],
        id="energy-as-system",
    ),
    pytest.param(sim(params=[1.0, 1.0, 9.81]), Typ, ["params is a list"], id="params-list"),
    pytest.param(sim(params=None), Typ, ["params is None"], id="params-none"),
    pytest.param(
        sim(params={"m": 1.0, "g": 9.81}), Par, ["'l'", "params has keys"], id="params-key"
    ),
    # ------------------------------------------------------------- physical parameters
    pytest.param(
        lambda: lx.chains.PlanarChain(2).params(m=[-1.0, 1.0], I=[0.1, 0.1]),
        Par,
        ["m[0] = -1", "link 1", "mass"],
        id="chain-negative-mass",
    ),
    pytest.param(
        lambda: lx.chains.SpatialChain("RR").params(m=[1.0, -2.0]),
        Par,
        ["m[1] = -2", "link 2"],
        id="spatial-chain-negative-mass",
    ),
    pytest.param(
        lambda: lx.chains.SpatialChain("R").params(inertia=_indefinite()),
        Par,
        ["inertia", "positive-semidefinite", "-1"],
        id="spatial-chain-indefinite",
    ),
    pytest.param(
        lambda: lx.bodies.SpatialBody(1.0, _indefinite(), _pose3, None),
        Par,
        ["SpatialBody inertia", "positive-semidefinite", "-1"],
        id="spatial-body-indefinite",
    ),
    pytest.param(
        lambda: lx.bodies.SpatialBody(1.0, jnp.diag(jnp.array([1.0, 1.0, 3.0])), _pose3, None),
        Par,
        ["triangle inequality", "I3 = 3"],
        id="spatial-body-triangle",
    ),
    pytest.param(
        lambda: lx.bodies.PointMass(-2.0, lambda q, p: q),
        Par,
        ["PointMass mass = -2", "positive"],
        id="point-mass-negative",
    ),
    pytest.param(
        lambda: lx.bodies.PlanarBody(1.0, -0.1, lambda q, p: q, lambda q, p: q[0]),
        Par,
        ["PlanarBody inertia", "-0.1"],
        id="planar-body-inertia",
    ),
    pytest.param(lambda: lx.models.planar_2r(m2=-1.0), Par, ["m2 = -1"], id="model-negative-mass"),
    # ------------------------------------------------------------- a structure's params
    # (JAX clamps an out-of-range read: a short array used to give a wrong answer)
    pytest.param(
        lambda: _tree_call("forward_dynamics", m=lambda v: v[:2]),
        Shp,
        ["params['m']", "shape (2,)", "(3,)", "Tree of 3 joints"],
        id="tree-short-mass",
    ),
    pytest.param(
        lambda: _tree_call("simulate", inertia=lambda v: v[:2]),
        Shp,
        ["params['inertia']", "(2, 3, 3)", "(3, 3, 3)"],
        id="tree-simulate-short-inertia",
    ),
    pytest.param(
        lambda: _tree_call("forward_dynamics_derivatives", offset=lambda v: v[:, :2]),
        Shp,
        ["params['offset']", "(3, 2)", "(3, 3)"],
        id="tree-derivatives-offset",
    ),
    pytest.param(
        lambda: _tree_call("linearize", damping=lambda v: v[:2]),
        Shp,
        ["params['damping']", "(2,)", "joint damping of 3 joints"],
        id="tree-linearize-damping",
    ),
    pytest.param(
        lambda: _tree_call("forward_dynamics", com=None),
        lx.ParameterError,
        ["params['com']", "missing", "keys"],
        id="tree-missing-com",
    ),
    pytest.param(
        lambda: _planar_call(l=lambda v: jnp.append(v, 1.0)),
        Shp,
        ["params['l']", "shape (3,)", "PlanarChain of 2 joints"],
        id="planar-chain-long-length",
    ),
    pytest.param(
        lambda: _floating_call(base_com=lambda v: v[:2]),
        Shp,
        ["params['base_com']", "(2,)", "(3,)", "floating base"],
        id="floating-base-com",
    ),
    # ------------------------------------------------------------- linearize / inverse dynamics
    pytest.param(
        lambda: TWO.linearize(jnp.array([0.3]), jnp.array([0.0]), {}),
        Shp,
        ["reads entry 1"],
        id="linearize-short-q",
    ),
    pytest.param(
        lambda: PEND.linearize(jnp.array([jnp.nan]), jnp.array([0.0]), P),
        lx.NonFiniteError,
        ["q_eq", "nan"],
        id="linearize-nan",
    ),
    pytest.param(
        lambda: PEND.linearize(jnp.array([0.3]), jnp.array([0.0]), {**P, "m": -1.0}),
        lx.MassMatrixError,
        ["positive-definite"],
        id="linearize-negative-mass",
    ),
    pytest.param(
        lambda: PEND.linearize(jnp.array([0.3]), jnp.array([0.0]), {"m": 1.0, "l": 1.0}),
        lx.ParameterError,
        ["'g'"],
        id="linearize-missing-parameter",
    ),
    pytest.param(
        lambda: PEND.inverse_dynamics(jnp.array([0.3]), jnp.array([0.0]), jnp.array([1j]), P),
        Typ,
        ["qdd", "complex"],
        id="inverse-dynamics-complex",
    ),
    pytest.param(
        lambda: TWO.inverse_dynamics(jnp.array([0.3]), jnp.array([0.0]), jnp.array([1.0]), {}),
        Shp,
        ["reads entry 1"],
        id="inverse-dynamics-short-q",
    ),
]


def _changed(params, changes):
    """`params` with entries replaced by `change(value)` (`None`: removed)."""
    out = dict(params)
    for key, change in changes.items():
        if change is None:
            del out[key]
        else:
            out[key] = change(out[key])
    return out


def _tree_call(what, **changes):
    """`what` of a damped 3-joint tree (a branch at body 0) with changed `params`."""
    tree = lx.chains.Tree("RRR", parents=(-1, 0, 0), axes=[(0, 0, 1), (0, 1, 0), (1, 0, 0)])
    system = tree.system()
    params = _changed(tree.params(damping=0.1), changes)
    q = jnp.array([0.1, 0.2, 0.3])
    if what == "simulate":
        return lx.simulate(system, q, 0 * q, params, t1=0.1)
    if what == "linearize":
        return system.linearize(q, 0 * q, params)
    return getattr(system, what)(q, 0 * q, params)


def _planar_call(**changes):
    chain = lx.chains.PlanarChain(2)
    params = _changed(chain.params(), changes)
    return chain.system().forward_dynamics(jnp.array([0.1, 0.2]), jnp.zeros(2), params)


def _floating_call(**changes):
    robot = lx.chains.FloatingTree(lx.chains.Tree("R", parents=(-1,)))
    params = _changed(robot.params(), changes)
    q = jnp.concatenate([jnp.zeros(3), jnp.array([1.0, 0, 0, 0]), jnp.array([0.2])])
    return robot.system().forward_dynamics(q, jnp.zeros(7), params)


@pytest.mark.parametrize(("call", "kind", "words"), CASES)
def test_bad_input_is_a_clear_lagrax_error(call, kind, words):
    with pytest.raises(Err) as info:
        call()
    assert isinstance(info.value, kind), f"{type(info.value).__name__}: {info.value}"
    message = str(info.value)
    for word in words:
        assert word in message, f"{word!r} not in: {message}"


def test_battery_is_large_enough():
    assert len(CASES) >= 30


# ----------------------------------------------------------------------------- under jit
@pytest.mark.parametrize(
    ("call", "words"),
    [
        pytest.param(
            lambda p: lx.simulate(PEND, Q0, QD0, p, t1=1.0, dt=-0.01, solver="rk4").q,
            ["dt", "-0.01"],
            id="dt-negative",
        ),
        pytest.param(
            lambda p: lx.simulate(PEND, Q0, QD0, p, t1=float("inf")).q, ["t1=inf"], id="t1-inf"
        ),
        pytest.param(
            lambda p: lx.simulate(PEND, Q0, QD0, p, t1=1.0, max_steps=0).q,
            ["max_steps=0"],
            id="max-steps",
        ),
        pytest.param(
            lambda p: lx.simulate(PEND, Q0, QD0, p, t1=1.0, rtol=0.0, atol=0.0).q,
            ["both 0"],
            id="tolerances",
        ),
        pytest.param(
            lambda p: lx.simulate(TWO, [0.3], [0.0], p, t1=1.0).q,
            ["reads entry 1"],
            id="q-short",
        ),
        pytest.param(
            lambda p: lx.LagrangianSystem(lambda q, qd, p: qd**2, n_dof=1).forward_dynamics(
                jnp.array([0.1]), jnp.array([0.0]), p
            ),
            ["shape (1,)"],
            id="T-vector",
        ),
        pytest.param(
            lambda p: _tree_call("forward_dynamics", m=lambda v: v[:2] * p["m"]),
            ["params['m']", "(2,)"],
            id="tree-short-mass",
        ),
        pytest.param(
            lambda p: lx.chains.PlanarChain(2).params(m=jnp.stack([-p["m"], p["m"]]), I=0.1)["m"],
            ["m"],
            id="chain-negative-mass-traced",
        ),
    ],
)
def test_bad_input_under_jit_raises(call, words):
    with pytest.raises(Exception) as info:  # noqa: PT011 - traced checks raise JAX's runtime error
        jax.block_until_ready(jax.jit(call)(P))
    message = str(info.value)
    for word in words:
        assert word in message, f"{word!r} not in: {message}"


@pytest.fixture(scope="module")
def jitted_rk4():
    """One compiled fixed-step solve with the step, t1 and tolerances traced."""
    return jax.jit(
        lambda dt, t1, rtol: lx.simulate(PEND, Q0, QD0, P, t1=t1, dt=dt, rtol=rtol, solver="rk4").q
    )


@pytest.mark.parametrize(
    ("dt", "t1", "rtol", "words"),
    [
        (-0.01, 1.0, 1e-8, "dt must be a positive"),
        (0.0, 1.0, 1e-8, "dt must be a positive"),
        (0.01, float("inf"), 1e-8, "t1 must be finite"),
        (0.01, -1.0, 1e-8, "t1 must be greater than t0"),
    ],
)
def test_traced_options_fail_at_run_time(jitted_rk4, dt, t1, rtol, words):
    ok = jitted_rk4(0.01, 1.0, 1e-8)
    assert np.all(np.isfinite(np.asarray(ok)))  # the same compiled call works on good input
    with pytest.raises(Exception, match=words):  # noqa: PT011
        jax.block_until_ready(jitted_rk4(dt, t1, rtol))


def test_traced_tolerances_fail_at_run_time():
    run = jax.jit(lambda rtol, atol: lx.simulate(PEND, Q0, QD0, P, t1=0.1, rtol=rtol, atol=atol).q)
    with pytest.raises(Exception, match="rtol must be a non-negative"):  # noqa: PT011
        jax.block_until_ready(run(-1.0, 1e-8))
    with pytest.raises(Exception, match="rtol and atol are both 0"):  # noqa: PT011
        jax.block_until_ready(run(0.0, 0.0))


def test_out_of_range_read_is_refused_every_time():
    # the check is cached per function and shapes: the cache must remember the failure
    for _ in range(2):
        with pytest.raises(lx.ShapeError, match="reads entry 1"):
            TWO.energy(jnp.array([0.3]), jnp.array([0.0]), {})
    ok = TWO.energy(jnp.array([0.3, 0.1]), jnp.array([0.0, 0.2]), {})  # the right length
    assert np.isfinite(float(ok))


# ----------------------------------------------------------------------------- diagnosis
def _nan_after_half(t, q, qd):
    return jnp.where(t > 0.5, jnp.nan, 0.0) * jnp.ones_like(q)


@pytest.mark.parametrize("fixed", [False, True], ids=["adaptive", "rk4"])
def test_nan_tau_is_named_not_the_step_budget(fixed):
    kw = dict(solver="rk4", dt=0.01) if fixed else dict(max_steps=500)
    with pytest.raises(lx.SimulationError) as info:
        lx.simulate(PEND, Q0, QD0, P, t1=1.0, tau=_nan_after_half, **kw)
    message = str(info.value)
    assert "tau(t, q, qd)" in message and "NaN or inf" in message
    assert "t=0.5" in message  # where it first happens
    assert "larger max_steps" not in message and "increasing `max_steps`" not in message
    assert "smaller dt" not in message and "singular" not in message


def test_nan_force_is_named():
    system = lx.LagrangianSystem(
        _pend_T, _pend_V, force=lambda t, q, qd, p: jnp.log(0.5 - t) * jnp.ones(1), n_dof=1
    )
    with pytest.raises(lx.SimulationError) as info:
        lx.simulate(system, Q0, QD0, P, t1=1.0, max_steps=500)
    message = str(info.value)
    assert "force function F(t, q, qd, params) is NaN or inf" in message
    assert "larger max_steps" not in message and "singular" not in message


def test_a_scalar_joint_damping_broadcasts():
    """A joint damping given as one number (the check lets it broadcast) damps every
    joint alike: the same `q̈` as the array `params()` builds from it."""
    tree = lx.chains.Tree("RRR", parents=(-1, 0, 0), axes=[(0, 0, 1), (0, 1, 0), (1, 0, 0)])
    params = tree.params(damping=0.3)
    q, qd = jnp.array([0.1, 0.2, 0.3]), jnp.array([0.5, -0.4, 0.2])
    system = tree.system()
    expected = system.forward_dynamics(q, qd, params)
    scalar = system.forward_dynamics(q, qd, {**params, "damping": jnp.asarray(0.3)})
    np.testing.assert_allclose(scalar, expected, rtol=1e-14, atol=1e-14)
