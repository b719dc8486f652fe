"""Serial chains (``lagrax.chains``) against independent oracles.

- the recursive Newton–Euler algorithm (``lagrax.newton_euler.rnea``: no energies, no
  autodiff, its own kinematics) at random parameters and states, n = 1 … 10, planar and
  spatial, revolute and prismatic;
- the lecture's 2R arm (``lagrax.models.planar_2r``, hand-written energies) and its
  free-body Newton–Euler torques;
- closed-form equations of two small spatial arms written out below;
- the planar chain against the same chain described in space (``SpatialChain`` with
  parallel z axes, and ``PlanarChain(bodies="spatial")``).
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import random_rotation
from lagrax.chains import PlanarChain, SpatialChain
from lagrax.newton_euler import rnea

NS = (1, 2, 3, 5, 10)
BATCH = 6  # random parameter sets per n, each at its own random state


# ----------------------------------------------------------------------------- helpers
def random_inertia(rng):
    """A physical inertia: principal moments obeying the triangle inequality, rotated."""
    i1, i2 = rng.uniform(0.02, 1.0, 2)
    i3 = rng.uniform(abs(i1 - i2), i1 + i2)
    rot = random_rotation(rng)
    return rot @ np.diag([i1, i2, i3]) @ rot.T


def planar_params(rng, chain):
    n = chain.n
    length = rng.uniform(0.2, 2.0, n)
    return chain.params(
        m=rng.uniform(0.1, 5.0, n),
        l=length,
        r=length * rng.uniform(0.05, 0.95, n),
        I=rng.uniform(0.01, 2.0, n),
        g=rng.uniform(0.0, 20.0),
    )


def spatial_chain(rng, n):
    types = "".join(rng.choice(["R", "P"], size=n, p=[0.7, 0.3]))
    if n > 1 and "P" not in types:
        types = types[:-1] + "P"
    axes = rng.normal(size=(n, 3))
    rotations = [random_rotation(rng) for _ in range(n)]
    return SpatialChain(types, axes, rotations, up=rng.normal(size=3))


def spatial_params(rng, chain):
    n = chain.n
    return chain.params(
        m=rng.uniform(0.1, 5.0, n),
        offset=rng.uniform(-1.0, 1.0, (n, 3)),
        com=rng.uniform(-0.5, 0.5, (n, 3)),
        inertia=np.stack([random_inertia(rng) for _ in range(n)]),
        g=rng.uniform(0.0, 20.0),
    )


def stack(dicts):
    return jax.tree_util.tree_map(lambda *xs: jnp.stack(xs), *dicts)


def states(rng, n, batch=BATCH):
    q = rng.uniform(-np.pi, np.pi, (batch, n))
    qd = rng.uniform(-2.0, 2.0, (batch, n))
    qdd = rng.uniform(-5.0, 5.0, (batch, n))
    return q, qd, qdd


@functools.cache
def compiled(chain):
    """Inverse dynamics (Lagrangian) and RNEA, each vmapped over (params, state) pairs."""
    system = chain.system()
    lag = jax.jit(jax.vmap(lambda p, q, qd, qdd: system.inverse_dynamics(q, qd, qdd, p)))
    ne = jax.jit(jax.vmap(lambda p, q, qd, qdd: rnea(chain, q, qd, qdd, p)))
    return lag, ne


def assert_rel_close(actual, expected, rtol, *, scale=None):
    actual, expected = np.asarray(actual), np.asarray(expected)
    if scale is None:
        scale = np.maximum(np.max(np.abs(expected), axis=-1, keepdims=True), 1.0)
    err = np.max(np.abs(actual - expected) / scale)
    assert err <= rtol, f"relative error {err:.3g} > {rtol:g}"


# --------------------------------------------------------------- chains vs recursive N–E
@pytest.mark.parametrize("n", NS)
def test_planar_chain_matches_rnea(n):
    rng = np.random.default_rng(100 + n)
    chain = PlanarChain(n)
    params = stack([planar_params(rng, chain) for _ in range(BATCH)])
    lag, ne = compiled(chain)
    q, qd, qdd = states(rng, n)
    tau_lag, tau_ne = lag(params, q, qd, qdd), ne(params, q, qd, qdd)
    assert tau_lag.shape == tau_ne.shape == (BATCH, n)
    assert_rel_close(tau_lag, tau_ne, 1e-11)


@pytest.mark.parametrize("n", NS)
def test_spatial_chain_matches_rnea(n):
    rng = np.random.default_rng(200 + n)
    chain = spatial_chain(rng, n)
    params = stack([spatial_params(rng, chain) for _ in range(BATCH)])
    lag, ne = compiled(chain)
    q, qd, qdd = states(rng, n)
    tau_lag, tau_ne = lag(params, q, qd, qdd), ne(params, q, qd, qdd)
    assert tau_lag.shape == tau_ne.shape == (BATCH, n)
    assert_rel_close(tau_lag, tau_ne, 1e-11)
    # the comparison can fail: a small change of one parameter is seen
    nudged = dict(params, m=params["m"].at[:, -1].multiply(1 + 1e-6))
    assert np.max(np.abs(ne(nudged, q, qd, qdd) - tau_lag)) > 1e-9


# ----------------------------------------------------------------- the lecture's 2R arm
ARM, _ = lx.models.planar_2r()
CHAIN2 = PlanarChain(2)
SYSTEM2 = CHAIN2.system()


def arm_params_pair(rng):
    m, length = rng.uniform(0.1, 5.0, 2), rng.uniform(0.2, 2.0, 2)
    r, inertia, g = length * rng.uniform(0.05, 0.95, 2), rng.uniform(0.01, 2.0, 2), 9.0
    chain_p = CHAIN2.params(m=m, l=length, r=r, I=inertia, g=g)
    arm_p = dict(
        m1=m[0],
        m2=m[1],
        l1=length[0],
        l2=length[1],
        r1=r[0],
        r2=r[1],
        I1=inertia[0],
        I2=inertia[1],
        g=g,
    )
    return chain_p, {k: jnp.asarray(v) for k, v in arm_p.items()}


@jax.jit
def _terms_2r(chain_p, arm_p, q, qd, qdd):
    out = {}
    for name, system, p in (("chain", SYSTEM2, chain_p), ("arm", ARM, arm_p)):
        out[name] = (
            system.mass_matrix(q, p),
            system.coriolis(q, qd, p),
            system.coriolis_matrix(q, qd, p),
            system.gravity(q, p),
            system.inverse_dynamics(q, qd, qdd, p),
        )
    out["free_body"] = lx.newton_euler.planar_2r(q, qd, qdd, arm_p)
    out["rnea"] = rnea(CHAIN2, q, qd, qdd, chain_p)
    return out


def test_two_link_chain_matches_planar_2r_model_and_free_body():
    rng = np.random.default_rng(3)
    for _ in range(5):
        chain_p, arm_p = arm_params_pair(rng)
        q, qd, qdd = (x[0] for x in states(rng, 2, batch=1))
        out = _terms_2r(chain_p, arm_p, q, qd, qdd)
        for got, want in zip(out["chain"], out["arm"], strict=True):
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
        tau = out["chain"][-1]
        np.testing.assert_allclose(tau, out["free_body"], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(out["rnea"], out["free_body"], rtol=1e-12, atol=1e-12)


# ------------------------------------------------------------ closed-form spatial arms
def test_yaw_pitch_arm_closed_form():
    """Joint 1 about z (vertical), joint 2 about y at the same point, a point mass at
    ``r`` along link 2's x axis: ``x = r (c1 c2, s1 c2, −s2)``, ``L = ½ m r² (q̇2² + c2² q̇1²)
    + m g r s2`` gives ``τ1 = m r² (c2² q̈1 − 2 s2 c2 q̇1 q̇2)``,
    ``τ2 = m r² (q̈2 + s2 c2 q̇1²) − m g r c2``."""
    chain = SpatialChain("RR", axes=[(0, 0, 1), (0, 1, 0)])
    m, r, g = 1.7, 0.8, 9.81
    p = chain.params(
        m=[0.0, m],
        offset=np.zeros((2, 3)),
        com=[(0, 0, 0), (r, 0, 0)],
        inertia=np.zeros((3, 3)),
        g=g,
    )
    q, qd, qdd = np.array([0.4, -0.7]), np.array([1.3, -0.6]), np.array([0.9, 2.1])
    c2, s2 = np.cos(q[1]), np.sin(q[1])
    expected = np.array(
        [
            m * r**2 * (c2**2 * qdd[0] - 2 * s2 * c2 * qd[0] * qd[1]),
            m * r**2 * (qdd[1] + s2 * c2 * qd[0] ** 2) - m * g * r * c2,
        ]
    )
    both = jax.jit(lambda *x: (chain.system().inverse_dynamics(*x, p), rnea(chain, *x, p)))
    tau_lag, tau_ne = both(q, qd, qdd)
    np.testing.assert_allclose(tau_lag, expected, rtol=1e-12)
    np.testing.assert_allclose(tau_ne, expected, rtol=1e-12)


def test_rotating_slider_closed_form():
    """A radial prismatic slider on a turntable: ``x = Rz(q1) (q2, 0, 0)``,
    ``T = ½ J q̇1² + ½ m (q̇2² + q2² q̇1²)``: ``τ1 = (J + m q2²) q̈1 + 2 m q2 q̇1 q̇2``,
    ``f2 = m (q̈2 − q2 q̇1²)`` (gravity along −z does no work)."""
    chain = SpatialChain("RP", axes=[(0, 0, 1), (1, 0, 0)])
    m, big_j = 2.5, 0.3
    p = chain.params(
        m=[1.0, m],
        offset=np.zeros((2, 3)),
        com=np.zeros((2, 3)),
        inertia=[np.diag([0.2, 0.2, big_j]), np.zeros((3, 3))],
    )
    q, qd, qdd = np.array([0.4, 0.7]), np.array([1.3, -0.6]), np.array([0.9, 2.1])
    expected = np.array(
        [
            (big_j + m * q[1] ** 2) * qdd[0] + 2 * m * q[1] * qd[0] * qd[1],
            m * (qdd[1] - q[1] * qd[0] ** 2),
        ]
    )
    both = jax.jit(lambda *x: (chain.system().inverse_dynamics(*x, p), rnea(chain, *x, p)))
    tau_lag, tau_ne = both(q, qd, qdd)
    np.testing.assert_allclose(tau_lag, expected, rtol=1e-12)
    np.testing.assert_allclose(tau_ne, expected, rtol=1e-12)


# ------------------------------------------------- planar chain == the same chain in space
def spatial_twin(n, planar_p):
    """``PlanarChain(n)`` as a ``SpatialChain``: z axes, links along x, gravity along −y."""
    chain = SpatialChain("R" * n, up=(0, 1, 0))
    length, zeros = planar_p["l"], jnp.zeros(n)
    offset = jnp.stack([jnp.concatenate([jnp.zeros(1), length[:-1]]), zeros, zeros], -1)
    com = jnp.stack([planar_p["r"], zeros, zeros], -1)
    inertia = planar_p["I"][:, None, None] * jnp.diag(jnp.array([0.5, 0.7, 1.0]))[None]
    p = chain.params(m=planar_p["m"], offset=offset, com=com, inertia=inertia, g=planar_p["g"])
    return chain, p


@pytest.mark.slow
@pytest.mark.parametrize("n", (2, 7))
def test_planar_bodies_equal_spatial_bodies(n):
    """'No more than the scene needs': the planar arm from planar bodies, from spatial
    bodies, and as a SpatialChain, give the same M, C q̇, G and forward dynamics."""
    rng = np.random.default_rng(300 + n)
    chain = PlanarChain(n)
    p = planar_params(rng, chain)
    twin, twin_p = spatial_twin(n, p)
    q, qd, tau = (x[0] for x in states(rng, n, batch=1))

    def terms(system, p):
        return (
            system.mass_matrix(q, p),
            system.coriolis(q, qd, p),
            system.gravity(q, p),
            system.forward_dynamics(q, qd, p, tau),
        )

    ref = jax.jit(lambda p: terms(chain.system(), p))(p)
    # forward dynamics follows from M, C, G: compared at n = 2 only (compile time)
    last = 4 if n == 2 else 3
    others = {
        "spatial bodies": jax.jit(lambda p: terms(chain.system(bodies="spatial"), p)[:last])(p),
        # the SpatialChain twin: M, C, G only (its forward dynamics follows from them)
        "spatial chain": jax.jit(lambda p: terms(twin.system(), p)[:3])(twin_p),
    }
    if n == 2:  # the public conversion (isotropic link inertia), M only
        conv, conv_p = chain.to_spatial(p)
        assert conv == twin
        others["to_spatial"] = (jax.jit(lambda p: conv.system().mass_matrix(q, p))(conv_p),)
    for name, res in others.items():
        for got, want in zip(res, ref, strict=False):
            scale = max(float(np.max(np.abs(want))), 1.0)
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * scale, err_msg=name)
    rneas = jax.jit(lambda: (rnea(chain, q, qd, tau, p), rnea(twin, q, qd, tau, twin_p)))
    tau_planar, tau_spatial = rneas()
    np.testing.assert_allclose(tau_spatial, tau_planar, rtol=1e-12, atol=1e-12)


# -------------------------------------------------------------- sweeps, gradients, dtypes
def test_params_vmap_and_grad():
    """Parameters are arrays: vmap over them equals one-by-one calls, and d τ / d params
    agrees between the Lagrangian and RNEA (both differentiable)."""
    rng = np.random.default_rng(11)
    chain = PlanarChain(3)
    system = chain.system()
    plist = [planar_params(rng, chain) for _ in range(4)]
    q, qd, qdd = (x[0] for x in states(rng, 3, batch=1))
    inverse = jax.jit(lambda p: system.inverse_dynamics(q, qd, qdd, p))
    batched = jax.jit(jax.vmap(inverse))(stack(plist))
    looped = np.stack([inverse(p) for p in plist])
    np.testing.assert_allclose(batched, looped, rtol=1e-13, atol=1e-13)

    def loss_grad(fn):
        return jax.jit(jax.grad(lambda p: jnp.sum(fn(p) ** 2)))(plist[0])

    g_lag = loss_grad(inverse)
    g_ne = loss_grad(lambda p: rnea(chain, q, qd, qdd, p))
    for k in g_lag:
        np.testing.assert_allclose(g_lag[k], g_ne[k], rtol=1e-10, atol=1e-10, err_msg=k)


def test_float32():
    chain = PlanarChain(3)
    system = chain.system()
    p32 = chain.params(m=[1.0, 2.0, 0.5], dtype=jnp.float32)
    q = jnp.array([0.3, -0.4, 0.9], jnp.float32)
    qd = jnp.array([1.0, 0.5, -0.2], jnp.float32)
    qdd = jax.jit(system.forward_dynamics)(q, qd, p32)
    tau = jax.jit(functools.partial(rnea, chain))(q, qd, qdd, p32)
    assert qdd.dtype == tau.dtype == jnp.float32
    np.testing.assert_allclose(tau, jnp.zeros(3), atol=1e-4)  # no input torque was applied
    spatial = SpatialChain("RP")
    ps32 = spatial.params(dtype=jnp.float32)
    tau_s = jax.jit(spatial.system().inverse_dynamics)(q[:2], qd[:2], qd[:2], ps32)
    assert tau_s.dtype == jnp.float32


def test_joint_positions_and_kinematics():
    chain = PlanarChain(2)
    p = chain.params(l=[1.0, 0.5])
    q = jnp.array([np.pi / 2, -np.pi / 2])
    np.testing.assert_allclose(
        chain.joint_positions(q, p), [[0, 0], [0, 1.0], [0.5, 1.0]], atol=1e-15
    )
    np.testing.assert_allclose(chain.com_positions(q, p), [[0, 0.5], [0.25, 1.0]], atol=1e-15)
    spatial = SpatialChain("RP", axes=[(0, 0, 2), (1, 0, 0)])
    origins, rots = spatial.frames(jnp.array([np.pi / 2, 0.3]), spatial.params())
    np.testing.assert_allclose(origins, [[0, 0, 0], [0, 1.3, 0]], atol=1e-15)
    np.testing.assert_allclose(rots[1], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)


def test_errors():
    with pytest.raises(ValueError, match="'R'"):
        SpatialChain("RX")
    with pytest.raises(ValueError, match="2 joints need 2 axes"):
        SpatialChain("RR", axes=[(0, 0, 1)])
    with pytest.raises(ValueError, match="not a rotation"):
        SpatialChain("R", rotations=[2 * np.eye(3)])
    with pytest.raises(ValueError, match="n >= 1"):
        PlanarChain(0)
    with pytest.raises(lx.ShapeError, match="'m'"):
        PlanarChain(3).params(m=[1.0, 2.0])
    with pytest.raises(lx.ParameterError, match=r"I\[1\] = -0.5"):
        PlanarChain(2).params(I=[0.1, -0.5])
    with pytest.raises(lx.ParameterError, match=r"inertia\[0\] violates the triangle"):
        SpatialChain("R").params(inertia=np.diag([1.0, 1.0, 3.0]))
    chain = PlanarChain(2)
    with pytest.raises(lx.ShapeError):
        chain.system().mass_matrix(jnp.zeros(3), chain.params())
    with pytest.raises(lx.ShapeError, match="qd"):
        rnea(chain, jnp.zeros(2), jnp.zeros(3), jnp.zeros(2), chain.params())
    with pytest.raises(TypeError, match="PlanarChain, SpatialChain or Tree"):
        rnea(object(), jnp.zeros(2), jnp.zeros(2), jnp.zeros(2), chain.params())
    with pytest.raises(lx.ParameterError, match="'I'"):
        p = chain.params()
        del p["I"]
        chain.system().mass_matrix(jnp.zeros(2), p)
