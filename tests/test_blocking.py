"""Cache blocking of large vmapped batches (`lagrax._core.blocking`): a blocked evaluation
gives the plain vmap's values and derivatives, for any batch size, and falls back to the
plain vmap where it cannot block."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax._core.blocking import BLOCK, blocked


def _f(x, p):
    return jnp.sin(x) * p["a"] + jnp.cumsum(x) ** 2


@pytest.mark.parametrize("batch", [BLOCK, BLOCK + 1, 3 * BLOCK + 5])
def test_blocked_equals_plain_vmap(batch):
    """Values, `jax.jacfwd` and `jax.grad` through `vmap` of a blocked function equal those
    of the function itself, including a remainder block; an unbatched argument is held."""
    x = jnp.asarray(np.random.default_rng(0).normal(size=(batch, 3)))
    p = {"a": jnp.asarray(1.7)}
    g = blocked(_f)
    ours, plain = jax.vmap(g, (0, None))(x, p), jax.vmap(_f, (0, None))(x, p)
    np.testing.assert_allclose(ours, plain, rtol=1e-14)
    jac = jax.vmap(jax.jacfwd(g), (0, None))(x, p)
    np.testing.assert_allclose(jac, jax.vmap(jax.jacfwd(_f), (0, None))(x, p), rtol=1e-15)

    def loss(fn, x, p):
        return jnp.sum(jax.vmap(fn, (0, None))(x, p) ** 2)

    for argnum in (0, 1):
        ours = jax.grad(loss, argnums=argnum + 1)(g, x, p)
        plain = jax.grad(loss, argnums=argnum + 1)(_f, x, p)
        np.testing.assert_allclose(
            jax.tree_util.tree_leaves(ours), jax.tree_util.tree_leaves(plain), rtol=1e-13
        )


def test_blocked_runs_in_blocks():
    """Above `BLOCK` states the program maps over blocks (a loop appears); at or below it,
    and for an unbatched call, the function is traced as it is."""
    g = blocked(_f)
    p = {"a": jnp.asarray(1.0)}
    big = str(jax.make_jaxpr(jax.vmap(g, (0, None)))(jnp.ones((2 * BLOCK, 3)), p))
    small = str(jax.make_jaxpr(jax.vmap(g, (0, None)))(jnp.ones((BLOCK, 3)), p))
    single = str(jax.make_jaxpr(g)(jnp.ones(3), p))
    assert "scan" in big and "length=2" in big
    assert "scan" not in small and "custom" not in small and "custom" not in single


def test_blocked_closure_over_batched_value_falls_back():
    """A function closing over a vmapped value cannot be blocked: it runs as a plain vmap
    with the same values."""
    x = jnp.linspace(0.0, 1.0, 3 * BLOCK)

    def outer(s):
        return blocked(lambda y: jnp.sin(y) * s)(jnp.asarray(2.0) + s)

    plain = jax.vmap(lambda s: jnp.sin(2.0 + s) * s)(x)
    np.testing.assert_allclose(jax.vmap(outer)(x), plain, rtol=1e-15)


@pytest.fixture(scope="module", params=["arm7", "planar"])
def arm(request):
    """The URDF arm, and a planar chain (whose derivatives are blocked too)."""
    if request.param == "planar":
        chain = lx.chains.PlanarChain(7)
        return chain.system(), chain.params(m=np.linspace(1.0, 0.4, 7))
    tree, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"))
    return tree.system(), params


def test_blocked_dynamics_match_unblocked(arm):
    """A chain's forward dynamics and their derivatives over a large batch are the same
    numbers blocked and unblocked, and equal plain autodiff."""
    system, params = arm
    rng = np.random.default_rng(1)
    q, qd, tau = (jnp.asarray(rng.uniform(-1, 1, (5 * BLOCK, 7))) for _ in range(3))

    def fd(a, b, c):
        return system.forward_dynamics(a, b, params, c)

    def run():
        return (
            jax.jit(jax.vmap(fd))(q, qd, tau),
            jax.jit(jax.vmap(jax.jacfwd(fd, argnums=(0, 1, 2))))(q, qd, tau),
            jax.jit(
                jax.vmap(lambda a, b, c: system.forward_dynamics_derivatives(a, b, params, c).dq)
            )(q, qd, tau),
        )

    blocked_out = run()
    assert "length=5\n" in str(jax.make_jaxpr(jax.vmap(fd))(q, qd, tau))  # 5 blocks
    # unblocked: the same functions over slices of at most BLOCK states
    jac = jax.jit(jax.vmap(jax.jacfwd(fd, argnums=(0, 1, 2))))
    pieces = [
        jac(q[k : k + BLOCK], qd[k : k + BLOCK], tau[k : k + BLOCK])
        for k in range(0, q.shape[0], BLOCK)
    ]
    plain = jax.tree_util.tree_map(lambda *xs: jnp.concatenate(xs), *pieces)
    pairs = zip(
        jax.tree_util.tree_leaves(blocked_out[1]), jax.tree_util.tree_leaves(plain), strict=True
    )
    for ours, ref in pairs:
        np.testing.assert_allclose(ours, ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(blocked_out[2], blocked_out[1][0], rtol=1e-12, atol=1e-12)
    for k in range(0, q.shape[0], 107):
        single = fd(q[k], qd[k], tau[k])
        np.testing.assert_allclose(blocked_out[0][k], single, rtol=1e-12, atol=1e-12)


def test_blocked_floating_base_matches_slices():
    """A floating base's forward dynamics and their derivatives call over a large batch
    (blocked) equal the same functions over slices of at most `BLOCK` states
    (unblocked)."""
    robot, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"), floating_base=True)
    system = robot.system()
    rng = np.random.default_rng(2)
    batch = 3 * BLOCK
    quat = rng.normal(size=(batch, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    q = jnp.asarray(
        np.concatenate([rng.normal(size=(batch, 3)), quat, rng.uniform(-1, 1, (batch, 7))], 1)
    )
    v = jnp.asarray(rng.normal(size=(batch, 13)))
    for call in (system.forward_dynamics, system.forward_dynamics_derivatives):
        fn = jax.jit(jax.vmap(lambda a, b, call=call: call(a, b, params)))
        whole = fn(q, v)
        pieces = [fn(q[k : k + BLOCK], v[k : k + BLOCK]) for k in range(0, batch, BLOCK)]
        plain = jax.tree_util.tree_map(lambda *xs: jnp.concatenate(xs), *pieces)
        pairs = zip(jax.tree_util.tree_leaves(whole), jax.tree_util.tree_leaves(plain), strict=True)
        # compiled separately, the blocked program and a slice's may round differently:
        # to a solve's round-off with this floating arm's M (cond(M) up to 5.5e4 here)
        for ours, ref in pairs:
            np.testing.assert_allclose(ours, ref, rtol=1e-10, atol=1e-10)
