"""Every run folder holds trajectory and errors as 200 dpi PNG and SVG (the tunnel adds detection); the figures'
helpers against independent results."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from PIL import Image

from cufund.scenarios import load_scenario
from cufund.scenarios.run_folder import run_into_folder
from cufund.viz.plots import centreline_coordinates

CASES = {
    "square": ([], ("trajectory", "errors")),
    "forest": (["duration=8"], ("trajectory", "errors")),
    "tunnel": (["duration=12"], ("trajectory", "errors", "detection")),
}


@pytest.mark.parametrize("name", list(CASES))
def test_run_folder_writes_every_figure_at_200_dpi_and_as_svg(name, tmp_path):
    overrides, figures = CASES[name]
    run_into_folder(load_scenario(name, overrides), tmp_path, log=False, replay=False)
    for stem in figures:
        png = tmp_path / f"{stem}.png"
        with Image.open(png) as img:
            assert img.format == "PNG"
            dpi = img.info.get("dpi")
            assert dpi is not None and round(dpi[0]) == 200 and round(dpi[1]) == 200, (stem, dpi)
            assert img.size[0] >= 12 * 200  # 12 inches wide or more, at 200 dpi
        root = ET.parse(tmp_path / f"{stem}.svg").getroot()
        assert root.tag == "{http://www.w3.org/2000/svg}svg"
        assert root.find(".//{http://www.w3.org/2000/svg}g[@id='figure_1']") is not None  # matplotlib's figure
    assert not (tmp_path / "replay.html").exists()


def test_centreline_coordinates_against_a_right_angle():
    """On an L-shaped line (2 m along +x, then 2 m along +y): distance along it and signed offset (left +)."""
    line = np.array([[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [2.0, 2.0, 1.0]])
    points = np.array([[1.0, 0.05, 0.0], [1.0, -0.03, 5.0], [2.1, 1.0, 1.0], [-1.0, 0.02, 1.0], [2.0, 3.0, 1.0]])
    s, d = centreline_coordinates(points, line)
    np.testing.assert_allclose(s, [1.0, 1.0, 3.0, -1.0, 5.0])
    np.testing.assert_allclose(d, [0.05, -0.03, -0.1, 0.02, 0.0], atol=1e-12)


def test_airborne_phases_from_the_true_height():
    """Climb from 0 to 1 m over t in [1, 2] s, hold, descend over [8, 9] s, on a 10 ms grid: airborne from the
    first sample above 5.5 cm (t = 1.06 s, 6 cm) to the last (t = 8.94 s)."""
    from cufund.viz.flight import Flight

    t = np.round(np.arange(0.0, 10.0 + 1e-9, 0.01), 10)
    z = np.interp(t, [0, 1, 2, 8, 9, 10], [0, 0, 1, 1, 0, 0])
    p = np.column_stack([np.zeros_like(t), np.zeros_like(t), z])
    phases = Flight(t, p, np.tile([1.0, 0, 0, 0], (len(t), 1))).airborne_phases(lift_m=0.055)
    assert [ph.name for ph in phases] == ["on the ground", "airborne", "landed"]
    assert phases[1].t0 == pytest.approx(1.06) and phases[1].t1 == pytest.approx(8.94)
    assert phases[0].t1 == phases[1].t0 and phases[1].t1 == phases[2].t0  # contiguous, never overlapping
