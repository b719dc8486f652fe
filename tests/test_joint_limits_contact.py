"""Joint limits as compliant contacts in joint space (``limits="contact"``).

A rod on a hinge, horizontal at ``q = 0``, is released from rest and falls onto its
upper limit (60°), where gravity holds it. Checked against independent sources:

- it comes to rest at the limit, its penetration the static one of the stop's law under
  the rod's gravity torque ``m g r cos 60°`` (closed form from the coefficients);
- the stop's force at a state past the limit is the Hunt–Crossley law's closed form,
  on the joint alone, never pulling;
- the energy balance (``h − h₀ − W``, the stop's stored energy in ``h`` and its
  dissipation in ``W``) closes along the impact;
- MuJoCo, which enforces the same limit by a soft constraint, rests at the same angle
  within its softness.
"""

import math

import numpy as np
import pytest

import lagrax as lx
from lagrax._core.errors import ConfigurationError
from lagrax.contact import ContactSystem, JointLimit

G, MASS, COM = 9.81, 1.0, 0.25  # the rod: 0.5 long, its centre of mass halfway
UPPER = math.radians(60.0)
XML = """
<mujoco>
  <option timestep="0.0005"/>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="arm" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" limited="true" range="-90 60"/>
      <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.02" mass="1"/>
    </body>
  </worldbody>
</mujoco>
"""
URDF = """<robot name="rod">
  <link name="base"/>
  <link name="rod"><inertial><origin xyz="0.25 0 0"/><mass value="1.0"/>
    <inertia ixx="0.0002" ixy="0" ixz="0" iyy="0.021" iyz="0" izz="0.021"/></inertial>
    <collision><origin xyz="0.5 0 0"/><geometry><sphere radius="0.02"/></geometry></collision>
  </link>
  <joint name="hinge" type="revolute"><parent link="base"/><child link="rod"/>
    <origin xyz="0 0 1"/><axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.0" effort="10" velocity="5"/></joint>
  <joint name="slide" type="prismatic"><parent link="rod"/><child link="tip"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.1" effort="10" velocity="5"/></joint>
  <link name="tip"><inertial><mass value="0.1"/>
    <inertia ixx="1e-5" ixy="0" ixz="0" iyy="1e-5" iyz="0" izz="1e-5"/></inertial></link>
</robot>"""


@pytest.fixture(scope="module")
def rod():
    scene, params = lx.chains.from_mjcf(XML, contact=True, limits="contact")
    # the saves resolve the ~10 ms impact (at t ≈ 0.276 s) finely: Solution.work is
    # integrated from them
    ts = np.concatenate(
        [
            np.linspace(0.0, 0.275, 30),
            np.linspace(0.2757, 0.30, 8001)[1:],
            np.linspace(0.30, 1.0, 30)[1:],
        ]
    )
    sol = lx.simulate(scene, [0.0], [0.0], params, t1=1.0, solver="kvaerno5", ts=ts)
    return scene, params, sol


def test_the_file_limits_become_stops_on_their_joint(rod):
    scene, params, _ = rod
    (limit,) = scene.limits
    assert limit.name == "hinge" and limit.angular and (limit.index, limit.rate) == (0, 0)
    assert (limit.lower, limit.upper) == pytest.approx((-math.pi / 2, UPPER))


def test_a_rod_released_against_its_limit_rests_there(rod):
    scene, params, sol = rod
    assert bool(sol.ok)
    co = scene.coefficients(params)
    k = float(co.limit_stiffness[0])
    rest = 0.0  # k δ^p = m g r cos(60° + δ): gravity's torque about the hinge, held
    for _ in range(5):
        torque = MASS * G * COM * math.cos(UPPER + rest)
        rest = (torque / k) ** (1.0 / scene.exponent)
    assert rest < 1e-4  # a small static penetration (radians)
    assert abs(float(sol.q[-1, 0]) - (UPPER + rest)) < 1e-3 * rest
    assert abs(float(sol.qd[-1, 0])) < 1e-9  # at rest
    # the upper stop (the second: lower before upper) holds the gravity torque
    assert float(sol.limit_force[-1, 1]) == pytest.approx(-torque, rel=1e-6)
    assert float(sol.limit_force[-1, 0]) == 0.0
    # the stop stopped it dead: it never bounced back off the limit
    hit = np.asarray(sol.ts) > 0.28
    assert np.all(np.asarray(sol.limit_gap[hit, 1]) < 0)
    assert float(np.min(sol.limit_gap[:, 1])) > -1e-3  # deepest in the impact


def test_the_stop_force_is_the_hunt_crossley_law(rod):
    scene, params, _ = rod
    co = scene.coefficients(params)
    k, c, p = float(co.limit_stiffness[0]), float(co.limit_dissipation[0]), scene.exponent
    delta, closing = 2e-4, 0.3  # past the upper limit, still turning into it
    state = scene.contact_state(np.array([UPPER + delta]), np.array([closing]), params)
    expected = k * delta**p * (1.0 + 1.5 * c * closing)
    assert float(state["limit_force"][1]) == pytest.approx(-expected, rel=1e-12)
    assert float(state["limit_elastic_force"][1]) == pytest.approx(k * delta**p, rel=1e-12)
    # on the joint alone (the rod's only joint), and the ground far below adds nothing
    assert float(state["generalized"][0]) == pytest.approx(-expected, rel=1e-12)
    # separating faster than 2/(3c): no pull
    state = scene.contact_state(np.array([UPPER + delta]), np.array([-1.0 / c]), params)
    assert float(state["limit_force"][1]) == 0.0
    energy = float(scene.contact_energy(np.array([UPPER + delta]), params))
    assert energy == pytest.approx(k * delta ** (p + 1) / (p + 1), rel=1e-12)


def test_the_energy_balance_closes_through_the_impact(rod):
    scene, params, sol = rod
    assert float(np.max(np.abs(sol.energy_error))) < 1e-4  # measured 8e-6
    # the stop took the fall's energy (rest: the stored spring, ~1e-5 J, aside)
    drop = MASS * G * COM * math.sin(UPPER)
    assert float(sol.work[-1]) == pytest.approx(-drop, rel=1e-3)


def test_mujoco_rests_at_the_same_limit(rod):
    mujoco = pytest.importorskip("mujoco")
    _, _, sol = rod
    model = mujoco.MjModel.from_xml_string(XML)
    data = mujoco.MjData(model)
    for _ in range(2000):  # 1 s at 0.5 ms
        mujoco.mj_step(model, data)
    assert abs(float(data.qvel[0])) < 1e-6
    # MuJoCo's soft limit sinks 4.7e-4 rad at rest, lagrax's stop 4e-5
    assert abs(float(data.qpos[0]) - float(sol.q[-1, 0])) < 1e-3


def test_urdf_limits_become_stops_a_slide_in_metres():
    scene, params = lx.chains.from_urdf(URDF, contact=True, limits="contact")
    hinge, slide = scene.limits
    assert (hinge.name, hinge.angular, hinge.lower, hinge.upper) == ("hinge", True, -1.5, 1.0)
    assert (slide.name, slide.angular, slide.index) == ("slide", False, 1)
    co = scene.coefficients(params)
    # both critically damped stops as fast as the ground contact: the hinge's
    # dissipation (per radian) is the slide's (per metre) times the scene's size, here
    # its one sphere's radius
    ratio = float(co.limit_dissipation[0]) / float(co.limit_dissipation[1])
    assert ratio == pytest.approx(0.02, rel=1e-12)


def test_limits_contact_needs_a_contact_scene():
    with pytest.raises(ConfigurationError, match="contact=True"):
        lx.chains.from_mjcf(XML, limits="contact")
    with pytest.raises(ConfigurationError, match="contact=True"):
        lx.chains.from_urdf(URDF, limits="contact")
    scene, _ = lx.chains.from_mjcf(XML, contact=True, limits="contact")
    with pytest.raises(ConfigurationError, match="lower < upper"):
        ContactSystem(scene.system, scene.spheres, scene.plane, limits=[JointLimit(0, 1.0, 0.5)])
    with pytest.raises(ConfigurationError, match="limit_stiffness"):
        ContactSystem(
            scene.system,
            scene.spheres,
            scene.plane,
            limits=[JointLimit(0, 0.0, 0.5)],
            limit_stiffness=-1.0,
        )


def test_a_joint_started_past_its_limit_starts_at_it(rod):
    scene, params, _ = rod
    q, v, ok = scene.initial_state(np.array([UPPER + 0.3]), np.array([0.7]), params)
    assert float(q[0]) == UPPER and float(v[0]) == 0.7 and bool(ok)
    q, _, _ = scene.initial_state(np.array([-2.0]), np.array([0.0]), params)
    assert float(q[0]) == -math.pi / 2
    q, _, _ = scene.initial_state(np.array([0.2]), np.array([0.0]), params)
    assert float(q[0]) == 0.2  # inside: unchanged
