"""Derivatives of the dynamics: the accelerations differentiated through the inverse
dynamics (a custom JVP) against plain automatic differentiation through the factorization
or the articulated-body recursion, against Pinocchio's analytical derivatives and against
`jax.test_util.check_grads` and central differences (through `simulate`:
`test_simulate_derivatives.py`).

The rule is switched off by `lagrax._systems.implicit.plain_autodiff()` at trace time:
the reference is the same computation, differentiated by JAX instead of by the identity
`δq̈ = M⁻¹(δτ − ∂r/∂q δq − ∂r/∂q̇ δq̇ − ∂r/∂p δp − ∂r/∂t δt)`.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import lagrax as lx
from _helpers import example_robot_data, pin_state, rel_error  # tests/_helpers.py
from _random_models import random_spatial  # tests/_random_models.py
from lagrax._systems import implicit

RTOL = 1e-12
EPS = float(np.finfo(np.float64).eps)
N_STATES = 3


def _states(n, seed, k=N_STATES):
    rng = np.random.default_rng(seed)
    return tuple(jnp.asarray(rng.uniform(-1.5, 1.5, (k, n))) for _ in range(3))


# ------------------------------------------------------------------ the systems
def _damped_forced_arm():
    """The 2R arm with a Rayleigh dissipation and a state- and time-dependent force."""
    arm, params = lx.models.planar_2r()

    def dissipation(q, qd, p):
        return 0.5 * p["c"] * (qd[0] ** 2 + qd[1] ** 2 + qd[0] * qd[1] * jnp.cos(q[1]))

    def force(t, q, qd, p):
        return jnp.stack([p["f"] * jnp.sin(q[1] + t), -p["f"] * qd[0] * qd[1]])

    system = lx.LagrangianSystem(
        arm.kinetic, arm.potential, n_dof=2, dissipation=dissipation, force=force
    )
    return system, {**params, "c": 0.3, "f": 0.7}


def _reeled_pendulum():
    """A pendulum whose length `l(t) = l0 (1 + a sin ν t)` is prescribed (time-dependent)."""

    def length(t, p):
        return p["l0"] * (1 + p["a"] * jnp.sin(p["nu"] * t))

    def kinetic(t, q, qd, p):
        ldot = jax.grad(length)(t, p)
        return 0.5 * p["m"] * (ldot**2 + (length(t, p) * qd[0]) ** 2)

    def potential(t, q, p):
        return -p["m"] * p["g"] * length(t, p) * jnp.cos(q[0])

    system = lx.LagrangianSystem(kinetic, potential, n_dof=1, time_dependent=True)
    return system, {"m": 0.8, "l0": 1.2, "a": 0.2, "nu": 1.7, "g": 9.81}


def _bodies():
    """A planar three-link scene of bodies with a spring and a damper, its equations from
    the bodies' poses."""
    from lagrax.bodies import Param, PlanarBody, Scene, TorsionalDamper, TorsionalSpring

    def position(k):
        def at(q, p):
            angles = jnp.cumsum(q)[: k + 1]
            return p["l"] * jnp.stack([jnp.sum(jnp.cos(angles)), jnp.sum(jnp.sin(angles))])

        return at

    bodies = [
        PlanarBody(
            mass=1.0 + 0.2 * k,
            inertia=0.05 + 0.01 * k,
            position=position(k),
            angle=lambda q, p, k=k: jnp.sum(q[: k + 1]),
        )
        for k in range(3)
    ]
    scene = Scene(
        bodies,
        springs=[TorsionalSpring(Param("k"), 1, 0.2)],
        dampers=[TorsionalDamper(Param("c"), 2)],
        n_dof=3,
        equations="poses",
    )
    return scene.system(), {"l": 0.7, "k": 2.0, "c": 0.4}


def _planar_chain():
    chain = lx.chains.PlanarChain(4)
    return chain.system(), chain.params(m=[1.0, 0.8, 0.6, 0.5])


def _spatial_chain():
    chain, params, _ = random_spatial(
        lambda **kw: lx.chains.SpatialChain("RPRR", **kw), 4, seed=7, gravity=True
    )
    return chain.system(), params


def _tree():
    # three bodies, two branches from the first, one prismatic (a fourth body on a branch
    # doubled the plain-autodiff oracles' compile time, to 70 s)
    tree, params, _ = random_spatial(
        lambda **kw: lx.chains.Tree("RPR", (-1, 0, 0), **kw), 3, seed=8, gravity=True
    )
    return tree.system(), {**params, "damping": jnp.array([0.3, 0.5, 0.2])}


def _urdf():
    tree, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"))
    return tree.system(), params


SYSTEMS = {
    "energies (2R arm)": lambda: lx.models.planar_2r(),
    "energies, dissipation and force": _damped_forced_arm,
    "time-dependent energies": _reeled_pendulum,
    "bodies (poses)": _bodies,
    "planar chain": _planar_chain,
    "spatial chain, revolute and prismatic": _spatial_chain,
    "tree, damped": _tree,
    "URDF arm": _urdf,
}


def _jacobians(system, params, q, qd, tau, t):
    """`∂q̈/∂(q, q̇, τ, t)` by `jacfwd` and the gradient of `|q̈|²` with respect to
    `(q, params)` by reverse mode, vmapped over states and compiled (traced now: the
    caller picks the rule)."""

    def fd(q, qd, tau, p, t):
        return system.forward_dynamics(q, qd, p, tau, t=t)

    def loss(q, qd, tau, p, t):
        return jnp.sum(fd(q, qd, tau, p, t) ** 2)

    jac = jax.jacfwd(lambda a, b, c, s: fd(a, b, c, params, s), argnums=(0, 1, 2, 3))
    grad = jax.grad(loss, argnums=(0, 3))
    both = jax.vmap(lambda a, b, c: (jac(a, b, c, t), grad(a, b, c, params, t)))
    return jax.jit(both)(q, qd, tau)


# ∂/∂params in one call (identification), checked on these; the gradient with respect to
# the params of every system is checked in test_rule_equals_plain_autodiff
WRT_PARAMS = ("energies, dissipation and force", "time-dependent energies", "tree, damped")


@functools.cache
def _case(name):
    """`(name, system, params)`, built once per name (the tests share compiled code)."""
    system, params = SYSTEMS[name]()
    return name, system, jax.tree_util.tree_map(jnp.asarray, params)


# (the URDF arm's rule is held to plain autodiff by test_derivatives_api_equals_jacobians
# and to Pinocchio below: its vmapped Jacobians and gradient are the slowest to compile)
@pytest.mark.parametrize("name", [k for k in SYSTEMS if k != "URDF arm"])
def test_rule_equals_plain_autodiff(name):
    name, system, params = _case(name)
    n = system.n_dof
    q, qd, tau = _states(n, seed=n)
    t = jnp.asarray(0.4)
    ours = _jacobians(system, params, q, qd, tau, t)
    with implicit.plain_autodiff():
        plain = _jacobians(system, params, q, qd, tau, t)
    paths, ref = zip(*jax.tree_util.tree_leaves_with_path(plain), strict=True)
    leaves = jax.tree_util.tree_leaves(ours)
    assert len(leaves) == len(ref) and len(leaves) > 5
    errors = {
        jax.tree_util.keystr(k): rel_error(a, b) for k, a, b in zip(paths, leaves, ref, strict=True)
    }
    # both sides solve with M: round-off of order cond(M) ε (the URDF arm's M reaches
    # cond ≈ 4e3 at these states), never less strict than 1e-12
    mass = jax.vmap(lambda a: system.mass_matrix(a, params, t=t))(q)
    cond = float(np.max(np.linalg.cond(np.asarray(mass))))
    assert max(errors.values()) <= max(RTOL, 10 * cond * EPS), (name, cond, errors)
    # the derivative with respect to τ is M⁻¹, whatever else the system has
    dtau = ours[0][2]
    identity = jnp.broadcast_to(jnp.eye(n), mass.shape)
    assert rel_error(jnp.einsum("kij,kjl->kil", dtau, mass), identity) <= 1e-10


@pytest.mark.parametrize("name", list(SYSTEMS))
def test_derivatives_api_equals_jacobians(name):
    """`forward_dynamics_derivatives` / `inverse_dynamics_derivatives` in one call equal
    `jacfwd` of `forward_dynamics` / `inverse_dynamics` (plain autodiff), with respect to
    the params too; `∂τ/∂q̈ = M`."""
    name, system, params = _case(name)
    n = system.n_dof
    q, qd, tau = _states(n, seed=10 + n, k=1)
    q, qd, tau = q[0], qd[0], tau[0]
    t = 0.3
    wrt = name in WRT_PARAMS
    fwd = system.forward_dynamics_derivatives(q, qd, params, tau, t, wrt_params=wrt)
    qdd = fwd.qdd
    inv = system.inverse_dynamics_derivatives(q, qd, qdd, params, t, wrt_params=wrt)
    argnums = (0, 1, 2, 3) if wrt else (0, 1, 2)
    with implicit.plain_autodiff():
        jf = jax.jacfwd(
            lambda a, b, c, p: system.forward_dynamics(a, b, p, c, t=t), argnums=argnums
        )(q, qd, tau, params)
        ji = jax.jacfwd(
            lambda a, b, c, p: system.inverse_dynamics(a, b, c, p, t=t), argnums=argnums
        )(q, qd, qdd, params)
    for ours, ref in (
        ((fwd.dq, fwd.dqd, fwd.dtau, fwd.dparams), jf),
        ((inv.dq, inv.dqd, inv.dqdd, inv.dparams), ji),
    ):
        for a, b in zip(
            jax.tree_util.tree_leaves(ours), jax.tree_util.tree_leaves(ref), strict=True
        ):
            assert rel_error(a, b) <= 1e-11, name
    assert rel_error(inv.tau, tau) <= 1e-10  # τ(q̈(τ)) = τ
    assert rel_error(inv.dqdd, system.mass_matrix(q, params, t=t)) <= RTOL
    if wrt:  # without them: the same, and no dparams
        without = system.forward_dynamics_derivatives(q, qd, params, tau, t)
        assert without.dparams is None and rel_error(without.dq, fwd.dq) <= RTOL
    else:
        assert fwd.dparams is None and inv.dparams is None


def _central(f, x, h):
    """`∂f/∂x` by central differences, one column per coordinate of a flat `x`."""
    cols = [(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(x.shape[0])]
    return jnp.stack(cols, axis=-1)


def test_rule_forward_and_reverse_to_second_order():
    """The rule's first and second derivatives of `q̈(q, q̇, τ, m₂)`, in forward and
    reverse mode and mixed, against central differences (of `q̈`, then of the exact
    Jacobian) and against each other: what `jax.test_util.check_grads(order=2)` checks,
    on whole Jacobians. Each is compiled whole: `check_grads` transforms a jitted
    function eagerly, and XLA then compiles the eager second-order reverse programs of
    even this 2R arm in 26–40 s (a fusion of ~170 pads), against 3 s jitted whole."""
    system, params = _damped_forced_arm()
    q, qd, tau = (x[0] for x in _states(2, seed=3))
    x0 = jnp.concatenate([q, qd, tau, jnp.array([1.3])])

    def fd(x):
        return system.forward_dynamics(x[:2], x[2:4], {**params, "m2": x[6]}, x[4:6], t=0.2)

    fwd, rev = jax.jit(jax.jacfwd(fd)), jax.jit(jax.jacrev(fd))
    jac = fwd(x0)
    assert rel_error(rev(x0), jac) <= RTOL
    assert rel_error(jac, _central(jax.jit(fd), x0, 1e-5)) <= 1e-8
    hess = jax.jit(jax.jacfwd(jax.jacfwd(fd)))(x0)
    assert hess.shape == (2, 7, 7) and float(jnp.max(jnp.abs(hess))) > 0.1
    assert rel_error(hess, jnp.swapaxes(hess, 1, 2)) <= RTOL  # symmetric second derivatives
    assert rel_error(hess, _central(fwd, x0, 1e-5)) <= 1e-8
    # reverse over reverse and forward over reverse, contracted with cotangents `u`, `w`:
    # `uᵀ (∂²q̈/∂x²) w` (whole `jacrev(jacrev)` Jacobians compile 10× slower, 35 s)
    u, w = jnp.array([0.7, -1.1]), jnp.linspace(-1.0, 1.0, 7)

    def pulled(x):
        return jax.vjp(fd, x)[1](u)[0]

    rev_rev = jax.jit(lambda x: jax.vjp(pulled, x)[1](w)[0])(x0)
    fwd_rev = jax.jit(lambda x: jax.jvp(pulled, (x,), (w,))[1])(x0)
    expected = jnp.einsum("i,ijk,k->j", u, hess, w)
    assert rel_error(rev_rev, expected) <= RTOL and rel_error(fwd_rev, expected) <= RTOL


def test_check_grads_of_a_chain():
    system, params = _spatial_chain()
    q, qd, tau = (x[0] for x in _states(4, seed=4))
    check_grads(
        jax.jit(lambda a, b, c: system.forward_dynamics(a, b, params, c)),
        (q, qd, tau),
        order=1,
        modes=("fwd", "rev"),
    )


def test_constrained_tangents_go_through_the_kkt_system():
    """A constrained system's accelerations differentiated by its rule (the tangents
    through the KKT system) equal plain autodiff: holonomic and velocity constraints."""
    pendulum, params = lx.models.cartesian_pendulum()
    knife = lx.ConstrainedSystem(
        pendulum.system,
        None,
        velocity_constraints=lambda q, p: jnp.stack([q[1], -q[0]]),
    )
    q, qd = jnp.array([0.6, -0.8]), jnp.array([0.8, 0.6])
    tau = jnp.array([0.3, -0.2])
    for system in (pendulum, knife):

        def acc(q, qd, tau, p, s=system):
            return s.accelerations(0.0, q, qd, p, tau)

        ours = jax.jacfwd(acc, argnums=(0, 1, 2, 3))(q, qd, tau, params)
        with implicit.plain_autodiff():
            ref = jax.jacfwd(acc, argnums=(0, 1, 2, 3))(q, qd, tau, params)
        for a, b in zip(
            jax.tree_util.tree_leaves(ours), jax.tree_util.tree_leaves(ref), strict=True
        ):
            assert rel_error(a, b) <= 1e-11


def test_constrained_derivatives_api_and_linearization():
    """`ConstrainedSystem.forward_dynamics_derivatives` equals plain autodiff's
    `jacfwd` (holonomic and velocity constraints, with `∂q̈/∂params`), its `∂q̈/∂τ` the
    closed form `M⁻¹ − M⁻¹Kᵀ S⁻¹ K M⁻¹` (`S = K M⁻¹ Kᵀ`), and `linearize` of the
    Cartesian pendulum hanging at rest has the eigenvalues `±i √(g/l)` of its swing and
    `−α ± √(α² − β²)` of its Baumgarte drift."""
    pendulum, params = lx.models.cartesian_pendulum(alpha=10.0, beta=5.0)
    knife = lx.ConstrainedSystem(
        pendulum.system, None, velocity_constraints=lambda q, p: jnp.stack([q[1], -q[0]])
    )
    q, qd, tau = jnp.array([0.6, -0.8]), jnp.array([0.8, 0.6]), jnp.array([0.3, -0.2])
    for system in (pendulum, knife):
        out = system.forward_dynamics_derivatives(q, qd, params, tau, wrt_params=True)

        def acc(a, b, c, p, s=system):
            return s.forward_dynamics(a, b, p, c)

        with implicit.plain_autodiff():
            ref = jax.jacfwd(acc, argnums=(0, 1, 2, 3))(q, qd, tau, params)
        assert rel_error(out.qdd, acc(q, qd, tau, params)) <= 1e-14
        for ours, plain in zip((out.dq, out.dqd, out.dtau), ref[:3], strict=True):
            assert rel_error(ours, plain) <= 1e-12
        for key in params:
            assert rel_error(out.dparams[key], ref[3][key]) <= 1e-12
        kmat = system.constraint_matrix(q, params)
        m_inv = jnp.linalg.inv(system.mass_matrix(q, params))
        m_inv_kt = m_inv @ kmat.T
        projected = m_inv - m_inv_kt @ jnp.linalg.solve(kmat @ m_inv_kt, m_inv_kt.T)
        assert rel_error(out.dtau, projected) <= 1e-13

    a_mat, b_mat = pendulum.linearize(jnp.array([0.0, -1.0]), jnp.zeros(2), params)
    swing = np.sqrt(params["g"] / params["l"])
    drift = -10.0 + np.array([1.0, -1.0]) * np.sqrt(10.0**2 - 5.0**2)
    expected = np.sort_complex(np.array([1j * swing, -1j * swing, *drift]))
    assert rel_error(np.sort_complex(np.linalg.eigvals(np.asarray(a_mat))), expected) <= 1e-12
    assert rel_error(b_mat, np.array([[0, 0], [0, 0], [1 / params["m"], 0], [0, 0]])) <= 1e-14
    with pytest.raises(lx.NonFiniteError):
        pendulum.forward_dynamics_derivatives(jnp.array([jnp.nan, -1.0]), jnp.zeros(2), params)


def test_tau_function_takes_its_own_tangents():
    """A state feedback `τ(t, q, q̇)` in the vector field: its Jacobian by the rule equals
    plain autodiff (the feedback's derivatives chain into the accelerations')."""
    system, params = lx.models.planar_2r()

    def closed_loop(q, qd):
        tau = -5.0 * jnp.sin(q) - 1.5 * qd * jnp.cos(q[::-1])
        return system.forward_dynamics(q, qd, params, tau)

    q, qd, _ = (x[0] for x in _states(2, seed=5))
    ours = jax.jacfwd(closed_loop, argnums=(0, 1))(q, qd)
    with implicit.plain_autodiff():
        ref = jax.jacfwd(closed_loop, argnums=(0, 1))(q, qd)
    assert max(rel_error(a, b) for a, b in zip(ours, ref, strict=True)) <= RTOL


@pytest.mark.parametrize("n", [2, 8])  # the scalar and the vector energy paths
def test_params_with_none_entries_pair_tangents_with_their_leaves(n):
    """A `None` in `params` (an empty subtree) before the differentiated entry: the rule's
    tangents pair with the right leaves. They were shifted by one, so the derivative with
    respect to `b` was silently taken along `c` (`0` where central differences give `−0.2`).
    """
    system = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * p["m"] * jnp.sum(qd**2),
        lambda q, p: 0.5 * p["b"] * q[0] ** 2 + 0.5 * p["c"] * q[1] ** 2 + 0.5 * jnp.sum(q**2),
        n_dof=n,
    )
    q, qd = jnp.linspace(0.3, -0.2, n), jnp.linspace(0.1, 0.4, n)
    params = {"a": None, "b": 2.0, "c": 5.0, "m": 1.5, "z": None}

    def acc(b):
        return system.forward_dynamics(q, qd, {**params, "b": b})

    exact = np.zeros(n)
    exact[0] = -q[0] / 1.5  # q̈₀ = −(b + 1) q₀ / m
    assert rel_error(jax.jacfwd(acc)(2.0), exact) <= RTOL
    assert rel_error(jax.grad(lambda b: acc(b)[0])(2.0), exact[0]) <= RTOL


# ------------------------------------------------------------------ against Pinocchio
# example-robot-data's robots as shipped (inputs we did not write): UR5 (6 revolute joints,
# fixed links merged) and Unitree Z1 (7 joints)
SHIPPED = {"ur5": "ur_description/urdf/ur5_robot.urdf", "z1": "z1_description/urdf/z1.urdf"}


@pytest.mark.parametrize("robot", ["arm7", "torso_two_arms", *SHIPPED])
def test_derivatives_match_pinocchio(robot):
    pin = pytest.importorskip("pinocchio", reason="Pinocchio (pip install pin) is the reference")
    if robot in SHIPPED:
        root = example_robot_data()
        if root is None:
            pytest.skip("example-robot-data is not installed")
        path = root / "robots" / SHIPPED[robot]
    else:
        path = lx.models.urdf_path(robot)
    tree, params = lx.chains.from_urdf(path)
    params = {**params, "damping": jnp.zeros(tree.n)}
    system = tree.system()
    model = pin.buildModelFromXML(path.read_text())
    data = model.createData()
    n = tree.n
    q, qd, tau = (np.asarray(x) for x in _states(n, seed=n, k=2))
    fwd = jax.jit(jax.vmap(lambda a, b, c: system.forward_dynamics_derivatives(a, b, params, c)))(
        q, qd, tau
    )
    inv = jax.jit(jax.vmap(lambda a, b, c: system.inverse_dynamics_derivatives(a, b, c, params)))(
        q, qd, tau
    )  # (τ's values as accelerations)
    worst = {}
    for k in range(q.shape[0]):
        qp, vp, order = pin_state(pin, model, tree, q[k], qd[k])
        t_pin, a_pin = np.zeros(n), np.zeros(n)
        t_pin[order], a_pin[order] = tau[k], tau[k]
        pin.computeABADerivatives(model, data, qp, vp, t_pin)
        m_inv = np.triu(data.Minv) + np.triu(data.Minv, 1).T
        pin.computeRNEADerivatives(model, data, qp, vp, a_pin)
        m = np.triu(data.M) + np.triu(data.M, 1).T
        ix = np.ix_(order, order)
        pairs = {
            "ddq_dq": (fwd.dq[k], data.ddq_dq[ix]),
            "ddq_dv": (fwd.dqd[k], data.ddq_dv[ix]),
            "Minv": (fwd.dtau[k], m_inv[ix]),
            "dtau_dq": (inv.dq[k], data.dtau_dq[ix]),
            "dtau_dv": (inv.dqd[k], data.dtau_dv[ix]),
            "M": (inv.dqdd[k], m[ix]),
        }
        if k == 0:  # an eager linearize: the one-state program (M⁻¹ by one LAPACK solve)
            a_mat, b_mat = system.linearize(q[0], qd[0], params, tau[0])
            pairs["linearize A"] = (a_mat[n:], np.hstack([data.ddq_dq[ix], data.ddq_dv[ix]]))
            pairs["linearize B"] = (b_mat[n:], m_inv[ix])
        for key, (ours, theirs) in pairs.items():
            worst[key] = max(worst.get(key, 0.0), rel_error(ours, theirs))
    assert max(worst.values()) <= 1e-10, worst
