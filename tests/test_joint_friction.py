"""Joint friction loss (MuJoCo's ``frictionloss``): regularized Coulomb friction with
stiction, the contacts' law (``lagrax._core.friction``), as a dissipation of the tree.

- Closed forms on a block on a slide (mass ``m``, friction loss ``f``, stiction velocity
  ``v_s``, no gravity): sliding (``|v| ≥ v_s``) it accelerates at ``(τ − f sign v)/m``;
  pushed from rest by ``τ < f`` it stays put but for the creep ``v* = v_s (1 − √(1 −
  τ/f))`` the law holds it at; the energy balance (``Solution.work``) holds; with a
  stiction peak ``f_s``, the force is ``f_s`` at ``v_s`` and ``f`` from ``3 v_s`` on.
- ``forward_dynamics_derivatives``' ``∂q̈/∂q̇`` against the closed form ``−f μ̂'(s)/(m
  v_s)`` in each branch of the law (at rest, creeping, easing, sliding), and against
  central differences.
- On a floating base: the friction's generalized force is ``−f sign θ̇`` on the joint
  and nothing on the base (``M (v̇ − v̇₀)``).
- ``Tree.params(frictionloss=...)`` gives the entries ``from_mjcf`` reads.
"""

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax.chains import from_mjcf

pytest.importorskip("mujoco", reason="the models are MJCF")

M, F, VS = 2.0, 0.8, 0.01
BLOCK = f"""<mujoco><option gravity="0 0 0"/><worldbody><body>
  <joint name="slide" type="slide" axis="1 0 0" frictionloss="{F}"/>
  <geom type="box" size="0.1 0.1 0.1" mass="{M}"/>
</body></worldbody></mujoco>"""


@pytest.fixture(scope="module")
def block():
    tree, params = from_mjcf(BLOCK, friction_velocity=VS)
    return tree.system(), params


def _slope(s):
    """`μ̂'(s)` with `μ_s = μ = 1`: `2 (1 − s)` below `s = 1`, zero above."""
    return 2.0 * (1.0 - s) if s <= 1.0 else 0.0


def test_sliding_block_accelerates_at_the_kinetic_force(block):
    system, params = block
    for v, tau in [(0.5, 0.3), (-0.5, 0.3), (VS, 2.0), (-3 * VS, -2.0)]:
        qdd = system.forward_dynamics(jnp.zeros(1), jnp.array([v]), params, jnp.array([tau]))
        assert abs(float(qdd[0]) - (tau - F * np.sign(v)) / M) < 1e-13


def test_stiction_peak_holds_more_than_sliding(block):
    """``frictionloss_static`` ``f_s > f``: the law peaks at ``f_s`` at ``v_s`` and is
    ``f`` from ``3 v_s`` on (the contacts' stiction)."""
    system, params = block
    params = dict(params, frictionloss_static=jnp.array([1.5 * F]))
    for v, force in [(VS, 1.5 * F), (-3 * VS, -F), (2 * VS, 1.25 * F)]:
        qdd = system.forward_dynamics(jnp.zeros(1), jnp.array([v]), params, jnp.array([0.1]))
        assert abs(float(qdd[0]) - (0.1 - force) / M) < 1e-13


def test_block_pushed_below_the_friction_loss_stays_put(block):
    system, params = block
    tau = 0.6 * F
    sol = lx.simulate(system, [0.0], [0.0], params, t1=1.0, tau=jnp.array([tau]), solver="kvaerno5")
    assert bool(sol.ok)
    creep = VS * (1.0 - np.sqrt(1.0 - tau / F))
    assert abs(float(sol.qd[-1, 0]) / creep - 1.0) < 1e-6
    assert 0.0 < float(sol.q[-1, 0]) < creep * 1.0  # never faster than the creep
    # the friction's work: without it the balance would be off by all of τ's work
    # (the kinetic energy is ~1e-5 of it: the error is relative to that energy)
    assert float(np.max(np.abs(sol.energy_error))) < 1e-4


def test_friction_derivative_is_the_law_slope(block):
    system, params = block
    q, tau = jnp.zeros(1), jnp.array([0.1])
    for v in [0.0, 0.3 * VS, -0.7 * VS, 1.5 * VS, 0.2]:
        out = system.forward_dynamics_derivatives(q, jnp.array([v]), params, tau)
        expected = -F * _slope(abs(v) / VS) / VS / M
        assert abs(float(out.dqd[0, 0]) - expected) < 1e-10 * max(1.0, abs(expected))
        h = 1e-7 * VS
        fd = system.forward_dynamics(q, jnp.array([v + h]), params, tau)
        fd = (fd - system.forward_dynamics(q, jnp.array([v - h]), params, tau)) / (2 * h)
        assert abs(float(out.dqd[0, 0] - fd[0])) < 1e-5 * max(1.0, abs(expected))


FLOATING = """<mujoco><option gravity="0 0 -9.8"/><worldbody><body pos="0 0 1">
  <freejoint/><geom type="box" size="0.2 0.1 0.05"/>
  <body pos="0.2 0 0"><joint name="hinge" axis="0 1 1" frictionloss="0.3" damping="0.1"/>
    <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/></body>
</body></worldbody></mujoco>"""


def test_floating_base_friction_is_a_joint_force():
    robot, params = from_mjcf(FLOATING)
    system = robot.system()
    rng = np.random.default_rng(1)
    quat = rng.normal(size=4)
    q = jnp.asarray(np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat), [0.4]]))
    v = jnp.asarray(np.concatenate([rng.normal(size=6), [-0.7]]))
    frictionless = {k: x for k, x in params.items() if k != "frictionloss"}
    frictionless.pop("friction_velocity")
    a = system.forward_dynamics(q, v, params)
    a0 = system.forward_dynamics(q, v, frictionless)
    force = np.asarray(system.mass_matrix(q, params) @ (a - a0))
    assert np.max(np.abs(force - np.array([0, 0, 0, 0, 0, 0, 0.3]))) < 1e-12


def test_tree_params_give_the_friction_entries():
    tree, params = from_mjcf(BLOCK, friction_velocity=VS)
    mine = tree.params(m=M, frictionloss=F, friction_velocity=VS, inertia=params["inertia"])
    assert float(mine["frictionloss"][0]) == F and float(mine["friction_velocity"]) == VS
    with pytest.raises(lx.ParameterError, match="friction_velocity"):
        tree.params(frictionloss=F, friction_velocity=0.0)
