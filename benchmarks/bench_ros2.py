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


def round_trips(duration: float = 10.0) -> None:
    d = 200 + os.getpid() % 30
    node = _node(d, "bench", "--topics", "/clock,/imu")
    cfg = _config(
        "square",
        {"domain_id": d, "lockstep_nodes": ["bench"], "timeout_s": 30},
        duration=duration,
        sensors={"imu": {"kind": "icm42688p", "rate_hz": 200.0}},
    )
    built = build_simulation(cfg)
    bridge = next(c for c in built.simulator.components if type(c).__name__ == "Ros2Bridge")
    w0 = time.perf_counter()
    built.simulator.run(duration)
    wall = time.perf_counter() - w0
    node.wait()
    steps = bridge.stats["steps"]
    print(
        f"lockstep: {steps} IMU steps answered in {wall:.2f} s wall: {steps / wall:,.0f} round trips/s "
        f"({duration / wall:.1f}x real time at 200 Hz; bridge waiting {bridge.stats['wait_s']:.2f} s; "
        f"whole simulation included)"
    )


def lidar_bandwidth(duration: float = 5.0) -> None:
    d = 200 + (os.getpid() + 7) % 30
    node = _node(d, "bench_lidar", "--topics", "/clock,/livox/lidar")
    cfg = _config(
        "square_lio",
        {"domain_id": d, "lockstep_nodes": ["bench_lidar"], "rate_hz": 10.0, "timeout_s": 30},
        duration=duration,
        estimator=None,
    )
    built = build_simulation(cfg)
    bridge = next(c for c in built.simulator.components if type(c).__name__ == "Ros2Bridge")
    w0 = time.perf_counter()
    result = built.simulator.run(duration)
    wall = time.perf_counter() - w0
    node.wait()
    mb = bridge.stats["bytes"] / 1e6
    print(
        f"LiDAR: {bridge.stats['messages']} messages, {mb:.1f} MB in {wall:.2f} s wall: {mb / wall:.1f} MB/s, "
        f"{duration / wall:.1f}x real time with the node receiving every cloud (simulation and ray casting included; "
        f"component seconds {result.component_seconds})"
    )


if __name__ == "__main__":
    round_trips()
    lidar_bandwidth()
