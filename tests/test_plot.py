"""``lagrax.plot``: each figure draws without error on the 2R arm and shows what it should."""

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import xarray as xr  # noqa: E402

import lagrax as lx  # noqa: E402


@pytest.fixture(scope="module")
def sol(arm):
    system, params = arm
    return lx.simulate(system, [0.3, 0.8], [0.0, 0.0], params, t1=1.0, n_save=41)


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def test_phase_portrait(sol):
    ax = lx.plot.phase_portrait(sol)
    assert len(ax.lines) == 2  # one curve per coordinate
    np.testing.assert_allclose(ax.lines[1].get_xydata(), np.c_[sol.q[:, 1], sol.qd[:, 1]])
    ax = lx.plot.phase_portrait(sol, dof=1, labels=["θ2"])
    assert len(ax.lines) == 1 and ax.get_legend().get_texts()[0].get_text() == "θ2"


@pytest.mark.parametrize("kind", ["lengths", "chain", "function"])
def test_animate(sol, arm_params, kind, tmp_path):
    lengths = [float(arm_params["l1"]), float(arm_params["l2"])]
    chain = lx.chains.PlanarChain(2)
    geometry = {
        "lengths": lengths,
        "chain": chain,
        "function": lambda q: lx.plot.planar_chain_points(q, lengths),
    }[kind]
    anim = lx.plot.animate(geometry, sol, params=chain.params(), max_frames=5)
    fig = anim._fig
    assert len(fig.axes[0].lines) == 2  # the mechanism and the tip's path
    html = anim.to_jshtml()  # renders every frame
    assert html.count("data:image/png;base64") == 5
    # the last frame draws the arm at the final state: base, elbow, tip
    links = fig.axes[0].lines[1].get_xydata()
    np.testing.assert_allclose(links, lx.plot.planar_chain_points(sol.q[-1], lengths), atol=1e-12)
    if kind == "lengths":
        anim.save(tmp_path / "arm.gif", writer="pillow")
        assert (tmp_path / "arm.gif").stat().st_size > 1_000


def test_animate_needs_params_for_a_chain(sol):
    with pytest.raises(ValueError, match="params="):
        lx.plot.animate(lx.chains.PlanarChain(2), sol)


def test_sweep_heatmap(arm):
    system, params = arm
    batch = lx.grid(params, m2=np.linspace(0.5, 2.0, 3), l1=np.linspace(0.5, 1.5, 4))
    ds = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, t1=0.2, progress=False)
    ax = lx.plot.sweep_heatmap(ds, "q", dof=1)
    mesh = ax.collections[0]
    assert mesh.get_array().shape == (3, 4)  # (m2, l1): the grid's shape
    np.testing.assert_allclose(mesh.get_array(), ds.q.sel(dof=1).values)
    assert len(ax.figure.axes) == 2  # the plot and its colour bar
    assert ax.get_xlabel() == "l1" and ax.get_ylabel() == "m2"
    assert not ax.patches  # nothing failed
    with pytest.raises(ValueError, match="dof="):
        lx.plot.sweep_heatmap(ds, "q")


def test_sweep_heatmap_marks_failures():
    m2, l1 = np.geomspace(0.1, 10.0, 3), np.linspace(0.5, 1.5, 2)
    values = np.array([[1.0, 2.0], [np.inf, 4.0], [5.0, 6.0]])
    ok = np.isfinite(values)
    ok[2, 0] = False  # a failure with a finite-looking value is still marked
    ds = xr.Dataset(
        {"steps": (("m2", "l1"), values), "ok": (("m2", "l1"), ok)}, coords={"m2": m2, "l1": l1}
    )
    ax = lx.plot.sweep_heatmap(ds, "steps", x="m2", y="l1", log=True)
    mesh = ax.collections[0]
    assert mesh.get_array().shape == (2, 3)  # transposed: l1 on y
    assert mesh.get_array().mask.sum() == 2
    assert len(ax.patches) == 2  # hatched cells
    assert "failed (2 of 6)" in ax.get_legend().get_texts()[0].get_text()
    assert ax.get_xscale() == "log"  # geometric grid values


def test_work_precision_chart():
    pt = lx.bench.WorkPrecisionPoint
    points = [
        pt("tsit5", "rtol", 1e-6, 1e-5, 1e-7, 1e-3, 1.0, 50, 300.0, True),
        pt("tsit5", "rtol", 1e-8, 1e-7, 1e-9, 2e-3, 1.0, 90, 540.0, True),
        pt("variational", "dt", 1e-2, 1e-3, 1e-5, 3e-3, 1.0, 100, np.nan, True),
        pt("variational", "dt", 5e-3, np.inf, np.inf, 3e-3, 1.0, 200, np.nan, False),
    ]
    fig = lx.plot.work_precision((points, 1e-12), title="t")
    error_ax, energy_ax = fig.axes
    assert len(energy_ax.lines) == 2  # one per method
    assert len(error_ax.lines) == 3  # and the reference's error level
    assert len(error_ax.lines[1].get_xdata()) == 1  # the failed run is not drawn
    with pytest.raises(TypeError):
        lx.plot.work_precision(points)
