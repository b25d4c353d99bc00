"""Real-time factor of a fleet: N vehicles in one world, each with an IMU, a 2-D LiDAR (Hokuyo UTM-30LX pattern,
40 Hz, 1081 beams), an estimator (IMU propagation corrected by a motion-capture pose) and a cascaded PID
controller flying its own square, all advanced together by :class:`cufund.simulator.fleet.FleetSimulator`
(vehicle-vehicle contacts, min separation, downwash and the others seen by the LiDARs included).

    .venv/bin/python benchmarks/bench_fleet.py [--n 1 10 100] [--seconds 2] [--threads 2]

Prints, per N, the simulated seconds per wall second of the whole fleet (>= 1: real time or faster) and the wall
time per vehicle-second, and the same from the process's CPU time (all threads): on a shared machine the wall
figures measure its load as much as the fleet; not a test (nothing is asserted)."""

from __future__ import annotations

import argparse
import os
import time

import numpy as np


def fleet_config(n: int, spacing: float = 4.0):
    from cufund.scenarios.schema import ScenarioConfig, load_scenario

    data = load_scenario("square_mocap").to_dict()
    side = int(np.ceil(np.sqrt(n)))
    vehicles = []
    for i in range(n):
        x, y = spacing * (i % side), spacing * (i // side)
        wp = [[x, y, 1.5], [x + 1, y, 1.5], [x + 1, y + 1, 1.5], [x, y + 1, 1.5], [x, y, 1.5]]
        vehicles.append({"name": f"uav{i + 1}", "start": {"p": [x, y, 0.0]}, "trajectory": {"waypoints": wp}})
    data.update(name=f"bench_fleet_{n}", world={"kind": "empty"}, vehicles=vehicles, downwash=True)
    return ScenarioConfig.from_dict(data)


def build(n: int, threads: int, batched_physics: bool = True):
    from cufund.geometry import Transform
    from cufund.scenarios.fleet import build_fleet
    from cufund.sensors.lidar import Lidar, LidarParams
    from cufund.sensors.lidar_component import LidarComponent
    from cufund.sensors.patterns import PlanarPattern

    fleet = build_fleet(fleet_config(n))
    fleet.simulator.batched_physics = batched_physics
    for name, member in zip(fleet.names, fleet.simulator.members, strict=True):
        sim = fleet.vehicle(name).simulator
        lidar = Lidar(
            PlanarPattern(),
            LidarParams(range_min=0.1, range_max=30.0, range_noise_std=0.01, seed=len(name), nthreads=threads),
            Transform((0.0, 0.0, 0.05)),
        )
        comp = LidarComponent(lidar, member.world, "/sensors/scan", rate_hz=40.0, truth_topic="/truth/scan")
        sim.add(comp)
        member.viewers.append(comp)  # it sees the other vehicles within its range
        member.view_range_m = 30.0
    return fleet


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[1, 10, 100])
    ap.add_argument("--seconds", type=float, default=2.0, help="simulated seconds per fleet (from take-off)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument(
        "--physics",
        choices=("batched", "each"),
        default="batched",
        help="all vehicles' physics steps in one C++ call per round (the default), or each simulator its own",
    )
    args = ap.parse_args()
    print(f"cores: {os.cpu_count()}, ray-cast threads: {args.threads}, physics: {args.physics}")
    print(f"load average (1, 5, 15 min): {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(
        f"{'N':>5} {'build s':>8} {'sim s':>7} {'wall s':>8} {'RTF':>8} {'ms / vehicle-s':>15}"
        f" {'CPU s':>8} {'CPU RTF':>8} {'CPU ms / vehicle-s':>19}"
    )
    for n in args.n:
        b0 = time.perf_counter()
        fleet = build(n, args.threads, args.physics == "batched")
        built_s = time.perf_counter() - b0
        w0, c0 = time.perf_counter(), time.process_time()
        fleet.simulator.reset()
        fleet.advance_to(args.seconds)
        wall, cpu = time.perf_counter() - w0, time.process_time() - c0
        sim_t = fleet.t
        print(
            f"{n:>5} {built_s:>8.2f} {sim_t:>7.2f} {wall:>8.2f} {sim_t / wall:>8.3f} {1000 * wall / (n * sim_t):>15.1f}"
            f" {cpu:>8.2f} {sim_t / cpu:>8.3f} {1000 * cpu / (n * sim_t):>19.1f}"
        )


if __name__ == "__main__":
    main()
