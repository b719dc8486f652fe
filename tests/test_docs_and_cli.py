"""The README example runs, and the `lagrax demo` command works end to end."""

import re
from pathlib import Path

import matplotlib
import numpy as np
import pytest

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


# ---------------------------------------------------------------- command-line help

BENCHMARKS = sorted((ROOT / "benchmarks").glob("bench_*.py"))


def _bench_module(path: Path):
    """A benchmark script imported as a module (its imports, no work: main is not run)."""
    import importlib.util
    import sys

    if str(path.parent) not in sys.path:
        sys.path.insert(0, str(path.parent))
    spec = importlib.util.spec_from_file_location(f"_bench_{path.stem}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _help(main, argv, capsys) -> str:
    with pytest.raises(SystemExit) as exit_:
        main([*argv, "--help"])
    assert exit_.value.code == 0
    return capsys.readouterr().out


def _options_without_default(text: str) -> list[str]:
    """Options of a --help text that take a value but do not show its default."""
    entries: list[str] = []
    for line in text.splitlines():
        if re.match(r"^  -", line):
            entries.append(line.strip())
        elif entries and re.match(r"^\s{4,}\S", line):
            entries[-1] += " " + line.strip()
        elif not line.strip():
            entries.append("")
    missing = []
    for entry in filter(None, entries):
        option = re.match(r"(-[-\w]+(?:, -[-\w]+)*)( [A-Z_]+)?", entry)
        assert option is not None, entry
        takes_value = option.group(2) is not None
        if takes_value and "(default: " not in entry:
            missing.append(entry)
    return missing


def test_cli_help_shows_defaults(capsys):
    seen = []
    for argv in (["demo"], ["bench", "work-precision"], ["bench", "stability"]):
        text = _help(cli.main, argv, capsys)
        assert not _options_without_default(text), (argv, _options_without_default(text))
        seen.append(text)
    assert "--t1 T1" in seen[0] and "(default: 10.0)" in seen[0]
    assert "(default: 1000)" in seen[0]  # --states
    assert "(default: lagrax-output)" in seen[2]


def test_benchmark_help_shows_defaults(capsys):
    assert len(BENCHMARKS) >= 7, BENCHMARKS
    for path in BENCHMARKS:
        text = _help(_bench_module(path).main, [], capsys)
        assert "usage:" in text, path.name
        missing = _options_without_default(text)
        assert not missing, (path.name, missing)
        assert "(default: " in text, path.name


def test_benchmarks_skip_a_missing_baseline_up_front(monkeypatch, capsys):
    import sys

    optional = _bench_module(ROOT / "benchmarks" / "_optional.py")
    monkeypatch.setitem(sys.modules, "numba", None)  # as if not installed
    assert optional.available("numba", "numba RK4 baseline") is False
    note = capsys.readouterr().out.strip()
    assert note.count("\n") == 0 and "numba RK4 baseline skipped" in note, note
    assert '".[bench]"' in note
    assert optional.available("numpy", "anything") is True
    assert capsys.readouterr().out == ""
    # bench_vs_scipy without SciPy: one line and a clean return, before any solve
    monkeypatch.setitem(sys.modules, "scipy", None)
    bench = _bench_module(ROOT / "benchmarks" / "bench_vs_scipy.py")
    assert bench.main([]) is None
    out = capsys.readouterr().out.strip()
    assert out.startswith("note: ") and "scipy is not installed" in out and "\n" not in out


# ---------------------------------------------------------------- the documentation site

DOC_PAGES = sorted((ROOT / "docs").glob("*.md"))


def _python_blocks(page):
    return re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S)


def test_docs_pages_have_python_examples():
    """index.md's example is the README's (run above); the other pages hold at least ten
    ```python blocks between them, each run by the test below."""
    assert "cart_pole = lx.LagrangianSystem(T, V" in (ROOT / "README.md").read_text()
    assert sum(len(_python_blocks(p)) for p in DOC_PAGES if p.name != "index.md") >= 10


@pytest.mark.slow  # the pages with examples: a dozen first compilations in all
@pytest.mark.parametrize(
    "page", [p for p in DOC_PAGES if p.name != "index.md"], ids=lambda p: p.stem
)
def test_docs_pages_python_examples_run(page, tmp_path, monkeypatch, capsys):
    """Every ```python block of a site's page runs, in order, in one namespace per page
    (a page of its own per test: a failing page does not hide the pages after it)."""
    monkeypatch.chdir(tmp_path)  # getting-started writes a figure
    namespace: dict = {}
    for block in _python_blocks(page):
        exec(compile(block, str(page.relative_to(ROOT)), "exec"), namespace)
    if page.name == "getting-started.md":
        assert namespace["ds"].attrs["n_failed"] == 0
        assert (tmp_path / "arm.png").stat().st_size > 10_000
    if page.name == "errors.md":
        assert "not positive-definite" in capsys.readouterr().out


def test_mkdocs_nav_and_api_reference_cover_the_public_api():
    """The nav names every page and notebook; the API pages document every public name."""
    yml = (ROOT / "mkdocs.yml").read_text()
    for page in DOC_PAGES:
        assert f": {page.name}" in yml, page.name
    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        assert f"notebooks/{nb.name}" in yml, nb.name
    api = "\n".join(p.read_text() for p in (ROOT / "docs" / "api").glob("*.md"))
    documented = set(re.findall(r"^::: lagrax\.(\w+)", api, flags=re.M))
    assert set(lx.__all__) <= documented, set(lx.__all__) - documented


def test_notebooks_are_committed_without_outputs():
    """The site executes them at build; the repository keeps them clean (CI skips their
    second execution by tests/test_notebooks.py after the docs build: see .ci/run)."""
    import json

    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        cells = json.loads(nb.read_text())["cells"]
        assert not any(c.get("outputs") for c in cells if c["cell_type"] == "code"), nb.name
