"""The live runner (``cufund.apps.live.LiveRun``, what ``cufund serve`` and ``cufund gcs`` fly): pacing, the cost of
running live, and how fast a command is answered.

1. Pacing: simulated seconds per wall second at speed 1 (target 1.000) while the vehicle hovers.
2. Overhead: the same scenario flying the same mission (a) in a LiveRun at speed inf (background thread, telemetry
   tap, guarded components) and (b) with the bare simulator in this thread (``advance_to`` in 50 ms chunks). The
   ratio (a)/(b) is the price of the live machinery (1.0: free).
3. Command latency: wall time from ``submit`` to the resolved ack at speed 1 (a command waits for the next
   commander step, 4 ms at 250 Hz, and for the simulation thread's next chunk).

Run: `.venv/bin/python benchmarks/bench_live.py [--scenario vehicle] [--seconds 5]`.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import statistics
import time

from cufund.apps.live import LiveRun
from cufund.missions import Commander
from cufund.scenarios import load_scenario
from cufund.scenarios.build import build_simulation

MISSION = {"command": "mission_upload", "items": [[-3.0, 2.0, 1.5], [-3.0, -2.0, 2.0], [-2.0, -2.0, 1.5]]}


def _airborne(run: LiveRun) -> None:
    run.submit({"command": "arm"}).result(timeout=10)
    run.submit({"command": "takeoff", "altitude": 1.5}).result(timeout=10)
    if not run.wait_until(lambda s: s["mode"] == "hold", 120):
        raise RuntimeError("no hover within 120 s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", default="vehicle")
    ap.add_argument("--seconds", type=float, default=5.0, help="wall seconds per measurement")
    args = ap.parse_args()

    with LiveRun(args.scenario, speed=1.0) as run:
        _airborne(run)
        t0, w0 = run.telemetry()["sim_t"], time.perf_counter()
        time.sleep(args.seconds)
        pace = (run.telemetry()["sim_t"] - t0) / (time.perf_counter() - w0)
        lat = []
        for _ in range(50):
            w = time.perf_counter()
            run.submit({"command": "get_params"}).result(timeout=10)
            lat.append(time.perf_counter() - w)
            time.sleep(0.013)
        lat.sort()
        run.set_speed(math.inf)
        run.submit(MISSION).result(timeout=10)
        run.submit({"command": "mission_start"}).result(timeout=10)
        t0, w0 = run.telemetry()["sim_t"], time.perf_counter()
        time.sleep(args.seconds)
        live_rate = (run.telemetry()["sim_t"] - t0) / (time.perf_counter() - w0)

    cfg = load_scenario(args.scenario)  # without its script, as LiveRun flies it
    cfg = cfg.replace(
        planner=dataclasses.replace(cfg.planner, params=dataclasses.replace(cfg.planner.params, script=()))
    )
    sim = build_simulation(cfg).simulator
    sim.reset()
    cmd = next(c for c in sim.components if isinstance(c, Commander))
    sim.advance_to(0.5)
    cmd.apply("arm")
    cmd.apply({"command": "takeoff", "altitude": 1.5})
    while cmd.mode != "hold":
        sim.advance_to(sim.t + 0.05)
    cmd.apply(MISSION)
    cmd.apply("mission_start")
    t0, w0 = sim.t, time.perf_counter()
    while time.perf_counter() - w0 < args.seconds:
        sim.advance_to(sim.t + 0.05)
    bare_rate = (sim.t - t0) / (time.perf_counter() - w0)

    print(f"scenario {args.scenario}")
    print(f"pacing at speed 1 (hover):        {pace:.3f} sim s per wall s")
    print(
        f"command ack latency at speed 1:   median {1e3 * statistics.median(lat):.1f} ms, "
        f"p95 {1e3 * lat[int(0.95 * len(lat)) - 1]:.1f} ms"
    )
    print(
        f"speed inf, flying a mission:      LiveRun {live_rate:.2f}x real time, bare simulator "
        f"{bare_rate:.2f}x; ratio {live_rate / bare_rate:.2f}"
    )


if __name__ == "__main__":
    main()
