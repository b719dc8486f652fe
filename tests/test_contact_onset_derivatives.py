"""Derivatives that move an impact's onset: the contact guide's dropped ball.

A 0.1 m ball (a point mass carrying a sphere, `c = 0.05`, Hertz's exponent and the
default stiffness) is dropped with its centre at 1 m; its height `0.25 s` after the
bounce, and the apex it is heading for, are differentiated with respect to the drop
height by `jax.grad` / `jax.jacrev` (reverse mode) and `jax.jacfwd`, against central
differences of solves at `rtol = atol = 1e-13` whose own convergence is shown (two
steps agreeing to 5e-7, their truncation error falling as the step squared).

Before the tangents were put under the error control (`AbstractSystem.rough_jacobian`),
these derivatives were −0.266 at the default tolerances and 0.1522 at `1e-10` against
0.15169: the onset falls inside a step, and the contact's slope `p k δ^{p−1}` is
singular at `δ = 0`, which the state's error does not see.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax.contact import ContactSystem, Plane, Sphere

G = 9.81
R = 0.1
H = 1.0  # the drop height of the centre
T1 = float(np.sqrt(2.0 * (H - R) / G)) + 0.25  # 0.25 s after the bounce


@pytest.fixture(scope="module")
def drop():
    """`outputs(h, **options) -> [height, apex]` at `T1`, jitted per option set."""
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, lambda q, p: G * q[1], n_dof=2)
    scene = ContactSystem(body, Sphere(R, lambda q, p: q), Plane([0.0, 1.0]), dissipation=0.05)

    def outputs(h, events=False, **options):
        if events:
            options["events"] = scene.events()
        sol = lx.simulate(
            scene, jnp.stack([0.0 * h, h]), jnp.zeros(2), {}, t1=T1, n_save=2, **options
        )
        y, v = sol.q[-1, 1], sol.qd[-1, 1]
        return jnp.stack([y, y + v**2 / (2.0 * G) - R])

    return outputs


def _central(f, x, steps):
    """Central differences of `f` at `x` along each axis of `x`, at the relative steps
    `steps` (one per axis): `(n_out, n_in)`."""
    x = np.asarray(x, float)
    cols = []
    for i, step in enumerate(steps):
        dx = step * (abs(x[i]) if x[i] else 1.0)
        up, down = x.copy(), x.copy()
        up[i] += dx
        down[i] -= dx
        cols.append((np.asarray(f(up)) - np.asarray(f(down))) / (2.0 * dx))
    return np.stack(cols, axis=-1)


def _converged_central(f, x, steps):
    """Central differences at `steps` and at 0.3 of them, their
    truncation errors checked to fall as the step squared (by 1/0.09 = 11.1, within a
    factor of 2: the state's error at `1e-13` does not reach them), and the Richardson
    extrapolation of the two, which cancels the `dh²` term."""
    coarse = _central(f, x, steps)
    fine = _central(f, x, [0.3 * s for s in steps])
    extrapolated = fine + (fine - coarse) * 0.09 / (1.0 - 0.09)
    ratio = (coarse - extrapolated) / (fine - extrapolated)
    assert np.all((ratio > 11.1 / 2) & (ratio < 11.1 * 2)), ratio
    # the extrapolation's correction is small: the differences themselves nearly agree
    assert np.all(np.abs(fine / extrapolated - 1.0) < 2e-5)
    return extrapolated


@pytest.fixture(scope="module")
def reference(drop):
    """Converged central differences of `[height, apex]` at `1e-13`."""
    f = jax.jit(lambda h: drop(h[0], rtol=1e-13, atol=1e-13))
    return _converged_central(f, [H], [1e-3])[:, 0]


def test_the_central_differences_give_the_issues_figure(reference):
    assert abs(reference[0] - 0.15169) < 1e-5  # the issue's 0.1517


@pytest.mark.parametrize(
    ("tol", "events"),
    [(None, False), (1e-10, False), (None, True), (1e-10, True)],
    ids=["defaults", "1e-10", "events", "events-1e-10"],
)
def test_drop_height_derivatives_through_the_bounce_match_central_differences(
    drop, reference, tol, events
):
    """With `events=scene.events()` too (the onset and release located: the tangents
    are those of the solve without them, under the error control)."""
    options = {"events": events}
    if tol is not None:
        options.update(rtol=tol, atol=tol)
    fd = reference
    forward = np.asarray(jax.jacfwd(lambda h: drop(h, **options))(H))
    reverse = np.asarray(jax.jacrev(lambda h: drop(h, **options))(H))
    grad = float(jax.grad(lambda h: drop(h, **options)[0])(H))
    np.testing.assert_allclose(forward, fd, rtol=1e-6)
    np.testing.assert_allclose(reverse, fd, rtol=1e-6)
    assert abs(grad / fd[0] - 1.0) < 1e-6


def test_ten_bounces_derivatives_match_central_differences():
    """The ball bouncing ten times (its stiffness and dissipation from `params`): the
    height and velocity in flight after the tenth bounce, with respect to the drop
    height, the dissipation and the stiffness, by `jax.jacfwd` at `1e-10`."""
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, lambda q, p: G * q[1], n_dof=2)
    ball, floor = Sphere(R, lambda q, p: q), Plane([0.0, 1.0])
    k0 = float(ContactSystem(body, ball, floor).coefficients({}).stiffness)  # the default
    scene = ContactSystem(
        body, ball, floor, dissipation=lambda p: p["c"], stiffness=lambda p: k0 * p["k"]
    )
    t1 = 4.6  # in flight after the tenth bounce (onsets at 0.43, 1.14, ..., 4.49 s)
    x0 = np.array([H, 0.05, 1.0])  # drop height, dissipation, stiffness / default

    def state(x, **options):
        params = {"c": x[1], "k": x[2]}
        sol = lx.simulate(
            scene, jnp.stack([0.0 * x[0], x[0]]), jnp.zeros(2), params, t1=t1, n_save=2, **options
        )
        return jnp.stack([sol.q[-1, 1], sol.qd[-1, 1]])

    onsets = lx.simulate(
        scene, [0.0, H], [0.0, 0.0], {"c": 0.05, "k": 1.0}, t1=t1, n_save=2, events=scene.events()
    ).events[0]
    assert int(onsets.count) == 20  # ten onsets and ten releases
    f = jax.jit(lambda x: state(x, rtol=1e-13, atol=1e-13))
    fd = _converged_central(f, x0, [1e-3, 1e-3, 1e-2])
    ad = np.asarray(jax.jacfwd(lambda x: state(x, rtol=1e-10, atol=1e-10))(jnp.asarray(x0)))
    np.testing.assert_allclose(ad, fd, rtol=1e-6)


def test_the_crossing_times_derivatives_are_the_implicit_functions():
    """`Solution.events` differentiated: the onset `t* = √(2(h − R)/g)`, so `dt*/dh =
    1/(g t*)` exactly (a free fall), in both modes; the release time against central
    differences; the values under differentiation those of the plain solve."""
    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, lambda q, p: G * q[1], n_dof=2)
    scene = ContactSystem(body, Sphere(R, lambda q, p: q), Plane([0.0, 1.0]), dissipation=0.05)

    def crossings(h, tol=1e-10):
        sol = lx.simulate(
            scene, jnp.stack([0.0 * h, h]), jnp.zeros(2), {}, t1=T1, n_save=2,
            rtol=tol, atol=tol, events=scene.events(),
        )  # fmt: skip
        record = sol.events[0]
        return jnp.stack([record.times[0], record.times[1], record.qd[0, 1]])

    onset = np.sqrt(2.0 * (H - R) / G)
    forward = np.asarray(jax.jacfwd(crossings)(H))
    reverse = np.asarray(jax.jacrev(crossings)(H))
    np.testing.assert_allclose(forward, reverse, rtol=1e-12)
    # differentiated, the values are those of the solve itself (the events loop's)
    primal, _ = jax.jvp(crossings, (H,), (1.0,))
    np.testing.assert_array_equal(np.asarray(primal), np.asarray(crossings(H)))
    assert abs(forward[0] * G * onset - 1.0) < 1e-9
    assert abs(forward[2] / (-1.0 / onset) - 1.0) < 1e-9  # v* = −g t*
    f = jax.jit(lambda h: crossings(h[0], 1e-13))
    fd = _converged_central(f, [H], [1e-3])[:, 0]
    assert abs(forward[1] / fd[1] - 1.0) < 1e-6


def test_a_controllers_gains_in_its_closure_are_differentiated_through_the_bounce():
    """A controller `tau(t, q, qd)` whose PD gains are the values differentiated, held in
    its closure (as a user writes one): the height and speed 0.25 s after the bounce,
    with respect to both gains, by `jax.jacfwd` and `jax.jacrev` at the default options,
    against central differences of `dopri8` solves at `1e-13` (two steps agreeing to
    3e-8). The gains are hoisted out of the closure (`jax.closure_convert`), so the
    tangents go under the error control as `params`' do: measured 9e-8, where the
    loop's own JVP, the only route a closure had before, is 21 % off."""
    from lagrax._solve import sensitivities

    body = lx.LagrangianSystem(lambda q, qd, p: 0.5 * qd @ qd, lambda q, p: G * q[1], n_dof=2)
    scene = ContactSystem(body, Sphere(R, lambda q, p: q), Plane([0.0, 1.0]), dissipation=0.05)

    def after(gains, **options):
        kp, kd = gains[0], gains[1]

        def tau(t, q, qd):  # a pull towards 1 m
            return jnp.stack([0.0 * q[0], kp * (1.0 - q[1]) - kd * qd[1]])

        sol = lx.simulate(
            scene, jnp.array([0.0, H]), jnp.zeros(2), {}, tau=tau, t1=T1, n_save=2, **options
        )
        return jnp.stack([sol.q[-1, 1], sol.qd[-1, 1]])

    x0 = np.array([3.0, 0.5])
    tight = jax.jit(lambda x: after(x, solver="dopri8", rtol=1e-13, atol=1e-13, max_steps=10**5))
    fd = _converged_central(tight, x0, [1e-3, 1e-3])
    scale = np.max(np.abs(fd))
    forward = np.asarray(jax.jacfwd(after)(jnp.asarray(x0)))
    reverse = np.asarray(jax.jacrev(after)(jnp.asarray(x0)))
    np.testing.assert_allclose(forward, fd, rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(reverse, fd, rtol=0, atol=1e-6 * scale)
    with sensitivities.plain_jvp():  # the loop's own JVP: what a closure got before
        plain = np.asarray(jax.jacfwd(after)(jnp.asarray(x0)))
    assert np.max(np.abs(plain - fd)) > 0.1 * scale


FREE_BODY = """<mujoco><worldbody><geom type="plane" size="2 2 0.1" friction="0.6"/>
<body pos="0 0 0.3"><freejoint/>
<geom type="sphere" size="0.04" pos="0.1 0 0" mass="1"/>
<geom type="sphere" size="0.03" pos="-0.1 0 0.02" mass="0.5"/></body>
</worldbody></mujoco>"""


def test_a_free_bodys_derivatives_through_its_landing_match_central_differences():
    """A lone free body (two spheres on a free joint, an MJCF with no other joint) thrown
    tumbling onto a floor with friction (μ = 0.6; `rodas4`): where it is after 0.6 s,
    differentiated with respect to the drop height, the roll rate and the forward
    speed by `jax.jacfwd`, against central differences at `1e-12` (two steps agreeing to
    2e-8; `jax.jacrev` takes the same forward sensitivities, 5e-10). The floating base's
    quaternion is normalized after every step; the forward sensitivities follow that
    projection (its derivative applied to the tangents), so they are under the error
    control as a planar scene's are: measured 1.4e-9, where the loop's own JVP (a
    projecting system's only route before) was 1.4e-5 off."""
    pytest.importorskip("mujoco")
    scene, params = lx.chains.from_mjcf(FREE_BODY, contact=True)
    assert scene.system.projects and scene.default_method == "rodas4"
    q0 = jnp.array([0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 1.0])

    def where(x, **options):
        q, v = q0.at[2].set(x[0]), jnp.zeros(6).at[4].set(x[1]).at[0].set(x[2])
        sol = lx.simulate(scene, q, v, params, t1=0.6, n_save=2, **options)
        return sol.q[-1, :3]

    x0 = jnp.array([0.3, 2.0, 0.5])
    tight = jax.jit(lambda x: where(x, rtol=1e-12, atol=1e-12))

    def central(h):
        rows = [(tight(x0.at[i].add(h)) - tight(x0.at[i].add(-h))) / (2 * h) for i in range(3)]
        return np.stack(rows, axis=1)

    coarse, fine = central(1e-4), central(1e-5)
    scale = np.max(np.abs(fine))
    assert np.max(np.abs(coarse - fine)) < 1e-7 * scale  # the differences converged
    assert abs(fine[0, 2]) > 0.1  # it slid and tumbled: the derivatives are not trivial
    np.testing.assert_allclose(jax.jacfwd(where)(x0), fine, rtol=0, atol=1e-7 * scale)
