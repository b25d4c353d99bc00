"""The controller kind ``policy``: an exported ONNX policy refused when its manifest does not match (naming the
field), its observation built from the estimate and the gyro (never truth) as policy_observation defines it, its
actions turned into commands as the environments' formulas say, and a scenario built with it."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

from cufund.control import policy_observation as po
from cufund.control.policy_action import ActionDecoder
from cufund.control.policy_controller import PolicyController, PolicyControllerParams, load_policy
from cufund.control.policy_manifest import OBS_LAYOUT_VERSION, PolicyManifest
from cufund.core.bus import Bus, BusView
from cufund.core.config import ConfigError
from cufund.core.messages import Imu, Odometry, Topics, TrajectorySetpoint
from cufund.envs.export_onnx import export_mlp, read_manifest
from cufund.vehicle import presets


def _manifest(**kw: Any) -> PolicyManifest:
    base: dict[str, Any] = dict(
        task="cufund/Hover-v0",
        action_mode="rotor_speeds",
        rate_hz=100.0,
        n_targets=1,
        target_dim=3,
        obs_dim=po.observation_size(1, 3),
        act_dim=4,
        vehicle="crazyflie",
        seed=0,
    )
    base.update(kw)
    return PolicyManifest(**base)


def _export(tmp_path, manifest: PolicyManifest, W=None, b=None, mean=None, var=None):
    rng = np.random.default_rng(1)
    d = manifest.obs_dim
    W0 = rng.normal(size=(d, 16)).astype(np.float32) * 0.3 if W is None else W
    b0 = np.zeros(16, np.float32)
    W1 = rng.normal(size=(16, 4)).astype(np.float32) * 0.3
    b1 = np.zeros(4, np.float32) if b is None else b
    layers = [(W0, b0), (W1, b1)] if W is None else [(W, b)]
    return export_mlp(tmp_path / "policy.onnx", layers, manifest, obs_mean=mean, obs_var=var), layers


def test_onnx_graph_is_the_mlp_it_was_given(tmp_path):
    """The exported graph computes clip(tanh(z W0 + b0) W1 + b1) on the standardised observation (numpy)."""
    import onnxruntime as ort

    m = _manifest()
    rng = np.random.default_rng(2)
    mean = rng.normal(size=m.obs_dim).astype(np.float32)
    var = rng.uniform(0.5, 2.0, m.obs_dim).astype(np.float32)
    path, layers = _export(tmp_path, m, mean=mean, var=var)
    obs = rng.normal(size=(100, m.obs_dim)).astype(np.float32) * 3
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    got = sess.run(["action"], {"obs": obs})[0]
    z = np.clip((obs.astype(np.float64) - mean) / (np.sqrt(var.astype(np.float64)) + 1e-8), -5, 5)
    h = np.tanh(z @ layers[0][0] + layers[0][1])
    want = np.clip(h @ layers[1][0] + layers[1][1], -1, 1)
    np.testing.assert_allclose(got, want, rtol=0, atol=2e-6)
    assert read_manifest(path)["obs_layout_version"] == OBS_LAYOUT_VERSION
    assert PolicyManifest.read(tmp_path / "policy.yaml") == m


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        ("obs_layout_version: 1", "obs_layout_version"),
        ("obs_layout: cufund.policy_observation", "obs_layout"),
        ("obs_dim: 22", "obs_dim"),
        ("act_dim: 4", "act_dim"),
        ("action_mode: rotor_speeds", "action_mode"),
        ("format: cufund-policy/1", "format"),
    ],
)
def test_refuses_a_manifest_that_does_not_match_naming_the_field(tmp_path, edit, field):
    _export(tmp_path, _manifest())
    y = tmp_path / "policy.yaml"
    text = y.read_text()
    key, value = edit.split(": ")
    bad = {
        "obs_layout_version": str(OBS_LAYOUT_VERSION + 1),
        "obs_layout": "someone.elses_layout",
        "obs_dim": "25",
        "act_dim": "3",
        "action_mode": "jetpack",
        "format": "cufund-policy/2",
    }[key]
    assert f"{key}: " in text
    lines = [f"{key}: {bad}" if ln.startswith(f"{key}: ") else ln for ln in text.splitlines()]
    y.write_text("\n".join(lines) + "\n")
    with pytest.raises(ConfigError, match=field):
        load_policy(tmp_path)


def test_refuses_another_vehicle_a_missing_manifest_and_a_wrong_input_or_output_size(tmp_path):
    _export(tmp_path, _manifest())
    with pytest.raises(ConfigError, match="vehicle is 'crazyflie'.*cu_astro"):
        load_policy(tmp_path, vehicle="cu_astro")
    load_policy(tmp_path, vehicle="crazyflie")
    # a network whose input is not the manifest's obs_dim
    other = tmp_path / "other"
    other.mkdir()
    m2 = _manifest(n_targets=2, obs_dim=po.observation_size(2, 3))
    _export(other, m2)
    (other / "policy.yaml").write_text((tmp_path / "policy.yaml").read_text())
    with pytest.raises(ConfigError, match="input"):
        load_policy(other)
    # a network whose output is not the manifest's act_dim (it would fly nothing: every action is refused)
    three = tmp_path / "three"
    three.mkdir()
    rng = np.random.default_rng(3)
    m3 = dataclasses.replace(_manifest(), act_dim=3)
    export_mlp(three / "policy.onnx", [(rng.normal(size=(m3.obs_dim, 3)).astype(np.float32), np.zeros(3))], m3)
    (three / "policy.yaml").write_text((tmp_path / "policy.yaml").read_text())
    with pytest.raises(ConfigError, match="output.*act_dim=4"):
        load_policy(three)
    (tmp_path / "policy.yaml").unlink()
    with pytest.raises(ConfigError, match="policy.yaml"):
        load_policy(tmp_path)
    with pytest.raises(ConfigError, match="no exported policy"):
        load_policy(tmp_path / "nowhere")
    with pytest.raises(ConfigError, match="controller.model"):
        PolicyControllerParams(model="")
    with pytest.raises(ConfigError, match="controller.targets"):
        PolicyControllerParams(model="x", targets="gps")


def _step(ctrl: PolicyController, bus: Bus, t: float) -> BusView:
    view = BusView(bus, ctrl.name, ctrl.inputs + ctrl.optional_inputs, ctrl.outputs, deny_truth=True)
    ctrl.setup(view)
    return view


def test_observation_from_estimate_and_gyro_and_rotor_speed_command(tmp_path):
    """A one-layer net with W = 0 gives the action clip(b): the command is omega_hover + b * span (the analytic
    hover speed sqrt(m g / 4 k_f)); the observation is po.build_observation of the estimate, the IMU's gyro
    rotated into the body and the previous action; no /truth/ topic is read."""
    m = _manifest()
    b = np.array([0.5, -0.25, 2.0, 0.0], np.float32)  # 2.0 clips to 1
    _export(tmp_path, m, W=np.zeros((m.obs_dim, 4), np.float32), b=b)
    sess, manifest, _ = load_policy(tmp_path)
    params = presets.crazyflie()
    q_BI = (math.cos(0.25), 0.0, 0.0, math.sin(0.25))  # IMU yawed by 0.5 rad
    ctrl = PolicyController(sess, manifest, ActionDecoder(params, manifest), q_BI=q_BI, gyro_cutoff_hz=0.0)
    ctrl.use_estimator(True)
    ctrl.active_state_topic = Topics.ESTIMATE
    bus = Bus()
    view = _step(ctrl, bus, 0.0)
    est = Odometry(0.0, np.array([0.1, -0.2, 0.9]), np.array([0.3, 0.0, -0.1]), np.array([1.0, 0, 0, 0]), np.zeros(3))
    w_I = np.array([0.2, -0.1, 0.4])
    bus.publish(Topics.ESTIMATE, est)
    bus.publish(Topics.IMU, Imu(0.0, np.array([0, 0, 9.81]), w_I))
    bus.publish(
        Topics.TRAJECTORY_SETPOINT, TrajectorySetpoint(0.0, np.array([0.0, 0.0, 1.0]), *(np.zeros(3),) * 3, 0, 0)
    )
    ctrl.step(0.0, view)
    cmd = bus.latest(Topics.ACTUATOR_COMMAND)
    w_hover = math.sqrt(params.mass * params.gravity / (4 * params.k_f))
    span = min(params.rotor_speed_max - w_hover, w_hover - params.rotor_speed_min)
    np.testing.assert_allclose(cmd.rotor_speeds, w_hover + np.clip(b, -1, 1) * span, rtol=1e-6)
    c, s = math.cos(0.5), math.sin(0.5)
    w_B = np.array([c * w_I[0] - s * w_I[1], s * w_I[0] + c * w_I[1], w_I[2]])
    want = po.build_observation(np.array([[0.0, 0.0, 1.0]]), est.p_W, est.v_W, est.q_WB, w_B, np.zeros(4))
    np.testing.assert_allclose(ctrl.last_obs, want, rtol=0, atol=1e-7)
    assert not any(t.startswith("/truth") for t in view.reads)
    # the next observation carries this action as a_prev
    ctrl.step(0.01, view)
    np.testing.assert_allclose(ctrl.last_obs[-4:], np.clip(b, -1, 1), rtol=0, atol=1e-7)


def test_thrust_rates_and_velocity_decoding_match_the_env_formulas():
    params = presets.cu_astro()
    m = _manifest(action_mode="thrust_rates", vehicle="cu_astro", max_rate=8.0)
    d = ActionDecoder(params, m)
    thrust, w = d.thrust_rates(np.array([0.1, 0.5, -1.0, 0.25]))
    assert thrust == pytest.approx(params.mass * params.gravity * 1.1)
    np.testing.assert_allclose(w, [4.0, -8.0, 2.0])
    thrust, _ = d.thrust_rates(np.array([1.0, 0, 0, 0]))
    assert thrust <= 4 * params.k_f * params.rotor_speed_max**2
    # velocity: level and at the setpoint speed, the thrust holds the weight and the rates are zero
    dv = ActionDecoder(params, dataclasses.replace(m, action_mode="velocity"))
    thrust, w = dv.velocity(
        np.array([0.5, 0.0, 0.0, 0.0]), np.array([0.5 * m.max_speed, 0, 0]), np.array([1.0, 0, 0, 0])
    )
    assert thrust == pytest.approx(params.mass * params.gravity)
    np.testing.assert_allclose(w, 0.0, atol=1e-12)
    # asked to speed up along +x, a level vehicle pitches nose down (positive body-y rate in FLU)
    _, w = dv.velocity(np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3), np.array([1.0, 0, 0, 0]))
    assert w[1] > 0 and abs(w[0]) < 1e-12


def test_a_scenario_flies_the_policy_kind_on_the_estimate_through_the_rate_loop(tmp_path):
    """square_mocap (IMU, motion capture with 8 ms latency, the IMU propagator) with ``controller: {kind: policy}`` and a thrust_rates network that always asks for the hover
    thrust m g and zero body rates: the scenario builds the policy at its 100 Hz and the rate loop at the scenario's
    rate_hz, the policy reads the estimate and the IMU (no truth), and the vehicle, on the ground at the start,
    neither climbs away nor tips over in 3 s (the rate loop holds it level)."""
    from cufund.control.rate_control import RateController
    from cufund.scenarios import load_scenario
    from cufund.scenarios.build import build_simulation, run_built

    m = _manifest(action_mode="thrust_rates", vehicle="cu_astro")
    _export(tmp_path, m, W=np.zeros((m.obs_dim, 4), np.float32), b=np.zeros(4, np.float32))
    cfg = load_scenario("square_mocap", [f"controller={{kind: policy, model: {tmp_path}}}", "duration=3.0"])
    built = build_simulation(cfg)
    run = run_built(built)
    assert (run.metrics["status"], run.metrics["message"]) == ("timeout", "duration elapsed")
    pc = [c for c in built.simulator.components if isinstance(c, PolicyController)]
    rc = [c for c in built.simulator.components if isinstance(c, RateController)]
    assert len(pc) == 1 and len(rc) == 1
    assert pc[0].rate_hz == 100.0 and rc[0].rate_hz == cfg.rates.rate_hz
    assert pc[0].active_state_topic == Topics.ESTIMATE and pc[0].use_gyro and rc[0].use_gyro
    assert pc[0].last_action is not None  # it ran
    p = np.asarray(run.result.states["p_W"])
    assert np.all(np.abs(p[:, :2]) < 0.2) and np.all(p[:, 2] < 0.5), (p.min(axis=0), p.max(axis=0))


def test_a_timed_reference_policy_sees_the_setpoint_extrapolated_ahead(tmp_path):
    """A policy trained on a timed reference (lookahead_s in policy.yaml) gets, in target block k, the setpoint
    moved k * lookahead_s ahead at its velocity and acceleration (p + v tau + a tau^2 / 2, by hand here), as the
    environment built it in training; without lookahead_s every block is the setpoint itself."""
    tau = 0.25
    for lookahead in (tau, 0.0):
        m = _manifest(n_targets=3, obs_dim=po.observation_size(3, 3), lookahead_s=lookahead)
        _export(tmp_path, m)
        sess, manifest, _ = load_policy(tmp_path)
        assert manifest.lookahead_s == lookahead
        ctrl = PolicyController(sess, manifest, ActionDecoder(presets.crazyflie(), manifest))
        ctrl.active_state_topic = Topics.ESTIMATE
        bus = Bus()
        view = _step(ctrl, bus, 0.0)
        p_V = np.array([0.2, 0.1, 1.2])
        bus.publish(Topics.ESTIMATE, Odometry(0.0, p_V, np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3)))
        p, v, a = np.array([1.0, 2.0, 1.5]), np.array([0.5, -1.0, 0.0]), np.array([2.0, 0.0, -4.0])
        bus.publish(Topics.TRAJECTORY_SETPOINT, TrajectorySetpoint(0.0, p, v, a, np.zeros(3), 0.0, 0.0))
        ctrl.step(0.0, view)
        blocks = ctrl.last_obs[:9].reshape(3, 3)
        for k in range(3):
            t = k * lookahead
            want = np.array([p[j] + v[j] * t + a[j] * t * t / 2 for j in range(3)]) - p_V
            np.testing.assert_allclose(blocks[k], want, rtol=0, atol=1e-6)


def test_a_negative_lookahead_is_refused_naming_the_field():
    with pytest.raises(ConfigError, match="lookahead_s"):
        _manifest(lookahead_s=-0.1)


def test_a_timed_reference_policy_is_refused_on_the_scenarios_waypoints(tmp_path):
    """targets: waypoints feeds the next waypoints, which a timed-reference policy (lookahead_s > 0) never saw: its
    blocks were a moving point and its extrapolations. Refused at build time, naming the key; an untimed policy
    flies them."""
    wp = ((0.0, 0.0, 1.0), (1.0, 0.0, 1.0), (1.0, 1.0, 1.0))
    for lookahead in (0.2, 0.0):
        m = _manifest(n_targets=3, obs_dim=po.observation_size(3, 3), lookahead_s=lookahead)
        _export(tmp_path, m)
        sess, manifest, _ = load_policy(tmp_path)
        decoder = ActionDecoder(presets.crazyflie(), manifest)
        if lookahead > 0:
            with pytest.raises(ConfigError, match="controller.targets: waypoints.*lookahead_s 0.2"):
                PolicyController(sess, manifest, decoder, targets="waypoints", waypoints=wp)
            PolicyController(sess, manifest, decoder, targets="setpoint")
        else:
            PolicyController(sess, manifest, decoder, targets="waypoints", waypoints=wp)


def test_a_gates_policy_is_refused_at_build_time(tmp_path):
    """A Gates-v0 policy's target blocks carry the gate normal (target_dim 6); the controller builds positions only:
    refused when built, naming target_dim (before, it was built and its first step failed inside onnxruntime)."""
    m = _manifest(task="cufund/Gates-v0", n_targets=2, target_dim=6, obs_dim=po.observation_size(2, 6))
    _export(tmp_path, m)
    sess, manifest, _ = load_policy(tmp_path)
    with pytest.raises(ConfigError, match="target_dim is 6"):
        PolicyController(sess, manifest, ActionDecoder(presets.crazyflie(), manifest))
