"""The simulator core: every message delivered, exact event times at any rate, latency, topological order,
flight software on the estimate (never on truth), advancing from outside, logs replayed bit for bit."""

import numpy as np
import pytest

import cufund
from cufund import RunStatus, Simulator, Topics
from cufund.core.bus import TopicAccessError
from cufund.core.messages import Odometry
from cufund.scenarios import load_scenario
from cufund.scenarios.build import build_simulation, run_scenario
from cufund.sensors import CameraComponent, DepthCamera, ImuSensor, Lidar, LidarComponent, imu_preset
from cufund.sensors.camera import CameraIntrinsics
from cufund.sensors.patterns import mid360

NS = 1_000_000_000


def _hover(z=1.0, params=None):
    q = cufund.Quadrotor(params or cufund.vehicle.presets.cu_astro())
    q.hover([0.0, 0.0, z])
    return q


class Probe(cufund.Component):
    """Subscribes to topics and keeps (visible time, message) of everything it receives."""

    def __init__(self, topics, rate_hz, name="probe"):
        self.inputs, self.rate_hz, self.name = tuple(topics), rate_hz, name
        self.got = {str(t): [] for t in topics}

    def setup(self, bus):
        self.subs = {str(t): bus.subscribe(t) for t in self.inputs}

    def step(self, t, bus):
        for topic, sub in self.subs.items():
            self.got[topic] += sub.take_stamped()


def test_a_100_hz_reader_gets_every_200_hz_imu_sample_in_order_once():
    sim = Simulator(_hover())
    sim.add(ImuSensor(imu_preset("icm42688p"), seed=1))
    probe = sim.add(Probe([Topics.IMU], 100.0))
    sim.run(1.0)
    got = probe.got[Topics.IMU]
    stamps = [m.t for _, m in got]
    # 200 samples in 1 s; the one at t = 1 s is not run (the run ends there)
    assert stamps == [k / 200 for k in range(200)][: len(stamps)] and len(stamps) >= 199
    assert len(set(stamps)) == len(stamps)
    assert all(vis == m.t for vis, m in got)  # no latency: visible when measured


def test_camera_lidar_imu_and_physics_together_at_exact_times_and_latency_shifts_arrival():
    world = cufund.worlds.load("corridor")

    def run(camera_latency):
        quad = _hover(1.0)
        quad.state.p[:] = [5.0, 0.0, 1.0]
        sim = Simulator(quad, physics_rate_hz=1000)
        cam = DepthCamera(CameraIntrinsics.from_fov(32, 24, 1.2))
        sim.add(CameraComponent(cam, world, rate_hz=30.0, latency_s=camera_latency))
        sim.add(LidarComponent(Lidar(mid360()), world, rate_hz=100.0))
        sim.add(ImuSensor(imu_preset("ideal"), seed=0))
        probe = sim.add(Probe([Topics.DEPTH_IMAGE, Topics.POINT_CLOUD, Topics.IMU], 7.0))
        r = sim.run(1.0)
        return probe.got, r

    got, r = run(0.0)
    cam_t = [vis for vis, _ in got[Topics.DEPTH_IMAGE]]
    assert len(cam_t) >= 26  # the probe's last run is at 6/7 s
    assert cam_t == [(k * NS // 30) / NS for k in range(len(cam_t))]  # k/30 s to the nanosecond, no drift
    assert [m.t for _, m in got[Topics.DEPTH_IMAGE]] == cam_t
    lidar = got[Topics.POINT_CLOUD]
    assert [m.t for _, m in lidar] == pytest.approx([0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7], abs=1e-12)
    assert [vis for vis, _ in lidar] == pytest.approx([0.1 * (k + 1) for k in range(8)], abs=1e-12)  # at frame end
    assert [vis for vis, _ in got[Topics.IMU]] == [k / 200 for k in range(172)]  # up to the probe's last run
    assert r.states["t"].shape == (1001,)  # the physics grid stays 1 kHz: events split steps, not the record
    delayed, _ = run(0.0125)
    assert [vis for vis, _ in delayed[Topics.DEPTH_IMAGE]] == [
        (k * NS // 30 + 12_500_000) / NS for k in range(len(delayed[Topics.DEPTH_IMAGE]))
    ]
    assert [m.t for _, m in delayed[Topics.DEPTH_IMAGE]] == cam_t[: len(delayed[Topics.DEPTH_IMAGE])]


def _free_fall(z=100.0):
    import dataclasses

    params = dataclasses.replace(
        cufund.vehicle.presets.cu_astro(), body_drag=(0.0, 0.0, 0.0), rotor_drag_xy=0.0, rotor_drag_z=0.0
    )
    quad = cufund.Quadrotor(params)
    quad.state.p[:] = [0.0, 0.0, z]
    quad.state.rotor_speeds[:] = 0.0
    return quad


def _sample_truth(quad, rate_hz, duration, *others):
    """(t, truth read) at each step of a ``rate_hz`` truth reader run for ``duration`` [s] beside ``others``."""
    seen = []

    class Sample(cufund.Component):
        inputs, reads_truth = (Topics.TRUTH_ODOMETRY,), True

        def step(self, t, bus):
            seen.append((t, bus.latest(Topics.TRUTH_ODOMETRY)))

    sample = Sample()
    sample.rate_hz = rate_hz
    sim = Simulator(quad)
    for c in others:
        sim.add(c)
    sim.add(sample)
    sim.run(duration)
    return seen


def test_events_between_physics_nodes_see_the_exact_state():
    """Free fall sampled by a 300 Hz component: the truth it reads is the state at its exact event time."""
    quad = _free_fall()
    seen = _sample_truth(quad, 300.0, 0.5)
    g = quad.params.gravity
    for t, truth in seen:
        assert truth.t == t
        assert truth.p_W[2] == pytest.approx(100.0 - 0.5 * g * t * t, abs=1e-10)  # RK4 is exact here
    assert len(seen) == 150


def test_estimator_added_last_runs_before_its_readers_within_an_instant():
    built = build_simulation(load_scenario("square_mocap", {"duration": 3.0}))
    sim = built.simulator
    est = next(c for c in sim.components if isinstance(c, cufund.Estimator))
    sim.components.remove(est)
    sim.components.append(est)  # added last
    seen = []

    class Reader(cufund.Controller):
        name, rate_hz = "reader", 200.0

        def update(self, t, state, bus):
            seen.append((t, state.t))

    sim.add(Reader())
    sim.run(2.0)
    order = [s["name"] for s in sim.schedule]
    assert order.index("imu") < order.index("imu_propagator") < order.index("position_controller")
    assert order.index("imu_propagator") < order.index("reader")
    assert order.index("position_controller") < order.index("attitude_controller") < order.index("rate_controller")
    assert len(seen) > 300 and all(t == stamp for t, stamp in seen)  # the estimate of this instant, not the last


@pytest.fixture(scope="module", params=["pid", "geometric"])
def mocap(request):
    cfg = load_scenario("square_mocap", {"controller.kind": request.param})
    built = build_simulation(cfg)
    from cufund.scenarios.build import odometry_metrics, tracking_metrics

    r = built.simulator.run(
        cfg.duration, done=lambda t, s: t >= built.landing_after and s.p_W[2] < 0.02 and np.linalg.norm(s.v_W) < 0.05
    )
    m = {**tracking_metrics(r, built.context.tracking_path), **odometry_metrics(r)}
    return built.simulator, r, m


def test_square_on_a_10_hz_pose_source_plus_imu_propagation_meets_the_square_bounds(mocap):
    sim, r, m = mocap
    assert r.status is RunStatus.COMPLETED
    assert m["tracking_rmse_m"] <= 0.02 and m["tracking_max_m"] <= 0.05
    assert m["odometry_rmse_m"] <= 0.01
    views = sim.views
    rate_loop = views.get("rate_controller") or views["geometric_controller"]
    assert Topics.POSE not in rate_loop.reads  # the slow pose is never what the rate loop flies on
    assert Topics.IMU in rate_loop.reads
    if "rate_controller" in views:
        # (and the vehicle status, through which the failsafe supervisor's flight termination stops the rotors)
        assert rate_loop.reads == {Topics.IMU, Topics.RATE_SETPOINT, Topics.VEHICLE_STATUS}


def test_no_flight_software_reads_a_truth_topic_with_an_estimator(mocap):
    sim, _, _ = mocap
    by_name = {s.name: s.component for s in sim._slots}
    flight_software = [n for n, c in by_name.items() if not c.reads_truth]
    assert {"imu_propagator", "trajectory_follower"} <= set(flight_software)
    for name in flight_software:
        assert not any(t.startswith("/truth/") for t in sim.views[name].reads), name
    assert any(t.startswith("/truth/") for t in sim.views["imu"].reads)  # the sensor models do


def test_truth_is_refused_to_flight_software_once_an_estimator_is_configured():
    class Cheat(cufund.Component):
        name, rate_hz, inputs = "cheat", 50.0, (Topics.TRUTH_ODOMETRY,)

        def step(self, t, bus):
            bus.latest(Topics.TRUTH_ODOMETRY)

    built = build_simulation(load_scenario("square_mocap"))
    built.simulator.add(Cheat())
    with pytest.raises(ValueError, match="cheat reads ground truth"):
        built.simulator.reset()

    class Sneaky(cufund.Component):  # reads truth without declaring it
        name, rate_hz = "sneaky", 50.0

        def step(self, t, bus):
            bus.latest(Topics.TRUTH_ODOMETRY)

    built = build_simulation(load_scenario("square_mocap"))
    built.simulator.add(Sneaky())
    with pytest.raises(cufund.core.bus.TruthAccessError, match="sneaky read the ground-truth topic /truth/odometry"):
        built.simulator.run(0.1)


def test_undeclared_topics_and_wrong_message_types_are_refused():
    class Writer(cufund.Component):
        rate_hz, outputs = 10.0, (Topics.IMU,)

        def step(self, t, bus):
            bus.publish(Topics.IMU, Odometry(t, np.zeros(3), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3)))

    sim = Simulator(_hover())
    sim.add(Writer())
    with pytest.raises(TypeError, match="/sensors/imu carries Imu messages, got Odometry"):
        sim.run(0.1)

    class Undeclared(cufund.Component):
        rate_hz = 10.0

        def step(self, t, bus):
            bus.publish(Topics.IMU, None)

    sim = Simulator(_hover())
    sim.add(Undeclared())
    with pytest.raises(TopicAccessError, match="Undeclared published on /sensors/imu, which is not among its declared"):
        sim.run(0.1)


def test_published_arrays_are_read_only_and_unshared():
    p = np.zeros(3)
    sp = cufund.core.messages.TrajectorySetpoint(0.0, p, p[:], np.zeros(3), np.zeros(3), 0.0, 0.0)
    with pytest.raises(ValueError, match="read-only"):
        sp.p_W[0] = 1.0
    p2 = np.ones(3)
    view = p2[:]
    msg = cufund.core.messages.ActuatorCommand(0.0, view)
    p2[0] = 5.0  # the publisher changes its buffer after publishing a view of it ...
    assert msg.rotor_speeds[0] == 1.0  # ... and the message does not change


def test_a_zero_latency_cycle_is_named_and_a_latency_breaks_it():
    a_topic, b_topic = cufund.Topic("/a", object), cufund.Topic("/b", object)

    class Node(cufund.Component):
        def __init__(self, name, i, o):
            self.name, self.inputs, self.outputs, self.rate_hz = name, (i,), (o,), 100.0

        def step(self, t, bus):
            bus.publish(self.outputs[0], t)

    sim = Simulator(_hover())
    sim.add(Node("left", a_topic, b_topic))
    right = sim.add(Node("right", b_topic, a_topic))
    with pytest.raises(ValueError, match=r"zero-latency cycle: left -\[/b\]-> right -\[/a\]-> left"):
        sim.run(0.1)
    right.latency_s = 0.001
    assert sim.run(0.1).status is RunStatus.COMPLETED


def test_advance_to_and_step_continue_a_run_exactly_like_run():
    def build():
        return build_simulation(load_scenario("square_mocap", {"duration": 4.0})).simulator

    whole = build().run(2.0)
    sim = build()
    sim.reset()
    assert sim.advance_to(0.7351)
    assert sim.t == 0.735  # stops on the grid: the step to 0.736 is not split
    for _ in range(10):
        sim.step()
    assert sim.t == 0.745
    sim.advance_to(1.2)
    sim.advance_to(1.2)  # no-op
    sim.advance_to(2.0)
    assert sim.t == 2.0
    part = sim.result()
    n = min(len(part.states["t"]), len(whole.states["t"]))
    for k in whole.states:
        np.testing.assert_array_equal(part.states[k][:n], whole.states[k][:n])
    with pytest.raises(ValueError, match="must not be before"):
        sim.advance_to(1.0)


def test_a_full_queue_drops_the_oldest_and_counts_it():
    sim = Simulator(_hover())
    sim.add(ImuSensor(imu_preset("ideal")))

    class Slow(cufund.Component):
        name, rate_hz, inputs = "slow", 1.0, (Topics.IMU,)

        def setup(self, bus):
            self.sub = bus.subscribe(Topics.IMU, maxlen=50)

        def step(self, t, bus):
            self.last = self.sub.take()

    slow = sim.add(Slow())
    r = sim.run(1.5)
    # 200 samples before its run at 1 s (50 kept, 150 dropped), 99 more by the end (49 dropped)
    assert r.dropped == {"slow:/sensors/imu": 199}
    assert len(slow.last) == 50 and slow.last[0].t == pytest.approx(0.755) and slow.last[-1].t == 1.0


def test_run_mcap_matches_the_histories_and_a_replayed_estimator_is_bit_identical(tmp_path):
    from cufund.estimation.imu_propagator import ImuPropagator
    from cufund.logs import LogPlayer, McapLogger, read_mcap

    cfg = load_scenario("square_mocap", {"duration": 3.0})
    with McapLogger(tmp_path / "run.mcap") as log:
        run = run_scenario(cfg, logger=log)
    est = run.result.topics[Topics.ESTIMATE]
    logged = [rec for rec in read_mcap(tmp_path / "run.mcap") if rec.topic == Topics.ESTIMATE]
    assert len(logged) == len(est["t"]) > 500
    np.testing.assert_array_equal(np.array([r.message.p_W for r in logged]), est["p_W"])
    np.testing.assert_array_equal(np.array([r.message.t for r in logged]), est["t"])
    truth = [rec.message for rec in read_mcap(tmp_path / "run.mcap", topics=[Topics.TRUTH_ODOMETRY])]
    assert truth[0].t == 0.0 and len(truth) > 1000
    # open loop: the same estimator on the logged sensor topics, no physics
    imu = cfg.sensors["imu"].params
    replay = Simulator(None, record_topics=(Topics.ESTIMATE,))
    replay.add(LogPlayer(tmp_path / "run.mcap", topics=[Topics.IMU, Topics.POSE]))
    replay.add(ImuPropagator(imu.rate_hz, cfg.vehicle_params().gravity, imu.q_BI))
    out = replay.run(run.result.sim_time_s).topics[Topics.ESTIMATE]
    n = len(est["t"])
    assert len(out["t"]) >= n - 1
    m = min(n, len(out["t"]))
    for field in ("t", "p_W", "v_W", "q_WB", "w_B"):
        assert out[field][:m].tobytes() == est[field][:m].tobytes(), field


def test_truth_readers_see_the_state_at_their_instant_when_flight_software_runs_between_them():
    """Truth is snapshotted only before components that may read it; a 400 Hz reader between 1 kHz instants of
    software that cannot read it still sees the exact state at its own time."""
    quad = _free_fall()

    class Software(cufund.Component):  # no truth access: instants where only it runs need no snapshot
        rate_hz = 1000.0

        def step(self, t, bus):
            pass

    seen = _sample_truth(quad, 400.0, 0.25, Software())
    g = quad.params.gravity
    assert len(seen) == 100
    for t, truth in seen:
        assert truth.t == t
        assert truth.p_W[2] == pytest.approx(100.0 - 0.5 * g * t * t, abs=1e-10)


def test_done_gets_the_truth_of_its_node_also_when_it_keeps_it():
    """``done`` receives the state at each node (built lazily where no snapshot was published); one it keeps
    still holds that node's state after the run has moved on."""
    quad = _free_fall()
    kept, read = {}, {}

    def done(t, truth):
        k = round(t * 1000)
        assert isinstance(truth, Odometry) and truth.t == t
        if k % 50 == 0:
            kept[k] = truth  # read only after the run
        elif k % 50 == 25:
            read[k] = truth.p_W.copy()  # read now
        return False

    sim = Simulator(quad)
    result = sim.run(0.3, done=done)
    rows = {round(t * 1000): i for i, t in enumerate(result.states["t"])}
    assert len(kept) == 7 and len(read) == 6  # nodes 0, 50, ..., 300 (the last is checked too)
    for k, truth in kept.items():
        assert np.array_equal(truth.p_W, result.states["p_W"][rows[k]]), k
        assert np.array_equal(truth.q_WB, result.states["q_WB"][rows[k]]), k
    for k, p in read.items():
        assert np.array_equal(p, result.states["p_W"][rows[k]]), k
