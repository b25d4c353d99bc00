"""The fleet's station in headless Chromium, as an operator uses it: select a vehicle, type the paper's zigzag
sentence, see the mission drawn on the map in the vehicle's colour, fly it; a refused request shows its reason
and leaves Fly disabled."""

from __future__ import annotations

import shutil

import pytest

from cufund.apps.gcs import GcsProcess
from cufund.apps.gcs.fleet_server import FLEET_COLOURS
from cufund.apps.gcs.process import wait_for

pytest.importorskip("cufund.missions.mission_request")  # parse_mission (the plain-language grammar)
webdriver = pytest.importorskip("selenium.webdriver")
from selenium.webdriver.chrome.service import Service  # noqa: E402  (after the importorskip)
from selenium.webdriver.common.by import By  # noqa: E402

CHROMEDRIVER = "/usr/bin/chromedriver"
pytestmark = pytest.mark.skipif(
    not shutil.which("chromium") or not shutil.which(CHROMEDRIVER),
    reason="needs Debian's chromium and chromium-driver (make deps)",
)
PAPER = "Generate a zigzag path with three rows, each row containing five waypoints"


@pytest.fixture(scope="module")
def page():
    options = webdriver.ChromeOptions()
    for a in ("--headless=new", "--no-sandbox", "--disable-gpu", "--window-size=1280,760", "--disable-dev-shm-usage"):
        options.add_argument(a)
    options.binary_location = shutil.which("chromium")
    d = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    d.set_script_timeout(10)
    try:
        with GcsProcess("fleet_square", "--speed", "5") as g:
            d.get(g.url)
            assert wait_for(lambda: d.find_element(By.ID, "conn").text == "connected", 20), "the page did not connect"
            yield d
    finally:
        d.quit()


def _row(d, name, cls):
    return d.find_element(By.CSS_SELECTOR, f'tr.vehicle[data-name="{name}"] .{cls}').text


def _pixel(d, x, y):
    """The map's colour at world point (x, y), as '#rrggbb' (the canvas pixel under it)."""
    return d.execute_script(
        """const [cx, cy] = window.fleetGcs.toCanvas(arguments[0], arguments[1]);
        const px = document.getElementById('map').getContext('2d').getImageData(Math.floor(cx), Math.floor(cy), 1, 1).data;
        return '#' + [px[0], px[1], px[2]].map((v) => v.toString(16).padStart(2, '0')).join('');""",
        x,
        y,
    )


def _near(a: str, b: str, tol: int = 40) -> bool:
    """Two '#rrggbb' colours within ``tol`` per channel (the canvas anti-aliases the dots)."""
    return all(abs(int(a[i : i + 2], 16) - int(b[i : i + 2], 16)) <= tol for i in (1, 3, 5))


def test_select_a_vehicle_preview_the_zigzag_and_fly_it(page):
    d = page
    rows = d.find_elements(By.CSS_SELECTOR, "tr.vehicle")
    assert [r.get_attribute("data-name") for r in rows] == ["uav1", "uav2", "uav3"]
    swatches = [r.find_element(By.CSS_SELECTOR, ".swatch").value_of_css_property("background-color") for r in rows]
    assert len(set(swatches)) == 3  # a colour each
    fly = d.find_element(By.ID, "fly")
    assert not fly.is_enabled()  # nothing previewed: nothing to fly
    assert not d.find_element(By.CSS_SELECTOR, 'button.cmd[data-to="selected"][data-cmd="arm"]').is_enabled()
    rows[1].click()  # select uav2
    assert d.find_element(By.ID, "selection").text == "uav2"
    assert d.find_element(By.CSS_SELECTOR, 'button.cmd[data-to="selected"][data-cmd="arm"]').is_enabled()
    box = d.find_element(By.ID, "mission-text")
    box.clear()
    box.send_keys(PAPER)
    d.find_element(By.ID, "preview").click()
    result = d.find_element(By.ID, "mission-result")
    assert wait_for(lambda: result.text.startswith("preview"), 10), result.text
    assert "uav2 15" in result.text and fly.is_enabled()
    wps = d.execute_script("return window.fleetGcs.state.preview.waypoints")
    assert list(wps) == ["uav2"] and len(wps["uav2"]) == 15
    # drawn on the map in uav2's colour, at each waypoint (checked on the canvas' pixels)
    red = FLEET_COLOURS[1]
    for x, y, _z in wps["uav2"][5:]:  # (the first row passes over the other vehicles' pads)
        assert wait_for(lambda x=x, y=y: _near(_pixel(d, x, y), red), 3), (x, y, _pixel(d, x, y))
    fly.click()
    assert wait_for(lambda: result.text.startswith("flying mission"), 10), result.text
    assert not fly.is_enabled()  # flown once
    assert wait_for(lambda: _row(d, "uav2", "mode") == "mission", 20), _row(d, "uav2", "mode")
    assert wait_for(lambda: _row(d, "uav2", "mission").startswith(("1/15", "2/15", "3/15")), 40), _row(
        d, "uav2", "mission"
    )
    assert _row(d, "uav1", "armed") == "disarmed" and _row(d, "uav3", "armed") == "disarmed"


def test_a_refused_request_shows_its_reason(page):
    d = page
    box = d.find_element(By.ID, "mission-text")
    box.clear()
    box.send_keys("zigzag with 3 rows of 5 waypoints at 0 m")
    d.find_element(By.ID, "preview").click()
    result = d.find_element(By.ID, "mission-result")
    assert wait_for(lambda: result.text.startswith("refused"), 10), result.text
    assert "below" in result.text
    assert not d.find_element(By.ID, "fly").is_enabled()
    assert wait_for(lambda: "mission request refused" in d.find_element(By.ID, "events").text, 5)


def test_survey_an_area_drawn_on_the_map_with_all_drones(page):
    from selenium.webdriver.common.action_chains import ActionChains

    d = page
    d.find_element(By.ID, "clear-area").click()
    d.find_element(By.ID, "draw-area").click()
    canvas = d.find_element(By.ID, "map")
    w, h = canvas.size["width"], canvas.size["height"]
    corners = [  # a rectangle in the middle of what the map shows now, on a 0.1 m grid
        tuple(
            round(c, 1)
            for c in d.execute_script("return window.fleetGcs.fromCanvas(arguments[0], arguments[1])", fx * w, fy * h)
        )
        for fx, fy in ((0.1, 0.8), (0.9, 0.8), (0.9, 0.2), (0.1, 0.2))
    ]
    for x, y in corners:  # each click in the map's transform of the moment (it refits as the area grows)
        cx, cy = d.execute_script("return window.fleetGcs.toCanvas(arguments[0], arguments[1])", x, y)
        ActionChains(d).move_to_element_with_offset(canvas, round(cx - w / 2), round(cy - h / 2)).click().perform()
    area = d.execute_script("return window.fleetGcs.state.area")
    assert len(area) == 4
    for (x, y), (ax, ay) in zip(corners, area, strict=True):
        assert abs(ax - x) < 0.1 and abs(ay - y) < 0.1, area
    assert d.find_element(By.ID, "area-info").text == "area of 4 corners"
    d.find_element(By.ID, "draw-area").click()
    box = d.find_element(By.ID, "mission-text")
    box.clear()
    box.send_keys("survey this polygon with all drones")
    d.find_element(By.ID, "preview").click()
    result = d.find_element(By.ID, "mission-result")
    assert wait_for(lambda: result.text.startswith(("preview", "refused")), 10), result.text
    assert result.text.startswith("preview"), result.text
    wps = d.execute_script("return window.fleetGcs.state.preview.waypoints")
    assert sorted(wps) == ["uav1", "uav2", "uav3"]
    (x0, y0), (x1, y1) = corners[0], corners[2]
    for wp in wps.values():  # inside the drawn area
        for x, y, _z in wp:
            assert x0 - 0.15 <= x <= x1 + 0.15 and y0 - 0.15 <= y <= y1 + 0.15, (corners, wps)
    assert d.find_element(By.ID, "fly").is_enabled()
