"""Kinematic trees (``lagrax.chains.Tree``): Featherstone's recursions run over parents
against the definition (autodiff of the energies), the independent Newton–Euler oracle
(``lagrax.newton_euler.rnea``, its own link-frame kinematics) and serial chains.
"""

import dataclasses
from functools import partial

import jax.numpy as jnp
import numpy as np
import pytest

from _random_models import check_energies, close, random_spatial  # tests/_random_models.py
from lagrax._multibody.articulated.tree_equations import ChainEquations
from lagrax._systems.derivatives import mass_and_force
from lagrax.chains import SpatialChain, Tree
from lagrax.newton_euler import rnea


def _random_tree(types, parents, seed):
    return random_spatial(partial(Tree, types, parents), len(types), seed, gravity=True)


def test_tree_recursions_equal_rnea():
    """Two bodies on the base, one of them with two children, one of those with a child;
    revolute and prismatic joints. The recursions unrolled and as a scan against each
    other and the oracle (the definition, autodiff of the energies, is slow to compile
    for spatial bodies: it is checked on a smaller tree below)."""
    tree, params, rng = _random_tree("RPRRP", (-1, -1, 0, 0, 2), seed=4)
    n = tree.n
    q, qd, tau = (jnp.asarray(rng.normal(size=n)) for _ in range(3))
    system = tree.system()
    unrolled, scanned = (
        dataclasses.replace(system, equations=ChainEquations(tree, scan=False)),
        dataclasses.replace(system, equations=ChainEquations(tree, scan=True)),
    )
    qdd = scanned.forward_dynamics(q, qd, params, tau)
    close(rnea(tree, q, qd, qdd, params), tau)  # the oracle reproduces tau from qdd
    mass = scanned.mass_matrix(q, params)
    close(mass, mass.T)
    assert np.linalg.eigvalsh(np.asarray(mass))[0] > 0
    close(scanned.inverse_dynamics(q, qd, qdd, params), tau)
    close(unrolled.forward_dynamics(q, qd, params, tau), qdd)
    close(unrolled.mass_matrix(q, params), mass)
    fast_m, fast_f = mass_and_force(scanned, None, 0.0, q, qd, params, tau)
    close(fast_m, mass)
    close(fast_f, mass @ qdd)
    # the energies by one outward pass over parents equal the pose maps' T + V
    check_energies((unrolled, scanned), dataclasses.replace(system, equations=None), q, qd, params)
    # bodies on different branches do not couple in M
    related = np.zeros((n, n), bool)
    for i in range(n):
        j = i
        while j >= 0:
            related[j, i] = related[i, j] = True
            j = tree.parents[j]
    assert np.all(np.asarray(mass)[~related] == 0.0)


def test_tree_equals_autodiff_with_damping():
    """A branch (two bodies on one) against the definition: ``M`` and
    ``f = τ − C q̇ − G − ∂D/∂q̇`` by autodiff of the energies; joint damping is the
    Rayleigh dissipation ``½ Σ b q̇²``, a torque ``−b q̇``."""
    tree, params, rng = _random_tree("RPR", (-1, 0, 0), seed=5)
    params = {**params, "damping": jnp.asarray([0.3, 1.0, 0.0])}
    q, qd, tau = (jnp.asarray(rng.normal(size=3)) for _ in range(3))
    system = tree.system()
    qdd = system.forward_dynamics(q, qd, params, tau)
    close(rnea(tree, q, qd, qdd, params), tau - params["damping"] * qd)
    fast_m, fast_f = mass_and_force(system, None, 0.0, q, qd, params, tau)
    auto_m, auto_f = mass_and_force(
        dataclasses.replace(system, equations=None), None, 0.0, q, qd, params, tau
    )
    close(fast_m, auto_m)
    close(fast_f, auto_f)
    close(np.linalg.solve(np.asarray(auto_m), np.asarray(auto_f)), qdd, rtol=1e-10)


def test_a_tree_that_is_a_chain_equals_the_chain():
    chain = SpatialChain("RPR", axes=[(0, 0, 1), (1, 0, 0), (0, 1, 0)], up=(0, 1, 0))
    tree = Tree("RPR", (-1, 0, 1), axes=chain.axes, rotations=chain.rotations, up=chain.up)
    rng = np.random.default_rng(0)
    chain_params = chain.params(offset=rng.normal(size=(3, 3)), com=rng.normal(size=(3, 3)))
    tree_params = tree.params(
        **{k: chain_params[k] for k in ("m", "offset", "com", "inertia", "g")}
    )
    q, qd, tau = (jnp.asarray(rng.normal(size=3)) for _ in range(3))
    close(
        tree.system().forward_dynamics(q, qd, tree_params, tau),
        chain.system().forward_dynamics(q, qd, chain_params, tau),
    )


def test_tree_structure_is_checked():
    with pytest.raises(ValueError, match="parent"):
        Tree("RR", (-1, 1))
    with pytest.raises(ValueError, match="joint_types"):
        Tree("RX", (-1, 0))
    with pytest.raises(ValueError, match="parent indices"):
        Tree("RR", (-1,))
    tree = Tree("RC", (-1, 0), joint_names=["shoulder", "elbow"])
    assert tree.joint_types == "RR"
    assert tree.children(-1) == (0,) and tree.children(0) == (1,)
    assert tree.system().coordinate_names == ("shoulder", "elbow")
