"""Array-valued parameters in `samples`: a `(members, *shape)` array sweeps a parameter
of shape `shape`, member by member, and labels the result with extra dimensions; one
element of one (`"m[3]"`) is swept along a `grid` axis or drawn by `samples`."""

from typing import Any

import numpy as np
import pytest

import lagrax as lx

N = 3  # members
T1 = 0.05


@pytest.fixture(scope="module")
def urdf_arm():
    tree, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"))
    return tree.system(), params


@pytest.fixture(scope="module")
def masses(urdf_arm):
    """Every link mass varied by ±20 %, one row per member."""
    _, params = urdf_arm
    scale = np.random.default_rng(7).uniform(0.8, 1.2, (N, 7))
    return np.asarray(params["m"]) * scale


def test_samples_of_link_masses_equal_simulate_per_member(urdf_arm, masses):
    system, params = urdf_arm
    q0, qd0 = np.linspace(-0.5, 0.5, 7), np.zeros(7)
    ds = lx.sweep(
        system,
        q0,
        qd0,
        lx.samples(params, m=masses, units={"m": "kg"}),
        t1=T1,
        progress=False,
    )
    assert ds.m.dims == ("member", "m_dim_0") and ds.m.shape == (N, 7)
    np.testing.assert_array_equal(ds.m.values, masses)
    assert ds.m.attrs["units"] == "kg"
    assert bool(ds.ok.all())
    for i in range(N):
        sol = lx.simulate(system, q0, qd0, {**params, "m": masses[i]}, t1=T1)
        # the same steps as simulate: equal up to vectorized round-off
        assert int(ds.num_steps[i]) == int(sol.stats["num_steps"])
        np.testing.assert_allclose(ds.q.values[i], sol.q[-1], rtol=0, atol=1e-12)
        np.testing.assert_allclose(ds.qd.values[i], sol.qd[-1], rtol=0, atol=1e-10)


def test_array_valued_samples_in_a_store(urdf_arm, masses, tmp_path):
    pytest.importorskip("zarr", reason="the store needs the zarr extra")
    xr = pytest.importorskip("xarray")
    system, params = urdf_arm
    batch = lx.samples(params, m=masses)
    kw: dict[str, Any] = dict(t1=T1, chunk_size=2, progress=False)
    q0, qd0 = np.linspace(-0.5, 0.5, 7), np.zeros(7)
    reference = lx.sweep(system, q0, qd0, batch, **kw)
    ds = lx.sweep(system, q0, qd0, batch, store=tmp_path / "m.zarr", **kw)
    xr.testing.assert_identical(ds.load(), reference)


def test_wrong_shapes_name_the_leaf_and_both_shapes(urdf_arm):
    _, params = urdf_arm
    with pytest.raises(lx.ShapeError, match=r"'m'.*\(4, 6\).*\(6,\).*\(7,\)"):
        lx.samples(params, m=np.ones((4, 6)))
    with pytest.raises(lx.ShapeError, match=r"'m'.*\(4,\).*\(\).*\(7,\)"):
        lx.samples(params, m=np.ones(4))  # one scalar a member for a (7,) parameter
    with pytest.raises(lx.ShapeError, match=r"'inertia'.*\(2, 7, 3\).*\(7, 3, 3\)"):
        lx.samples(params, inertia=np.ones((2, 7, 3)))
    with pytest.raises(lx.ShapeError, match="one entry per member"):
        lx.samples(params, m=np.ones((0, 7)))
    with pytest.raises(lx.ShapeError, match=r"grid\(\) sweeps scalar.*'m'.*'m\[0\]'.*samples"):
        lx.grid(params, m=np.ones(3))
    with pytest.raises(lx.ShapeError, match=r"samples\(\) needs values of one length"):
        lx.samples(params, m=np.ones((2, 7)), g=[9.8, 9.81, 9.82])


def test_grid_over_one_element_equals_simulate_with_that_element_set(urdf_arm):
    """`grid(params, **{"m[3]": ...})` (the fourth link's mass, the rest fixed) crossed
    with a scalar: each member equals `simulate` with that one entry replaced, and the
    result's dimensions are named after the element."""
    system, params = urdf_arm
    q0, qd0 = np.linspace(-0.5, 0.5, 7), np.zeros(7)
    mass3, gravity = np.array([1.0, 3.0]), np.array([9.0, 9.81])
    batch = lx.grid(params, **{"m[3]": mass3}, g=gravity, units={"m[3]": "kg"})
    ds = lx.sweep(system, q0, qd0, batch, t1=T1, progress=False)
    assert ds.q.dims == ("m[3]", "g", "dof") and ds["m[3]"].attrs["units"] == "kg"
    np.testing.assert_array_equal(ds["m[3]"].values, mass3)
    for i, m3 in enumerate(mass3):
        for j, g in enumerate(gravity):
            m = np.array(params["m"], copy=True)
            m[3] = m3
            sol = lx.simulate(system, q0, qd0, {**params, "m": m, "g": g}, t1=T1)
            assert int(ds.num_steps[i, j]) == int(sol.stats["num_steps"])
            np.testing.assert_allclose(ds.q.values[i, j], sol.q[-1], rtol=0, atol=1e-12)
    # the inertia's element (link 2, zz), drawn member by member, negative index
    izz = np.asarray(params["inertia"])[2, 2, 2] * np.array([0.5, 2.0])
    ds = lx.sweep(
        system, q0, qd0, lx.samples(params, **{"inertia[2, -1, 2]": izz}), t1=T1, progress=False
    )
    for k, value in enumerate(izz):
        inertia = np.array(params["inertia"], copy=True)
        inertia[2, 2, 2] = value
        sol = lx.simulate(system, q0, qd0, {**params, "inertia": inertia}, t1=T1)
        np.testing.assert_allclose(ds.q.values[k], sol.q[-1], rtol=0, atol=1e-12)


def test_element_names_are_checked(urdf_arm):
    _, params = urdf_arm
    with pytest.raises(lx.ConfigurationError, match=r"'mass\[3\]'.*'mass'.*not one of"):
        lx.grid(params, **{"mass[3]": [1.0, 2.0]})
    with pytest.raises(lx.ShapeError, match=r"'m\[7\]'.*\(7,\).*\(7,\)"):
        lx.grid(params, **{"m[7]": [1.0, 2.0]})
    with pytest.raises(lx.ShapeError, match=r"'inertia\[1\]'.*\(1,\).*\(7, 3, 3\)"):
        lx.grid(params, **{"inertia[1]": [1.0, 2.0]})
    with pytest.raises(lx.ConfigurationError, match="swept whole as well"):
        lx.samples(params, **{"m[1]": [1.0, 2.0]}, m=np.ones((2, 7)))
    with pytest.raises(lx.ShapeError, match="1-D"):
        lx.grid(params, **{"m[1]": np.ones((2, 2))})
