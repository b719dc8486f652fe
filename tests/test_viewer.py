"""lagrax.plot.show3d: the saved page plays offline in headless Chromium (the `viz` extra and
a chromium binary; skipped without them), and bad input is refused."""

import base64
import io
import shutil
import sys
from types import SimpleNamespace

import jax.numpy as jnp
import numpy as np
import pytest

import lagrax as lx
from lagrax import ArgumentTypeError, ConfigurationError, ShapeError

pytest.importorskip("meshcat", reason="the 3D viewer needs the viz extra (meshcat)")


@pytest.fixture(scope="module")
def arm7():
    tree, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"))
    q0 = jnp.array([0.3, 0.8, 0.0, -1.0, 0.2, 0.5, 0.0])
    sol = lx.simulate(tree.system(), q0, jnp.zeros(7), params, t1=1.0)
    return tree, params, sol


@pytest.fixture(scope="module")
def planar():
    system, params = lx.models.planar_2r()
    sol = lx.simulate(system, jnp.array([0.0, 0.0]), jnp.zeros(2), params, t1=1.0)
    return params, sol


def test_tree_poses_are_the_trees_frames(arm7):
    tree, params, sol = arm7
    view = lx.plot.show3d(sol, tree, params=params, fps=20.0)
    p = view.poses
    assert p.times.size == 21 and p.origins.shape == (21, 8, 3)
    assert len(p.links) == 7 and p.links[0] == (0, 1)
    origins, rots = tree.frames(jnp.asarray(sol.q[-1]), params)
    np.testing.assert_allclose(p.origins[-1, 1:], origins, atol=1e-9)
    np.testing.assert_allclose(p.rotations[-1, 1:], rots, atol=1e-9)


def test_floating_tree_poses_follow_the_base():
    robot, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"), floating_base=True)
    n = robot.n
    angle = 0.7
    q = np.zeros((2, 7 + n))
    q[:, :3] = [1.0, 2.0, 3.0]
    q[:, 3:7] = [np.sin(angle / 2), 0.0, 0.0, np.cos(angle / 2)]  # a turn about x
    sol = SimpleNamespace(ts=np.array([0.0, 1.0]), q=q)  # the two fields show3d reads
    p = lx.plot.show3d(sol, robot, params=params, fps=1.0).poses
    origins = np.asarray(robot.tree.frames(jnp.zeros(n), params)[0])
    c, s = np.cos(angle), np.sin(angle)
    turn = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    np.testing.assert_allclose(p.origins[0, 0], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(p.origins[0, 1:], [1.0, 2.0, 3.0] + origins @ turn.T, atol=1e-12)
    np.testing.assert_allclose(p.rotations[0, 0], turn, atol=1e-12)


def test_planar_chain_is_drawn_upright_in_xz(planar):
    params, sol = planar
    p = lx.plot.show3d(sol, params=params).poses
    assert p.planar and np.all(p.origins[..., 1] == 0.0)
    np.testing.assert_allclose(p.origins[0, 2], [float(params["l1"] + params["l2"]), 0.0, 0.0])


def test_bad_input_is_refused(arm7, planar):
    tree, params, sol = arm7
    _, sol2 = planar
    with pytest.raises(ShapeError, match="2 coordinates per state but the Tree has 7"):
        lx.plot.show3d(sol2, tree, params=params)
    with pytest.raises(ConfigurationError, match="needs its parameters"):
        lx.plot.show3d(sol, tree)
    with pytest.raises(ConfigurationError, match="fps must be a positive"):
        lx.plot.show3d(sol, tree, params=params, fps=0.0)
    with pytest.raises(ArgumentTypeError, match="cannot draw a str"):
        lx.plot.show3d(sol, "arm7")


def test_a_sweeps_batch_and_a_missing_extra_are_named(arm7, monkeypatch):
    tree, params, sol = arm7
    batch = SimpleNamespace(ts=np.stack([sol.ts, sol.ts]), q=np.stack([sol.q, sol.q]))
    with pytest.raises(ShapeError, match="pick one member first"):
        lx.plot.show3d(batch, tree, params=params)
    monkeypatch.setitem(sys.modules, "meshcat", None)  # as if the viz extra were missing
    with pytest.raises(ImportError, match=r"pip install 'lagrax\[viz\]'"):
        lx.plot.show3d(sol, tree, params=params)


def test_page_is_standalone(arm7, tmp_path):
    tree, params, sol = arm7
    view = lx.plot.show3d(sol, tree, params=params)
    path = view.save(tmp_path / "run.html")
    text = path.read_text()
    assert "MeshCat.Viewer" in text and "lagraxCommands" in text
    assert "http://" not in text.split("<script>")[0] and 'src="http' not in text
    assert view._repr_html_().startswith("<div") and "srcdoc=" in view._repr_html_()
    assert "8 bodies, 7 rods" in repr(view)


# -- in a real browser ---------------------------------------------------------------------


def _chromium() -> tuple[str, str]:
    """The chromium and chromedriver binaries, or skip."""
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver")
    if browser is None or driver is None:
        pytest.skip("no chromium/chromedriver binary (apt-get install chromium chromium-driver)")
    return browser, driver


@pytest.fixture(scope="module")
def browser():
    try:
        from selenium import webdriver
    except ImportError:
        pytest.skip("the browser test needs selenium (the dev extra)")
    binary, driver_path = _chromium()
    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for flag in (
        "--headless=new",
        "--no-sandbox",
        "--disable-dev-shm-usage",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        "--window-size=800,600",
    ):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    service = webdriver.ChromeService(executable_path=driver_path)
    driver = webdriver.Chrome(options=options, service=service)
    driver.execute_cdp_cmd("Network.enable", {})
    driver.execute_cdp_cmd(
        "Network.emulateNetworkConditions",
        {"offline": True, "latency": 0, "downloadThroughput": 0, "uploadThroughput": 0},
    )
    yield driver
    driver.quit()


def _image(driver, script: str) -> np.ndarray:
    """RGB pixels of the viewer's canvas after running `script` (rendered at once)."""
    from PIL import Image

    url = driver.execute_script(script + "; return viewer.capture_image();")
    data = base64.b64decode(url.split(",", 1)[1])
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), dtype=float)


def test_saved_page_plays_offline_in_chromium(arm7, browser, tmp_path):
    tree, params, sol = arm7
    path = lx.plot.show3d(sol, tree, params=params, play=False).save(tmp_path / "arm7.html")
    browser.get(path.as_uri())
    assert browser.execute_script("return window.lagraxReady === true")
    duration = browser.execute_script("return window.lagraxDuration")
    assert duration == pytest.approx(1.0)
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == [], errors
    # the controls: play, pause, reset, the time slider and the speed
    labels = browser.execute_script(
        "return Array.from(document.querySelectorAll('.dg .property-name'))"
        ".map((e) => e.textContent)"
    )
    assert {"play", "pause", "reset", "time", "timeScale"} <= set(labels)

    hidden = "viewer.animator.seek(0); viewer.scene_tree.find(['lagrax']).object.visible = false"
    shown = "viewer.scene_tree.find(['lagrax']).object.visible = true; viewer.animator.seek(0)"
    background, start = _image(browser, hidden), _image(browser, shown)
    robot = np.abs(start - background).sum(axis=-1) > 30
    h, w = robot.shape
    assert robot.sum() > 500, "the robot covers almost no pixels"
    rows, cols = np.nonzero(robot)
    assert h / 4 < rows.mean() < 3 * h / 4 and w / 4 < cols.mean() < 3 * w / 4
    end = _image(browser, f"viewer.animator.seek({duration})")
    moved = np.abs(end - start).sum(axis=-1) > 30
    assert moved.sum() > 200, "the first and last frames look the same"
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == [], errors


def test_floating_base_page_turns_in_chromium(browser, tmp_path):
    robot, params = lx.chains.from_urdf(lx.models.urdf_path("arm7"), floating_base=True)
    q = np.zeros((2, 7 + robot.n))
    q[:, 6] = 1.0
    q[1, :7] = [0.3, 0.0, 0.2, np.sin(0.6), 0.0, 0.0, np.cos(0.6)]  # moved, turned about x
    q[1, 8] = 0.8
    sol = SimpleNamespace(ts=np.array([0.0, 1.0]), q=q)
    path = lx.plot.show3d(sol, robot, params=params, fps=10.0, play=False).save(tmp_path / "f.html")
    browser.get(path.as_uri())
    assert browser.execute_script("return window.lagraxReady === true")
    start = _image(browser, "viewer.animator.seek(0)")
    end = _image(browser, "viewer.animator.seek(1.0)")
    assert (np.abs(end - start).sum(axis=-1) > 30).sum() > 200
    errors = [e for e in browser.get_log("browser") if e["level"] == "SEVERE"]
    assert errors == [], errors
