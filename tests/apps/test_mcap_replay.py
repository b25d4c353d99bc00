"""`cufund replay`: a log re-opened in MeshCat (headless: the scene commands are recorded, not sent)."""

from __future__ import annotations

import argparse

import numpy as np
import pytest
import umsgpack
from scipy.spatial.transform import Rotation

from cufund import messages as M
from cufund import presets
from cufund.apps import log_replay
from cufund.logs import McapLogger
from cufund.viz.meshcat_scene import import_meshcat
from cufund.viz.replay import _RecordingWindow

T_BL = (np.array([0.1, -0.02, 0.05]), Rotation.from_euler("y", 20, degrees=True).as_quat(scalar_first=True))


def _pose(t: float) -> tuple[np.ndarray, np.ndarray]:
    """Truth: along x at 1 m/s at 1 m, yawing at 0.5 rad/s."""
    return np.array([t, 0.0, 1.0]), Rotation.from_euler("z", 0.5 * t).as_quat(scalar_first=True)


def _write_log(path, with_estimate: bool = True) -> list[tuple[int, M.PointCloud, tuple]]:
    rng = np.random.default_rng(4)
    clouds = []
    with McapLogger(path) as log:
        for k in range(200):  # 100 Hz for 2 s
            t, ns = k * 0.01, k * 10_000_000
            p, q = _pose(t)
            log.write("/truth/odometry", M.Odometry(t, p, np.array([1.0, 0, 0]), q, np.array([0, 0, 0.5])), ns, ns)
            estimate = None
            if with_estimate:
                estimate = (p + [0.0, 0.1, 0.0], q)
                log.write("/estimator/odometry", M.Odometry(t, estimate[0], np.zeros(3), q, np.zeros(3)), ns, ns)
            if k % 10 == 5:  # 10 Hz LiDAR
                n = 40
                cloud = M.PointCloud(
                    t,
                    np.linspace(0, 0.09, n),
                    rng.normal(size=(n, 3)).astype(np.float32),
                    rng.random(n) * 10,
                    rng.random(n),
                    np.arange(n) % 16,
                    k // 10,
                )
                log.write("/sensors/lidar", cloud, ns, ns)
                clouds.append((ns, cloud, estimate or (p, q)))
    return clouds


def _commands(window) -> list[dict]:
    return [umsgpack.unpackb(c) for c in window.commands]


def _replay(path, **kw):
    window = _RecordingWindow()
    vis = import_meshcat().Visualizer(window=window)
    stats = log_replay.replay_log(path, vis, presets.cu_astro(), speed=0, **kw)
    return stats, _commands(window)


def test_replay_draws_truth_poses_per_frame_and_clouds_in_world(tmp_path):
    path = tmp_path / "run.mcap"
    clouds = _write_log(path)
    stats, commands = _replay(path, rate_hz=25.0, T_BL=T_BL)
    assert stats.clouds == len(clouds) == 20 and stats.duration_s == pytest.approx(1.99)
    vehicle = [c for c in commands if c["type"] == "set_transform" and c["path"] == "/meshcat/vehicle"]
    assert len(vehicle) == stats.frames == 50  # 2 s at 25 frames/s (the last frame shows the final pose)
    for k, command in enumerate(vehicle[:-1]):  # frame k shows the newest pose before its end, (k + 1) * 40 ms
        t = (4 * (k + 1) - 1) * 0.01
        p, q = _pose(t)
        expected = np.eye(4)
        expected[:3, :3], expected[:3, 3] = Rotation.from_quat(q, scalar_first=True).as_matrix(), p
        assert np.allclose(np.array(command["matrix"]).reshape(4, 4).T, expected, atol=1e-12), k
    estimate = [c for c in commands if c["type"] == "set_transform" and c["path"] == "/meshcat/estimate"]
    assert len(estimate) == 50 and estimate[-1]["matrix"][13] == pytest.approx(0.1)  # y of the estimate
    assert any(c["type"] == "set_object" and c["path"] == "/meshcat/estimated" for c in commands)

    drawn = [c for c in commands if c["type"] == "set_object" and c["path"] == "/meshcat/lidar"]
    assert len(drawn) == 20
    _, cloud, (p_WB, q_WB) = clouds[-1]
    R_WB = Rotation.from_quat(q_WB, scalar_first=True)
    R_BL = Rotation.from_quat(T_BL[1], scalar_first=True)
    expected = R_WB.apply(R_BL.apply(cloud.points_L.astype(np.float64)) + T_BL[0]) + p_WB
    geometry = drawn[-1]["object"]["geometries"][0]["data"]["attributes"]["position"]
    got = np.frombuffer(geometry["array"].data, np.float32).reshape(-1, 3)
    assert np.allclose(got, expected, atol=1e-5)


def test_replay_without_estimate_uses_truth_for_clouds(tmp_path):
    path = tmp_path / "run.mcap"
    clouds = _write_log(path, with_estimate=False)
    stats, commands = _replay(path, rate_hz=10.0)
    assert stats.frames == 20 and not any(c.get("path") == "/meshcat/estimate" for c in commands)
    _, cloud, (p_WB, q_WB) = clouds[0]
    first = next(c for c in commands if c["type"] == "set_object" and c["path"] == "/meshcat/lidar")
    got = np.frombuffer(
        first["object"]["geometries"][0]["data"]["attributes"]["position"]["array"].data, np.float32
    ).reshape(-1, 3)
    expected = Rotation.from_quat(q_WB, scalar_first=True).apply(cloud.points_L.astype(np.float64)) + p_WB
    assert np.allclose(got, expected, atol=1e-5)


def test_replay_paces_to_the_requested_speed(tmp_path):
    path = tmp_path / "run.mcap"
    _write_log(path, with_estimate=False)
    now = [0.0]
    slept = []

    def sleep(seconds: float) -> None:
        slept.append(seconds)
        now[0] += seconds

    window = _RecordingWindow()
    log_replay.replay_log(
        path,
        import_meshcat().Visualizer(window=window),
        presets.cu_astro(),
        speed=4.0,
        rate_hz=10.0,
        sleep=sleep,
        clock=lambda: now[0],
    )
    assert len(slept) == 19 and all(s == pytest.approx(0.1 / 4.0) for s in slept[:-1])  # a 100 ms frame: 25 ms
    assert sum(slept) == pytest.approx(1.99 / 4.0)  # 2 s of log at 4x real time


def test_cli_arguments_and_unreadable_logs(tmp_path, capsys):
    parser = argparse.ArgumentParser()
    log_replay.add_arguments(parser)
    assert parser.parse_args(["run.mcap", "--speed", "2.5"]).speed == 2.5
    with pytest.raises(SystemExit) as exit_info:
        parser.parse_args(["run.mcap", "--speed", "-1"])
    assert exit_info.value.code == 2
    bad = tmp_path / "run.mcap"
    bad.write_bytes(b"\x89MCAP0\r\n" + b"\0" * 64)
    assert log_replay.run(parser.parse_args([str(bad), "--no-wait"])) == 2
    assert "run.mcap" in capsys.readouterr().err
    no_pose = tmp_path / "imu.mcap"
    with McapLogger(no_pose) as log:
        log.write("/sensors/imu", M.Imu(0.0, np.zeros(3), np.zeros(3)), 0, 0)
    with pytest.raises(ValueError, match="neither /truth/odometry nor /estimator/odometry"):
        log_replay.replay_log(no_pose, None, presets.cu_astro())
