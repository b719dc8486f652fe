"""Chains' structure-aware equations (Featherstone's recursions) against the definition.

Every fast path (the articulated-body algorithm for ``q̈``, the composite-rigid-body
algorithm for ``M``, recursive Newton–Euler for ``M q̈ + C q̇ + G``, and the energies
by one outward pass), written out link by link and as a ``lax.scan``, must equal the
autodiff Euler–Lagrange equations of the chain's energies (``equations=None``) and the
independent Newton–Euler oracle ``lagrax.newton_euler.rnea``, for random chains,
parameters and states.
"""

import dataclasses
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from _helpers import check_grad_against_central_difference
from _random_models import check_energies, close, random_spatial  # tests/_random_models.py
from lagrax._multibody.articulated.tree_equations import ChainEquations
from lagrax._systems.derivatives import mass_and_force
from lagrax.chains import PlanarChain, SpatialChain
from lagrax.newton_euler import rnea


def _random_planar(n, seed):
    rng = np.random.default_rng(seed)
    chain = PlanarChain(n)
    params = chain.params(
        m=rng.uniform(0.5, 2, n),
        l=rng.uniform(0.3, 1.2, n),
        r=rng.uniform(0.05, 0.6, n),
        I=rng.uniform(0.01, 0.2, n),
        g=rng.uniform(5, 12),
    )
    return chain, params, rng


def _random_spatial(types, seed):
    return random_spatial(partial(SpatialChain, types), len(types), seed)


def _variants(chain):
    """The chain's system with its recursions unrolled, as a scan, and by autodiff."""
    system = chain.system()
    return (
        dataclasses.replace(system, equations=ChainEquations(chain, scan=False)),
        dataclasses.replace(system, equations=ChainEquations(chain, scan=True)),
        dataclasses.replace(system, equations=None),
    )


def _check_chain(chain, params, rng, generic=True):
    n = chain.n
    q, qd, tau = (jnp.asarray(rng.normal(size=n)) for _ in range(3))
    unrolled, scanned, autodiff = _variants(chain)
    qdd = scanned.forward_dynamics(q, qd, params, tau)
    # the oracle: recursive Newton–Euler in link frames reproduces tau from qdd
    close(rnea(chain, q, qd, qdd, params), tau)
    mass = scanned.mass_matrix(q, params)
    close(mass, mass.T)
    assert np.linalg.eigvalsh(np.asarray(mass))[0] > 0
    close(scanned.inverse_dynamics(q, qd, qdd, params), tau)
    if n <= 8:
        close(unrolled.forward_dynamics(q, qd, params, tau), qdd)
        close(unrolled.mass_matrix(q, params), mass)
        close(unrolled.inverse_dynamics(q, qd, qdd, params), tau)
    check_energies((unrolled, scanned), autodiff, q, qd, params)
    if generic:
        close(autodiff.forward_dynamics(q, qd, params, tau), qdd)
        close(autodiff.mass_matrix(q, params), mass)
        # M and M q̈ = f as the constrained (KKT) path asks for them
        fast_m, fast_f = mass_and_force(scanned, None, 0.0, q, qd, params, tau)
        auto_m, auto_f = mass_and_force(autodiff, None, 0.0, q, qd, params, tau)
        close(fast_m, auto_m)
        close(fast_f, auto_f)


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8])
def test_planar_recursions_equal_autodiff_and_rnea(n):
    _check_chain(*_random_planar(n, seed=n))


def test_planar_twenty_links_equal_rnea():
    _check_chain(*_random_planar(20, seed=20), generic=False)


# longer chains: the 20 joints below, against RNEA (the autodiff path's programs for seven
# joints took 30 s of the suite's time to compile, for what four joints already check)
@pytest.mark.parametrize("types", ["R", "P", "RP", "RRPR"])
def test_spatial_recursions_equal_autodiff_and_rnea(types):
    _check_chain(*_random_spatial(types, seed=len(types)))


def test_spatial_twenty_joints_equal_rnea():
    _check_chain(*_random_spatial("RRPRRRPRRRRPRRRRRRPR", seed=7), generic=False)


def test_recursions_under_vmap_and_grad():
    """vmap over parameters equals a loop; the gradient of q̈ with respect to a mass
    equals the autodiff path's."""
    chain, params, rng = _random_spatial("RRR", seed=3)
    fast, _, autodiff = _variants(chain)
    q, qd = jnp.asarray(rng.normal(size=3)), jnp.asarray(rng.normal(size=3))
    masses = jnp.asarray(rng.uniform(0.5, 2, (4, 3)))

    def qdd(system, m):
        return system.forward_dynamics(q, qd, {**params, "m": m})

    batched = jax.vmap(lambda m: qdd(fast, m))(masses)
    for i in range(4):
        close(batched[i], qdd(fast, masses[i]))
    close(
        jax.grad(lambda m: jnp.sum(qdd(fast, m) ** 2))(masses[0]),
        jax.grad(lambda m: jnp.sum(qdd(autodiff, m) ** 2))(masses[0]),
        rtol=1e-10,
    )


def test_simulate_gradient_matches_finite_differences():
    """Gradients flow through the recursions inside a solve."""
    chain = PlanarChain(4)
    system = chain.system()
    assert isinstance(system.equations, ChainEquations)
    q0, qd0 = jnp.array([0.3, -0.2, 0.4, 0.1]), jnp.zeros(4)

    def final_angle(m0):
        params = chain.params(m=jnp.stack([m0, 1.0, 1.0, 1.0]))
        sol = lx.simulate(system, q0, qd0, params, t1=0.5, rtol=1e-10, atol=1e-10)
        return sol.q_end[2]

    check_grad_against_central_difference(final_angle, 1.0)


def test_singular_chain_gives_nan_not_a_number():
    """A chain whose articulated inertia vanishes (a massless, inertia-free link at the
    tip) has no defined q̈: the recursion returns NaN, which simulate reports."""
    chain = PlanarChain(2)
    params = chain.params(m=[1.0, 0.0], I=[0.1, 0.0])
    qdd = chain.system().accelerations(0.0, jnp.array([0.1, 0.2]), jnp.zeros(2), params, None)
    assert np.all(np.isnan(np.asarray(qdd))) or not np.all(np.isfinite(np.asarray(qdd)))
