"""The fleet-wide figure (cufund.viz.fleet_plot): the separations it plots equal distances worked out by hand, the
PNG shows every vehicle in its own colour and the closest approach in red, and every fleet run folder gets it."""

from __future__ import annotations

import numpy as np
import pytest

from cufund.scenarios import load_scenario
from cufund.scenarios.run_folder import run_into_folder
from cufund.scenarios.schema import ScenarioConfig
from cufund.viz.fleet_plot import fleet_separation, plot_fleet


def test_separation_on_the_union_of_instants_by_hand():
    # a flies east at 1 m/s from (0, 0) for 4 s (records every second); b stands at (2, 1) from t = 1 s to 3 s
    a = (np.arange(5.0), np.stack([np.arange(5.0), np.zeros(5), np.zeros(5)], 1))
    b = (np.array([1.0, 3.0]), np.array([[2.0, 1.0, 0.0], [2.0, 1.0, 0.0]]))
    t, pairs = fleet_separation({"a": a, "b": b})
    np.testing.assert_array_equal(t, [0, 1, 2, 3, 4])
    # b held at (2, 1) outside its span: |(t - 2, -1)|
    np.testing.assert_allclose(pairs[("a", "b")], np.hypot(np.arange(5.0) - 2, 1.0))
    assert fleet_separation({"a": a}) == (pytest.approx(np.zeros(0)), {})


def _pixels_near(img: np.ndarray, rgb: tuple[float, float, float], tol: float = 0.06) -> int:
    return int(np.count_nonzero(np.all(np.abs(img[..., :3] - np.asarray(rgb)) < tol, axis=-1)))


def test_the_figure_shows_each_vehicle_in_its_colour_and_the_closest_approach(tmp_path):
    import matplotlib
    import matplotlib.image

    t = np.linspace(0, 10, 101)
    tracks = {
        "uav1": (t, np.stack([t, np.zeros_like(t), np.full_like(t, 2.0)], 1)),
        "uav2": (t, np.stack([10 - t, np.full_like(t, 1.0), np.full_like(t, 2.0)], 1)),  # passes uav1 at t = 5
        "uav3": (t, np.stack([np.full_like(t, 5.0), 6 + 0 * t, np.full_like(t, 2.0)], 1)),
    }
    with matplotlib.rc_context({"svg.fonttype": "none"}):  # text as text in the SVG
        paths = plot_fleet(tracks, tmp_path / "fleet", "three", min_separation_m=2.0)
    assert [p.name for p in paths] == ["fleet.png", "fleet.svg"] and all(p.stat().st_size > 0 for p in paths)
    img = matplotlib.image.imread(paths[0])
    tab10 = matplotlib.colormaps["tab10"]
    for i in range(3):
        assert _pixels_near(img, tab10(i)[:3]) > 500, i  # each track drawn in its own colour
    assert _pixels_near(img, (0xD6 / 255, 0x27 / 255, 0x28 / 255)) > 200  # the closest approach, in red
    svg = paths[1].read_text()
    assert "min 1.00 m" in svg and "uav1–uav2, t = 5.0 s" in svg  # 1 m apart as they pass, by hand (two text lines)


def test_every_fleet_run_folder_has_the_figure(tmp_path):
    data = load_scenario("fleet_square").to_dict()
    data["duration"] = 2.0
    run_into_folder(ScenarioConfig.from_dict(data), tmp_path, log=False, replay=False)
    assert (tmp_path / "fleet.png").stat().st_size > 10_000 and (tmp_path / "fleet.svg").exists()
    run_into_folder(ScenarioConfig.from_dict(data), tmp_path / "no_plots", log=False, plots=False, replay=False)
    assert not (tmp_path / "no_plots" / "fleet.png").exists()
