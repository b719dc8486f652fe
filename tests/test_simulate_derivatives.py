"""Derivatives through `simulate`: reverse mode (`jax.grad`, `jax.jacrev`), forward mode
(`jax.jvp`, `jax.jacfwd`: lagrax picks `diffrax.ForwardMode` for its lean loop), forward
over reverse (`jax.hessian`), `vmap` of `grad`, and events with a reset, against central
finite differences; an adjoint that cannot do forward mode is a clear error."""

import diffrax as dfx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import rel_error  # tests/_helpers.py


@pytest.fixture(scope="module")
def arm_loss():
    system, params = lx.models.planar_2r()
    qd0 = jnp.zeros(2)

    def final(q0, m2, **kw):
        sol = lx.simulate(
            system, q0, qd0, {**params, "m2": m2}, t1=1.0, n_save=2, rtol=1e-11, atol=1e-11, **kw
        )
        return jnp.concatenate([sol.q[-1], sol.qd[-1]])

    return final


def _central(fn, x, eps=1e-6):
    """The Jacobian of `fn` at `x` by central differences, column by column."""
    cols = [(fn(x + eps * e) - fn(x - eps * e)) / (2 * eps) for e in np.eye(x.shape[0])]
    return np.stack(cols, axis=-1)


def test_simulate_forward_and_reverse_against_finite_differences(arm_loss):
    q0, m2 = jnp.array([0.3, 0.8]), 1.2
    fwd = jax.jacfwd(arm_loss)(q0, m2)
    rev = jax.jacrev(arm_loss)(q0, m2)
    fd = _central(lambda q: np.asarray(arm_loss(q, m2)), np.asarray(q0))
    assert rel_error(fwd, fd) <= 1e-6 and rel_error(rev, fwd) <= 1e-9
    # with respect to a parameter, by jax.jvp
    _, dm = jax.jvp(lambda m: arm_loss(q0, m), (m2,), (1.0,))
    fd_m = (arm_loss(q0, m2 + 1e-6) - arm_loss(q0, m2 - 1e-6)) / 2e-6
    assert rel_error(dm, fd_m) <= 1e-6
    # forward over reverse: a Hessian (lagrax picks diffrax.DirectAdjoint)
    hess = jax.hessian(lambda q: arm_loss(q, m2)[0])(q0)
    fd_h = _central(lambda q: np.asarray(jax.grad(lambda a: arm_loss(a, m2)[0])(q)), q0)
    assert rel_error(hess, fd_h) <= 1e-5


def test_vmap_of_grad_through_simulate(arm_loss):
    q0 = jnp.array([[0.3, 0.8], [0.5, -0.2], [1.0, 0.1]])
    grads = jax.vmap(jax.grad(lambda q: jnp.sum(arm_loss(q, 1.0) ** 2)))(q0)
    for k in range(q0.shape[0]):
        one = jax.grad(lambda q: jnp.sum(arm_loss(q, 1.0) ** 2))(q0[k])
        assert rel_error(grads[k], one) <= 1e-9


def test_forward_mode_through_events_and_resets():
    """`jax.jacfwd` through a solve with an impact (a reset) equals reverse mode and
    central differences: the event time's and the reset's derivatives included."""
    system = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * p["m"] * qd[0] ** 2, lambda q, p: p["m"] * p["g"] * q[0], n_dof=1
    )
    params = {"m": 1.0, "g": 9.81, "e": 0.8}
    floor = lx.Event(
        lambda t, q, qd, p: q[0],
        direction=-1,
        reset=lambda t, q, qd, p: (q, -p["e"] * qd),
    )

    def final(y0):
        sol = lx.simulate(
            system, y0[:1], y0[1:], params, t1=1.5, n_save=2, events=floor, rtol=1e-12, atol=1e-12
        )
        return jnp.concatenate([sol.q[-1], sol.qd[-1]])

    y0 = jnp.array([1.0, 0.5])
    fwd = jax.jacfwd(final)(y0)
    assert rel_error(fwd, jax.jacrev(final)(y0)) <= 1e-9
    assert rel_error(fwd, _central(lambda y: np.asarray(final(y)), np.asarray(y0))) <= 1e-6


def test_forward_mode_with_a_reverse_adjoint_is_a_clear_error(arm_loss):
    with pytest.raises(lx.ConfigurationError, match="adjoint="):
        jax.jacfwd(lambda q: arm_loss(q, 1.0, adjoint=dfx.RecursiveCheckpointAdjoint()))(
            jnp.array([0.3, 0.8])
        )
    # an explicit ForwardMode also works where lagrax cannot see the mode (inside jit)
    loss = jax.jit(lambda q: arm_loss(q, 1.0, adjoint=dfx.ForwardMode()))
    out = jax.jacfwd(loss)(jnp.array([0.3, 0.8]))
    assert rel_error(out, jax.jacfwd(lambda q: arm_loss(q, 1.0))(jnp.array([0.3, 0.8]))) <= 1e-12


def test_reverse_mode_by_sensitivities_and_by_checkpoints_agree():
    """`jax.grad` with few differentiated scalars runs forward sensitivities, transposed;
    a `tau` function closing over the differentiated value, or many differentiated
    scalars, runs the checkpointed reverse loop; `diffrax.RecursiveCheckpointAdjoint`
    runs `diffeqsolve`. All are the derivative of (nearly) the same solve, and agree with
    central differences and forward mode."""
    system, params = lx.models.planar_2r()
    q0, qd0 = jnp.array([0.3, 0.8]), jnp.zeros(2)
    tight = dict(t1=1.0, n_save=2, rtol=1e-11, atol=1e-11)

    def loss(sol):
        return jnp.sum(sol.q[-1] ** 2) + jnp.sum(sol.qd[-1])

    def visible(torque, **kw):  # a constant torque: an argument, two scalars
        return loss(lx.simulate(system, q0, qd0, params, tau=torque, **tight, **kw))

    def closed_over(torque):  # the same torque closed over: only the checkpointed loop
        return loss(lx.simulate(system, q0, qd0, params, tau=lambda t, q, qd: torque, **tight))

    torque = jnp.array([0.4, -0.7])
    g_sens = jax.grad(visible)(torque)
    g_ckpt = jax.grad(closed_over)(torque)
    g_dfx = jax.grad(lambda k: visible(k, adjoint=dfx.RecursiveCheckpointAdjoint()))(torque)
    fd = _central(lambda k: np.asarray(visible(k))[None], np.asarray(torque))[0]
    assert rel_error(g_sens, fd) <= 1e-6
    assert rel_error(g_sens, g_ckpt) <= 1e-9 and rel_error(g_sens, g_dfx) <= 1e-6

    # many differentiated scalars (a 40-entry stiffness table): the checkpointed loop
    springs = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * jnp.sum(qd**2),
        lambda q, p: 0.5 * jnp.mean(p["w"]) * jnp.sum(q**2) + 0.1 * jnp.sum(q**4),
        n_dof=2,
    )

    def many(w):
        return loss(lx.simulate(springs, q0, qd0, {"w": w}, **tight))

    table = jnp.linspace(1.0, 3.0, 40)
    direction = jnp.asarray(np.random.default_rng(0).normal(size=40))
    _, along = jax.jvp(many, (table,), (direction,))
    assert rel_error(jnp.dot(jax.grad(many)(table), direction), along) <= 1e-9


def _tree_loss():
    """A damped, driven 2-joint chain (axes z then y): a loss reading the saves, the end state, the
    energy and the work (every post-processed output carries the tangents)."""
    tree = lx.chains.Tree("RR", parents=(-1, 0), axes=[(0, 0, 1), (0, 1, 0)])
    system, params = tree.system(), tree.params(damping=0.2, m=[1.0, 0.7])

    def loss(q0, p, tau, t1=0.4):
        sol = lx.simulate(system, q0, 0.1 * q0, p, tau=tau, t1=t1, n_save=3)
        out = jnp.sum(sol.q**2) + jnp.sum(sol.qd[-1]) + jnp.sum(sol.energy[1:])
        return out + sol.work[-1] + jnp.sum(sol.q_end)

    return loss, params


@pytest.mark.parametrize(
    "case", ["grad q0", "grad m", "grad tau", "grad t1", "jacfwd q0", "jvp q0", "vmap grad"]
)
def test_forward_sensitivities_as_state_equal_the_loops_jvp(case):
    """Forward mode through the lean loop solves the augmented system (the tangents as
    state, `lagrax._solve.sensitivities`): the same numbers as `jax.jvp` of the loop itself
    to round-off, for `jax.grad` by forward sensitivities (with respect to `q0`, a
    parameter, a constant `tau`; `t1` takes the loop's own JVP), `jax.jacfwd`, `jax.jvp`
    and `vmap(grad)`."""
    from lagrax._solve import sensitivities

    loss, params = _tree_loss()
    q0, tau = jnp.array([0.3, -0.4]), jnp.array([0.5, -0.2])
    calls = {
        "grad q0": lambda: jax.grad(loss)(q0, params, tau),
        "grad m": lambda: jax.grad(lambda m: loss(q0, {**params, "m": m}, tau))(params["m"]),
        "grad tau": lambda: jax.grad(lambda t: loss(q0, params, t))(tau),
        "grad t1": lambda: jax.grad(lambda t1: loss(q0, params, tau, t1))(0.4),
        "jacfwd q0": lambda: jax.jacfwd(loss)(q0, params, tau),
        "jvp q0": lambda: jax.jvp(lambda q: loss(q, params, tau), (q0,), (jnp.ones(2),))[1],
        "vmap grad": lambda: jax.vmap(jax.grad(loss), in_axes=(0, None, None))(
            q0[None, :] + jnp.linspace(0.0, 0.2, 3)[:, None], params, tau
        ),
    }
    jax.clear_caches()  # the switch acts while tracing
    ours = calls[case]()
    jax.clear_caches()
    with sensitivities.plain_jvp():
        plain = calls[case]()
    jax.clear_caches()
    assert np.all(np.isfinite(ours))
    assert rel_error(ours, plain) <= 1e-13


def test_closures_over_differentiated_values():
    """A `tau` function closing over the differentiated value: the value is hoisted out
    of the closure, so both modes take the solve's own derivative rules (forward mode
    took the loop's own JVP before, and a raw JAX error before that), and match central
    differences. An energy closing over it cannot be differentiated by the compiled solve
    (the derivative came out as a silent zero): a `ConfigurationError` that says to pass
    it through `params`, in either mode."""
    system, params = lx.models.planar_2r()
    q0 = jnp.array([0.3, 0.5])

    def driven(k):
        tau = lambda t, q, qd: k * jnp.ones(2)  # noqa: E731
        sol = lx.simulate(system, q0, 0 * q0, params, tau=tau, t1=0.3, n_save=2)
        return jnp.sum(sol.q[-1] ** 2)

    fd = (driven(0.7 + 1e-6) - driven(0.7 - 1e-6)) / 2e-6
    assert rel_error(jax.jvp(driven, (0.7,), (1.0,))[1], fd) <= 1e-7
    assert rel_error(jax.grad(driven)(0.7), fd) <= 1e-7

    def stiff(k):
        springs = lx.LagrangianSystem(
            lambda q, qd, p: 0.5 * jnp.sum(qd**2), lambda q, p: 0.5 * k * jnp.sum(q**2), n_dof=2
        )
        return jnp.sum(lx.simulate(springs, q0, 0 * q0, {}, t1=0.3, n_save=2).q[-1] ** 2)

    for transform in (jax.grad, lambda f: lambda k: jax.jvp(f, (k,), (1.0,))[1]):
        with pytest.raises(lx.ConfigurationError, match="close over.*through params"):
            transform(stiff)(0.7)


def test_params_with_none_entries_through_simulate():
    """A `None` in `params` before the differentiated entry: gradients and JVPs through
    `simulate` match central differences (the tangents-as-state rule paired them with the
    next leaf, a silent wrong gradient)."""
    system = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * p["m"] * jnp.sum(qd**2),
        lambda q, p: 0.5 * p["b"] * q[0] ** 2 + 0.5 * p["c"] * q[1] ** 2,
        n_dof=2,
    )
    q0, qd0 = jnp.array([0.3, -0.2]), jnp.array([0.1, 0.4])
    params = {"a": None, "b": 2.0, "c": 5.0, "m": 1.5}

    def loss(b):
        sol = lx.simulate(
            system, q0, qd0, {**params, "b": b}, t1=1.0, n_save=2, rtol=1e-11, atol=1e-11
        )
        return jnp.sum(sol.q[-1] ** 2)

    fd = (loss(2.0 + 1e-5) - loss(2.0 - 1e-5)) / 2e-5
    assert rel_error(jax.grad(loss)(2.0), fd) <= 1e-6
    assert rel_error(jax.jvp(loss, (2.0,), (1.0,))[1], fd) <= 1e-6
