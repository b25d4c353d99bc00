"""The stereo_camera sensor kind: topics, identical stamps, calibration in its params, hw_sync, the vio_room world."""

import numpy as np
import pytest

import cufund
from cufund.core.config import ConfigError
from cufund.scenarios import build_simulation
from cufund.scenarios.schema import ScenarioConfig
from cufund.sensors.camera import RgbCamera
from cufund.sensors.camera_component import CameraRigComponent
from cufund.sensors.camera_models import CameraIntrinsics
from cufund.worlds.vio_room import vio_room


def _scenario(**stereo):
    return {
        "name": "stereo_test",
        "world": {"kind": "vio_room", "seed": 0},
        "sensors": {"imu": "icm42688p", "stereo": {"kind": "stereo_camera", **stereo}},
        "trajectory": {"waypoints": [[0, 0, 1.0], [0.3, 0, 1.0]], "v_max": 0.5, "a_max": 1.0, "hover_s": 0.1},
        "duration": 0.2,
    }


def _nolog(**stereo):
    return _scenario(**stereo)


def test_stereo_rig_publishes_two_images_with_identical_stamps():
    small = {"width": 64, "height": 48, "fx": 40.0, "fy": 40.0, "cx": 31.5, "cy": 23.5}
    data = _scenario(intrinsics=small, rate_hz=20.0)
    cfg = ScenarioConfig.from_dict(data)
    spec = cfg.sensors["stereo"]
    rig = spec.params.cameras()
    assert len(rig) == 2 and rig[0].intrinsics.width == 64
    # the default pair: cam0 left (+y) of cam1 by the baseline, both looking along body x
    np.testing.assert_allclose(np.subtract(rig[0].T_BC.t, rig[1].T_BC.t), (0.0, 0.11, 0.0))
    built = build_simulation(cfg)
    sim = built.simulator
    sim.record_topics = (*sim.record_topics, "/sensors/cam0/image", "/sensors/cam1/image")
    result = sim.run(0.2)
    a, b = result.topics["/sensors/cam0/image"], result.topics["/sensors/cam1/image"]
    np.testing.assert_array_equal(a["t"], b["t"])
    np.testing.assert_allclose(a["t"], np.arange(len(a["t"])) * 0.05, atol=1e-12)
    assert a["image"].shape[1:] == (48, 64) and a["image"].dtype == np.uint8
    assert not np.array_equal(a["image"][0], b["image"][0])  # the baseline shifts the view


def test_stereo_params_reject_bad_extrinsics_and_hw_sync_needs_a_whole_rate_ratio():
    with pytest.raises(ConfigError, match=r"extrinsics\[0\].*finite"):
        ScenarioConfig.from_dict(_nolog(extrinsics=[{"p": [0, float("nan"), 0]}]))
    with pytest.raises(ConfigError, match=r"extrinsics\[1\].q must be a finite unit quaternion"):
        ScenarioConfig.from_dict(_nolog(extrinsics=[{"p": [0, 0, 0]}, {"q": [1, 1, 0, 0]}]))
    with pytest.raises(ConfigError, match="distortion_model must be one of"):
        ScenarioConfig.from_dict(
            _nolog(
                intrinsics={"width": 8, "height": 8, "fx": 4, "fy": 4, "cx": 3.5, "cy": 3.5, "distortion_model": "fov"}
            )
        )
    cfg = ScenarioConfig.from_dict(_nolog(rate_hz=30.0, hw_sync=True))
    with pytest.raises(ConfigError, match="whole multiple of rate_hz"):
        build_simulation(cfg)


def test_vio_room_ids_name_the_objects_seen():
    w = vio_room(0)
    K = CameraIntrinsics(80, 60, 50.0, 50.0, 39.5, 29.5)
    img, ids, labels = RgbCamera(K, shadows=True, grayscale=True).render(
        w, (0.0, 0.0, 1.2), (1, 0, 0, 0), want_ids=True
    )
    assert img.shape == (60, 80) and ids.dtype == np.int32 and ids.shape == (60, 80)
    assert ids.min() >= -1 and (ids >= 0).mean() > 0.8  # -1: the sky above the open room
    assert labels[ids[30, 40]] in ("wall", "poster") and labels[ids[59, 40]] in ("floor", "rug")
    assert labels == tuple(w.labels())
    with pytest.raises(ValueError, match="seed must be an integer"):
        vio_room(-1)
    assert isinstance(cufund.worlds.load("vio_room", seed=1), cufund.World)


def test_hw_sync_triggers_frames_on_imu_samples():
    small = {"width": 16, "height": 12, "fx": 10.0, "fy": 10.0, "cx": 7.5, "cy": 5.5}
    data = _scenario(intrinsics=small, rate_hz=20.0, hw_sync=True)
    data["sensors"]["imu"] = {"kind": "icm42688p", "phase_s": 0.0013}
    built = build_simulation(ScenarioConfig.from_dict(data))
    sim = built.simulator
    sim.record_topics = (*sim.record_topics, "/sensors/cam0/image", "/sensors/imu")
    result = sim.run(0.2)
    t_cam, t_imu = result.topics["/sensors/cam0/image"]["t"], result.topics["/sensors/imu"]["t"]
    np.testing.assert_allclose(t_cam, 0.0013 + 0.05 * np.arange(len(t_cam)), atol=1e-12)
    # every frame's stamp is an IMU sample's
    assert np.min(np.abs(t_cam[:, None] - t_imu[None, :]), axis=1).max() < 1e-12
    data["sensors"]["stereo"]["phase_s"] = 0.01
    with pytest.raises(ConfigError, match="give phase_s or hw_sync, not both"):
        build_simulation(ScenarioConfig.from_dict(data))


def test_a_single_camera_rig_from_one_extrinsic():
    from cufund.sensors.kinds import StereoCameraParams

    p = StereoCameraParams(extrinsics=[{"p": [0.1, 0.0, 0.05], "q": [1, 0, 0, 0]}], topics=["/sensors/front/image"])
    (cam,) = p.cameras()
    assert cam.T_BC.t == (0.1, 0.0, 0.05) and p.camera_topics(1) == ("/sensors/front/image",)
    with pytest.raises(ConfigError, match="need one topic per camera"):
        StereoCameraParams(topics=["/a"])


def test_the_rig_round_trips_through_the_scenario_dict_and_a_missing_camchain_is_named(tmp_path):
    import yaml

    ext = [{"p": [0.1, 0.05, 0.0], "q": [1, 0, 0, 0]}, {"p": [0.1, -0.05, 0.0], "q": [0.0, 0.0, 0.0, 1.0]}]
    eq = {
        "width": 32,
        "height": 24,
        "fx": 20.0,
        "fy": 20.0,
        "cx": 15.5,
        "cy": 11.5,
        "distortion_model": "equidistant",
        "distortion": [0.01, 0.0, 0.0, 0.0],
    }
    cfg = ScenarioConfig.from_dict(_scenario(extrinsics=ext, intrinsics=eq, shutter="rolling", color="rgb"))
    again = ScenarioConfig.from_dict(yaml.safe_load(yaml.safe_dump(cfg.to_dict())))
    assert again.sensors["stereo"].params == cfg.sensors["stereo"].params
    assert again.sensors["stereo"].params.cameras()[1].T_BC.q == (0.0, 0.0, 0.0, 1.0)
    cfg = ScenarioConfig.from_dict(_scenario(calibration="missing.yaml"), base_dir=tmp_path)
    with pytest.raises(ConfigError, match="calibration: no Kalibr camchain file"):
        build_simulation(cfg)


def test_each_cameras_noise_stream_derives_from_the_scenario_seed():
    small = {"width": 32, "height": 24, "fx": 20.0, "fy": 20.0, "cx": 15.5, "cy": 11.5}

    seeds = []

    def images(seed):
        data = _scenario(intrinsics=small, rate_hz=20.0, full_well_e=500.0, read_noise_dn=2.0)
        data["seed"] = seed
        sim = build_simulation(ScenarioConfig.from_dict(data)).simulator
        (rig,) = [c for c in sim.components if isinstance(c, CameraRigComponent)]
        seeds.append([cam.seed for cam in rig.cameras])
        sim.record_topics = (*sim.record_topics, "/sensors/cam0/image", "/sensors/cam1/image")
        topics = sim.run(0.1).topics
        return [topics[f"/sensors/cam{i}/image"]["image"].astype(int) for i in (0, 1)]

    a0, a1 = images(1)
    b0, b1 = images(1)
    c0, _ = images(2)
    np.testing.assert_array_equal(a0, b0)  # same seed: the same images
    np.testing.assert_array_equal(a1, b1)
    assert np.any(a0 != c0)  # another scenario seed: other noise
    assert np.std(a0[0] - c0[0]) > 1.0
    # each camera its own stream, from the scenario seed and its name
    assert seeds[0] == seeds[1] and seeds[0][0] != seeds[0][1] and seeds[2][0] not in seeds[0]
