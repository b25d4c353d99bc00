"""The lockstep simulator: rates, ordering, state-topic resolution, run status, recording, determinism."""

import numpy as np
import pytest

import cufund
from cufund import RunStatus, Simulator, Topics
from cufund.templates.controller_template import MyController
from cufund.templates.estimator_template import MyEstimator
from cufund.templates.mapper_template import MyMapper
from cufund.templates.planner_template import MyPlanner
from cufund.templates.sensor_template import MyPositionSensor


class Counter(cufund.Component):
    def __init__(self, rate_hz, log, tag):
        self.rate_hz, self.log, self.tag = rate_hz, log, tag

    def step(self, t, bus):
        self.log.append((round(t, 9), self.tag))


def _quad(z=1.0):
    q = cufund.Quadrotor(cufund.vehicle.presets.cu_astro())
    q.hover([0, 0, z])
    return q


def test_components_run_at_their_rates_in_order():
    log = []
    sim = Simulator(_quad(), physics_rate_hz=1000)
    sim.add(Counter(100, log, "a"))
    sim.add(Counter(250, log, "b"))
    sim.run(0.1)
    assert sum(1 for _, tag in log if tag == "a") == 10
    assert sum(1 for _, tag in log if tag == "b") == 25
    assert log[0] == (0.0, "a") and log[1] == (0.0, "b")  # order of adding within a tick
    assert [t for t, tag in log if tag == "a"] == pytest.approx(np.arange(10) * 0.01)


def test_any_rate_runs_at_exact_times_and_bad_rates_are_named():
    log = []
    sim = Simulator(_quad(), physics_rate_hz=1000)
    sim.add(Counter(300, log, "x"))  # does not divide the physics rate: physics steps are split at its events
    sim.run(0.1)
    # event k at k/300 s rounded down to the nanosecond, computed from k (no drift)
    assert [t for t, _ in log] == [round((k * 10**9 // 300) / 1e9, 9) for k in range(30)]
    with pytest.raises(ValueError, match="physics_rate_hz"):
        Simulator(_quad(), physics_rate_hz=-1)
    with pytest.raises(ValueError, match="duration"):
        sim.run(float("nan"))
    with pytest.raises(ValueError, match=r"Counter\.rate_hz must be a finite number > 0"):
        sim.add(Counter(0.0, [], "y"))


def test_free_fall_crashes_and_holds_rotors_without_commands():
    sim = Simulator(_quad(z=3.0))
    sim.vehicle.state.rotor_speeds[:] = 0.0
    r = sim.run(3.0)
    assert r.status is RunStatus.CRASHED
    # fell from 3 m: contact after about sqrt(2 h / g) s
    assert r.sim_time_s == pytest.approx(np.sqrt(2 * 2.95 / 9.80665), abs=0.02)
    np.testing.assert_array_equal(r.states["rotor_speeds"], 0.0)


def test_hover_without_controller_holds_rotor_speeds_and_completes():
    sim = Simulator(_quad(z=2.0))
    r = sim.run(0.5)
    assert r.status is RunStatus.COMPLETED and r.sim_time_s == pytest.approx(0.5)
    assert r.states["t"].shape == (501,)
    np.testing.assert_allclose(r.states["p_W"][-1], [0, 0, 2.0], atol=1e-9)


def test_diverged_on_runaway():
    class Push(cufund.Component):
        rate_hz = 1000.0

        def __init__(self, quad):
            self.quad = quad

        def step(self, t, bus):
            self.quad.force_ext_W[:] = (1e9, 0.0, 0.0)

    q = _quad(z=2.0)
    sim = Simulator(q)
    sim.add(Push(q))
    r = sim.run(2.0)
    assert r.status is RunStatus.DIVERGED and "bounds" in r.message


def test_done_condition_and_timeout():
    sim = Simulator(_quad(z=2.0))
    r = sim.run(1.0, done=lambda t, s: t >= 0.25)
    assert r.status is RunStatus.COMPLETED and r.sim_time_s == pytest.approx(0.25)
    r = Simulator(_quad(z=2.0)).run(0.2, done=lambda t, s: False)
    assert r.status is RunStatus.TIMEOUT


def test_controller_uses_estimator_output_once_attached():
    p = cufund.vehicle.presets.cu_astro()
    sim = Simulator(_quad(z=1.0), record_topics=(Topics.ESTIMATE,))
    sim.add(MyPositionSensor(sigma_m=0.01, seed=3))
    sim.add(MyEstimator())
    ctrl = sim.add(MyController(p))
    planner = sim.add(MyPlanner())
    sim.add(MyMapper())
    r = sim.run(1.0)
    assert ctrl.active_state_topic == Topics.ESTIMATE and planner.active_state_topic == Topics.ESTIMATE
    assert r.topics[Topics.ESTIMATE]["p_W"].shape == (100, 3)
    # an explicit choice wins, but flight software may not fly on ground truth once an estimator is attached
    ctrl.state_topic = Topics.TRUTH_ODOMETRY
    with pytest.raises(
        ValueError, match="my_controller reads ground truth .*/truth/odometry.* estimator is configured"
    ):
        sim.run(0.01)
    ctrl.state_topic = None
    sim.add(MyEstimator())
    with pytest.raises(ValueError, match="state_topic must be set when several estimators"):
        sim.run(0.01)


def test_template_controller_hovers_on_ground_truth():
    p = cufund.vehicle.presets.cu_astro()
    sim = Simulator(_quad(z=1.0))
    ctrl = sim.add(MyController(p))
    r = sim.run(2.0)
    assert ctrl.active_state_topic == Topics.GROUND_TRUTH
    assert abs(r.states["p_W"][-1, 2] - 1.0) < 0.01


def test_same_seed_identical_histories_and_records():
    def once(seed):
        p = cufund.vehicle.presets.cu_astro()
        sim = Simulator(_quad(z=1.0), record_topics=(Topics.ACTUATOR_COMMAND,))
        sim.add(MyPositionSensor(sigma_m=0.02, seed=seed))
        sim.add(MyEstimator())
        sim.add(MyPlanner())  # holds the height first estimated (noisy): the seed matters
        sim.add(MyController(p))
        return sim.run(1.0)

    a, b, c = once(7), once(7), once(8)
    for k in a.states:
        np.testing.assert_array_equal(a.states[k], b.states[k])
    np.testing.assert_array_equal(
        a.topics[Topics.ACTUATOR_COMMAND]["rotor_speeds"], b.topics[Topics.ACTUATOR_COMMAND]["rotor_speeds"]
    )
    assert not np.array_equal(a.states["p_W"], c.states["p_W"])


def test_rejects_non_components():
    with pytest.raises(TypeError, match="Component"):
        Simulator(_quad()).add(object())
    with pytest.raises(TypeError, match="Quadrotor"):
        Simulator("quad")


def test_recorder_histories_in_result():
    from cufund.templates.recorder_template import MyRecorder

    p = cufund.vehicle.presets.cu_astro()
    sim = Simulator(_quad(z=1.0))
    sim.add(MyPlanner(radius=0.3))
    sim.add(MyController(p))
    sim.add(MyRecorder(rate_hz=50))
    r = sim.run(1.0)
    rec = r.recordings["setpoint_distance"]
    assert rec["t"].shape == (50,) and rec["t"][1] == pytest.approx(0.02)
    # the planner's first setpoint is where the vehicle starts, so the first distance is zero
    assert rec["distance_m"][0] == pytest.approx(0.0, abs=1e-12) and rec["distance_m"].max() > 0.01
