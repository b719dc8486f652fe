"""``lagrax.plot``: each figure draws what it should (the data of its lines are the
solution's, the mechanism the geometry's), labels time and units, and keeps exact zeros
off log axes."""

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

import jax.numpy as jnp  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import xarray as xr  # noqa: E402

import lagrax as lx  # noqa: E402

LENGTHS3 = (0.6, 0.5, 0.4)


def pendulum3_points(q):
    """Pivot and bobs of a 3-link pendulum, absolute angles from the downward vertical."""
    x = np.cumsum([length * np.sin(a) for length, a in zip(LENGTHS3, q, strict=True)])
    y = np.cumsum([-length * np.cos(a) for length, a in zip(LENGTHS3, q, strict=True)])
    return np.r_[[[0.0, 0.0]], np.c_[x, y]]


@pytest.fixture(scope="module")
def pendulum3():
    """A hand-written 3-link pendulum (unit bob masses), angles from the downward vertical."""

    def positions(q):
        x = jnp.cumsum(jnp.asarray(LENGTHS3) * jnp.sin(q))
        y = jnp.cumsum(-jnp.asarray(LENGTHS3) * jnp.cos(q))
        return x, y

    def kinetic(q, qd, p):
        (vx, vy) = [jnp.cumsum(jnp.asarray(LENGTHS3) * c * qd) for c in (jnp.cos(q), jnp.sin(q))]
        return 0.5 * jnp.sum(vx**2 + vy**2)

    def potential(q, p):
        return p["g"] * jnp.sum(positions(q)[1])

    system = lx.LagrangianSystem(kinetic, potential, n_dof=3)
    params = {"g": 9.81}
    sol = lx.simulate(
        system, [0.9, 0.3, -0.4], [0.0, 0.0, 0.0], params, t1=1.0, n_save=41, solver="rk4", dt=0.01
    )
    return system, params, sol


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
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(ax.lines) == 1 and texts == ["θ2", "start, t = 0 s", "end, t = 1 s"]
    assert ax.get_xlabel() == "q [rad]" and ax.get_ylabel() == "q̇ [rad/s]"


@pytest.mark.parametrize("kind", ["lengths", "chain", "function"])
def test_animate(sol, arm_params, kind, tmp_path):
    lengths = [float(arm_params["l1"]), float(arm_params["l2"])]
    chain = lx.chains.PlanarChain(2)
    geometry = {
        "lengths": lengths,
        "chain": chain,
        "function": lambda q: lx.plot.planar_chain_points(q, lengths),
    }[kind]
    anim = lx.plot.animate(sol, geometry, params=chain.params(), max_frames=5)
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
    with pytest.raises(lx.ConfigurationError, match="params="):
        lx.plot.animate(sol, lx.chains.PlanarChain(2))


def test_animate_old_argument_order_is_deprecated(sol):
    with pytest.warns(DeprecationWarning, match=r"animate\(sol, geometry\)"):
        anim = lx.plot.animate([1.0, 1.0], sol, max_frames=3)
    anim.to_jshtml()  # draws the last frame: the arm at the final state
    links = anim._fig.axes[0].lines[1].get_xydata()
    np.testing.assert_allclose(links, lx.plot.planar_chain_points(sol.q[-1], [1.0, 1.0]))
    with pytest.raises(lx.ConfigurationError, match="Solution"):
        lx.plot.animate([1.0, 1.0], [1.0, 1.0])
    with pytest.raises(lx.ShapeError, match="one per coordinate"):
        lx.plot.animate(sol, [1.0, 1.0, 1.0])


def test_a_pendulum_from_the_vertical_draws_with_its_geometry(pendulum3):
    system, params, sol = pendulum3
    q = np.asarray(sol.q)
    # the geometry is the model's: its points' heights give the model's V
    for qi in q[::10]:
        pts = pendulum3_points(qi)
        np.testing.assert_allclose(
            9.81 * pts[1:, 1].sum(), float(system.energy(qi, np.zeros(3), params)), rtol=1e-12
        )
    ax = lx.plot.arm_snapshots(sol, pendulum3_points, n_snapshots=5)
    drawn = [np.asarray(line.get_xydata()) for line in ax.lines[1:]]
    idx = np.linspace(0, len(q) - 1, 5).round().astype(int)
    assert len(drawn) == 5
    for i, pts in zip(idx, drawn, strict=True):
        np.testing.assert_allclose(pts, pendulum3_points(q[i]), atol=1e-14)
        # hanging down: every bob below the pivot (the lecture's convention would not)
        assert np.all(pts[1:, 1] < 0)
    np.testing.assert_allclose(ax.lines[0].get_xydata(), [pendulum3_points(a)[-1] for a in q])
    anim = lx.plot.animate(sol, pendulum3_points, max_frames=4)
    anim.to_jshtml()
    np.testing.assert_allclose(anim._fig.axes[0].lines[1].get_xydata(), pendulum3_points(q[-1]))
    fig = lx.plot.summary(sol, pendulum3_points)
    np.testing.assert_allclose(fig.axes[1].lines[-1].get_xydata(), pendulum3_points(q[-1]))


def test_snapshots_have_a_time_colour_bar(sol, arm_params):
    ax = lx.plot.arm_snapshots(sol, params=arm_params, n_snapshots=4)
    colorbar = ax.figure.axes[1]
    assert colorbar.get_ylabel() == "t [s]"
    assert colorbar.get_ylim() == (float(sol.ts[0]), float(sol.ts[-1]))
    cmap = plt.get_cmap("viridis")
    colours = [line.get_color() for line in ax.lines[1:]]
    np.testing.assert_allclose(colours[0], cmap(0.0))  # dark purple first
    np.testing.assert_allclose(colours[-1], cmap(1.0))  # yellow last
    # the default geometry is the lecture's 2R arm with params' link lengths
    lengths = [float(arm_params["l1"]), float(arm_params["l2"])]
    np.testing.assert_allclose(
        ax.lines[-1].get_xydata(), lx.plot.planar_chain_points(sol.q[-1], lengths)
    )


def test_energy_error_keeps_exact_zeros_off_the_log_axis(sol):
    err = np.abs(np.asarray(sol.energy_error))
    assert err[0] == 0.0 and err[1:].min() > 0  # the case the axis must survive
    ax = lx.plot.energy_error(sol)
    ax.figure.canvas.draw()
    y = np.asarray(ax.lines[0].get_ydata())
    assert np.isnan(y[0]) and np.all(y[1:] > 0)
    bottom, top = ax.get_ylim()
    assert bottom > 0.1 * err[1:].min() and top >= err.max()
    assert bottom > 1e-15
    assert ax.get_ylabel() == "|h(t) − h(0) − W(t)| / scale" and ax.get_xlabel() == "t [s]"


def test_sweep_heatmap(arm):
    system, params = arm
    batch = lx.grid(
        params, m2=np.linspace(0.5, 2.0, 3), l1=np.linspace(0.5, 1.5, 4), units={"m2": "kg"}
    )
    ds = lx.sweep(system, [0.3, 0.8], [0.0, 0.0], batch, t1=0.2, progress=False)
    ax = lx.plot.sweep_heatmap(ds, "q", dof=1)
    mesh = ax.collections[0]
    assert mesh.get_array().shape == (3, 4)  # (m2, l1): the grid's shape
    np.testing.assert_allclose(mesh.get_array(), ds.q.sel(dof=1).values)
    assert len(ax.figure.axes) == 2  # the plot and its colour bar
    assert ax.get_xlabel() == "l1" and ax.get_ylabel() == "m2 [kg]"
    assert not ax.patches  # nothing failed
    with pytest.raises(lx.ShapeError, match="dof="):
        lx.plot.sweep_heatmap(ds, "q")
    # a 1-D grid: a line over the swept values, labelled with their units
    ax = lx.plot.sweep_heatmap(ds.sel(l1=1.5), "q", dof=1)
    np.testing.assert_allclose(
        ax.lines[0].get_xydata(), np.c_[ds.m2.values, ds.q.sel(l1=1.5, dof=1).values]
    )
    assert ax.get_xlabel() == "m2 [kg]" and ax.get_ylabel() == "final q[1]"
    # no time dimension here, so the message must not suggest selecting one
    with pytest.raises(lx.ShapeError, match="1-D or 2-D") as err:
        lx.plot.sweep_heatmap(ds, ds.q.sel(dof=0).expand_dims(extra=[0, 1]))
    assert "time" not in str(err.value)


def test_sweep_heatmap_of_an_amplitude_study():
    values = np.array([1.0, np.nan, 3.0, 4.0])
    ds = xr.Dataset(
        {"period": (("q0_0",), values, {"units": "s"}), "ok": (("q0_0",), np.isfinite(values))},
        coords={"q0_0": ("q0_0", np.linspace(0.5, 2.0, 4), {"units": "rad"})},
    )
    ax = lx.plot.sweep_heatmap(ds, "period")
    np.testing.assert_allclose(ax.lines[0].get_xydata(), [[0.5, 1.0], [1.5, 3.0], [2.0, 4.0]])
    assert ax.get_xlabel() == "q0_0 [rad]" and ax.get_ylabel() == "period [s]"
    assert len(ax.patches) == 1  # the failed member's band
    assert "failed (1 of 4)" in ax.get_legend().get_texts()[0].get_text()
    traj = xr.DataArray(np.ones((4, 3)), dims=("q0_0", "time"), name="q")
    with pytest.raises(lx.ShapeError, match=r"isel\(time=-1\)"):
        lx.plot.sweep_heatmap(ds, traj.expand_dims(l=[1.0]))


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
    # every drawn point is labelled with its tolerance or step
    labels = sorted(t.get_text() for t in error_ax.texts if not t.get_text().startswith("ref"))
    assert labels == ["0.01", "1e-6", "1e-8"]
    assert error_ax.get_xlabel().startswith("wall time per solve [ms]")
    with pytest.raises(TypeError):
        lx.plot.work_precision(points)
