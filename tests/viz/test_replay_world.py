"""replay.html draws the scenario's world: a headless-Chromium screenshot of a short forest run shows tree pixels
where the page's camera projects the trees (the projection computed here from the camera the page states)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from cufund.scenarios import load_scenario, run_scenario
from cufund.scenarios.run_folder import world_of
from cufund.viz.flight import Flight
from cufund.viz.replay import replay_html

W, H = 800, 600
GUI = (550, 0, W, 310)
"""MeshCat's controls (x0, y0, x1, y1) at this window size; the legend is bottom-left."""
LEGEND = (0, 450, 320, H)


@pytest.fixture(scope="module")
def forest():
    config = load_scenario("forest", ["duration=10"])
    run = run_scenario(config)
    return run, world_of(config)


def _screenshot(html: str, tmp_path, name: str) -> np.ndarray:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    assert exe, "Chromium is required (the Makefile installs Debian's chromium)"
    page, png = tmp_path / f"{name}.html", tmp_path / f"{name}.png"
    page.write_text(html, encoding="utf-8")
    subprocess.run(
        [
            exe,
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            "--use-gl=swiftshader",
            "--enable-unsafe-swiftshader",
            f"--user-data-dir={tmp_path / 'profile'}",
            f"--window-size={W},{H}",
            "--virtual-time-budget=5000",
            f"--screenshot={png}",
            page.as_uri(),
        ],
        check=True,
        capture_output=True,
        timeout=180,
    )
    import matplotlib.image

    return (matplotlib.image.imread(png)[..., :3] * 255).astype(int)


def _project(view: dict, points_W: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel (x right, y down) and depth of each point for a pinhole camera at ``eye_W`` looking at ``target_W``
    with ``up_W`` up and a vertical field of view ``fov_deg`` (three.js' PerspectiveCamera)."""
    eye, target, up = (np.array(view[k], float) for k in ("eye_W", "target_W", "up_W"))
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    upward = np.cross(right, forward)
    d = points_W - eye
    depth = d @ forward
    t = np.tan(np.radians(view["fov_deg"]) / 2)
    x = (d @ right) / (depth * t * W / H)
    y = (d @ upward) / (depth * t)
    return np.column_stack([(x + 1) / 2 * W, (1 - y) / 2 * H]), depth


def _tree_like(rgb: np.ndarray) -> np.ndarray:
    """The trunks' albedo (0.4, 0.25, 0.1) lit: red over green over blue in those ratios (not the grey-brown
    ground (0.35, 0.3, 0.2), the sky, the grid or the paths)."""
    r, g, b = (rgb[..., k].astype(float) for k in range(3))
    return (r >= 40) & (g > 0.5 * r) & (g < 0.75 * r) & (b < 0.4 * r)


def _inside(box: tuple[int, int, int, int], px: np.ndarray) -> np.ndarray:
    return (px[:, 0] >= box[0]) & (px[:, 0] < box[2]) & (px[:, 1] >= box[1]) & (px[:, 1] < box[3])


def _visible_trees(world, view) -> tuple[np.ndarray, np.ndarray]:
    """Pixels of the trunks' axes 1 m above the ground, for trunks at least 3 pixels wide in the picture and
    outside the page's controls and legend."""
    trees = [o for o in world.objects if o.label == "tree"]
    centres = np.array([[*o.vertices[:, :2].mean(axis=0), 1.0] for o in trees])
    radius = np.array([np.ptp(o.vertices[:, 0]) / 2 for o in trees])
    px, depth = _project(view, centres)
    radius_px = radius / (depth * np.tan(np.radians(view["fov_deg"]) / 2)) * H / 2
    ok = (depth > 0) & (radius_px >= 3) & (px[:, 0] >= 0) & (px[:, 0] < W) & (px[:, 1] >= 0) & (px[:, 1] < H)
    ok &= ~_inside(GUI, px) & ~_inside(LEGEND, px)
    return px[ok].astype(int), centres[ok]


def test_forest_replay_shows_trees_where_they_project(forest, tmp_path):
    run, world = forest
    flight = Flight.from_result(run.result, run.reference)
    html = replay_html(flight, run.config.vehicle_params(), world, size=(W, H))
    view = json.loads(re.search(r'<script id="cufund-view" type="application/json">(.*?)</script>', html).group(1))
    img = _screenshot(html, tmp_path, "forest")
    assert img.shape[:2] == (H, W)
    px, _ = _visible_trees(world, view)
    assert len(px) >= 15, f"only {len(px)} trees in view: the camera is not framed on the forest flight"
    hits = _tree_like(img[px[:, 1], px[:, 0]])
    # a path or the vehicle may cross a trunk's pixel; nothing else is drawn in front of a trunk's axis
    assert hits.mean() >= 0.9, f"{hits.sum()} of {len(px)} projected trunks are tree-coloured"

    # the control: the same flight and camera without the world has no tree colour at those pixels
    bare = _screenshot(replay_html(flight, run.config.vehicle_params(), None, size=(W, H)), tmp_path, "bare")
    assert _tree_like(bare[px[:, 1], px[:, 0]]).mean() < 0.1


def test_replay_frames_the_flight_and_states_the_legend(forest):
    run, world = forest
    flight = Flight.from_result(run.result, run.reference)
    html = replay_html(flight, run.config.vehicle_params(), world, size=(W, H))
    view = json.loads(re.search(r'<script id="cufund-view" type="application/json">(.*?)</script>', html).group(1))
    # every flown position projects into the picture (the camera is framed on the flight's bounding box)
    px, depth = _project(view, flight.p_W[::50])
    assert np.all(depth > 0) and np.all((px >= 0) & (px <= [W, H]))
    legend = re.search(r'<div id="cufund-legend">(.*?)\n<script', html, re.S).group(1)
    for text in ("flown (truth)", "estimate", "setpoints", "tree (620)", "ground"):
        assert text in legend
    assert "viewer.animator.folder.open()" in html  # MeshCat's animation slider is shown
