"""Legged robots stand: dropped under joint PD onto the ground, they come to rest on their
feet, their base height steady (≤ 1 mm over the last second), their feet in the ground by
at most 2 mm, and the feet's normal forces sum to the weight `m g`.

The default suite runs a planar two-legged body (five coordinates, cheap to compile);
`LAGRAX_ALL_ROBOTS=1` runs solo12 from example-robot-data, its feet read from its URDF
(`from_urdf(..., contact=[feet])`).

Each runs twice. With the defaults: the default coefficients and the default method for
a scene where a contact can stick, the linearly implicit `rodas4`. And with an explicit
method (`tsit5`) and contact coefficients chosen for it, from the scene: the stiffness
that gives a static penetration of 0.5 mm under each foot's share of the weight
(`k = (m g / n_feet) / δ^1.5`), the dissipation that damps that spring critically
(`c = 4/3 √(1.5 / (g δ))`) and a stiction velocity of 1 cm/s. (The defaults, 10⁻⁴ of
the scene's size, are for the implicit default: an explicit method crawls on them.)
"""

import glob
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import every_robot
from lagrax.contact import ContactSystem, Plane, Sphere

G = 9.81
DEPTH = 5e-4  # the static penetration the stiffness is chosen for


def _coefficients(weight, n_feet):
    """`(stiffness, dissipation)` for a static penetration `DEPTH` under `weight/n_feet`
    per foot (Hertz's exponent 3/2), critically damped."""
    return (weight / n_feet) / DEPTH**1.5, 4.0 / 3.0 * np.sqrt(1.5 / (G * DEPTH))


def _check_standing(sol, ts, height):
    """The claims: a solve that succeeded, the base's `height` steady over the last
    second, the feet never deeper than 2 mm, and dropped (in the air at first)."""
    assert bool(sol.ok)
    last = ts >= ts[-1] - 1.0
    height = np.asarray(height)
    assert np.ptp(height[last]) <= 1e-3  # base height drift over the last second
    assert float(np.min(sol.contact_gap)) >= -2e-3  # penetration, all along
    assert float(np.min(sol.contact_gap[0])) > 0.05  # it was dropped: in the air at first


# --------------------------------------------------------------------------- planar
A, L, R = 0.15, 0.2, 0.01  # half the body's length, a leg's length, a foot's radius
M, MLEG = 2.0, 0.2
SIDES = (-1.0, 1.0)


def _rot(t):
    return jnp.array([[jnp.cos(t), -jnp.sin(t)], [jnp.sin(t), jnp.cos(t)]])


def _along(q, i, s, r):
    """A point at distance `r` down leg `i` (on side `s`) from its hip: the body is a bar
    `q[:3] = (x, y, θ)`, the legs hang from its ends at the angles `q[3:]`."""
    a = q[2] + q[3 + i]
    return q[:2] + _rot(q[2]) @ jnp.array([s * A, 0.0]) + r * jnp.stack([jnp.sin(a), -jnp.cos(a)])


def _kinetic(q, qd, p):
    out = 0.5 * M * (qd[0] ** 2 + qd[1] ** 2) + 0.5 * M * (2 * A) ** 2 / 12 * qd[2] ** 2
    for i, s in enumerate(SIDES):
        _, v = jax.jvp(lambda a, i=i, s=s: _along(a, i, s, 0.5 * L), (q,), (qd,))
        out = out + 0.5 * MLEG * v @ v + 0.5 * MLEG * L**2 / 12 * (qd[2] + qd[3 + i]) ** 2
    return out


def _potential(q, p):
    legs = sum(MLEG * _along(q, i, s, 0.5 * L)[1] for i, s in enumerate(SIDES))
    return G * (M * q[1] + legs)


def test_a_two_legged_body_dropped_under_joint_pd_stands():
    body = lx.LagrangianSystem(_kinetic, _potential, n_dof=5)
    feet = [
        Sphere(
            R, lambda q, p, i=i, s=s: _along(q, i, s, L), angle=lambda q, p, i=i: q[2] + q[3 + i]
        )
        for i, s in enumerate(SIDES)
    ]
    weight = (M + 2 * MLEG) * G
    k, c = _coefficients(weight, 2)
    scene = ContactSystem(
        body, feet, Plane([0.0, 1.0]), friction=0.8, stiffness=k, dissipation=c,
        stiction_velocity=0.01,
    )  # fmt: skip
    stance = jnp.array([-0.3, 0.3])  # the legs splayed

    def pd(t, q, qd):
        return jnp.concatenate([jnp.zeros(3), 20.0 * (stance - q[3:]) - 0.5 * qd[3:]])

    ts = np.linspace(0.0, 2.0, 201)
    q0 = jnp.concatenate([jnp.array([0.0, 0.3, 0.0]), stance])  # the body 0.3 m up
    run = dict(t1=2.0, ts=ts, tau=pd, rtol=1e-6, atol=1e-6, solver="tsit5")  # chosen for it
    sol = lx.simulate(scene, q0, jnp.zeros(5), {}, **run)
    _check_standing(sol, ts, sol.q[:, 1])
    forces = np.asarray(sol.contact_force[-1])
    assert abs(forces[:, 1].sum() / weight - 1.0) < 1e-4  # measured 8e-6
    assert abs(forces[:, 0].sum()) < 1e-4 * weight  # the legs push apart, friction holds


def test_a_two_legged_body_stands_with_the_defaults():
    """No coefficient and no method chosen: the default stiffness (10⁻⁴ of the scene's
    size deep at rest), dissipation and stiction velocity, and the default method for a
    scene where a contact can stick (`rodas4`). Measured: 264 steps, the base 7 µm lower
    over the last second, 0.065 mm the deepest, the feet's forces `m g (1 − 2e-9)`."""
    body = lx.LagrangianSystem(_kinetic, _potential, n_dof=5)
    feet = [
        Sphere(
            R, lambda q, p, i=i, s=s: _along(q, i, s, L), angle=lambda q, p, i=i: q[2] + q[3 + i]
        )
        for i, s in enumerate(SIDES)
    ]
    scene = ContactSystem(body, feet, Plane([0.0, 1.0]), friction=0.8)
    assert scene.default_method == "rodas4"
    stance = jnp.array([-0.3, 0.3])

    def pd(t, q, qd):
        return jnp.concatenate([jnp.zeros(3), 20.0 * (stance - q[3:]) - 0.5 * qd[3:]])

    ts = np.linspace(0.0, 2.0, 201)
    q0 = jnp.concatenate([jnp.array([0.0, 0.3, 0.0]), stance])
    sol = lx.simulate(scene, q0, jnp.zeros(5), {}, t1=2.0, ts=ts, tau=pd)
    _check_standing(sol, ts, sol.q[:, 1])
    last = ts >= 1.0
    assert np.ptp(np.asarray(sol.q[last, 0])) <= 1e-3  # creep ≤ 1 mm/s along the ground
    weight = (M + 2 * MLEG) * G
    forces = np.asarray(sol.contact_force[-1])
    assert abs(forces[:, 1].sum() / weight - 1.0) < 1e-4


# --------------------------------------------------------------------------- solo12
FEET = ["FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT"]
STANCE = [0.1, 0.8, -1.6, -0.1, 0.8, -1.6, 0.1, -0.8, 1.6, -0.1, -0.8, 1.6]  # its SRDF's


def _solo12_feet():
    """solo12 from example-robot-data on a floating base with its four feet as spheres
    (`from_urdf(..., contact=FEET)`): `(scene, params)`; skips where it is not installed."""
    pattern = "lib/python*/site-packages/cmeel.prefix/share/example-robot-data/robots"
    found = glob.glob(f"{sys.prefix}/{pattern}/solo_description/robots/solo12.urdf")
    if not found:
        pytest.skip("example-robot-data is not installed (pip install example-robot-data)")
    return lx.chains.from_urdf(found[0], floating_base=True, contact=FEET)


def solo12_standing(t1=2.0, defaults=False):
    """solo12 dropped from a base height of 0.3 m (its feet 7 cm up) in its SRDF's
    `standing` posture, held there by joint PD (`kp = 10`, `kd = 0.3`): its scene, params,
    the saves, the solution and its weight. `defaults`: the scene as `from_urdf` makes
    it and the default method, else coefficients and `tsit5` chosen for each other."""
    feet, params = _solo12_feet()
    weight = G * float(params["base_m"] + jnp.sum(params["m"]))
    k, c = _coefficients(weight, 4)
    scene = feet if defaults else ContactSystem(
        feet.system, feet.spheres, feet.plane, friction=feet.friction, stiffness=k,
        dissipation=c, stiction_velocity=0.01,
    )  # fmt: skip
    stance = jnp.asarray(STANCE)

    def pd(t, q, v):
        return jnp.concatenate([jnp.zeros(6), 10.0 * (stance - q[7:]) - 0.3 * v[6:]])

    q0 = jnp.concatenate([jnp.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 1.0]), stance])
    ts = np.linspace(0.0, t1, 201)
    run = dict(t1=t1, ts=ts, tau=pd)
    if not defaults:
        run.update(rtol=1e-5, atol=1e-5, solver="tsit5")  # chosen for the coefficients
    sol = lx.simulate(scene, q0, jnp.zeros(18), params, **run)
    return scene, params, ts, sol, weight


@every_robot("the planar two-legged body above holds the claim in the suite")
def test_solo12_dropped_under_joint_pd_stands():
    """Compiling the 18-coordinate floating base with its four feet takes minutes on a
    loaded 2-core machine (the run: 30,000 steps); the planar test above covers the
    claim in the default suite."""
    scene, params, ts, sol, weight = solo12_standing()
    _check_standing(sol, ts, sol.q[:, 2])
    forces = np.asarray(sol.contact_force[-1])
    assert abs(forces[:, 2].sum() / weight - 1.0) < 1e-4  # measured 1.6e-5
    assert np.all(forces[:, 2] > 0.2 * weight / 4)  # on all four feet


@every_robot("the planar two-legged body above holds the claim in the suite")
def test_solo12_stands_with_the_defaults():
    """The scene as `from_urdf(..., contact=feet)` makes it and the default method
    (`rodas4`). Measured: 882 steps, the base 6 µm lower over the last half second,
    0.024 mm the deepest foot; about 40 s from the import to the result."""
    scene, params, ts, sol, weight = solo12_standing(defaults=True)
    assert scene.default_method == "rodas4"
    _check_standing(sol, ts, sol.q[:, 2])
    last = ts >= ts[-1] - 1.0
    assert np.ptp(np.asarray(sol.q[last, 0])) <= 1e-3  # creep ≤ 1 mm/s along the ground
    assert np.ptp(np.asarray(sol.q[last, 1])) <= 1e-3
    forces = np.asarray(sol.contact_force[-1])
    assert abs(forces[:, 2].sum() / weight - 1.0) < 1e-4
    assert np.all(forces[:, 2] > 0.2 * weight / 4)  # on all four feet


@every_robot("the ball under a PD pull (test_contact_onset_derivatives.py) holds the claim")
def test_solo12s_base_height_moves_with_its_pd_gains_and_friction_by_its_derivative():
    """solo12 dropped under joint PD with the default coefficients and method: its base
    height 0.4 s later (landed at 0.12 s, settling) differentiated with respect to the
    gains `kp`, `kd` (in the controller's closure, as a user writes it) and the feet's
    friction (through `params`), by `jax.jacfwd` and `jax.grad`, against central
    differences at `1e-10` (relative steps 1e-3 and 1e-4 agreeing to 1e-5 of the
    largest entry). Measured 1.9e-7 of it in both modes (the loop's own JVP, the route a
    closure took before: 8.8e-7); about 6 minutes on a 2-core CPU."""
    feet, params = _solo12_feet()
    scene = ContactSystem(feet.system, feet.spheres, feet.plane, friction=lambda p: p["mu"])
    stance = jnp.asarray(STANCE)
    q0 = jnp.concatenate([jnp.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 1.0]), stance])

    def height(x, **options):
        kp, kd = x[0], x[1]

        def pd(t, q, v):
            return jnp.concatenate([jnp.zeros(6), kp * (stance - q[7:]) - kd * v[6:]])

        p = dict(params, mu=x[2])
        sol = lx.simulate(scene, q0, jnp.zeros(18), p, t1=0.4, n_save=2, tau=pd, **options)
        return sol.q[-1, 2]

    x0 = jnp.array([10.0, 0.3, 1.0])
    tight = jax.jit(lambda x: height(x, rtol=1e-10, atol=1e-10, max_steps=200_000))

    def central(step):
        return np.array(
            [
                (tight(x0.at[i].multiply(1 + step)) - tight(x0.at[i].multiply(1 - step)))
                / (2 * step * float(x0[i]))
                for i in range(3)
            ]
        )

    coarse, fine = central(1e-3), central(1e-4)
    scale = np.max(np.abs(fine))
    assert np.max(np.abs(coarse - fine)) < 1e-4 * scale  # the differences converged
    forward = np.asarray(jax.jacfwd(height)(x0))
    reverse = np.asarray(jax.grad(height)(x0))
    np.testing.assert_allclose(forward, fine, rtol=0, atol=1e-5 * scale)
    np.testing.assert_allclose(reverse, fine, rtol=0, atol=1e-5 * scale)
