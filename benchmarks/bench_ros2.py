"""ROS 2 bridge benchmark (not a timed test): lockstep round trips per second with an external node (its own
process, :mod:`cufund.apps.ros2.node`) answering every IMU step, and the LiDAR bandwidth the bridge sustains.

    .venv/bin/python benchmarks/bench_ros2.py

Targets (issue 27): >= 2,000 round trips/s (a 200 Hz IMU at >= 10x real time); a Mid-360 at 10 Hz at >= 5x real
time. Loopback only, a domain of its own."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

from cufund.scenarios.build import build_simulation
from cufund.scenarios.schema import ScenarioConfig, load_scenario


def _config(name: str, ros2: dict, **changes) -> ScenarioConfig:
    cfg = load_scenario(name)
    data = cfg.to_dict()
    data.update(changes)
    data["ros2"] = ros2
    return ScenarioConfig.from_dict(data, cfg.base_dir)


def _node(d: int, name: str, *extra: str) -> subprocess.Popen:
    out = os.path.join(tempfile.mkdtemp(), "node.json")
    cmd = [sys.executable, "-m", "cufund.apps.ros2.node", "--domain", str(d), "--name", name, "--out", out]
    return subprocess.Popen([*cmd, "--idle-exit", "2", *extra])


def _run(cfg: ScenarioConfig, duration: float) -> tuple[float, dict, object]:
    """(wall seconds after the nodes announced themselves, the bridge's stats, the result)."""
    built = build_simulation(cfg)
    bridge = next(c for c in built.simulator.components if type(c).__name__ == "Ros2Bridge")
    w0 = time.perf_counter()
    result = built.simulator.run(duration)
    wall = time.perf_counter() - w0 - bridge.stats["ready_s"]
    return wall, dict(bridge.stats), result


def round_trips(duration: float = 20.0) -> None:
    d = 200 + os.getpid() % 30
    node = _node(d, "bench", "--topics", "/clock,/imu", "--raw")
    imu = {"imu": {"kind": "icm42688p", "rate_hz": 200.0}}
    cfg = _config(
        "square", {"domain_id": d, "lockstep_nodes": ["bench"], "timeout_s": 30}, duration=duration, sensors=imu
    )
    wall, stats, _ = _run(cfg, duration)
    node.wait()
    alone = _config("square", None, duration=duration, sensors=imu)
    w0 = time.perf_counter()
    build_simulation(alone).simulator.run(duration)
    sim_wall = time.perf_counter() - w0
    steps = stats["steps"]
    bridge_s = wall - sim_wall
    print(
        f"lockstep: {steps} IMU steps (200 Hz) answered by the node in {wall:.2f} s wall after it announced itself: "
        f"{steps / wall:,.0f} steps/s with the whole simulation ({duration / wall:.1f}x real time); the simulation "
        f"alone takes {sim_wall:.2f} s, so the bridge's round trips (publish the IMU sample and /clock, which the node "
        f"reads, wait for the answer; the truth and /tf, which no one reads, are not encoded) run at {steps / max(bridge_s, 1e-9):,.0f}/s (waiting {stats['wait_s']:.2f} s in all)"
    )


def lidar_bandwidth(duration: float = 10.0) -> None:
    d = 200 + (os.getpid() + 7) % 30
    node = _node(d, "bench_lidar", "--topics", "/clock,/livox/lidar", "--raw")
    ros2 = {"domain_id": d, "lockstep_nodes": ["bench_lidar"], "rate_hz": 10.0, "timeout_s": 30}
    cfg = _config("square_lio", ros2, duration=duration, estimator=None)
    wall, stats, result = _run(cfg, duration)
    node.wait()
    mb = stats["bytes"] / 1e6
    bridge_s = result.component_seconds.get("ros2_bridge", 0.0) - stats["wait_s"]
    print(
        f"LiDAR (Mid-360, 10 Hz): {mb:.1f} MB over {duration:g} s simulated in {wall:.2f} s wall "
        f"({duration / wall:.1f}x real time with the ray casting and the node taking every cloud); the bridge's "
        f"own encoding and writing: {bridge_s:.2f} s, {mb / max(bridge_s, 1e-9):.0f} MB/s, "
        f"{duration / max(bridge_s, 1e-9):.0f}x real time; lidar sensor {result.component_seconds.get('lidar', 0):.2f} s"
    )


if __name__ == "__main__":
    round_trips()
    lidar_bandwidth()
