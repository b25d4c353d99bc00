"""replay.html opens in a real browser (headless Chromium, from disk, no server) and draws the scene."""

import shutil
import subprocess

import numpy as np
import pytest

from cufund.scenarios import load_scenario, run_scenario
from cufund.viz.flight import Flight
from cufund.viz.replay import replay_html, viewer_page, write_replay_html


@pytest.fixture(scope="module")
def run():
    return run_scenario(load_scenario("square"))


def _chromium() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, "Chromium is required (the Makefile installs Debian's chromium)"
    return exe


def _screenshot(html_path, png_path, tmp_path):
    subprocess.run(
        [
            _chromium(),
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--use-gl=swiftshader",
            "--enable-unsafe-swiftshader",
            f"--user-data-dir={tmp_path / 'profile'}",
            "--window-size=800,600",
            "--virtual-time-budget=4000",
            f"--screenshot={png_path}",
            html_path.as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=180,
    )
    import matplotlib.image

    return (matplotlib.image.imread(png_path)[..., :3] * 255).astype(int)


def _near(img, rgb, tol=40):
    return int(np.count_nonzero(np.linalg.norm(img - np.array(rgb), axis=-1) < tol))


def test_replay_is_self_contained(run):
    html = replay_html(Flight.from_result(run.result, run.reference), run.config.vehicle_params())
    assert "new MeshCat.Viewer" in html
    assert html.count("data:application/octet-binary;base64,") >= 10  # scene and animation embedded
    assert "<script src" not in html and "<link" not in html  # nothing loaded from elsewhere


def test_replay_draws_in_chromium(run, tmp_path):
    flight = Flight.from_result(run.result, run.reference)
    page = write_replay_html(tmp_path / "replay.html", flight, run.config.vehicle_params())
    img = _screenshot(page, tmp_path / "shot.png", tmp_path)
    assert img.shape[:2] == (600, 800)
    # the flown path (red, 0xd62728) and the planned path (green, 0x2ca02c) are drawn unlit in their own colours;
    # MeshCat's empty scene has neither (a blue-grey gradient and a grid)
    assert _near(img, (214, 39, 40)) > 40
    # and the page is not one flat colour
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 50


def test_empty_scene_has_no_path_colour(tmp_path):
    """The control for the check above: the same viewer page with nothing drawn has no red path pixels."""
    page = tmp_path / "empty.html"
    page.write_text(viewer_page([]), encoding="utf-8")
    img = _screenshot(page, tmp_path / "empty.png", tmp_path)
    assert _near(img, (214, 39, 40)) < 10


def test_cufund_replay_draws_the_run_folders_world(tmp_path):
    """`cufund replay` on a forest run's log draws the forest the run flew in (rebuilt from config.yaml beside
    the log: the same trunks as the world kind builds on its own) and frames the camera on the flight."""
    import umsgpack

    from cufund.apps import log_replay
    from cufund.scenarios.run_folder import run_into_folder
    from cufund.viz.meshcat_scene import import_meshcat
    from cufund.viz.replay import _RecordingWindow
    from cufund.worlds.builtin import forest

    run = run_into_folder(load_scenario("forest", ["duration=3"]), tmp_path, plots=False, replay=False)
    log = tmp_path / "run.mcap"
    params, T_BL = log_replay.run_context(log, None)
    window = _RecordingWindow()
    stats = log_replay.replay_log(
        log, import_meshcat().Visualizer(window=window), params, speed=0, T_BL=T_BL, world=log_replay.run_world(log)
    )
    commands = [umsgpack.unpackb(c) for c in window.commands]
    trees = next(c for c in commands if c["type"] == "set_object" and c["path"] == "/meshcat/world/tree")
    position = trees["object"]["geometries"][0]["data"]["attributes"]["position"]
    drawn = np.frombuffer(position["array"].data, np.float32).reshape(-1, 3)
    expected = np.vstack([o.vertices for o in forest(0, 620, 64.0, 2.0).objects if o.label == "tree"])
    assert np.allclose(drawn, expected, atol=1e-4)
    assert ("tree (620)", 0x66401A) in stats.legend
    # the scene is moved so that the flight's bounding-box centre is where MeshCat's camera orbits
    root = next(c for c in commands if c["type"] == "set_transform" and c["path"] == "/meshcat")
    p = run.result.states["p_W"]
    centre = (p.min(axis=0) + p.max(axis=0)) / 2
    assert np.allclose(np.array(root["matrix"]).reshape(4, 4).T[:3, 3], -centre, atol=0.05)
