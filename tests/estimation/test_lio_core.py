"""LioCore on short offline flights made with the standalone IMU and LiDAR models (truth known exactly)."""

import dataclasses

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cufund.core.config import ConfigError
from cufund.estimation import FlatBodyMotion, LioCore, LioParams, record_flight, replay
from cufund.geometry import Transform, yaw_of
from cufund.planning.minimum_snap import MinimumSnapTrajectory
from cufund.sensors import ImuModel, imu_preset
from cufund.sensors.calibration import after_calibration
from cufund.sensors.lidar import Lidar, mid360_params
from cufund.sensors.patterns import Mid360Pattern
from cufund.worlds import load

T_BL = Transform(t=(0.05, 0.0, 0.05))


def _flight(world, waypoints, yaw, t_end, seed=1, point_rate=60_000):
    traj = MinimumSnapTrajectory(
        np.asarray(waypoints, float), yaw=np.asarray(yaw, float), v_max=1.5, a_max=2.0, t_start=1.2
    )
    motion = FlatBodyMotion(traj)
    imu_params = imu_preset("icm42688p")
    lidar = Lidar(Mid360Pattern(point_rate=point_rate), mid360_params(seed=seed), T_BL)
    rec = record_flight(motion, ImuModel(after_calibration(imu_params), seed=seed), lidar, world, 0.0, t_end)
    st = motion.state(np.array([0.0]))
    params = LioParams(imu=imu_params, T_BL=T_BL, p_WB0=tuple(st["p_W"][0]), pad_yaw=yaw_of(st["q_WB"][0]))
    return rec, params


def _errors(outputs, motion):
    t = np.array([o.t for o in outputs])
    truth = motion.state(t)
    pos = np.linalg.norm(np.array([o.p_W for o in outputs]) - truth["p_W"], axis=1)
    q = np.array([o.q_WB for o in outputs])
    rot = (
        Rotation.from_quat(q[:, [1, 2, 3, 0]]).inv() * Rotation.from_quat(truth["q_WB"][:, [1, 2, 3, 0]])
    ).magnitude()
    return pos, np.degrees(rot)


@pytest.fixture(scope="module")
def tunnel_flight():
    world = load("imav2025_tunnel")
    rec, params = _flight(world, [[-3, -1.5, 1.5], [-1.5, -1.2, 1.6]], [0.0, 0.8], 3.2)
    core = LioCore(params)
    at_scans, at_imu = replay(core, rec)
    return rec, core, at_scans, at_imu


def test_tunnel_flight_tracks_truth_at_scans_and_at_imu_rate(tunnel_flight):
    rec, core, at_scans, at_imu = tunnel_flight
    moving = rec.motion.state(np.array([o.t for o in at_scans]))["v_W"]
    assert np.max(np.linalg.norm(moving, axis=1)) > 0.5  # the vehicle did fly
    pos, rot = _errors(at_scans, rec.motion)
    assert np.sqrt(np.mean(pos**2)) < 0.01 and pos.max() < 0.02
    assert np.sqrt(np.mean(rot**2)) < 0.1
    # Between scans the IMU-propagated output stays close too, one per IMU sample once initialised.
    pos_i, rot_i = _errors(at_imu, rec.motion)
    assert pos_i.max() < 0.03 and rot_i.max() < 0.3
    assert len(at_imu) == np.count_nonzero(rec.t_imu >= at_imu[0].t)
    d = [x for x in core.diagnostics if not x.skipped]
    assert len(d) == len(at_scans)
    assert all(x.inliers > 500 and x.iterations >= 1 and len(x.eigenvalues) == 6 for x in d)
    assert not any(x.degenerate_directions for x in d)  # the arena constrains every direction


def test_moving_during_initialisation_is_an_error():
    traj = MinimumSnapTrajectory(np.array([[-3, -1.5, 1.5], [-2, -1.5, 1.5]]), v_max=1.0, a_max=2.0, t_start=0.3)
    motion = FlatBodyMotion(traj)
    imu = ImuModel(after_calibration(imu_preset("icm42688p")), seed=0)
    st = motion.state(np.arange(0, 1.2, 0.005))
    acc, gyr = imu.measure(st["q_WB"], st["w_B"], st["a_W"], st["alpha_B"])
    core = LioCore(LioParams(p_WB0=(-3, -1.5, 1.5)))
    with pytest.raises(ValueError, match="moved during static initialisation"):
        for t, f, w in zip(np.arange(0, 1.2, 0.005), acc, gyr, strict=True):
            core.add_imu(t, f, w)
    # The same samples with the vehicle held still for the first second initialise fine.
    still = LioCore(LioParams(p_WB0=(-3, -1.5, 1.5)))
    rest = motion.state(np.zeros(1))
    f0, w0 = ImuModel(after_calibration(imu_preset("icm42688p")), seed=0).measure(
        np.repeat(rest["q_WB"], 240, 0), np.zeros((240, 3)), np.zeros((240, 3)), np.zeros((240, 3))
    )
    for t, f, w in zip(np.arange(0, 1.2, 0.005), f0, w0, strict=True):
        still.add_imu(t, f, w)
    assert still.initialised


def test_bad_input_is_an_error_or_a_counted_skip(tunnel_flight):
    rec, _, _, _ = tunnel_flight
    core = LioCore(_params_like(rec))
    frames = rec.frames
    j = 0
    for i, f in enumerate(frames[:16]):
        t_end = f.t + f.dt.max()
        while rec.t_imu[j] <= t_end:
            core.add_imu(rec.t_imu[j], rec.acc_I[j], rec.gyr_I[j])
            if j == 250:  # a repeated and an out-of-order sample
                assert core.add_imu(rec.t_imu[j], rec.acc_I[j], rec.gyr_I[j]) is None
                assert core.add_imu(rec.t_imu[j] - 0.1, rec.acc_I[j], rec.gyr_I[j]) is None
            j += 1
        pts = f.points_L.copy()
        if i == 13:
            pts, dt = pts[:0], f.dt[:0]  # empty frame
        else:
            dt = f.dt
        if i == 14:
            pts[::10] = np.nan
        core.add_scan(f.t, dt, pts)
    assert core.skipped_imu == 2
    assert [d.skipped for d in core.diagnostics].count("empty frame") == 1
    assert core.dropped_points >= len(frames[14].points_L) // 10
    with pytest.raises(ValueError, match="f_I"):
        core.add_imu(100.0, [np.nan, 0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="points_L"):
        core.add_scan(100.0, np.zeros(3), np.zeros((3, 2)))
    with pytest.raises(ConfigError, match="q_BI"):
        dataclasses.replace(imu_preset("icm42688p"), q_BI=(1.0, 0.5, 0.0, 0.0))
    with pytest.raises(ConfigError, match="init_duration_s"):
        LioParams(init_duration_s=0.5)


def _params_like(rec):
    st = rec.motion.state(np.array([0.0]))
    return LioParams(imu=imu_preset("icm42688p"), T_BL=T_BL, p_WB0=tuple(st["p_W"][0]), pad_yaw=yaw_of(st["q_WB"][0]))


def test_corridor_flight_flags_the_axis_and_does_not_diverge():
    world = load("corridor", length=200.0)
    rec, params = _flight(world, [[100, 0, 1.2], [102.5, 0.1, 1.2]], [0.0, 0.0], 4.0, point_rate=60_000)
    core = LioCore(params)
    at_scans, _ = replay(core, rec)
    moving = [d for d in core.diagnostics if not d.skipped and d.t > 1.5]
    flagged = [d for d in moving if any(abs(v[3]) > 0.9 for v in d.degenerate_directions)]
    assert len(flagged) >= 0.8 * len(moving)
    pos, rot = _errors(at_scans, rec.motion)
    # Along the axis only the IMU measures the ~2.5 m travelled: centimetres of drift, not metres.
    assert pos.max() < 0.25 and rot.max() < 0.5
    assert np.sqrt(np.mean(rot**2)) < 0.1


def test_our_odometry_figures_equal_evo_ape_on_the_tum_files(tunnel_flight, tmp_path):
    from evo.core import metrics, sync
    from evo.tools import file_interface

    from cufund.estimation import odometry_errors, read_tum, write_tum

    rec, _, at_scans, _ = tunnel_flight
    t = np.array([o.t for o in at_scans])
    truth = rec.motion.state(t)
    est_file, ref_file = tmp_path / "estimate.tum", tmp_path / "truth.tum"
    write_tum(est_file, t, np.array([o.p_W for o in at_scans]), np.array([o.q_WB for o in at_scans]))
    write_tum(ref_file, t, truth["p_W"], truth["q_WB"])
    t_back, p_back, q_back = read_tum(est_file)
    ours = odometry_errors(p_back, q_back, *read_tum(ref_file)[1:])
    ref, est = sync.associate_trajectories(
        file_interface.read_tum_trajectory_file(ref_file), file_interface.read_tum_trajectory_file(est_file)
    )
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    stats = ape.get_all_statistics()
    assert ours["odometry_rmse_m"] == pytest.approx(stats["rmse"], rel=1e-6)
    assert ours["odometry_max_m"] == pytest.approx(stats["max"], rel=1e-6)
    assert ours["odometry_min_m"] == pytest.approx(stats["min"], rel=1e-6, abs=1e-9)
    rot = metrics.APE(metrics.PoseRelation.rotation_angle_deg)
    rot.process_data((ref, est))
    assert ours["odometry_rot_rmse_deg"] == pytest.approx(rot.get_statistic(metrics.StatisticsType.rmse), rel=1e-5)


def test_an_ideal_imu_with_zero_noise_densities_still_works():
    world = load("imav2025_tunnel")
    traj = MinimumSnapTrajectory(np.array([[-3, -1.5, 1.5], [-2.5, -1.2, 1.5]]), v_max=1.5, a_max=2.0, t_start=1.1)
    motion = FlatBodyMotion(traj)
    ideal = imu_preset("ideal")
    rec = record_flight(
        motion, ImuModel(ideal, seed=0), Lidar(Mid360Pattern(point_rate=40_000), mid360_params(), T_BL), world, 0.0, 2.2
    )
    st = motion.state(np.zeros(1))
    core = LioCore(LioParams(imu=ideal, T_BL=T_BL, p_WB0=tuple(st["p_W"][0]), pad_yaw=yaw_of(st["q_WB"][0])))
    at_scans, _ = replay(core, rec)
    pos, rot = _errors(at_scans, motion)
    assert len(at_scans) >= 10 and pos.max() < 0.02 and rot.max() < 0.2
