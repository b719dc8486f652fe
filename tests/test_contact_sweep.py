"""A sweep of a `ContactSystem` keeps the contact gaps and forces (`observables=`): equal
to each member's `simulate`, the resting and sliding loads of the closed forms, named
dimensions, and through a checkpoint and a zarr store.

A point mass with a sphere of radius `R` on the floor `y = 0`, at its static
penetration, one member resting, the others sliding at 2 m/s under friction `μ`.
"""

import numpy as np
import pytest

import lagrax as lx
from lagrax.contact import ContactSystem, Plane, Sphere

G, R = 9.81, 0.1
TS = np.array([0.1, 0.2, 0.3])
MU = np.array([0.3, 0.3, 0.6])
MASS = np.array([1.0, 1.0, 2.0])
V0 = np.array([0.0, 2.0, 2.0])  # the first member rests, the others slide
OBSERVED = ("contact_gap", "contact_force")


@pytest.fixture(scope="module")
def scene():
    """The scene, its members (friction, mass, dissipation from params) and their
    initial states, each at its static penetration `(m g/k)^{2/3}`."""
    body = lx.LagrangianSystem(
        lambda q, qd, p: 0.5 * p["m"] * qd @ qd, lambda q, p: p["m"] * G * q[1], n_dof=2
    )
    point = ContactSystem(
        body,
        Sphere(R, lambda q, p: q),
        Plane([0.0, 1.0]),
        friction=lambda p: p["mu"],
        dissipation=lambda p: p["c"],
    )
    params = {"m": 1.0, "mu": 0.3, "c": 50.0}
    k = float(point.coefficients(params).stiffness)
    y = R - (MASS * G / k) ** (1 / 1.5)
    q0 = np.stack([np.zeros(3), y], axis=1)
    qd0 = np.stack([V0, np.zeros(3)], axis=1)
    batch = {"m": MASS, "mu": MU, "c": np.full(3, 50.0)}
    return point, q0, qd0, batch


def _sweep(scene, **kw):
    point, q0, qd0, batch = scene
    kw = dict(chunk_size=2, schedule="lockstep", rtol=1e-11, atol=1e-11, **kw)
    return lx.sweep(point, q0, qd0, batch, t1=0.3, **kw)


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    return tmp_path_factory.mktemp("contact_sweep") / "ckpt"


@pytest.fixture(scope="module")
def kept(scene, checkpoint):
    """The sweep keeping the gaps and forces at `TS` (in lock-step: each member is
    `simulate`'s solve, to round-off), checkpointed."""
    return _sweep(scene, keep=TS, observables=OBSERVED, checkpoint=checkpoint)


def test_kept_contact_forces_equal_simulate_and_the_closed_forms(scene, kept):
    point, q0, qd0, batch = scene
    assert kept.attrs["n_failed"] == 0
    assert kept.contact_gap.dims == ("member", "time", "contact")
    assert kept.contact_force.dims == ("member", "time", "contact", "axis")
    for i in range(3):
        p = {k: v[i] for k, v in batch.items()}
        weight = MASS[i] * G
        # the contact at each kept state, to round-off
        for j, t in enumerate(TS):
            q, qd = kept.q.values[i, j], kept.qd.values[i, j]
            at = point.observables(t, q, qd, p, np.zeros(2))
            np.testing.assert_allclose(
                kept.contact_force[i, j], at["contact_force"], atol=1e-13 * weight
            )
            np.testing.assert_allclose(kept.contact_gap[i, j], at["contact_gap"], atol=1e-16)
        # and simulate's solve: its state to the tolerance (the steps differ for the
        # sliding members: measured 6e-14 m), its forces to that times the contact's
        # stiffness, 1.5 m g/δ ≈ 1.5e6 N/m (measured 7e-9 of the weight)
        sol = lx.simulate(point, q0[i], qd0[i], p, t1=0.3, ts=TS, rtol=1e-11, atol=1e-11)
        np.testing.assert_allclose(kept.q[i], sol.q, atol=1e-12)
        np.testing.assert_allclose(kept.contact_force[i], sol.contact_force, atol=1e-7 * weight)
        np.testing.assert_allclose(kept.contact_gap[i], sol.contact_gap, atol=1e-12)
    force = kept.contact_force.sum("contact").values  # (member, time, axis)
    # the normal force carries the weight; sliding, friction is μ m g against the motion
    weight = np.broadcast_to((MASS * G)[:, None], force.shape[:2])
    np.testing.assert_allclose(force[..., 1], weight, rtol=1e-6)
    sliding = np.broadcast_to((-np.sign(V0) * MU * MASS * G)[:, None], force.shape[:2])
    np.testing.assert_allclose(force[..., 0], sliding, atol=1e-6 * G)
    # the active set: every contact penetrates, so carries force
    assert bool((kept.contact_gap <= 0).all())


def test_kept_at_the_end_and_through_checkpoint_and_store(scene, kept, checkpoint, tmp_path):
    final = _sweep(scene, observables=True)
    assert final.contact_force.dims == ("member", "contact", "axis")
    # (the default method here is the linearly implicit rodas4: the two programs' linear
    # solves and Jacobians differ in their round-off)
    np.testing.assert_allclose(final.contact_force, kept.contact_force.isel(time=-1), rtol=1e-10)
    # the same sweep again loads its chunks from the checkpoint
    again = _sweep(scene, keep=TS, observables=OBSERVED, checkpoint=checkpoint)
    np.testing.assert_array_equal(again.contact_force, kept.contact_force)
    np.testing.assert_array_equal(again.contact_gap, kept.contact_gap)
    # a checkpoint holds its own sweep's results: not one that keeps other observables
    with pytest.raises(lx.CheckpointError, match="different sweep definition"):
        _sweep(scene, keep=TS, checkpoint=checkpoint)
    with pytest.raises(lx.CheckpointError, match="different sweep definition"):
        _sweep(scene, keep=TS, observables="contact_gap", checkpoint=checkpoint)
    pytest.importorskip("zarr")
    stored = _sweep(scene, keep=TS, observables=OBSERVED, store=tmp_path / "s.zarr")
    assert stored.contact_force.dims == kept.contact_force.dims
    np.testing.assert_array_equal(stored.contact_force.values, kept.contact_force.values)
    reopened = lx.open_sweep(tmp_path / "s.zarr")
    np.testing.assert_array_equal(reopened.contact_gap.values, kept.contact_gap.values)


def test_unknown_observables_are_refused_naming_them(scene):
    with pytest.raises(lx.ConfigurationError, match="'contact_forces'.*did you mean"):
        _sweep(scene, observables="contact_forces")
    with pytest.raises(lx.ConfigurationError, match="keep= reduction"):
        _sweep(scene, keep=lambda s: s.q[-1], observables=True)
    with pytest.raises(lx.ArgumentTypeError, match="observables"):
        _sweep(scene, observables=[1])
