"""A system built inside a function that JAX transforms, its energies closing over the
function's traced argument (`V = ½ k q·q + Σ cos q` with `k` the argument): its calls
are traced even where the arrays passed are concrete, and a derivative with respect to
`k` goes through the computation (a custom rule sees only its arguments). Each call used
to fail with a raw JAX error (`TracerBoolConversionError`, `UnexpectedTracerError`, a
nested `jit`'s "No constant handler") under `jit`, `vmap`, `grad` or `jvp`.

Closed forms: `q̈ = −k q + sin q`, so `∂q̈₀/∂k = −q₀`, `∂q̈₀/∂q₀ = −k + cos q₀` and its
derivative with respect to `k` is `−1`."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import rel_error  # tests/_helpers.py

Q = jnp.array([0.3, 0.5])
K = 0.7


def _springs(k):
    return lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * jnp.sum(qd**2),
        lambda q, p: 0.5 * k * jnp.sum(q**2) + jnp.sum(jnp.cos(q)),
        n_dof=2,
    )


def _forward(k):
    return _springs(k).forward_dynamics(Q, Q, {})[0]


def _linearized(k):
    return _springs(k).linearize(Q, 0 * Q, {})[0][2, 0]


def _derivatives(k):
    return _springs(k).forward_dynamics_derivatives(Q, Q, {}).dq[0, 0]


def _inverse(k):
    return _springs(k).inverse_dynamics_derivatives(Q, Q, Q, {}).dq[0, 0]


CASES = {  # value at K, its derivative with respect to k
    "forward_dynamics": (_forward, -K * Q[0] + np.sin(Q[0]), -Q[0]),
    "linearize": (_linearized, -K + np.cos(Q[0]), -1.0),
    "forward_dynamics_derivatives": (_derivatives, -K + np.cos(Q[0]), -1.0),
    "inverse_dynamics_derivatives": (_inverse, K - np.cos(Q[0]), 1.0),
}
TRANSFORMS = {
    "jit": lambda f: jax.jit(f),
    "vmap": lambda f: lambda k: jax.vmap(f)(jnp.array([k, 2 * k]))[0],
    "grad": jax.grad,
    "jvp": lambda f: lambda k: jax.jvp(f, (k,), (1.0,))[1],
}


@pytest.mark.parametrize("transform", list(TRANSFORMS))
@pytest.mark.parametrize("call", list(CASES))
def test_calls_of_a_system_built_inside_a_transform(call, transform):
    fn, value, slope = CASES[call]
    expected = slope if transform in ("grad", "jvp") else value
    assert rel_error(TRANSFORMS[transform](fn)(K), expected) <= 1e-12


def test_constrained_system_built_inside_jit_and_grad():
    """A rod pendulum in Cartesian coordinates whose gravity `k` the free system's `V`
    closes over: the multipliers under `jit` and `∂ẍ/∂k` under `grad` against the closed
    form (at rest, horizontal rod: `ẍ = 0`, `ÿ = −k`, `λ = 0`; at rest, hanging: `ÿ = 0`)."""

    def rod(k):
        free = lx.LagrangianSystem(
            lambda q, qd, p: 0.5 * jnp.sum(qd**2), lambda q, p: k * q[1], n_dof=2
        )
        return lx.ConstrainedSystem(free, lambda q, p: jnp.stack([q @ q - 1.0]))

    horizontal, zero = jnp.array([1.0, 0.0]), jnp.zeros(2)
    qdd = jax.jit(lambda k: rod(k).forward_dynamics(horizontal, zero, {}))(9.81)
    assert rel_error(qdd, jnp.array([0.0, -9.81])) <= 1e-12
    slope = jax.grad(lambda k: rod(k).forward_dynamics(horizontal, zero, {})[1])(9.81)
    assert rel_error(slope, -1.0) <= 1e-12


def test_simulate_of_a_system_built_inside_vmap():
    """Harmonic springs (no `cos` term): `q(t) = q₀ cos(√k t)`."""

    def final(k):
        springs = lx.LagrangianSystem(
            lambda q, qd, p: 0.5 * jnp.sum(qd**2), lambda q, p: 0.5 * k * jnp.sum(q**2), n_dof=2
        )
        sol = lx.simulate(springs, Q, 0 * Q, {}, t1=0.5, n_save=2, rtol=1e-11, atol=1e-11)
        return sol.q[-1]

    ks = jnp.array([0.7, 1.7])
    exact = Q[None] * jnp.cos(jnp.sqrt(ks)[:, None] * 0.5)
    assert rel_error(jax.vmap(final)(ks), exact) <= 1e-8


def test_check_state_under_jit_is_a_named_error():
    """`check_state` reads concrete values to name a problem: given traced ones (under
    `jit`, or a system closing over a traced value) it is a `ConfigurationError` that
    says so (it was a raw `TracerBoolConversionError`)."""
    system, params = lx.models.planar_2r()
    with pytest.raises(lx.ConfigurationError, match="check_state.*outside jax.jit"):
        jax.jit(lambda q: system.check_state(q, q, params))(Q)
    with pytest.raises(lx.ConfigurationError, match="check_state.*close over"):
        jax.jit(lambda k: _springs(k).check_state(Q, Q, {}))(K)
    rod = lx.ConstrainedSystem(system, lambda q, p: jnp.stack([q @ q - 1.0]))
    with pytest.raises(lx.ConfigurationError, match="check_state"):
        jax.jit(lambda q: rod.check_state(q, q, params))(Q)
    system.check_state(Q, Q, params)  # concrete values: checked, no error
