"""A sensor type is a property of its registration: a test registers a new type (its message and its mounting key)
and a kind of it, flies it in a scenario, and finds the declared message on its topic and the mounting applied; the
schema knows the new key from the registry alone (no table of its own)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cufund import ConfigError, ScenarioConfig
from cufund.core.build_context import BuildContext
from cufund.core.components import Sensor
from cufund.core.messages import Imu, Message, Odometry, Pose, message
from cufund.core.registry import Kind, SensorType, extrinsic_keys, register, sensor_type, unregister
from cufund.scenarios.build import build_simulation, run_built


@message
class Range(Message):
    """Height of the rangefinder's mounting point above z = 0 [m] (a test's own message type)."""

    t: float
    height_m: float


@dataclasses.dataclass(frozen=True)
class RangeParams:
    rate_hz: float = 50.0
    wrong_message: bool = False
    """Publish an Imu instead of a Range (the bus must refuse it)."""


class Rangefinder(Sensor):
    name = "rangefinder"

    def __init__(self, params: RangeParams, t_BR: np.ndarray, topic: str) -> None:
        self.params, self.rate_hz, self.topic, self.t_BR = params, params.rate_hz, topic, t_BR

    def measure(self, t: float, truth: Odometry) -> Message:
        if self.params.wrong_message:
            return Imu(t, np.zeros(3), np.zeros(3))
        w, x, y, z = truth.q_WB
        R_WB_row_z = np.array([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)])
        p_WR_z = truth.p_W[2] + R_WB_row_z @ self.t_BR
        return Range(t, float(p_WR_z))


def _build(p: RangeParams, ctx: BuildContext) -> list[Sensor]:
    T = ctx.part.extrinsic
    return [Rangefinder(p, np.zeros(3) if T is None else np.asarray(T.t), ctx.part.topic)]


@pytest.fixture
def rangefinder():
    register(SensorType("rangefinder", Range, "T_BR", "a downward range to the ground (test)"))
    register(Kind("sensor", "test_rangefinder", RangeParams, _build, doc="test", sensor_type="rangefinder"))
    try:
        yield
    finally:
        unregister("sensor", "test_rangefinder")
        unregister("sensor_type", "rangefinder")


A = math.radians(25.0)
T_BR = {"p": [0.12, -0.05, -0.04], "q": [math.cos(A / 2), 0.0, math.sin(A / 2), 0.0]}


def _scenario(**sensor: object) -> ScenarioConfig:
    return ScenarioConfig.from_dict(
        {
            "name": "range",
            "sensors": {"range": {"kind": "test_rangefinder", **sensor}},
            "trajectory": {"waypoints": [[0.0, 0.0, 0.4], [0.8, 0.3, 0.6]], "hover_s": 0.2, "move_v_max": 2.0},
            "duration": 3.0,
        }
    )


def test_a_registered_sensor_type_flies_with_its_message_and_mounting(rangefinder):
    cfg = _scenario(T_BR=T_BR)
    spec = cfg.sensors["range"]
    assert spec.sensor_type == "rangefinder" and spec.topic.type is Range  # typed from the registration
    assert spec.extrinsic.t == (0.12, -0.05, -0.04)
    assert "T_BR" in cfg.to_dict()["sensors"]["range"]  # written back under the type's key
    assert ScenarioConfig.from_dict(cfg.to_dict()) == cfg

    built = build_simulation(cfg)
    run = run_built(built)
    msgs = built.simulator.bus.recorded("/sensors/range")
    assert len(msgs) >= 100 and all(type(m) is Range for m in msgs)
    got = run.result.topics["/sensors/range"]
    states = run.result.states
    i = np.searchsorted(states["t"], got["t"])
    np.testing.assert_array_equal(states["t"][i], got["t"])  # every reading at a recorded state
    q = states["q_WB"][i]
    R = Rotation.from_quat(np.c_[q[:, 1:], q[:, :1]]).as_matrix()  # scipy's [x, y, z, w]
    expect = states["p_W"][i, 2] + R[:, 2, :] @ np.array(T_BR["p"])
    assert np.max(expect) > 0.3  # it flew: the readings cover the climb
    np.testing.assert_allclose(got["height_m"], expect, rtol=0, atol=1e-12)


def test_the_topic_refuses_another_message_type(rangefinder):
    with pytest.raises(TypeError, match="carries Range messages, got Imu"):
        run_built(build_simulation(_scenario(wrong_message=True)))


def test_extrinsic_keys_come_from_the_registry(rangefinder):
    assert {"T_BI", "T_BL", "T_BC", "T_BR"} <= extrinsic_keys()
    assert sensor_type("rangefinder").extrinsic_key == "T_BR"
    with pytest.raises(ConfigError, match=r"sensors.range.T_BL: a rangefinder sensor's extrinsic is T_BR, got T_BL"):
        _scenario(T_BL=T_BR)
    with pytest.raises(ConfigError, match=r"unknown key 'T_BQ' in sensors.range"):
        _scenario(T_BQ=T_BR)  # no sensor type declares it
    with pytest.raises(ConfigError, match=r"sensors.imu.T_BR: a imu sensor's extrinsic is T_BI, got T_BR"):
        ScenarioConfig.from_dict({"sensors": {"imu": {"kind": "icm42688p", "T_BR": T_BR}}})
    with pytest.raises(ConfigError, match=r"sensors.range.T_BR.q must be a unit quaternion"):
        _scenario(T_BR={"q": [1, 1, 0, 0]})


def test_the_key_is_unknown_once_the_type_is_gone():
    assert "T_BR" not in extrinsic_keys()
    with pytest.raises(ConfigError, match=r"unknown key 'T_BR' in sensors.imu"):
        ScenarioConfig.from_dict({"sensors": {"imu": {"kind": "icm42688p", "T_BR": T_BR}}})


@pytest.mark.parametrize("key", ["BR", "T_R", "T_XR", "T_B", "T_B1", "t_br", ""])
def test_a_malformed_extrinsic_key_is_refused_at_registration(key):
    with pytest.raises(ValueError, match="SensorType.extrinsic_key must be T_B<X>"):
        SensorType("sonar", Range, key)


def test_a_sensor_kind_names_a_registered_type():
    with pytest.raises(ValueError, match="its sensor_type 'sonar' is not a registered SensorType"):
        register(Kind("sensor", "test_sonar", RangeParams, _build, sensor_type="sonar"))
    with pytest.raises(ValueError, match="must name a registered SensorType for a sensor kind"):
        Kind("sensor", "test_sonar", RangeParams, _build)
    with pytest.raises(ValueError, match="SensorType.message must be a message class"):
        SensorType("sonar", "Range")
    with pytest.raises(ValueError, match=r"used by the sensor kinds .*icm42688p"):
        unregister("sensor_type", "imu")
    with pytest.raises(ValueError, match="a sensor type named 'imu' is registered already"):
        register(SensorType("imu", Range, "T_BI"))


def test_the_sensor_template_registers_as_a_pose_kind():
    from cufund.templates.sensor_template import KINDS

    for k in KINDS:
        register(k)
    try:
        cfg = ScenarioConfig.from_dict(
            {"sensors": {"mocap": {"kind": "my_position_sensor", "sigma_m": 0.0, "rate_hz": 50.0}}, "duration": 1.0}
        )
        assert cfg.sensors["mocap"].topic.type is Pose and cfg.sensors["mocap"].sensor_type == "pose"
        run = run_built(build_simulation(cfg))
        got = run.result.topics["/sensors/mocap"]
        states = run.result.states
        assert 50 <= len(got["t"]) <= 51
        i = np.searchsorted(states["t"], got["t"])
        np.testing.assert_array_equal(got["p_W"], states["p_W"][i])  # sigma 0: the true position
    finally:
        for k in KINDS:
            unregister(k.group, k.name)
