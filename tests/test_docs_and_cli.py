"""The README example runs, and the `lagrax demo` command works end to end."""

import re
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")

import lagrax as lx  # noqa: E402
from lagrax import cli  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def test_readme_python_example_runs(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the sweep example writes a file
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert blocks, "README has no python example"
    spaces = []
    for block in blocks:
        namespace: dict = {}
        exec(compile(block, "README.md", "exec"), namespace)
        spaces.append(namespace)
    # the cart-pole example: its energy drift at rtol=atol=1e-10 must be small
    sol = next(ns["sol"] for ns in spaces if "sol" in ns)
    assert bool(sol.ok)
    assert float(np.max(np.abs(sol.energy_error))) < 1e-7
    # the sweep example: every member finished, labelled by the grid, saved
    ds = next(ns["ds"] for ns in spaces if "ds" in ns)
    assert ds.attrs["n_failed"] == 0 and ds.q.dims == ("m2", "l1", "dof")
    assert (tmp_path / "sweep.npz").exists()


def test_demo_command(tmp_path, capsys):
    code = cli.main(["demo", "--out", str(tmp_path), "--t1", "2", "--states", "50"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert (tmp_path / "demo_2r.png").stat().st_size > 10_000
    rel = float(re.search(r"max relative difference ([0-9.e+-]+)", out).group(1))
    assert rel < 1e-12
    assert "energy error" in out


def test_plot_functions_return_axes(tmp_path):
    system, params = lx.models.planar_2r()
    sol = lx.simulate(system, [0.3, 0.2], [0.0, 0.0], params, t1=1.0, n_save=51)
    assert lx.plot.joint_trajectories(sol) is not None
    assert lx.plot.energy_error(sol) is not None
    ax = lx.plot.arm_snapshots(sol, [1.0, 1.0], n_snapshots=5)
    assert len(ax.lines) == 6  # tip path + 5 snapshots
    fig = lx.plot.summary(sol, [1.0, 1.0], title="t")
    fig.savefig(tmp_path / "s.png")
    # forward kinematics used for drawing: tip of a straight arm along +x
    pts = lx.plot.planar_chain_points(np.array([0.0, 0.0]), [1.0, 2.0])
    np.testing.assert_allclose(pts, [[0, 0], [1, 0], [3, 0]], atol=1e-15)


def test_bench_work_precision_command(tmp_path, capsys):
    code = cli.main(
        [
            "bench",
            "work-precision",
            "--out",
            str(tmp_path),
            "--t1",
            "2",
            "--repeats",
            "1",
            "--methods",
            "tsit5",
        ]
    )
    assert code == 0
    rows = (tmp_path / "work_precision.csv").read_text().splitlines()
    assert rows[0].startswith("method,setting,value,final_error")
    assert len(rows) == 1 + len(lx.bench.DEFAULT_LADDERS["tsit5"][1])
    assert (tmp_path / "work_precision.png").stat().st_size > 10_000


def test_stability_plots(tmp_path):
    system, params = lx.models.planar_2r()
    sol = lx.simulate(system, [0.3, 0.2], [0.0, 0.0], params, t1=1.0, n_save=21)
    lx.bench.plot_long_horizon({"tsit5": sol}).savefig(tmp_path / "a.png")
    ts = np.linspace(0, 1, 11)
    lx.bench.plot_chaos({1e-6: (ts, ts * 1e-3)}).savefig(tmp_path / "b.png")
    rows = [lx.bench.AtlasRow("case", "m", "ok", "a | b", "", 0.1)]
    lx.bench.write_table(rows, tmp_path / "s.md", tmp_path / "s.csv")
    assert "a / b" in (tmp_path / "s.md").read_text()  # pipes escaped for Markdown
