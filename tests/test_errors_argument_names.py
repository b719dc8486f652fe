"""Bad input to every public entry point names the caller's argument: `q0` and `qd0` for
`simulate`, `sweep` and the periodic orbits, `q_eq`, `qd_eq`, `tau_eq` for `linearize`,
the derivatives calls' `q`, `qd`, `qdd`, `tau`, and `from_mujoco_state`'s `qpos` and
`qvel` (each message checked against the signature it came from)."""

import inspect
import warnings

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx

Q2, Q3 = np.zeros(2), np.zeros(3)


@pytest.fixture(scope="module")
def systems():
    arm, arm_params = lx.models.planar_2r()
    four_bar, bar_params = lx.models.four_bar()
    robot = lx.chains.FloatingTree(lx.chains.Tree("R", parents=(-1,)))
    return {
        "arm": (arm, arm_params),
        "four_bar": (four_bar, bar_params),
        "floating": (robot.system(), robot.params()),
    }


def _old_order_sweep(arm, params, q0, qd0):
    with warnings.catch_warnings():  # sweep(system, params, q0, qd0): the order before 0.2
        warnings.simplefilter("ignore", DeprecationWarning)
        return lx.sweep(arm, lx.grid(params, g=[9.0, 9.8]), q0, qd0, t1=0.1)


def _floating_state(n_q=8, n_v=7):
    q = np.zeros(n_q)
    q[6] = 1.0  # the quaternion's w (x, y, z, w)
    return q, np.zeros(n_v)


# (id, system, call, the function whose argument is named, message start)
CASES = [
    ("simulate-q0", "arm", lambda s, p: lx.simulate(s, Q3, Q2, p, t1=0.1), lx.simulate, "q0"),
    ("simulate-qd0", "arm", lambda s, p: lx.simulate(s, Q2, Q3, p, t1=0.1), lx.simulate, "qd0"),
    ("sweep-q0", "arm", lambda s, p: _old_order_sweep(s, p, Q3, Q2), lx.sweep, "q0"),
    ("sweep-qd0", "arm", lambda s, p: _old_order_sweep(s, p, Q2, Q3), lx.sweep, "qd0"),
    (
        "sweep-q0-new-order",
        "arm",
        lambda s, p: lx.sweep(s, Q3, Q2, lx.grid(p, g=[9.0, 9.8]), t1=0.1),
        lx.sweep,
        "q0",
    ),
    (
        "periodic_orbit-q0",
        "arm",
        lambda s, p: lx.periodic_orbit(s, Q3, Q2, p, period=1.0),
        lx.periodic_orbit,
        "q0",
    ),
    (
        "periodic_orbit-qd0",
        "arm",
        lambda s, p: lx.periodic_orbit(s, Q2, Q3, p, period=1.0),
        lx.periodic_orbit,
        "qd0",
    ),
    (
        "continue_orbits-q0",
        "arm",
        lambda s, p: lx.continue_orbits(s, Q3, Q2, p, "g", [9.0, 9.8], period=1.0),
        lx.continue_orbits,
        "q0",
    ),
    (
        "orbit_map-qd0",
        "arm",
        lambda s, p: lx.orbit_map(s, Q2, Q3, lx.grid(p, g=[9.0, 9.8]), period=1.0),
        lx.orbit_map,
        "qd0",
    ),
    ("linearize-q_eq", "arm", lambda s, p: s.linearize(Q3, Q2, p), "linearize", "q_eq"),
    ("linearize-qd_eq", "arm", lambda s, p: s.linearize(Q2, Q3, p), "linearize", "qd_eq"),
    ("linearize-tau_eq", "arm", lambda s, p: s.linearize(Q2, Q2, p, Q3), "linearize", "tau_eq"),
    (
        "forward_dynamics_derivatives-q",
        "arm",
        lambda s, p: s.forward_dynamics_derivatives(Q3, Q2, p),
        "forward_dynamics_derivatives",
        "q",
    ),
    (
        "forward_dynamics_derivatives-tau",
        "arm",
        lambda s, p: s.forward_dynamics_derivatives(Q2, Q2, p, Q3),
        "forward_dynamics_derivatives",
        "tau",
    ),
    (
        "inverse_dynamics_derivatives-qdd",
        "arm",
        lambda s, p: s.inverse_dynamics_derivatives(Q2, Q2, Q3, p),
        "inverse_dynamics_derivatives",
        "qdd",
    ),
    (
        "constrained-linearize-qd_eq",
        "four_bar",
        lambda s, p: s.linearize(np.zeros(s.n_dof), np.zeros(s.n_dof + 1), p),
        "linearize",
        "qd_eq",
    ),
    (
        "constrained-forward_dynamics_derivatives-qd",
        "four_bar",
        lambda s, p: s.forward_dynamics_derivatives(np.zeros(s.n_dof), np.zeros(s.n_dof + 1), p),
        "forward_dynamics_derivatives",
        "qd",
    ),
    (
        "floating-simulate-q0",
        "floating",
        lambda s, p: lx.simulate(s, np.zeros(7), _floating_state()[1], p, t1=0.1),
        lx.simulate,
        "q0",
    ),
    (
        "floating-linearize-q_eq",
        "floating",
        lambda s, p: s.linearize(np.zeros(7), _floating_state()[1], p),
        "linearize",
        "q_eq",
    ),
    (
        "floating-linearize-tau_eq",
        "floating",
        lambda s, p: s.linearize(*_floating_state(), p, np.zeros(8)),
        "linearize",
        "tau_eq",
    ),
    (
        "floating-forward_dynamics_derivatives-qd",
        "floating",
        lambda s, p: s.forward_dynamics_derivatives(*_floating_state(8, 8), p),
        "forward_dynamics_derivatives",
        "qd",
    ),
    (
        "floating-inverse_dynamics_derivatives-qdd",
        "floating",
        lambda s, p: s.inverse_dynamics_derivatives(*_floating_state(), np.zeros(6), p),
        "inverse_dynamics_derivatives",
        "qdd",
    ),
    (
        "from_mujoco_state-qpos",
        None,
        lambda s, p: lx.chains.from_mujoco_state(np.zeros(6), np.zeros(6)),
        lx.chains.from_mujoco_state,
        "qpos",
    ),
    (
        "from_mujoco_state-qvel",
        None,
        lambda s, p: lx.chains.from_mujoco_state(np.zeros(9), np.zeros(7)),
        lx.chains.from_mujoco_state,
        "qvel",
    ),
    (
        "to_mujoco_state-v",
        None,
        lambda s, p: lx.chains.to_mujoco_state(np.zeros(9), np.zeros((2, 8))),
        lx.chains.to_mujoco_state,
        "v",
    ),
]


@pytest.mark.parametrize(("system", "call", "function", "name"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])  # fmt: skip
def test_a_bad_argument_is_named_as_the_caller_wrote_it(systems, system, call, function, name):
    s, p = systems[system] if system is not None else (None, None)
    if isinstance(function, str):  # a method: the system's own
        function = getattr(s, function)
    assert name in inspect.signature(function).parameters  # the caller's argument
    with pytest.raises(lx.ShapeError) as info:
        call(s, p)
    message = str(info.value)
    assert message.split()[0] in (name, f"{name}'s"), message
    if name in ("qpos", "q", "q0", "q_eq") and system == "floating":
        # a floating base's q has 7 + n entries, its velocities 6 + n
        assert "has 8 configuration coordinates (and 7 velocities)" in message, message


def test_the_issue_case_names_q0(systems):
    arm, params = systems["arm"]
    with pytest.raises(lx.ShapeError) as info:
        _old_order_sweep(arm, params, Q3, Q2)
    assert str(info.value) == "q0 has length 3 but planar 2R arm has 2 degrees of freedom"


def test_shapes_compared_name_both_arguments():
    free = lx.LagrangianSystem(lambda q, qd, p: 0.5 * jnp.sum(qd**2))  # no n_dof
    with pytest.raises(lx.ShapeError, match=r"^qd0 has shape \(3,\) but q0 has shape \(2,\)"):
        lx.simulate(free, Q2, Q3, {}, t1=0.1)
    with pytest.raises(lx.ShapeError, match=r"^qd_eq has shape \(3,\) but q_eq has shape \(2,\)"):
        free.linearize(Q2, Q3, {})
    with pytest.raises(lx.ShapeError, match=r"^qdd has shape \(3,\) but q has shape \(2,\)"):
        free.inverse_dynamics_derivatives(Q2, Q2, Q3, {})


def test_a_non_finite_argument_is_named(systems):
    robot, params = systems["floating"]
    q, v = _floating_state()
    with pytest.raises(lx.NonFiniteError, match="^q_eq contains non-finite values"):
        robot.linearize(np.where(np.arange(8) == 0, np.nan, q), v, params)
    with pytest.raises(lx.NonFiniteError, match="^tau contains non-finite values"):
        robot.forward_dynamics_derivatives(q, v, params, np.full(7, np.inf))
