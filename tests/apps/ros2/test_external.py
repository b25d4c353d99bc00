"""``ros2_external``: a scenario's estimator is a ROS 2 node in another process. It receives the motion-capture pose
the component publishes, answers each with a nav_msgs/Odometry of that pose, and the scenario's estimate is that
pose bit for bit; the truth is refused to it like to any flight software; a node that is not there is an error
naming it, not a hang."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from test_bridge import domain, finish, start_node

from cufund.apps.ros2.bridge import Ros2Timeout
from cufund.core.config import ConfigError
from cufund.scenarios.build import build_simulation, run_scenario
from cufund.scenarios.schema import ScenarioConfig, load_scenario


def _config(d: int, node: str, **external) -> ScenarioConfig:
    cfg = load_scenario("vehicle")
    data = cfg.to_dict()
    data["duration"] = 1.0
    data["estimator"] = {
        "kind": "ros2_external",
        "node": node,
        "domain_id": d,
        "rate_hz": 10.0,
        "timeout_s": 20.0,
        "reads": {"/sensors/pose": "/mocap/pose"},
        "writes": {"/estimator/odometry": "/odom"},
        **external,
    }
    return ScenarioConfig.from_dict(data, cfg.base_dir)


def test_an_external_estimator_node_gives_the_scenario_its_estimate(tmp_path):
    d = domain(5)
    node, out = start_node(tmp_path, d, "mocap_est", "--topics", "/clock", "--estimator", "/mocap/pose:/odom")
    run = run_scenario(_config(d, "mocap_est"))
    got = finish(node, out)
    est = run.result.topics["/estimator/odometry"]
    pose = run.result.topics["/sensors/pose"]
    assert len(got["received"]["/mocap/pose"]) == len(est["t"]) >= 5
    n = len(est["t"])
    np.testing.assert_array_equal(np.asarray(est["t"]), np.asarray(pose["t"])[:n])
    np.testing.assert_array_equal(np.asarray(est["p_W"]), np.asarray(pose["p_W"])[:n])
    np.testing.assert_array_equal(np.asarray(est["q_WB"]), np.asarray(pose["q_WB"])[:n])


def test_an_external_node_may_not_read_the_truth():
    cfg = _config(domain(6), "cheat", reads={"/truth/odometry": "/truth"})
    with pytest.raises(ConfigError, match="ground truth"):
        build_simulation(cfg)


def test_a_missing_external_node_is_an_error_naming_it():
    cfg = _config(domain(7), "absent", timeout_s=1.0)
    with pytest.raises(Ros2Timeout, match="absent"):
        run_scenario(cfg)


@pytest.mark.parametrize("name", ["odom", "/odom/", "/a//b", 3])
def test_a_ros2_name_dds_would_refuse_is_refused_with_the_scenario(name):
    # not at the run's start, where the participant's topic would raise ValueError
    with pytest.raises(ConfigError, match="ros2_external.writes./estimator/odometry must be an absolute ROS 2"):
        _config(domain(8), "n", writes={"/estimator/odometry": name})
