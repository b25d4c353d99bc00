"""Web ground station figures, in headless Chromium against `cufund gcs` (vehicle scenario with a Mid-360 LiDAR,
real time):

1. telemetry rate seen in the browser with the point-cloud layer on (target >= 30 Hz), and the cloud rate;
2. click-to-setpoint latency: from a click on the ground grid (click-to-go; the release's own event time stamp, so
   a busy page's delay in handling it counts) until the commander's acknowledgement reaches the page, until the
   page's telemetry panel shows the clicked point as the vehicle's target (target <= 50 ms), until the next frame
   the page paints after that, and until the 3-D view has drawn the new setpoint marker; with how busy the page's
   main thread was (CDP Performance TaskDuration);
3. the server process's CPU (simulation included) with no tab, then with three tabs open (cloud layer on).

    .venv/bin/python benchmarks/bench_gcs.py [--seconds 10] [--clicks 20] [--speed 1] [--fps 20] [--query aa=1]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import time

from cufund.apps.gcs import GcsProcess
from cufund.apps.gcs.process import wait_for


def cpu_seconds(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime of all threads


def tree_cpu_seconds(root: int) -> float:
    """CPU seconds of ``root``'s descendants still running (the browser's processes under chromedriver)."""
    parent = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    parent[int(entry)] = int(f.read().rsplit(")", 1)[1].split()[1])
            except OSError:
                continue
    tree, frontier = set(), {root}
    while frontier:
        frontier = {p for p, pp in parent.items() if pp in frontier} - tree
        tree |= frontier
    total = 0.0
    for pid in tree:
        try:
            total += cpu_seconds(pid)
        except OSError:
            pass
    return total


def io_cpu(gcs: GcsProcess) -> float:
    """CPU seconds of the server's event-loop thread (HTTP, websockets, telemetry; not the simulation)."""
    import json
    import urllib.request

    with urllib.request.urlopen(urllib.request.Request(gcs.base + "/api/stats", headers=gcs.auth), timeout=10) as r:
        return json.loads(r.read())["io_thread_cpu_s"]


def cpu_share(gcs: GcsProcess, seconds: float) -> tuple[float, float]:
    """CPU cores used by the whole server process and by its event-loop thread over ``seconds`` of wall time."""
    c0, i0, t0 = cpu_seconds(gcs.pid), io_cpu(gcs), time.monotonic()
    time.sleep(seconds)
    dt = time.monotonic() - t0
    return (cpu_seconds(gcs.pid) - c0) / dt, (io_cpu(gcs) - i0) / dt


def scripted_latency(gcs: GcsProcess, n: int) -> tuple[list[float], list[float]]:
    """Go-to commands from a Python websocket client (no browser): ms until the ack, and until a telemetry message
    shows the new target."""
    import json

    import websocket

    ws = websocket.create_connection(gcs.base.replace("http://", "ws://") + "/ws?token=" + gcs.token, timeout=10)
    ws.send(json.dumps({"type": "seen", "telemetry": 0, "cloud": 0}))
    got, acks, seen = 0, [], []
    try:
        for k in range(n):
            goal = [-2.0 + 0.3 * ((k % 3) - 1), 0.3 * ((k % 2) * 2 - 1), 1.5]
            t0 = time.perf_counter()
            ws.send(json.dumps({"type": "command", "id": 100 + k, "command": {"command": "goto", "p_W": goal}}))
            ack_at = seen_at = None
            while ack_at is None or seen_at is None:
                raw = ws.recv()
                if isinstance(raw, bytes):
                    continue
                m = json.loads(raw)
                now = time.perf_counter()
                if m["type"] == "telemetry":
                    got += 1
                    ws.send(json.dumps({"type": "seen", "telemetry": got, "cloud": 0}))
                    tg = m.get("target_p_W")
                    if seen_at is None and tg and max(abs(a - b) for a, b in zip(tg, goal, strict=True)) < 1e-6:
                        seen_at = now
                elif m["type"] == "ack" and m["id"] == 100 + k:
                    assert m["result"] == "accepted", m
                    ack_at = now
            acks.append((ack_at - t0) * 1e3)
            seen.append((seen_at - t0) * 1e3)
            time.sleep(0.3)
    finally:
        ws.close()
    return acks, seen


def percentile(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, int(round(q / 100 * (len(s) - 1))))]


def spread(values: list[float]) -> str:
    return (
        f"median {statistics.median(values):.1f} ms, p90 {percentile(values, 90):.1f} ms, max {max(values):.1f} ms "
        f"over {len(values)}"
    )


def main_thread_busy(d, seconds: float) -> float:
    """Share of wall time the page's main thread spent running tasks (Chrome's Performance.getMetrics)."""

    def task() -> tuple[float, float]:
        m = {x["name"]: x["value"] for x in d.execute_cdp_cmd("Performance.getMetrics", {})["metrics"]}
        return m["TaskDuration"], m["Timestamp"]

    d0, t0 = task()
    time.sleep(seconds)
    d1, t1 = task()
    return (d1 - d0) / (t1 - t0)


def browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for a in (
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader",
        "--window-size=1300,800",
        "--disable-background-timer-throttling",
        "--disable-renderer-backgrounding",
        "--disable-backgrounding-occluded-windows",
    ):
        options.add_argument(a)
    options.binary_location = shutil.which("chromium")
    return webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=options)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="length of each rate / CPU window [s]")
    ap.add_argument("--clicks", type=int, default=20)
    ap.add_argument("--speed", default="1")
    ap.add_argument("--fps", type=int, default=20, help="the page's 3-D redraw cap (?fps=)")
    ap.add_argument("--query", default="", help="more of the page's URL parameters, e.g. 'view=page&dpr=1'")
    args = ap.parse_args()
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By

    print(f"load average at the start: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    with GcsProcess(
        "vehicle",
        "--speed",
        args.speed,
        "--set",
        "sensors.lidar.kind=mid360",
        "--set",
        "sensors.lidar.T_BL.p=[0,0,0.08]",
        "--set",
        "planner.auto_disarm_s=0",
    ) as gcs:
        time.sleep(2.0)
        idle, idle_io = cpu_share(gcs, args.seconds)
        d = browser()
        try:
            url = f"{gcs.url}&fps={args.fps}" + (f"&{args.query}" if args.query else "")
            d.get(url)
            assert wait_for(
                lambda: d.execute_script("return window.gcs.stats.telemetry > 10 && window.gcs.stats.frames > 0"), 30
            )
            stats = (
                "return [window.gcs.stats.telemetry, window.gcs.stats.clouds, performance.now(), "
                "window.gcs.stats.frames]"
            )
            n0, c0, w0, f0 = d.execute_script(stats)
            b0 = tree_cpu_seconds(d.service.process.pid)
            time.sleep(args.seconds)
            n1, c1, w1, f1 = d.execute_script(stats)
            b1 = tree_cpu_seconds(d.service.process.pid)
            rate, clouds = (n1 - n0) / ((w1 - w0) / 1e3), (c1 - c0) / ((w1 - w0) / 1e3)
            frames = (f1 - f0) / ((w1 - w0) / 1e3)
            fps, aa = d.execute_script("return [window.gcs.stats.fps, window.gcs.stats.antialias]")
            print(
                f"telemetry in the browser, cloud layer on: {rate:.1f} Hz (target >= 30); clouds {clouds:.1f} Hz; "
                f"3-D frames {frames:.1f} /s (capped at {fps:.0f} fps by the view's congestion control; "
                f"multisampling {'on' if aa else 'off'})"
            )
            print(
                f"the browser's CPU (all its processes): {(b1 - b0) / ((w1 - w0) / 1e3):.2f} cores, "
                f"{(b1 - b0) * 1e3 / max(1, f1 - f0):.0f} ms per 3-D frame"
            )
            d.execute_cdp_cmd("Performance.enable", {})
            busy = main_thread_busy(d, min(args.seconds, 5.0))
            print(f"the page's main thread busy {busy * 100:.0f} % of the time (the 3-D view draws in a worker)")

            d.execute_script("window.gcs.send({command: 'arm'})")
            time.sleep(0.5)
            d.execute_script("window.gcs.send({command: 'takeoff', altitude: 1.5})")
            assert wait_for(
                lambda: (
                    (t := d.execute_script("return window.gcs.stats.lastTelemetry"))["mode"] == "hold"
                    and t["p_W"][2] > 1.3
                ),
                60,
            ), "take-off did not finish"
            rtt = [d.execute_async_script("window.gcs.ping().then(arguments[0])") for _ in range(20)]
            print(
                f"websocket round trip page -> server -> page: median {statistics.median(rtt):.1f} ms, "
                f"max {max(rtt):.1f} ms"
            )
            d.find_element(By.ID, "click-goto").click()
            d.find_element(By.ID, "follow").click()  # a still camera: the clicked pixels stay where they were
            canvas = d.execute_script("return window.gcs.canvas")
            acks, seen, painted, handled, drawn = [], [], [], [], []
            for k in range(args.clicks):
                goal = [-2.0 + 0.4 * ((k % 3) - 1), 0.4 * ((k % 2) * 2 - 1), 0.0]
                px = d.execute_script("return window.gcs.screenOf(arguments[0])", goal)
                r = d.execute_script("return arguments[0].getBoundingClientRect()", canvas)
                ActionChains(d).move_to_element_with_offset(
                    canvas, int(px["x"] - r["x"] - r["width"] / 2), int(px["y"] - r["y"] - r["height"] / 2)
                ).click().perform()
                click = wait_for(
                    lambda: (
                        (c := d.execute_script("return window.gcs.lastClick"))
                        and all(c.get(k) is not None for k in ("seenAt", "ackAt", "paintedAt", "drawnAt"))
                        and c
                    ),
                    10,
                )
                assert click, "the click did not reach the commander"
                acks.append(click["ackAt"] - click["t0"])
                seen.append(click["seenAt"] - click["t0"])
                painted.append(click["paintedAt"] - click["t0"])
                handled.append(click["handledAt"] - click["t0"])
                drawn.append(click["drawnAt"] - click["t0"])
                d.execute_script("window.gcs.lastClick = null")
                time.sleep(0.3)
            print(f"click (event time stamp) to its handler: {spread(handled)}")
            print(f"click-to-ack: {spread(acks)}")
            print(f"click-to-setpoint (the panel shows the clicked point as the target): {spread(seen)} (target <= 50)")
            print(f"click-to-setpoint painted (the page's next frame): {spread(painted)}")
            print(f"click to the 3-D view's frame with the new setpoint marker (drawn by its worker): {spread(drawn)}")

            acks, seen = scripted_latency(gcs, args.clicks)
            print(
                f"the same from a Python websocket client: ack median {statistics.median(acks):.1f} ms, "
                f"target in telemetry {spread(seen)}"
            )

            for _ in range(2):
                d.switch_to.new_window("tab")
                d.get(url)
            time.sleep(2.0)
            three, three_io = cpu_share(gcs, args.seconds)
            tel = d.execute_script("return window.gcs.stats.lastTelemetry")
            print(
                f"server process CPU (simulation included): {idle:.2f} cores with no tab, {three:.2f} with three "
                f"tabs; real-time factor {tel['real_time_factor']:.2f}"
            )
            print(
                f"server event-loop thread (all but the simulation): {idle_io * 100:.1f} % of a core with no tab, "
                f"{three_io * 100:.1f} % with three tabs (cloud layer on)"
            )
        finally:
            d.quit()
        print(f"load average during the run: {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
