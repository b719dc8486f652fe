"""Floating bases (``from_urdf(..., floating_base=True)``, ``lagrax.chains.FloatingTree``).

- Dynamics against Pinocchio's free-flyer model (``pin.JointModelFreeFlyer``): ``M`` (CRBA),
  the bias (``nonLinearEffects``), ``rnea`` and ``aba`` at random states, in Pinocchio's
  own coordinates (``q = (x, y, z, qx, qy, qz, qw, joints)``, ``v`` in the base frame), on
  the bundled URDF robots and on solo12 from example-robot-data when it is installed.
- ``q̇ = N(q) v`` against Pinocchio's ``integrate`` (a central difference along ``v``),
  the centre of mass and the centroidal momentum against Pinocchio's.
- Invariants: a dropped robot's centre of mass falls at ``g`` whatever its joints do; a
  free-floating satellite with a 7-joint arm in zero gravity conserves its linear and
  angular momentum over 100 s through ``simulate``, whose quaternion stays on the unit
  sphere.
"""

import glob
import sys
import xml.etree.ElementTree as ET

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import assert_free_motion_conserved, pin_state, rel_error
from lagrax.models import urdf_path

pin = pytest.importorskip(
    "pinocchio", reason="Pinocchio (pip install pin) is the reference for floating-base dynamics"
)


def _solo12() -> str | None:
    """solo12's URDF from example-robot-data (its cmeel prefix), if installed."""
    pattern = "lib/python*/site-packages/cmeel.prefix/share/example-robot-data/robots"
    found = glob.glob(f"{sys.prefix}/{pattern}/solo_description/robots/solo12.urdf")
    return found[0] if found else None


def _torso_without_lift() -> str:
    """torso_two_arms with its massless `world` link and `lift` joint removed: the pelvis
    is the floating base (a base needs a mass)."""
    root = ET.fromstring(urdf_path("torso_two_arms").read_text())
    for el in list(root):
        if el.get("name") in ("world", "lift"):
            root.remove(el)
    return ET.tostring(root, encoding="unicode")


def _robot(name: str):
    if name == "solo12":
        path = _solo12()
        if path is None:
            pytest.skip("example-robot-data is not installed (pip install example-robot-data)")
        with open(path, encoding="utf-8") as f:
            xml = f.read()
    elif name == "torso_two_arms":
        xml = _torso_without_lift()
    else:
        xml = urdf_path(name).read_text()
    robot, params = lx.chains.from_urdf(xml, floating_base=True)
    params = dict(params, damping=jnp.zeros_like(params["damping"]))  # Pinocchio: none
    model = pin.buildModelFromXML(xml, pin.JointModelFreeFlyer())
    return robot, params, model


def _random_state(rng, n):
    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    q = np.concatenate([rng.normal(size=3), quat, rng.uniform(-1.5, 1.5, n)])
    return q, rng.normal(size=6 + n)


def _pin(model, robot, q, v):
    """lagrax's `(q, v)` as Pinocchio's, and the order of lagrax's velocities in
    Pinocchio's (the base's six first in both)."""
    qp, vp, order = pin_state(pin, model, robot.tree, q[7:], v[6:])
    qp[:7], vp[:6] = q[:7], v[:6]
    return qp, vp, np.concatenate([np.arange(6), order])


def _random_inputs(rng, n):
    """A random state `(q, v)` and a random `τ` and `v̇`."""
    q, v = _random_state(rng, n)
    return q, v, rng.normal(size=6 + n), rng.normal(size=6 + n)


def _in_pin_order(model, idx, x):
    """A velocity-sized vector of lagrax's in Pinocchio's order (`idx` from `_pin`)."""
    out = np.zeros(model.nv)
    out[idx] = x
    return out


def _symmetric(upper):
    """A symmetric matrix from the upper triangle Pinocchio fills (`crba`, `Minv`)."""
    return np.triu(upper) + np.triu(upper, 1).T


@pytest.mark.parametrize("name", ["arm7", "torso_two_arms", "solo12"])
def test_dynamics_match_pinocchio_free_flyer(name):
    robot, params, model = _robot(name)
    data = model.createData()
    system = robot.system()
    assert system.n_configuration == 7 + robot.n  # (Pinocchio: 2 per continuous joint)
    assert model.nv == system.n_dof == 6 + robot.n
    rng = np.random.default_rng(7)
    errors = []
    for _ in range(3):
        q, v, tau, vdot = _random_inputs(rng, robot.n)
        qp, vp, idx = _pin(model, robot, q, v)
        tau_p, vdot_p = _in_pin_order(model, idx, tau), _in_pin_order(model, idx, vdot)
        m_p = pin.crba(model, data, qp)
        m_p = _symmetric(m_p)
        errors.append(
            (
                rel_error(system.mass_matrix(q, params), m_p[np.ix_(idx, idx)]),
                rel_error(
                    system.bias(q, v, params), pin.nonLinearEffects(model, data, qp, vp)[idx]
                ),
                rel_error(
                    system.inverse_dynamics(q, v, vdot, params),
                    pin.rnea(model, data, qp, vp, vdot_p)[idx],
                ),
                rel_error(
                    system.forward_dynamics(q, v, params, tau),
                    pin.aba(model, data, qp, vp, tau_p)[idx],
                ),
            )
        )
    assert np.max(errors) <= 1e-12, errors


def test_configuration_rate_is_pinocchios_integrate():
    """`q̇ = N(q) v` is the derivative of Pinocchio's `integrate(q, ε v)` at `ε = 0`."""
    robot, params, model = _robot("arm7")
    system = robot.system()
    q, v = _random_state(np.random.default_rng(3), robot.n)
    qp, vp, _ = _pin(model, robot, q, v)
    eps = 1e-6
    rate_p = (pin.integrate(model, qp, eps * vp) - pin.integrate(model, qp, -eps * vp)) / (2 * eps)
    rate = np.asarray(system.configuration_rate(jnp.asarray(q), jnp.asarray(v)))
    assert rel_error(rate[:7], rate_p[:7]) < 1e-8
    assert rel_error(rate[7:], v[6:]) == 0.0
    off = jnp.asarray(q).at[3].add(0.1)  # off the unit sphere
    projected = system.project_configuration(off)
    assert abs(float(jnp.linalg.norm(projected[3:7])) - 1.0) < 1e-15


def test_momentum_and_com_match_pinocchio():
    robot, params, model = _robot("torso_two_arms")
    data = model.createData()
    system = robot.system()
    q, v = _random_state(np.random.default_rng(5), robot.n)
    qp, vp, _ = _pin(model, robot, q, v)
    com = np.asarray(system.center_of_mass(q, params))
    assert rel_error(com, pin.centerOfMass(model, data, qp)) < 1e-13
    h = np.asarray(system.momentum(q, v, params))  # (L about the world origin, p)
    h_g = pin.computeCentroidalMomentum(model, data, qp, vp)  # (p, L about the CoM)
    assert rel_error(h[3:], h_g.linear) < 1e-13
    assert rel_error(h[:3] - np.cross(com, h[3:]), h_g.angular) < 1e-13
    kinetic = pin.computeKineticEnergy(model, data, qp, vp)
    potential = pin.computePotentialEnergy(model, data, qp)
    assert rel_error(system.energy(q, v, params), kinetic + potential) < 1e-13


def test_dropped_robot_centre_of_mass_falls_at_g():
    """With no external force but gravity, `m c̈ = m g` exactly, whatever the joint
    torques, damping and motion: `c̈ = d/dt (p / m)` along `(q̇, v̇) = (N(q) v, aba)`."""
    robot, params, _ = _robot("arm7")
    params = dict(params, damping=jnp.full(robot.n, 0.3))  # internal forces: no effect on c̈
    system = robot.system()
    mass = float(params["base_m"] + jnp.sum(params["m"]))
    rng = np.random.default_rng(11)
    for _ in range(3):
        q, v = (jnp.asarray(x) for x in _random_state(rng, robot.n))
        tau = jnp.concatenate([jnp.zeros(6), jnp.asarray(rng.normal(size=robot.n))])
        vdot = system.forward_dynamics(q, v, params, tau)
        qrate = system.configuration_rate(q, v)
        _, pdot = jax.jvp(lambda a, b: system.momentum(a, b, params)[3:], (q, v), (qrate, vdot))
        g = float(params["g"])
        assert rel_error(pdot / mass, jnp.array([0.0, 0.0, -g])) < 1e-12


def _satellite():
    """A 100 kg satellite with a 7-joint arm (2 kg links), in zero gravity."""
    arm = lx.chains.Tree(
        "RRRRRRR", parents=range(-1, 6), axes=[(0, 0, 1), (0, 1, 0)] * 3 + [(0, 0, 1)]
    )
    robot = lx.chains.FloatingTree(arm, base_name="satellite")
    params = robot.params(
        base_m=100.0,
        base_inertia=np.diag([10.0, 12.0, 14.0]),
        base_com=(0.01, -0.02, 0.03),
        m=2.0,
        offset=[(0.5, 0, 0.2)] + [(0, 0, 0.3)] * 6,
        com=(0.02, 0.01, 0.15),
        g=0.0,
    )
    return robot, params


def test_free_floating_satellite_conserves_momentum():
    """Over 100 s (Dopri8, tolerances 1e-13) the linear and the angular momentum each stay
    constant to 1e-10 relative (measured: 1e-12 and 2e-11; at tolerances 1e-12 the
    angular momentum drifts by 1.2e-10), the energy to 1e-10, and the quaternion stays on
    the unit sphere."""
    robot, params = _satellite()
    system = robot.system()
    rng = np.random.default_rng(1)
    q0, v0 = _random_state(rng, robot.n)
    v0[:6] *= 0.3
    sol = lx.simulate(
        system, q0, v0, params, t1=100.0, solver="dopri8", rtol=1e-13, atol=1e-13, n_save=101
    )
    assert sol.q.shape == (101, 14) and sol.qd.shape == (101, 13)
    assert_free_motion_conserved(system, params, sol)


def test_configuration_interface_defaults():
    """An ordinary system's configuration is its own: `q̇ = v`, `n_q = n_v`, no projection."""
    system, _ = lx.models.planar_2r()
    q, v = jnp.array([0.3, 0.4]), jnp.array([1.0, -2.0])
    assert system.n_configuration == system.n_dof
    assert system.configuration_rate(q, v) is v
    assert system.project_configuration(q) is q


def test_floating_base_errors():
    robot, params = _satellite()
    system = robot.system()
    with pytest.raises(lx.ShapeError, match="14"):
        system.forward_dynamics(jnp.zeros(13), jnp.zeros(13), params)
    with pytest.raises(lx.ShapeError, match="13"):
        system.forward_dynamics(jnp.r_[jnp.zeros(6), 1.0, jnp.zeros(7)], jnp.zeros(14), params)
    # a NaN in the base's position: the accelerations do not read it, so only the
    # input check can catch it (eagerly, naming q; under jit, at run time)
    q = jnp.r_[jnp.nan, jnp.zeros(5), 1.0, jnp.zeros(7)]
    v = jnp.zeros(13)
    assert np.all(np.isfinite(system.accelerations(0.0, q, v, params, None)))
    with pytest.raises(lx.NonFiniteError, match="q "):
        system.forward_dynamics(q, v, params)
    with pytest.raises(Exception, match="configuration q is not finite"):  # noqa: PT011
        jax.block_until_ready(jax.jit(lambda a: system.forward_dynamics(a, v, params))(q))
    with pytest.raises(lx.URDFError, match="world"):  # a massless root cannot float
        lx.chains.from_urdf(urdf_path("torso_two_arms"), floating_base=True)
    with pytest.raises(lx.ParameterError, match="base_m"):
        robot.params(base_m=0.0)


def test_dropped_robot_falls_at_g_through_simulate():
    """Dropped with its joints moving, the centre of mass follows `c0 + ċ0 t − ½ g t² up`
    (to 1e-12 m over 0.5 s, Dopri8 at tolerances 1e-13) while the joints swing."""
    robot, params, _ = _robot("arm7")
    system = robot.system()
    q0 = jnp.concatenate([jnp.array([0.0, 0.0, 1.0, 0.1, 0.2, 0.0, 1.0]), jnp.full(robot.n, 0.4)])
    v0 = jnp.concatenate([jnp.zeros(6), jnp.ones(robot.n)])
    sol = lx.simulate(
        system, q0, v0, params, t1=0.5, n_save=6, solver="dopri8", rtol=1e-13, atol=1e-13
    )
    com = jax.vmap(lambda q: system.center_of_mass(q, params))(sol.q)
    mass = params["base_m"] + jnp.sum(params["m"])
    com_rate = system.momentum(sol.q[0], v0, params)[3:] / mass
    t = sol.ts[:, None]
    fall = com[:1] + t * com_rate[None] - 0.5 * params["g"] * t**2 * jnp.array([[0.0, 0, 1]])
    assert float(jnp.max(jnp.abs(com - fall))) < 1e-12
    assert float(jnp.max(jnp.abs(sol.q[-1, 7:] - sol.q[0, 7:]))) > 1e-2  # the joints moved


def _dropped_arm():
    """arm7 on a floating base, dropped with its joints and base moving."""
    robot, params, _ = _robot("arm7")
    system = robot.system()
    q0 = jnp.concatenate([jnp.array([0.0, 0.0, 1.0, 0.1, 0.2, 0.0, 1.0]), jnp.full(robot.n, 0.4)])
    q0 = system.project_configuration(q0)
    v0 = jnp.concatenate([jnp.array([0.1, 0.0, 0.5, 0.0, 0.3, 0.0]), jnp.ones(robot.n)])
    return robot, system, params, q0, v0


def test_sweep_of_a_floating_base_equals_simulate():
    """A sweep over the base mass: `q` (size `7 + n`) on its own `q_dof` axis labelled
    by the configuration names, `qd` (size `6 + n`) on `dof`; each member equals its
    own `simulate` run."""
    robot, system, params, q0, v0 = _dropped_arm()
    masses = np.array([0.5, 1.0, 2.0]) * float(params["base_m"])
    opts = dict(t1=0.3, n_save=4, rtol=1e-10, atol=1e-10)
    members = lx.samples(params, base_m=masses)
    ds = lx.sweep(system, q0, v0, members, keep="trajectory", **opts)
    assert ds.q.dims == ("member", "time", "q_dof") and ds.qd.dims == ("member", "time", "dof")
    assert list(ds.q_dof.values[:7]) == ["base_x", "base_y", "base_z"] + [
        f"base_q{c}" for c in "xyzw"
    ]
    assert list(ds.dof.values[:6]) == list(system.coordinate_names[:6])
    assert list(ds.q_dof.values[7:]) == list(ds.dof.values[6:]) == list(robot.joint_names)
    for k, m in enumerate(masses):
        sol = lx.simulate(system, q0, v0, dict(params, base_m=jnp.asarray(m)), **opts)
        # round-off apart (a batched program against a single one): 1e-12 of |v| ~ 1
        assert np.max(np.abs(ds.q.values[k] - np.asarray(sol.q))) < 1e-10
        assert np.max(np.abs(ds.qd.values[k] - np.asarray(sol.qd))) < 1e-10
    assert bool(ds.ok.all()) and float(np.max(np.abs(ds.constraint_violation))) < 1e-14
    final = lx.sweep(system, q0, v0, lx.samples(params, base_m=masses), keep="final", t1=0.3)
    assert final.q.dims == ("member", "q_dof") and final.qd.dims == ("member", "dof")


def test_event_with_a_floating_base():
    """A terminal event on the centre of mass's height: it falls on the parabola
    `c_z(t) = c_z0 + ċ_z0 t − ½ g t²` whatever the joints do, so the crossing of a level
    is known in closed form."""
    robot, system, params, q0, v0 = _dropped_arm()
    level = 0.6
    height = lx.Event(
        lambda t, q, qd, p: system.center_of_mass(q, p)[2] - level, direction=-1, terminal=True
    )
    sol = lx.simulate(
        system, q0, v0, params, t1=2.0, events=height, solver="dopri8", rtol=1e-12, atol=1e-12
    )
    c0 = float(system.center_of_mass(q0, params)[2])
    mass = float(params["base_m"] + jnp.sum(params["m"]))
    rate = float(system.momentum(q0, v0, params)[5]) / mass
    g = float(params["g"])
    t_star = (rate + np.sqrt(rate**2 + 2 * g * (c0 - level))) / g
    record = sol.events[0]
    assert int(record.count) == 1 and sol.ok
    assert abs(float(record.times[0]) - t_star) < 1e-9
    assert abs(float(sol.t_end) - t_star) < 1e-9
    assert record.q.shape[-1] == 7 + robot.n and record.qd.shape[-1] == 6 + robot.n


# ---------------------------------------------------------------------------- derivatives
@pytest.fixture(scope="module", params=["arm7", "solo12"])
def free_flyer(request):
    return _robot(request.param)


def test_derivatives_match_pinocchio_free_flyer(free_flyer):
    """`forward_dynamics_derivatives` and `inverse_dynamics_derivatives` of a floating
    base against Pinocchio's `computeABADerivatives` and `computeRNEADerivatives` on the
    same free-flyer model: derivatives with respect to the configuration on its tangent
    space, the base moved in its own frame (Pinocchio's `integrate`)."""
    robot, params, model = free_flyer
    data = model.createData()
    system = robot.system()
    rng = np.random.default_rng(11)
    errors = []
    for _ in range(2):
        q, v, tau, vdot = _random_inputs(rng, robot.n)
        qp, vp, idx = _pin(model, robot, q, v)
        tau_p, vdot_p = _in_pin_order(model, idx, tau), _in_pin_order(model, idx, vdot)
        block = np.ix_(idx, idx)
        fwd = system.forward_dynamics_derivatives(q, v, params, tau)
        pin.computeABADerivatives(model, data, qp, vp, tau_p)
        m_inv = _symmetric(data.Minv)
        inv = system.inverse_dynamics_derivatives(q, v, vdot, params)
        dq_p, dv_p, m_p = pin.computeRNEADerivatives(model, data, qp, vp, vdot_p)
        m_p = _symmetric(m_p)
        errors.append(
            [
                rel_error(fwd.qdd, data.ddq[idx]),
                rel_error(fwd.dq, data.ddq_dq[block]),
                rel_error(fwd.dqd, data.ddq_dv[block]),
                rel_error(fwd.dtau, m_inv[block]),
                rel_error(inv.tau, pin.rnea(model, data, qp, vp, vdot_p)[idx]),
                rel_error(inv.dq, dq_p[block]),
                rel_error(inv.dqd, dv_p[block]),
                rel_error(inv.dqdd, m_p[block]),
            ]
        )
    assert np.max(errors) <= 1e-10, errors


def test_floating_linearize_matches_pinocchio_differences():
    """`linearize` of a moving floating base (`v_eq ≠ 0`, so that the base's
    `−½ ad_V` block matters) against central differences of the nonlinear tangent-space
    map built from Pinocchio alone: `δ̇ = dDifference(q_eq, q_eq ⊕ δ) v` and
    `v̇ = aba(q_eq ⊕ δ, v, τ)`, with `⊕` Pinocchio's `integrate`."""
    robot, params, model = _robot("arm7")
    data = model.createData()
    system = robot.system()
    rng = np.random.default_rng(2)
    q, v = _random_state(rng, robot.n)
    tau = rng.normal(size=6 + robot.n)
    a_mat, b_mat = system.linearize(q, v, params, tau)
    qp, vp, idx = _pin(model, robot, q, v)
    tau_p = _in_pin_order(model, idx, tau)
    nv = model.nv

    def f(x, u):
        delta, w = x[:nv], x[nv:]
        moved = pin.integrate(model, qp, delta)
        jac = pin.dDifference(model, qp, moved, pin.ArgumentPosition.ARG1)
        return np.concatenate([jac @ w, pin.aba(model, data, moved, w, u)])

    x0, eps = np.concatenate([np.zeros(nv), vp]), 1e-6
    cols_x = [(f(x0 + eps * e, tau_p) - f(x0 - eps * e, tau_p)) / (2 * eps) for e in np.eye(2 * nv)]
    cols_u = [(f(x0, tau_p + eps * e) - f(x0, tau_p - eps * e)) / (2 * eps) for e in np.eye(nv)]
    a_ref, b_ref = np.array(cols_x).T, np.array(cols_u).T
    both = np.concatenate([idx, nv + idx])
    assert rel_error(a_mat, a_ref[np.ix_(both, both)]) < 1e-7
    assert rel_error(b_mat, b_ref[np.ix_(both, idx)]) < 1e-7
    # the base block is the twist's −½ ad_V, not zero, for a moving base
    assert float(jnp.max(jnp.abs(a_mat[:6, :6]))) > 0.1


def test_floating_derivatives_with_damping_and_params_match_autodiff():
    """With joint damping and with respect to `params`: the derivatives call against
    plain autodiff of `forward_dynamics` along `q ⊕ δ`, under `jit` and `vmap` too."""
    from lagrax._multibody.floating.derivatives import retract

    robot, params, _ = _robot("arm7")
    params = dict(params, damping=jnp.full(robot.n, 0.3))
    system = robot.system()
    rng = np.random.default_rng(4)
    q, v = (jnp.asarray(x) for x in _random_state(rng, robot.n))
    tau = jnp.asarray(rng.normal(size=6 + robot.n))
    out = system.forward_dynamics_derivatives(q, v, params, tau, wrt_params=True)

    def fd(delta, w, u, p):
        return system.forward_dynamics(retract(q, delta), w, p, u)

    zero = jnp.zeros(6 + robot.n)
    ref = jax.jacfwd(fd, argnums=(0, 1, 2, 3))(zero, v, tau, params)
    assert rel_error(out.dq, ref[0]) < 1e-12
    assert rel_error(out.dqd, ref[1]) < 1e-12
    assert rel_error(out.dtau, ref[2]) < 1e-12
    for key in ("damping", "m", "com"):
        assert rel_error(out.dparams[key], ref[3][key]) < 1e-12, key
    inv = system.inverse_dynamics_derivatives(q, v, out.qdd, params)
    assert rel_error(inv.tau, tau) < 1e-12  # τ(v̇(τ)) = τ
    assert rel_error(inv.dqd, -inv.dqdd @ out.dqd) < 1e-10  # ∂v̇/∂v = −M⁻¹ ∂τ/∂v
    batch = jax.jit(jax.vmap(lambda a, b: system.forward_dynamics_derivatives(a, b, params)))
    many = batch(jnp.stack([q, q]), jnp.stack([v, 2 * v]))
    one = system.forward_dynamics_derivatives(q, 2 * v, params)
    assert rel_error(many.dq[1], one.dq) < 1e-12


_MIMIC_TREE = """<robot name="mimic_tree">
  <link name="base"><inertial><origin xyz="0.02 0.01 -0.03"/><mass value="3"/>
    <inertia ixx="0.1" ixy="0.01" ixz="0" iyy="0.2" iyz="0.02" izz="0.25"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 1 0"/></joint>
  <link name="a"><inertial><origin xyz="0.1 0 0.1"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0.002" iyy="0.02" iyz="0" izz="0.015"/></inertial></link>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0.3 0 0" rpy="0.2 0 0.4"/><axis xyz="1 0 0"/>
    <mimic joint="j1" multiplier="0.7" offset="0.1"/></joint>
  <link name="b"><inertial><origin xyz="0 0.1 0"/><mass value="0.5"/>
    <inertia ixx="0.004" ixy="0" ixz="0" iyy="0.003" iyz="0.001" izz="0.005"/></inertial></link>
  <joint name="j3" type="prismatic"><parent link="base"/><child link="c"/>
    <origin xyz="0 0.2 0"/><axis xyz="0 0.6 0.8"/></joint>
  <link name="c"><inertial><origin xyz="0.05 0 0"/><mass value="0.8"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
</robot>"""


def test_floating_derivatives_mimic_prismatic_branches_match_autodiff():
    """The analytic free-root recursion on a tree with two branches from the base, a
    mimic joint (`θ_2 = 0.7 θ_1 + 0.1`), a prismatic joint and joint damping, at a moving
    and accelerating base: `τ`, `∂τ/∂q` (along `q ⊕ δ`), `∂τ/∂v` and `M` against plain
    forward-mode autodiff of the free-root Newton–Euler recursion, to 1e-12."""
    from lagrax._multibody.floating.derivatives import retract

    robot, params = lx.chains.from_urdf(_MIMIC_TREE, floating_base=True)
    assert robot.n == 2 and robot.tree.mimic  # j2 follows j1
    params = dict(params, damping=jnp.asarray([0.3, 0.2, 0.5]))
    system = robot.system()
    rng = np.random.default_rng(5)
    for _ in range(2):
        q, v = (jnp.asarray(x) for x in _random_state(rng, robot.n))
        vdot = jnp.asarray(rng.normal(size=6 + robot.n))
        out = system.inverse_dynamics_derivatives(q, v, vdot, params)
        zero = jnp.zeros(6 + robot.n)
        jq, jv = jax.jacfwd(
            lambda d, w, q=q, vdot=vdot: system._inverse(retract(q, d), w, vdot, params),
            argnums=(0, 1),
        )(zero, v)
        assert rel_error(out.tau, system._inverse(q, v, vdot, params)) < 1e-12
        assert rel_error(out.dq, jq) < 1e-12
        assert rel_error(out.dqd, jv) < 1e-12
        assert rel_error(out.dqdd, system.mass_matrix(q, params)) < 1e-12


def test_floating_derivatives_bad_input():
    robot, params, _ = _robot("arm7")
    system = robot.system()
    q, v = _random_state(np.random.default_rng(0), robot.n)
    with pytest.raises(lx.ShapeError, match="qd"):
        system.forward_dynamics_derivatives(q, v[:-1], params)
    with pytest.raises(lx.NonFiniteError, match="qd"):
        system.forward_dynamics_derivatives(q, np.where(np.arange(v.size) == 2, np.nan, v), params)
    position_nan = np.where(np.arange(q.size) == 0, np.nan, q)  # not read by the dynamics
    with pytest.raises(lx.NonFiniteError, match="q "):
        system.inverse_dynamics_derivatives(position_nan, v, v, params)
    # under jit, equinox's run-time check (JAX's runtime error, with the message)
    for call in (
        lambda: jax.jit(lambda a: system.linearize(a, v, params))(position_nan),
        lambda: jax.jit(lambda u: system.forward_dynamics_derivatives(q, v, params, u))(
            np.full(v.size, np.inf)
        ),
    ):
        with pytest.raises(Exception, match="not finite"):  # noqa: PT011
            jax.block_until_ready(call())
