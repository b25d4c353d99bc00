"""LioEstimator (the simulator component) runs LioCore on what it reads from the bus, in time order."""

from types import SimpleNamespace

import numpy as np
import pytest

from cufund import Estimator
from cufund.core.messages import Imu, Topics
from cufund.estimation import FlatBodyMotion, LioCore, LioEstimator, LioParams, record_flight, replay
from cufund.geometry import Transform, yaw_of
from cufund.planning.minimum_snap import MinimumSnapTrajectory
from cufund.sensors import ImuModel, imu_preset
from cufund.sensors.calibration import after_calibration
from cufund.sensors.lidar import Lidar, mid360_params
from cufund.sensors.patterns import Mid360Pattern
from cufund.worlds import load


class _Queue:
    def __init__(self):
        self.items = []

    def take(self):
        items, self.items = self.items, []
        return items


class _Bus:
    def __init__(self):
        self.queues = {}
        self.published = []

    def subscribe(self, topic):
        return self.queues.setdefault(topic, _Queue())

    def publish(self, topic, message):
        self.published.append((topic, message))


def test_estimator_publishes_at_imu_rate_what_the_core_computes():
    T_BL = Transform(t=(0.05, 0.0, 0.05))
    traj = MinimumSnapTrajectory(np.array([[-3, -1.5, 1.5], [-2.2, -1.3, 1.6]]), v_max=1.5, a_max=2.0, t_start=1.1)
    motion = FlatBodyMotion(traj)
    rec = record_flight(
        motion,
        ImuModel(after_calibration(imu_preset("icm42688p")), seed=2),
        Lidar(Mid360Pattern(point_rate=60_000), mid360_params(seed=2), T_BL),
        load("imav2025_tunnel"),
        0.0,
        2.2,
    )
    st = motion.state(np.zeros(1))
    params = LioParams(T_BL=T_BL, p_WB0=tuple(st["p_W"][0]), pad_yaw=yaw_of(st["q_WB"][0]))
    est = LioEstimator(params)
    assert isinstance(est, Estimator) and est.rate_hz == 200.0
    assert (
        Topics.IMU in est.inputs
        and Topics.POINT_CLOUD in est.inputs
        and est.outputs == (Topics.ESTIMATE, Topics.ESTIMATOR_DIAGNOSTICS)
    )
    bus = _Bus()
    est.setup(bus)
    frames = list(rec.frames)
    outputs = []
    for t, f, w in zip(rec.t_imu, rec.acc_I, rec.gyr_I, strict=True):
        while frames and frames[0].t + frames[0].dt.max() <= t:  # a frame is published when it ends
            fr = frames.pop(0)
            bus.queues[Topics.POINT_CLOUD].items.append(SimpleNamespace(t=fr.t, dt=fr.dt, points_L=fr.points_L))
        bus.queues[Topics.IMU].items.append(Imu(t=t, f_I=f, w_I=w))
        out = est.estimate(t, bus)
        if out is not None:
            outputs.append(out)
    assert est.core.initialised and len(est.diagnostics) > 5
    diag = [m for topic, m in bus.published if topic == Topics.ESTIMATOR_DIAGNOSTICS]  # one per frame processed
    assert [d.t for d in diag] == [d.t for d in est.diagnostics]
    assert all(d.eigenvalues.shape == (6,) or d.skipped for d in diag)
    # One output per IMU sample from initialisation on, stamped with the sample times.
    assert [o.t for o in outputs] == list(rec.t_imu[rec.t_imu >= outputs[0].t])
    # The same data through the core directly gives the same estimate.
    _, at_imu = replay(LioCore(params), rec)
    ref = {o.t: o for o in at_imu}
    common = [o for o in outputs if o.t in ref]
    assert len(common) > 150
    last = common[-1]
    np.testing.assert_array_equal(last.p_W, ref[last.t].p_W)  # deterministic: bit-identical
    np.testing.assert_array_equal(last.q_WB, ref[last.t].q_WB)
    err = np.linalg.norm(last.p_W - motion.state(np.array([last.t]))["p_W"][0])
    assert err < 0.02


def test_run_on_log_reproduces_the_online_figures_and_writes_the_files(tmp_path):
    from cufund.core.messages import Odometry, PointCloud
    from cufund.estimation import odometry_errors, read_tum, run_on_log
    from cufund.logs import McapLogger

    T_BL = Transform(t=(0.05, 0.0, 0.05))
    traj = MinimumSnapTrajectory(np.array([[-3, -1.5, 1.5], [-2.4, -1.2, 1.6]]), v_max=1.5, a_max=2.0, t_start=1.1)
    motion = FlatBodyMotion(traj)
    rec = record_flight(
        motion,
        ImuModel(after_calibration(imu_preset("icm42688p")), seed=4),
        Lidar(Mid360Pattern(point_rate=60_000), mid360_params(seed=4), T_BL),
        load("imav2025_tunnel"),
        0.0,
        2.4,
    )
    truth = motion.state(rec.t_imu)
    events = []
    for k, t in enumerate(rec.t_imu):
        events.append(
            (
                t,
                0,
                Topics.TRUTH_ODOMETRY,
                Odometry(t=t, p_W=truth["p_W"][k], v_W=truth["v_W"][k], q_WB=truth["q_WB"][k], w_B=truth["w_B"][k]),
            )
        )
        events.append((t, 1, Topics.IMU, Imu(t=t, f_I=rec.acc_I[k], w_I=rec.gyr_I[k])))
    for i, f in enumerate(rec.frames):
        n = len(f.dt)
        cloud = PointCloud(
            t=f.t,
            dt=f.dt,
            points_L=f.points_L,
            ranges=np.linalg.norm(f.points_L, axis=1).astype(float),
            intensity=np.ones(n),
            channel=np.zeros(n, dtype=np.int64),
            frame=i,
        )
        events.append((f.t + f.dt.max(), 2, Topics.POINT_CLOUD, cloud))
    events.sort(key=lambda e: (e[0], e[1]))
    log = tmp_path / "run.mcap"
    with McapLogger(log) as writer:
        for t, _, topic, msg in events:
            ns = int(round(t * 1e9))
            writer.write(topic, msg, ns, ns)
    params = LioParams(T_BL=T_BL)
    figures = run_on_log(log, params, tmp_path / "out")
    for name in ("odometry.json", "odometry.png", "estimate.tum", "truth.tum"):
        assert (tmp_path / "out" / name).stat().st_size > 0
    # The same data straight into the core (pad pose given, truth exact): the same figures.
    st = motion.state(np.zeros(1))
    at_scans, at_imu = replay(
        LioCore(LioParams(T_BL=T_BL, p_WB0=tuple(st["p_W"][0]), pad_yaw=yaw_of(st["q_WB"][0]))), rec
    )
    t, p, q = read_tum(tmp_path / "out" / "estimate.tum")
    ref = motion.state(t)
    direct = odometry_errors(p, q, ref["p_W"], ref["q_WB"])
    assert figures["odometry_rmse_m"] == pytest.approx(direct["odometry_rmse_m"], abs=2e-4)
    assert figures["odometry_rmse_m"] < 0.01 and figures["odometry_rot_rmse_deg"] < 0.2
    assert figures["lio_scans"] >= 10 and figures["lio_ms_per_scan_median"] > 0
    assert figures["odometry_samples"] > 150
    online = {o.t: o.p_W for o in at_imu}
    common = [k for k, tk in enumerate(t) if tk in online]
    assert len(common) > 150
    np.testing.assert_allclose(p[common], np.array([online[t[k]] for k in common]), atol=1e-8)  # TUM's 9 decimals
