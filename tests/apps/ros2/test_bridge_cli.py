"""``cufund ros2`` and the scenario key ``ros2:``: validated into frozen data naming the field, kept in config.yaml;
a lockstep node that never answers exits 1 naming it (no traceback), bad input exits 2."""

from __future__ import annotations

import pytest

pytest.importorskip("cyclonedds")

from test_bridge import domain

from cufund.apps.cli import main
from cufund.core.config import ConfigError
from cufund.scenarios.build import build_simulation
from cufund.scenarios.schema import ScenarioConfig, load_scenario


def _with(ros2) -> ScenarioConfig:
    cfg = load_scenario("vehicle")
    data = cfg.to_dict()
    data["ros2"] = ros2
    return ScenarioConfig.from_dict(data, cfg.base_dir)


def test_the_ros2_key_round_trips_and_is_off_by_default():
    assert load_scenario("vehicle").ros2 is None
    cfg = _with({"domain_id": 7, "lockstep_nodes": ["a"], "topics": {"/sensors/imu": "/imu_raw"}})
    again = ScenarioConfig.from_dict(cfg.to_dict(), cfg.base_dir)
    assert again.ros2 == cfg.ros2 and again.ros2.params.domain_id == 7
    assert _with(True).ros2.params.domain_id == 0 and _with(False).ros2 is None


@pytest.mark.parametrize(
    "ros2, message",
    [
        ({"domain_id": 300}, "ros2.domain_id must be an integer in \\[0, 232\\]"),
        ({"domian_id": 1}, "unknown key 'domian_id' in ros2"),
        ({"topics": {"/sensors/imu": "imu"}}, "ros2.topics./sensors/imu must be an absolute ROS 2 topic name"),
        ({"commands": {"teleport": "/x"}}, "ros2.commands: unknown command 'teleport'"),
        ({"timeout_s": 0}, "ros2.timeout_s must be a number of seconds"),
        ({"lockstep_nodes": "n1"}, "ros2.lockstep_nodes must be a list"),
    ],
)
def test_bad_ros2_settings_name_the_field(ros2, message):
    with pytest.raises(ConfigError, match=message):
        _with(ros2)


def test_a_fleet_is_not_bridged():
    # each vehicle's scenario inherits the fleet's parts: three bridges on one domain, every goal to every vehicle
    cfg = load_scenario("fleet_survey")
    data = cfg.to_dict()
    data["ros2"] = {"domain_id": 9}
    with pytest.raises(ConfigError, match="ros2: the ROS 2 bridge serves one vehicle"):
        ScenarioConfig.from_dict(data, cfg.base_dir)


def test_a_topic_the_bridge_cannot_publish_is_refused_when_built():
    with pytest.raises(ConfigError, match="/sensors/lidarr cannot be published: not a topic of this scenario"):
        build_simulation(_with({"topics": {"/sensors/lidarr": "/points"}}))
    with pytest.raises(ConfigError, match="/vehicle/status cannot be published: no standard ROS 2 message"):
        build_simulation(_with({"topics": {"/vehicle/status": "/status"}}))


def test_cufund_ros2_exits_1_naming_a_silent_node_and_2_on_bad_input(tmp_path, capsys):
    args = ["ros2", "vehicle", "--set", "duration=1", "--no-log", "--timeout", "1"]
    assert main([*args, "--domain-id", str(domain(10)), "--lockstep-node", "ghost", "--out", str(tmp_path / "a")]) == 1
    err = capsys.readouterr().err
    assert "node(s) ghost did not announce themselves" in err and "Traceback" not in err
    assert main([*args, "--domain-id", "999", "--out", str(tmp_path / "b")]) == 2
    assert "ros2.domain_id must be an integer" in capsys.readouterr().err
