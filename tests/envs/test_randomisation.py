"""Domain randomisation: values drawn per env inside the task's ranges; a drawn vehicle flies exactly as a
QuadrotorBatch built with those parameters; latency delays the applied action by whole steps; wind is horizontal
at the drawn speed; observation and IMU noise have the configured deviations (against the noise model's formula)."""

from __future__ import annotations

import dataclasses

import gymnasium
import numpy as np

import cufund.envs  # noqa: F401
from cufund.control import policy_observation as po
from cufund.sensors.imu import imu_preset
from cufund.vehicle import QuadrotorBatch, presets


def test_draws_lie_in_the_ranges_and_spread() -> None:
    rnd = {
        "mass": [0.8, 1.2],
        "inertia": [0.9, 1.1],
        "motor_constant": [0.95, 1.05],
        "motor_lag": [0.5, 2.0],
        "drag": [0.0, 2.0],
        "latency_steps": [0, 3],
        "wind_mps": [0.5, 1.5],
    }
    v = gymnasium.make_vec("cufund/Hover-v0", num_envs=512, randomisation=rnd)
    v.reset(seed=2)
    s = v._core.drawn_scales
    for col, key in enumerate(["mass", "inertia", "motor_constant", "motor_lag", "drag"]):
        lo, hi = rnd[key]
        assert lo <= s[:, col].min() and s[:, col].max() <= hi
        assert s[:, col].max() - s[:, col].min() > 0.9 * (hi - lo)  # 512 uniform draws cover the range
    lat = v._core.latency
    assert set(lat.tolist()) == {0, 1, 2, 3}
    speed = np.linalg.norm(v.batch.wind_W, axis=1)
    assert np.all(v.batch.wind_W[:, 2] == 0.0)
    assert 0.5 <= speed.min() and speed.max() <= 1.5 + 1e-12


def test_a_drawn_vehicle_flies_as_a_batch_with_its_parameters() -> None:
    v = gymnasium.make_vec(
        "cufund/Hover-v0",
        num_envs=1,
        randomisation={
            "mass": [1.3, 1.3],
            "inertia": [0.7, 0.7],
            "motor_constant": [1.1, 1.1],
            "motor_lag": [2.0, 2.0],
            "drag": [1.5, 1.5],
        },
    )
    v.reset(seed=0)
    p = presets.crazyflie()
    drawn = dataclasses.replace(
        p,
        mass=p.mass * 1.3,
        inertia=tuple(tuple(x * 0.7 for x in row) for row in p.inertia),
        k_f=p.k_f * 1.1,
        tau_m=p.tau_m * 2.0,
        rotor_drag_xy=p.rotor_drag_xy * 1.5,
        rotor_drag_z=p.rotor_drag_z * 1.5,
        body_drag=tuple(x * 1.5 for x in p.body_drag),
        max_integration_step=0.01,
    )
    ref = QuadrotorBatch(drawn, 1)
    b = v.batch
    for name in ("p", "v", "q", "w", "rotor_speeds"):
        getattr(ref, name)[:] = getattr(b, name)
    # the rotor speed at rest after reset is the drawn vehicle's hover speed
    np.testing.assert_allclose(b.rotor_speeds[0], np.sqrt(drawn.mass * drawn.gravity / (4 * drawn.k_f)), rtol=1e-15)
    hover = np.sqrt(p.mass * p.gravity / (4 * p.k_f))  # the action mapping stays the nominal vehicle's
    span = min(p.rotor_speed_max - hover, hover - p.rotor_speed_min)
    for a in np.random.default_rng(1).uniform(-0.2, 0.2, (20, 1, 4)):
        v.step(a)
        ref.step(0.01, hover + a * span)
        for name in ("p", "v", "q", "w", "rotor_speeds"):
            np.testing.assert_array_equal(getattr(b, name), getattr(ref, name))


def test_latency_applies_the_action_given_steps_before() -> None:
    acts = np.random.default_rng(3).uniform(-0.5, 0.5, (15, 1, 4))
    late = gymnasium.make_vec("cufund/Hover-v0", num_envs=1, randomisation={"latency_steps": [3, 3]})
    now = gymnasium.make_vec("cufund/Hover-v0", num_envs=1)
    late.reset(seed=9)
    now.reset(seed=9)
    delayed = np.concatenate([np.zeros((3, 1, 4)), acts[:-3]])
    for a, d in zip(acts, delayed, strict=True):
        o_late, *_ = late.step(a)
        o_now, *_ = now.step(d)
        np.testing.assert_array_equal(late.batch.p, now.batch.p)
        np.testing.assert_array_equal(o_late[0, -4:], a[0].astype(np.float32))  # a_prev: the action given


def test_observation_noise_has_the_drawn_deviation() -> None:
    n = 4000
    v = gymnasium.make_vec(
        "cufund/Hover-v0",
        num_envs=n,
        randomisation={"position_noise_m": [0.1, 0.1], "velocity_noise_mps": [0.05, 0.05]},
    )
    obs, _ = v.reset(seed=0)
    b = v.batch
    exact = po.build_observation(np.tile([0.0, 0.0, 1.0], (n, 1, 1)), b.p, b.v, b.q, b.w, np.zeros((n, 4)))
    err = obs.astype(np.float64) - exact
    sl = po.slices(1)
    assert abs(err[:, sl["targets"]].std() - 0.1) < 0.005
    assert abs(err[:, sl["v_W"]].std() - 0.05) < 0.0025
    assert np.all(err[:, sl["R_WB"]] == 0)


def test_imu_noise_follows_the_gyro_noise_model() -> None:
    n = 4000
    v = gymnasium.make_vec("cufund/Hover-v0", num_envs=n, imu_noise=True, imu="bmi088")
    obs, _ = v.reset(seed=0)
    white, walk, turn_on = (x[0] for x in imu_preset("bmi088").gyro.per_axis(3))
    dt = v.config.dt
    err = obs[:, po.slices(1)["w_B"]].astype(np.float64) - v.batch.w
    # first sample: turn-on bias + white noise (the walk starts at zero)
    want = np.sqrt(turn_on**2 + white**2 / dt)
    assert abs(err.std() / want - 1.0) < 0.03
    off = gymnasium.make_vec("cufund/Hover-v0", num_envs=n)
    o2, _ = off.reset(seed=0)
    np.testing.assert_array_equal(o2[:, po.slices(1)["w_B"]], off.batch.w.astype(np.float32))


def test_gyro_turn_on_bias_is_held_and_the_walk_grows_as_the_noise_model() -> None:
    """The parts the first sample cannot show: the turn-on bias is held over the episode and the bias random walk
    has variance k walk^2 dt after k steps (cufund.sensors.noise's discretisation); no white noise here."""
    from cufund import _core
    from cufund.envs.vector_env import task_params

    n, k, walk, turn_on = 4000, 20, 0.5, 0.02
    v = gymnasium.make_vec("cufund/Hover-v0", num_envs=n)
    t = task_params(v.config)
    t.imu_noise, t.gyro_white, t.gyro_walk, t.gyro_turn_on = True, 0.0, walk, turn_on
    core = _core.envs.EnvBatch(v.params.to_core(), t, n)
    w = po.slices(1)["w_B"]
    obs = core.reset(0)
    bias = obs[:, w].astype(np.float64) - core.batch.w
    assert abs(bias.std() / turn_on - 1.0) < 0.03
    for _ in range(k):
        obs, _, term, trunc = core.step(np.zeros((n, 4)))
        assert not (term.any() or trunc.any())
    drift = obs[:, w].astype(np.float64) - core.batch.w - bias
    assert abs(drift.std() / (walk * np.sqrt(k * v.config.dt)) - 1.0) < 0.05
