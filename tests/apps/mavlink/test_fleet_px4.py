"""N PX4 SITL instances against one fleet: each instance its own TCP port and vehicle, in lockstep (no instance
sees a period before every vehicle has reached it), played by Px4Harness as the single-vehicle tests do."""

from __future__ import annotations

import os
import threading

import numpy as np
import pytest

from cufund.apps.mavlink.fleet_px4 import Px4FleetBridge, px4_fleet_scenario
from cufund.apps.mavlink.px4_harness import Px4Harness
from cufund.apps.mavlink.px4_links import TcpServerLink
from cufund.apps.mavlink.px4_sim import Px4BridgeParams
from cufund.core.config import ConfigError
from cufund.scenarios.schema import ScenarioConfig
from cufund.vehicle.presets import iris

U_HOVER = (iris().hover_rotor_speed - 100.0) / 1000.0  # iris: omega = 1000 u + 100 rad/s
IDEAL = {"imu": "ideal_imu", "magnetometer": "magnetometer", "barometer": "ideal_barometer", "gps": "ideal_gps"}


def _fleet(n: int = 2, **extra) -> ScenarioConfig:
    return ScenarioConfig.from_dict(
        {
            "name": "px4_fleet",
            "vehicle": "iris",
            "seed": 3,
            "duration": 60.0,
            "sensors": dict(IDEAL),
            "planner": {"kind": "commander"},
            "controller": "pid",
            "vehicles": [{"name": f"uav{i + 1}", "start": {"p": [4.0 * i, 0.0, 0.0]}} for i in range(n)],
            **extra,
        }
    )


def test_the_fleet_is_px4s_world_vehicle_by_vehicle():
    from cufund.scenarios.fleet import vehicle_scenario

    fleet = _fleet()
    own = {"name": "uav3", "start": {"p": [8.0, 0.0, 0.0]}, "sensors": {"imu": "icm42688p"}, "planner": "commander"}
    fleet = fleet.replace(vehicles=(*fleet.vehicles, own))
    cfg = px4_fleet_scenario(fleet)
    for name in ("uav1", "uav3"):
        v = vehicle_scenario(cfg, name)
        for group in ("estimator", "mapper", "planner", "controller", "mission"):
            assert getattr(v, group) is None, (name, group)
        rates = {s.sensor_type: s.params.rate_hz for s in v.sensors.values()}
        assert rates == {"imu": 250.0, "magnetometer": 100.0, "barometer": 50.0, "gps": 5.0}
    assert vehicle_scenario(cfg, "uav3").sensors["imu"].kind == "icm42688p"  # its own model kept
    assert vehicle_scenario(cfg, "uav1").sensors["imu"].kind == "ideal_imu"
    with pytest.raises(ConfigError, match="vehicles"):
        px4_fleet_scenario(ScenarioConfig.from_dict({"name": "one", "vehicle": "iris"}))


def test_two_instances_fly_their_own_vehicles_in_lockstep():
    params = Px4BridgeParams(speed=None, wait_first_controls=True)
    bridge = Px4FleetBridge(_fleet(2), params, links=[TcpServerLink("127.0.0.1", 0) for _ in range(2)])
    ports = [b.port_number for b in bridge.bridges.values()]
    assert len(set(ports)) == 2
    outcome: dict = {}
    thread = threading.Thread(
        target=lambda: outcome.setdefault("result", bridge.run(duration=2.0, connect_timeout=10.0)), daemon=True
    )
    thread.start()
    px4 = [Px4Harness.tcp("127.0.0.1", p) for p in ports]
    seen: dict[int, list] = {0: [], 1: []}
    # instance 0 holds hover thrust, instance 1 more: only vehicle 2 climbs
    u = [[U_HOVER] * 4, [U_HOVER + 0.08] * 4]
    try:
        for _ in range(400):  # 1.6 s of 250 Hz periods
            for i in (0, 1):
                s = px4[i].step(timeout=10.0)
                seen[i].append(s.sensor.time_usec)
                px4[i].controls(u[i], True, s.sensor.time_usec)
            # lockstep: neither instance is handed a period the other has not reached
            assert abs(seen[0][-1] - seen[1][-1]) == 0
    finally:
        for h in px4:
            h.close()
        thread.join(20.0)
        bridge.close()
    assert not thread.is_alive()
    result = outcome["result"]
    assert np.all(np.diff(seen[0]) == 4000) and np.all(np.diff(seen[1]) == 4000)
    p1 = bridge.bridges["uav1"].simulator.vehicle.state.p
    p2 = bridge.bridges["uav2"].simulator.vehicle.state.p
    assert p2[2] - p1[2] > 0.1  # more thrust: only vehicle 2 rose
    assert p1[0] == pytest.approx(0.0, abs=0.05) and p2[0] == pytest.approx(4.0, abs=0.05)
    assert all(s["controls"] >= 400 for s in result.stats.values())
    assert result.periods_per_wall_s > 0 and set(result.results) == {"uav1", "uav2"}


def test_a_missing_instance_is_named():
    bridge = Px4FleetBridge(_fleet(2), links=[TcpServerLink("127.0.0.1", 0) for _ in range(2)])
    try:
        with pytest.raises(TimeoutError, match="uav1"):
            bridge.run(duration=1.0, connect_timeout=0.3)
    finally:
        bridge.close()


def test_cli_serves_instance_plus_i_for_each_vehicle(tmp_path, capsys):
    import socket

    import yaml

    from cufund.apps.cli import main

    scenario = tmp_path / "fleet.yaml"
    scenario.write_text(yaml.safe_dump(_fleet(2).to_dict()))
    for _ in range(50):  # two consecutive free TCP ports above 4560
        with socket.socket() as a, socket.socket() as b:
            a.bind(("127.0.0.1", 0))
            base = a.getsockname()[1]
            try:
                b.bind(("127.0.0.1", base + 1))
            except OSError:
                continue
        break
    argv = ["px4-sim", str(scenario), "--instance", str(base - 4560), "--speed", "max", "--duration", "0.5",
            "--connect-timeout", "20"]  # fmt: skip
    code: dict = {}
    thread = threading.Thread(target=lambda: code.setdefault("exit", main(argv)), daemon=True)
    thread.start()
    px4 = [Px4Harness.tcp("127.0.0.1", base + i) for i in range(2)]
    try:
        for _ in range(124):  # 0.5 s of 4 ms periods, the first exchange one period in, the one at 0.5 s not run
            for h in px4:
                s = h.step(timeout=10.0)
                h.controls([U_HOVER] * 4, True, s.sensor.time_usec)
    finally:
        for h in px4:
            h.close()
        thread.join(30.0)
    assert code.get("exit") == 0
    out = capsys.readouterr().out
    for i in range(2):
        assert (
            f"uav{i + 1} on iris, waiting for PX4 instance {base - 4560 + i} (MAVLink system {base - 4560 + i + 1})"
            in out
        )
        assert f"tcp://127.0.0.1:{base + i} (SITL, lockstep)" in out
    assert "status: completed" in out


def test_cli_refuses_hitl_for_a_fleet(tmp_path, capsys):
    import yaml

    from cufund.apps.cli import main

    scenario = tmp_path / "fleet.yaml"
    scenario.write_text(yaml.safe_dump(_fleet(2).to_dict()))
    assert main(["px4-sim", str(scenario), "--hitl", "/dev/null", "--speed", "1"]) == 2
    assert "a fleet scenario runs as SITL instances" in capsys.readouterr().err


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="Linux's CPU affinity")
def test_cli_runs_a_fleet_on_the_cpu_asked_for(tmp_path, capsys, monkeypatch):
    import socket

    import yaml

    from cufund.apps.cli import main

    pinned: list[set[int]] = []
    monkeypatch.setattr(os, "sched_setaffinity", lambda pid, cpus: pinned.append(set(cpus)))
    cpu = sorted(os.sched_getaffinity(0))[-1]
    scenario = tmp_path / "fleet.yaml"
    scenario.write_text(yaml.safe_dump(_fleet(2).to_dict()))
    for _ in range(50):  # two consecutive free TCP ports above 4560
        with socket.socket() as a, socket.socket() as b:
            a.bind(("127.0.0.1", 0))
            base = a.getsockname()[1]
            try:
                b.bind(("127.0.0.1", base + 1))
            except OSError:
                continue
        break
    argv = ["px4-sim", str(scenario), "--instance", str(base - 4560), "--cpu", str(cpu), "--connect-timeout", "0.2"]
    assert main(argv) == 1  # nobody connects
    assert pinned == [{cpu}]
    assert "did not connect" in capsys.readouterr().err
