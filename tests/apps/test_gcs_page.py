"""The ground station's page as an operator sees it at 1280 px (Debian's headless Chromium through selenium): plots
with axis titles, a legend and a time axis, the attitude indicator and heading, readable estimator health and
events, no sideways scrolling, the controls a scenario cannot serve disabled with the reason on hover, and a Start
button that starts a run nothing flew before. Screenshots go to the test's temporary directory."""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest

from cufund.apps.gcs import GcsProcess
from cufund.apps.gcs.process import wait_for
from gcs_support import CHROMEDRIVER, chromium

pytest.importorskip("selenium.webdriver")
from selenium.webdriver.common.by import By

pytestmark = pytest.mark.skipif(
    not shutil.which("chromium") or not shutil.which(CHROMEDRIVER),
    reason="needs Debian's chromium and chromium-driver (make deps)",
)

WIDTH = 1280


@pytest.fixture(scope="module")
def driver():
    d = chromium(WIDTH, 800)
    yield d
    d.quit()


def text(d, id_):
    return d.find_element(By.ID, id_).text


def telemetry(d):
    return d.execute_script("return window.gcs.stats.lastTelemetry")


def ack(d, command, timeout=15):
    return wait_for(
        lambda: next(
            (a for a in reversed(d.execute_script("return window.gcs.stats.acks")) if a["command"] == command), None
        ),
        timeout,
    )


def open_page(d, gcs):
    d.get(gcs.url + "&fps=4")
    assert wait_for(lambda: text(d, "conn") == "connected" and telemetry(d), 30), "the page did not connect"
    assert d.execute_script("return window.innerWidth") == WIDTH


def no_sideways_scrolling(d):
    """Neither the page nor the side panel is wider than what shows: [scrollWidth, clientWidth] of each."""
    sizes = d.execute_script(
        "const e = document.documentElement, s = document.getElementById('side');"
        "return [e.scrollWidth, e.clientWidth, s.scrollWidth, s.clientWidth];"
    )
    assert sizes[0] <= sizes[1] and sizes[2] <= sizes[3], sizes


def disabled_without_title(d):
    return d.execute_script(
        "return [...document.querySelectorAll('button:disabled, select:disabled, input:disabled, textarea:disabled')]"
        ".filter((el) => !el.title.trim()).map((el) => el.id || el.outerHTML.slice(0, 60));"
    )


def colour_pixels(d, canvas_id, rgb):
    """How many pixels of the canvas are within 40 of the colour ``rgb`` (what it drew, read back)."""
    data = d.execute_script(
        "const c = document.getElementById(arguments[0]);"
        "return Array.from(c.getContext('2d').getImageData(0, 0, c.width, c.height).data);",
        canvas_id,
    )
    px = np.asarray(data, dtype=float).reshape(-1, 4)
    return int(((np.abs(px[:, :3] - rgb).max(axis=1) < 40) & (px[:, 3] > 128)).sum())


def test_after_arm_and_take_off_the_page_reads_well_at_1280_px(driver, tmp_path):
    from PIL import Image

    d = driver
    with GcsProcess("vehicle", "--speed", "2", "--telemetry-hz", "20", "--set", "planner.auto_disarm_s=0") as g:
        open_page(d, g)
        assert text(d, "tel-mission") == "—"  # no mission yet (was "-1/0")
        d.find_element(By.ID, "cmd-arm").click()
        assert ack(d, "arm")["result"] == "accepted"
        d.find_element(By.ID, "cmd-takeoff").click()
        assert ack(d, "takeoff")["result"] == "accepted"
        assert wait_for(lambda: text(d, "tel-mode") == "hold", 30), text(d, "tel-mode")
        # the plots: axis titles, a legend (DOM), a time axis and the curves drawn (the canvas read back)
        d.execute_script("document.getElementById('fig-pos').scrollIntoView()")
        for fig, ylabel in (("fig-pos", "position [m]"), ("fig-err", "error [m]")):
            assert d.find_element(By.CSS_SELECTOR, f"#{fig} .ylabel").text == ylabel
            assert d.find_element(By.CSS_SELECTOR, f"#{fig} .xlabel").text == "time t [s]"
        legend = d.find_element(By.CSS_SELECTOR, "#fig-pos .legend").text
        assert all(w in legend for w in ("x", "y", "z", "vehicle", "setpoint")), legend
        assert "tracking" in d.find_element(By.CSS_SELECTOR, "#fig-err .legend").text
        assert colour_pixels(d, "plot-pos", (0x1F, 0x77, 0xB4)) > 30  # z, climbing
        assert colour_pixels(d, "plot-pos", (0x55, 0x55, 0x55)) > 20  # the axis' tick labels
        d.save_screenshot(str(tmp_path / "gcs_plots.png"))
        d.execute_script("document.getElementById('side').scrollTop = 0")
        shot = tmp_path / "gcs_after_takeoff.png"
        d.save_screenshot(str(shot))
        with Image.open(shot) as im:
            assert im.size[0] == WIDTH
        no_sideways_scrolling(d)
        assert disabled_without_title(d) == []
        # attitude, heading and the estimator in words (the vehicle heads east: ENU yaw 0 is 090 degrees)
        assert re.fullmatch(r"roll -?\d+\.\d°, pitch -?\d+\.\d°", text(d, "att-text")), text(d, "att-text")
        assert re.match(r"heading (08[89]|09[01])°", text(d, "hdg-text")), text(d, "hdg-text")
        est = text(d, "tel-est")
        assert est.startswith("ok") and "{" not in est, est
        # events: each says its kind once ("mode takeoff", "armed"; not "mode mode takeoff", "armed armed")
        lines = text(d, "events").splitlines()
        assert any(line.endswith(" armed") for line in lines) and any("mode takeoff" in line for line in lines)
        for line in lines:
            words = line.split()
            assert all(a != b for a, b in zip(words, words[1:], strict=False)), line


def test_events_read_once_failsafes_readably_and_a_closing_browser_tab_is_one_line(driver):
    d = driver
    g = GcsProcess("vehicle", "--speed", "1").start()
    try:
        # a second tab opened and closed: one line on the server's stderr, no traceback
        first = d.current_window_handle
        d.switch_to.new_window("tab")
        open_page(d, g)
        d.close()
        d.switch_to.window(first)
        open_page(d, g)
        cases = [
            ({"t": 3.0, "kind": "mode", "message": "mode takeoff"}, "3.00 s  mode takeoff"),
            ({"t": 3.0, "kind": "armed", "message": "armed"}, "3.00 s  armed"),
            (
                {"t": 4.5, "kind": "mission_item_reached", "message": "mission item 0 reached"},
                "4.50 s  mission item 0 reached",
            ),
            ({"t": 5.0, "kind": "command", "message": "arm: accepted"}, "5.00 s  command arm: accepted"),
            (
                {
                    "t": 12.0,
                    "kind": "failsafe",
                    "message": "failsafe land: motor failure: motor 2",
                    "action": "land",
                    "severity": "critical",
                },
                "12.00 s  FAILSAFE land: motor failure: motor 2",
            ),
            (
                {"t": 20.0, "kind": "failsafe", "message": "battery low", "action": "return"},
                "20.00 s  FAILSAFE battery low — return",
            ),
        ]
        for event, expected in cases:
            assert d.execute_script("return window.gcs.eventText(arguments[0]).text", event) == expected
        d.get("about:blank")  # this tab leaves too
        assert wait_for(lambda: tabs(g) == 0, 10)
    finally:
        err = g.stop()
    assert [line.split(" (")[0] for line in err.splitlines()] == ["cufund gcs: a tab closed its connection"] * 2, err


def tabs(g):
    import json
    import urllib.request

    with urllib.request.urlopen(urllib.request.Request(g.base + "/api/stats", headers=g.auth), timeout=10) as r:
        return json.load(r)["tabs"]


def test_start_starts_a_held_run_and_nothing_flies_before_it(driver, tmp_path):
    """square has no commander: every commander control is disabled with the reason; the run waits at its first
    instant; Start lets it fly."""
    d = driver
    with GcsProcess("square", "--speed", "2", "--telemetry-hz", "20") as g:
        open_page(d, g)
        start = d.find_element(By.ID, "cmd-start")
        assert wait_for(start.is_enabled, 10)
        for id_ in ("cmd-arm", "cmd-takeoff", "cmd-land", "cmd-rtl", "cmd-hold", "cmd-goto", "cmd-upload"):
            el = d.find_element(By.ID, id_)
            assert not el.is_enabled() and "no commander" in el.get_attribute("title"), id_
        assert disabled_without_title(d) == []
        first = telemetry(d)
        assert wait_for(lambda: d.execute_script("return window.gcs.stats.telemetry") > 20, 10)
        held = telemetry(d)
        assert held["t"] == first["t"] <= 0.01 and held["truth_p_W"][2] == pytest.approx(0.0, abs=1e-6)
        d.save_screenshot(str(tmp_path / "gcs_held.png"))
        start.click()
        assert ack(d, "start")["result"] == "accepted"
        assert wait_for(lambda: telemetry(d)["truth_p_W"][2] > 1.0, 30)
        assert not start.is_enabled() and start.get_attribute("title") == "the run has started"
        no_sideways_scrolling(d)
