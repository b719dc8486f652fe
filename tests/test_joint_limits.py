"""Joint limits as impacts (``from_urdf(..., limits="impact")`` and
``lagrax.chains.limit_events``).

A 2-link arm from a small URDF, released from a raised shoulder, swings under gravity into
its shoulder's lower limit and its elbow's limits. Checked against the laws of a rigid
stop, not against the implementation's formula:

- every hit is at the limit angle (the recorded state before the impact);
- the reset reverses the joint's rate times the restitution, and the impulse it applies
  is a generalized force on that joint alone: ``M (q̇⁺ − q̇⁻)`` is zero in the other
  joints (the stop cannot push them);
- hence the kinetic energy falls by ``½ (1 − e²) (q̇_i⁻)² / (M⁻¹)_ii`` at each hit:
  the energy of the saved trajectory (conserved between hits, no damping) steps down by
  that much, with ``M⁻¹`` from an independent dense inverse of ``M``;
- the joints stay within their limits for the whole run.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax.chains import from_urdf, limit_events

URDF = """<robot name="arm2">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="0 0 -0.25"/><mass value="1.0"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.001"/></inertial></link>
  <link name="lower"><inertial><origin xyz="0 0 -0.2"/><mass value="0.6"/>
    <inertia ixx="0.008" ixy="0" ixz="0" iyy="0.008" iyz="0" izz="0.0005"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <axis xyz="0 1 0"/><limit lower="-0.6" upper="2.5" effort="10" velocity="5"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/>
    <origin xyz="0 0 -0.5"/><axis xyz="0 1 0"/>
    <limit lower="-0.8" upper="0.8" effort="5" velocity="5"/></joint>
</robot>"""
E = 0.5


@pytest.fixture(scope="module")
def swing():
    tree, params = from_urdf(URDF, limits="impact", restitution=E)
    events = limit_events(tree)
    sol = lx.simulate(
        tree.system(),
        jnp.array([1.5, 0.0]),
        jnp.zeros(2),
        params,
        t1=5.0,
        n_save=2001,
        events=events,
        rtol=1e-11,
        atol=1e-11,
    )
    return tree, params, events, sol


def _hits(sol, k):
    rec = sol.events[k]
    c = int(rec.count)
    return np.asarray(rec.times[:c]), np.asarray(rec.q[:c]), np.asarray(rec.qd[:c])


def test_hits_are_at_the_limits_and_the_joints_stay_within(swing):
    tree, params, events, sol = swing
    assert sol.ok and len(events) == 2
    np.testing.assert_allclose(params["restitution"], [E, E])
    total = 0
    for k, (lo, hi) in enumerate(tree.limits):
        times, q, _ = _hits(sol, k)
        total += len(times)
        at = np.where(np.abs(q[:, k] - lo) < np.abs(q[:, k] - hi), lo, hi)
        np.testing.assert_allclose(q[:, k], at, atol=1e-9)
        assert np.all(np.asarray(sol.q[:, k]) >= lo - 1e-9)
        assert np.all(np.asarray(sol.q[:, k]) <= hi + 1e-9)
    times, q, _ = _hits(sol, 0)
    assert len(times) >= 2 and q[0, 0] == pytest.approx(-0.6, abs=1e-9)
    assert total >= 5


def test_each_impact_obeys_restitution_and_acts_on_its_joint_only(swing):
    tree, params, events, sol = swing
    system = tree.system()
    for k, ev in enumerate(events):
        for t, q, qd in zip(*_hits(sol, k), strict=True):
            q_after, qd_after = ev.reset(t, jnp.asarray(q), jnp.asarray(qd), params)
            assert float(qd_after[k]) == pytest.approx(-E * qd[k], rel=1e-12)
            impulse = np.asarray(system.mass_matrix(q_after, params)) @ (qd_after - qd)
            other = 1 - k
            assert abs(impulse[other]) <= 1e-12 * abs(impulse[k])
            assert abs(impulse[k]) > 0


def test_energy_drops_by_the_restitution_law_at_each_hit(swing):
    tree, params, _, sol = swing
    system = tree.system()
    ts, energy = np.asarray(sol.ts), np.asarray(sol.energy)
    hits = sorted(
        (t, k, q, qd) for k in range(tree.n) for t, q, qd in zip(*_hits(sol, k), strict=True)
    )
    bounds = [ts[0]] + [h[0] for h in hits] + [ts[-1] + 1]
    plateaus = []  # the energy between hits: constant (no damping)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        inside = energy[(ts > a) & (ts < b)]
        if inside.size:
            assert np.ptp(inside) < 1e-7 * max(1.0, abs(inside[0]))
        plateaus.append(inside[0] if inside.size else np.nan)
    checked = 0
    for j, (_, k, q, qd) in enumerate(hits):
        before, after = plateaus[j], plateaus[j + 1]
        if np.isnan(before) or np.isnan(after):
            continue  # two hits with no save between them
        inverse = np.linalg.inv(np.asarray(system.mass_matrix(jnp.asarray(q), params)))
        drop = 0.5 * (1 - E**2) * qd[k] ** 2 / inverse[k, k]
        assert before - after == pytest.approx(drop, rel=1e-6, abs=1e-9)
        checked += 1
    assert checked >= 4


def test_restitution_as_an_argument_and_one_joint():
    tree, params = from_urdf(URDF)  # limits=None: unchanged params, limits not enforced
    assert "restitution" not in params
    (event,) = limit_events(tree, restitution=1.0, joints=["shoulder"])
    q, qd = jnp.array([-0.6, 0.3]), jnp.array([-2.0, 0.5])
    q_after, qd_after = event.reset(0.0, q, qd, params)
    assert float(qd_after[0]) == pytest.approx(2.0, rel=1e-14)
    energy = jax.jit(tree.system().energy)
    assert float(energy(q_after, qd_after, params)) == pytest.approx(
        float(energy(q, qd, params)), rel=1e-13
    )
    assert float(event.condition(0.0, jnp.array([0.2, 0.0]), qd, params)) == pytest.approx(0.8)


def test_bad_limit_options_are_named():
    tree, params = from_urdf(URDF)
    with pytest.raises(lx.ConfigurationError, match="'bounce'"):
        from_urdf(URDF, limits="bounce")
    with pytest.raises(lx.ConfigurationError, match=r"restitution\[0\] = 1.5"):
        from_urdf(URDF, limits="impact", restitution=1.5)
    with pytest.raises(lx.ConfigurationError, match="'wrist'"):
        limit_events(tree, joints=["wrist"])
    unlimited = URDF.replace('type="revolute"', 'type="continuous"')
    with pytest.raises(lx.ConfigurationError, match="no joint .* finite limit"):
        from_urdf(unlimited, limits="impact")
    with pytest.raises(lx.ParameterError, match="restitution"):
        lx.simulate(
            tree.system(), [0.0, 0.0], [0.0, 0.0], params, t1=0.1, events=limit_events(tree)
        )


# The same arm on a free-floating base (2 kg, its own inertia), in zero gravity.
FLOATING = URDF.replace(
    '<link name="base"/>',
    '<link name="base"><inertial><mass value="2.0"/>'
    '<inertia ixx="0.05" ixy="0" ixz="0" iyy="0.04" iyz="0" izz="0.03"/></inertial></link>',
)


def test_floating_base_joint_hits_its_limit():
    """A floating base's joints stop at their limits too (``q[7:]``, ``v[6:]``): in zero
    gravity the elbow, set swinging, hits both its stops; each hit is at the limit angle,
    reverses the elbow's rate times the restitution, and its impulse ``M (v⁺ − v⁻)`` acts
    on the elbow alone, not on the base, so the robot's spatial momentum is the same
    after every hit as before (an internal impulse), and the kinetic energy falls by
    ``½ (1 − e²) v_k² / (M⁻¹)_kk``."""
    robot, params = from_urdf(FLOATING, floating_base=True, limits="impact", restitution=E, g=0.0)
    assert isinstance(robot, lx.chains.FloatingTree)
    np.testing.assert_allclose(params["restitution"], [E, E])
    system, events = robot.system(), limit_events(robot)
    assert len(events) == 2
    q0 = jnp.array([0.1, -0.2, 0.3, 0.0, 0.0, 0.0, 1.0, 0.2, 0.0])
    v0 = jnp.array([0.05, 0.0, -0.1, 0.0, 0.2, 0.0, 0.0, 4.0])
    sol = lx.simulate(
        system, q0, v0, params, t1=3.0, n_save=301, events=events, rtol=1e-11, atol=1e-11
    )
    assert sol.ok
    h = np.asarray(jax.vmap(lambda q, v: system.momentum(q, v, params))(sol.q, sol.qd))
    assert np.max(np.abs(h - h[0])) <= 1e-9 * np.linalg.norm(h[0])
    mass_matrix = jax.jit(system.mass_matrix)
    hits = 0
    for k, (ev, (lo, hi)) in enumerate(zip(events, robot.tree.limits, strict=True)):
        assert np.all(np.asarray(sol.q[:, 7 + k]) >= lo - 1e-9)
        assert np.all(np.asarray(sol.q[:, 7 + k]) <= hi + 1e-9)
        for t, q, v in zip(*_hits(sol, k), strict=True):
            hits += 1
            assert min(abs(q[7 + k] - lo), abs(q[7 + k] - hi)) < 1e-9
            q_after, v_after = ev.reset(t, jnp.asarray(q), jnp.asarray(v), params)
            assert float(v_after[6 + k]) == pytest.approx(-E * v[6 + k], rel=1e-12)
            mass = np.asarray(mass_matrix(q_after, params))
            impulse = mass @ (np.asarray(v_after) - v)
            others = np.delete(impulse, 6 + k)
            assert np.max(np.abs(others)) <= 1e-12 * abs(impulse[6 + k])
            # the impulse acts at the stop (q_after: the crossing clipped to the limit)
            h_before = np.asarray(system.momentum(q_after, jnp.asarray(v), params))
            h_after = np.asarray(system.momentum(q_after, v_after, params))
            scale = np.linalg.norm(h_before)
            np.testing.assert_allclose(h_after, h_before, rtol=0, atol=1e-12 * scale)
            drop = 0.5 * (1 - E**2) * v[6 + k] ** 2 / np.linalg.inv(mass)[6 + k, 6 + k]
            kinetic = 0.5 * (v @ mass @ v - np.asarray(v_after) @ mass @ np.asarray(v_after))
            assert kinetic == pytest.approx(drop, rel=1e-10)
    assert len(_hits(sol, 1)[0]) >= 2 and hits >= 2
