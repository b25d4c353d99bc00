"""The web ground station in a real browser (Debian's headless Chromium through selenium): the page's buttons fly
the vehicle, the telemetry DOM shows it, the 3-D view draws it, tabs stay in sync and catch up."""

import io
import shutil

import numpy as np
import pytest

from cufund.apps.gcs import GcsProcess
from cufund.apps.gcs.process import wait_for

webdriver = pytest.importorskip("selenium.webdriver")
from selenium.webdriver.chrome.service import Service  # noqa: E402  (after the importorskip)
from selenium.webdriver.common.by import By  # noqa: E402

CHROMEDRIVER = "/usr/bin/chromedriver"
pytestmark = pytest.mark.skipif(
    not shutil.which("chromium") or not shutil.which(CHROMEDRIVER),
    reason="needs Debian's chromium and chromium-driver (make deps)",
)


@pytest.fixture(scope="module")
def gcs():
    with GcsProcess("vehicle", "--speed", "5", "--telemetry-hz", "20", "--set", "planner.auto_disarm_s=0") as g:
        yield g


@pytest.fixture(scope="module")
def driver():
    options = webdriver.ChromeOptions()
    for a in (
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader",
        "--window-size=1000,650",
        "--disable-dev-shm-usage",
    ):
        options.add_argument(a)
    options.binary_location = shutil.which("chromium")
    d = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    d.set_script_timeout(10)
    yield d
    d.quit()


def text(d, id_):
    return d.find_element(By.ID, id_).text


def number(d, id_):
    try:
        return float(text(d, id_))
    except ValueError:
        return float("nan")


def telemetry(d):
    return d.execute_script("return window.gcs.stats.lastTelemetry")


def layer_points(d, name):
    """The points the 3-D view's line layer ``name`` draws (asked of the view's worker), as an (n, 3) array."""
    return np.reshape(d.execute_async_script("window.gcs.layerPoints(arguments[0]).then(arguments[1])", name), (-1, 3))


def click(d, id_):
    d.find_element(By.ID, id_).click()


def set_value(d, id_, value):
    el = d.find_element(By.ID, id_)
    el.clear()
    el.send_keys(str(value))


def ack(d, command, timeout=10):
    return wait_for(
        lambda: next(
            (a for a in reversed(d.execute_script("return window.gcs.stats.acks")) if a["command"] == command), None
        ),
        timeout,
    )


def open_page(d, gcs):
    d.get(gcs.url + "&fps=8")  # software WebGL on a shared CI machine: fewer frames, snappier page
    assert wait_for(lambda: text(d, "conn") == "connected" and telemetry(d), 20), "the page did not connect"


def test_buttons_fly_takeoff_goto_and_a_mission(gcs, driver):
    d = driver
    open_page(d, gcs)
    click(d, "cmd-arm")
    assert ack(d, "arm")["result"] == "accepted"
    assert wait_for(lambda: text(d, "tel-armed") == "true", 5)
    click(d, "cmd-takeoff")
    assert ack(d, "takeoff")["result"] == "accepted"
    assert wait_for(lambda: number(d, "tel-alt") > 1.0, 20), f"altitude {text(d, 'tel-alt')}"
    assert wait_for(lambda: text(d, "tel-mode") == "hold", 20)

    goal = np.array([-1.2, 0.5, 1.6])
    for axis, v in zip("xyz", goal, strict=True):
        set_value(d, f"goto-{axis}", v)
    click(d, "cmd-goto")
    assert ack(d, "goto")["result"] == "accepted"

    # the planned path shown is the go-to's
    def planned():
        return layer_points(d, "planned")

    assert wait_for(lambda: len(planned()) and np.allclose(planned()[-1], goal, atol=1e-4), 5), planned()
    arrived = wait_for(
        lambda: (
            (t := telemetry(d))
            and np.linalg.norm(np.array(t["truth_p_W"]) - goal) < 0.1
            and np.linalg.norm(t["v_W"]) < 0.1
        ),
        30,
    )
    assert arrived, f"at {telemetry(d)['truth_p_W']}, goal {goal}"

    waypoints = np.array([[-1.2, 1.2, 1.5], [-2.0, 1.2, 1.8], [-2.0, 0.5, 1.5]])
    set_value(d, "waypoints", "\n".join(" ".join(str(v) for v in w) for w in waypoints))
    click(d, "cmd-upload")
    assert ack(d, "mission_upload")["result"] == "accepted"
    click(d, "cmd-mission-start")
    assert ack(d, "mission_start")["result"] == "accepted"
    assert wait_for(lambda: "mission complete" in text(d, "events"), 60), text(d, "events")
    log = text(d, "events")
    reached = [log.index(f"mission item {k} reached") for k in range(3)]
    assert reached == sorted(reached)
    # the flown path the page draws passes each waypoint, in order
    flown = layer_points(d, "flown")
    nearest = [int(np.argmin(np.linalg.norm(flown - w, axis=1))) for w in waypoints]
    assert all(np.linalg.norm(flown[i] - w) < 0.2 for i, w in zip(nearest, waypoints, strict=True))  # acceptance 0.15 m
    assert nearest == sorted(nearest)


@pytest.mark.parametrize("view", ["worker", "page"])
def test_the_3d_view_draws_the_vehicle(gcs, driver, view):
    """Drawn where the page's own projection (the one a click on the ground is picked with) puts it, by the view's
    worker and by the same view in the page itself (browsers without OffscreenCanvas, ``?view=page``)."""
    from PIL import Image

    d = driver
    if not d.current_url.startswith(gcs.base) or ("view=page" in d.current_url) != (view == "page"):
        d.get(gcs.url + "&fps=8" + ("&view=page" if view == "page" else ""))
        assert wait_for(lambda: text(d, "conn") == "connected" and telemetry(d), 20), "the page did not connect"
    assert d.execute_script("return window.gcs.viewInWorker") == (view == "worker")
    click(d, "cmd-pause")
    assert ack(d, "sim_pause")["result"] == "accepted"
    try:
        wait_for(lambda: telemetry(d)["paused"], 5)
        px = d.execute_script("return window.gcs.vehicleScreen()")
        assert px and 0 < px["z"] < 1, px

        def shot():  # once the view has drawn what the page posted, and the page has shown that frame
            d.execute_async_script(
                "window.gcs.drawn().then(() => requestAnimationFrame(() => requestAnimationFrame(arguments[0])))"
            )
            return np.asarray(Image.open(io.BytesIO(d.get_screenshot_as_png())).convert("RGB"), dtype=float)

        with_vehicle = shot()
        d.find_element(By.CSS_SELECTOR, "[data-layer=vehicle]").click()
        without = shot()
        d.find_element(By.CSS_SELECTOR, "[data-layer=vehicle]").click()
        scale = with_vehicle.shape[1] / d.execute_script("return window.innerWidth")
        x, y, r = int(px["x"] * scale), int(px["y"] * scale), int(25 * scale)
        near = np.abs(with_vehicle - without)[y - r : y + r, x - r : x + r].max(axis=2)
        top = int(120 * scale)  # below the layer checkboxes (one of them changed)
        far = np.abs(with_vehicle - without)[top:, : x - 4 * r].max(axis=2) if x > 4 * r else np.zeros(1)
        # the vehicle's pixels differ from what is behind it, and only around where it is projected
        assert (near > 60).sum() > 30, (near > 60).sum()
        assert (far > 60).sum() < 10
    finally:
        click(d, "cmd-resume")
        if view == "page":
            open_page(d, gcs)


def test_click_on_the_ground_goes_there(gcs, driver):
    """A click on the 3-D view (click to go) sends a go-to to the ground point under the pointer (picked analytically
    on z = 0 with the camera the view draws with, as the previous test checks), at the altitude typed for go-to."""
    from selenium.webdriver.common.action_chains import ActionChains

    d = driver
    if not d.current_url.startswith(gcs.base) or "view=page" in d.current_url:
        open_page(d, gcs)
    assert wait_for(lambda: telemetry(d)["mode"] == "hold" and telemetry(d)["armed"], 20), telemetry(d)["mode"]
    set_value(d, "goto-z", 1.4)
    d.find_element(By.ID, "click-goto").click()
    d.find_element(By.ID, "follow").click()  # a still camera
    try:
        goal = np.array([-1.6, 0.8])
        px = d.execute_script("return window.gcs.screenOf(arguments[0])", [*goal, 0.0])
        canvas = d.execute_script("return window.gcs.canvas")
        r = d.execute_script("return arguments[0].getBoundingClientRect()", canvas)
        ActionChains(d).move_to_element_with_offset(
            canvas, round(px["x"] - r["x"] - r["width"] / 2), round(px["y"] - r["y"] - r["height"] / 2)
        ).click().perform()
        assert ack(d, "goto")["result"] == "accepted"
        target = wait_for(
            lambda: (t := telemetry(d)["target_p_W"]) and np.linalg.norm(np.array(t[:2]) - goal) < 0.05 and t, 5
        )
        assert target, (telemetry(d)["target_p_W"], goal)
        assert target[2] == pytest.approx(1.4)
        click = d.execute_script("return window.gcs.lastClick")
        assert click["p_W"] == pytest.approx(target, abs=1e-9) and click["seenAt"] >= click["t0"]
    finally:
        d.find_element(By.ID, "click-goto").click()
        d.find_element(By.ID, "follow").click()


def test_malformed_socket_message_in_the_page(gcs, driver):
    d = driver
    if not d.current_url.startswith(gcs.base):
        open_page(d, gcs)
    t0 = telemetry(d)["t"]
    n0 = len(d.execute_script("return window.gcs.stats.errors"))
    d.execute_script("window.gcs.raw('{\"type\": 42')")
    assert wait_for(lambda: len(d.execute_script("return window.gcs.stats.errors")) > n0, 5)
    assert wait_for(lambda: telemetry(d)["t"] > t0 + 0.3, 10)
    assert text(d, "conn") == "connected"


def test_tabs_in_sync_and_reconnect_catches_up(gcs, driver):
    d = driver
    if not d.current_url.startswith(gcs.base):
        open_page(d, gcs)
    first = d.current_window_handle
    d.switch_to.new_window("tab")
    try:
        open_page(d, gcs)
        second = d.current_window_handle
        path_len = len(layer_points(d, "flown"))
        assert path_len > 20  # caught up: the path flown before this tab opened
        d.execute_script("document.getElementById('controller').value = 'geometric'")
        click(d, "cmd-controller")
        assert ack(d, "controller")["result"] == "accepted"
        d.switch_to.window(first)
        assert wait_for(lambda: text(d, "tel-controller") == "geometric", 10)
        assert "controller: accepted" in text(d, "events")
        # the socket drops; the page reconnects and catches up (a second hello, the event log again)
        hellos = d.execute_script("return window.gcs.stats.hellos")
        d.execute_script("window.gcs.dropConnection()")
        assert wait_for(lambda: d.execute_script("return window.gcs.stats.hellos") > hellos, 10)
        assert wait_for(lambda: text(d, "conn") == "connected", 5)
        assert "controller: accepted" in text(d, "events")
        d.switch_to.window(second)
        d.close()
    finally:
        d.switch_to.window(first)
    click(d, "cmd-land")
    assert ack(d, "land")["result"] == "accepted"
    assert wait_for(lambda: telemetry(d)["mode"] in ("land", "idle"), 5)


def test_ltlf_mission_preview_is_drawn_before_it_flies(gcs, driver):
    d = driver
    if not d.current_url.startswith(gcs.base):
        open_page(d, gcs)
    set_value(d, "ltl-formula", "F(b) & F(a) & G(!c)")
    click(d, "cmd-ltl-preview")
    assert ack(d, "mission_preview")["result"] == "accepted"
    plan = d.execute_script("return window.gcs.lastPlan")
    p = np.array(telemetry(d)["p_W"])
    a, b = np.array([2.0, 0.0, 1.5]), np.array([2.0, 2.0, 1.5])  # the page's example regions
    order = ["a", "b"] if np.linalg.norm(p - a) <= np.linalg.norm(p - b) else ["b", "a"]
    assert plan["regions"] == order and text(d, "ltl-plan").startswith(" → ".join(order))
    assert d.find_element(By.ID, "cmd-ltl-fly").is_enabled()
