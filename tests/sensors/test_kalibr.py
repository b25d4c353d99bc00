"""Kalibr camchain YAML: read, written, read back; EuRoC's published cam0 calibration gives the mounting its sensor.yaml
states; bad files get errors naming the camera and key."""

import time

import numpy as np
import pytest
import yaml

from cufund.geometry import Transform, homogeneous
from cufund.sensors.camera_models import R_CO, CameraCalibration, CameraIntrinsics
from cufund.sensors.kalibr import dump_kalibr, load_kalibr

# EuRoC MAV dataset, cam0/sensor.yaml: T_BS (body = IMU <- camera, optical frame), intrinsics, radtan coefficients
EUROC_T_BS = np.array(
    [
        [0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975],
        [0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768],
        [-0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949],
        [0.0, 0.0, 0.0, 1.0],
    ]
)
EUROC_CAM0 = {
    "camera_model": "pinhole",
    "intrinsics": [458.654, 457.296, 367.215, 248.375],
    "distortion_model": "radtan",
    "distortion_coeffs": [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05],
    "resolution": [752, 480],
    "timeshift_cam_imu": 0.0,
}


def _orthonormalised(T):
    u, _, vt = np.linalg.svd(T[:3, :3])
    out = T.copy()
    out[:3, :3] = u @ vt
    return out


def test_euroc_cam0_is_mounted_where_its_sensor_yaml_says(tmp_path):
    T_BS = _orthonormalised(EUROC_T_BS)
    path = tmp_path / "camchain.yaml"
    path.write_text(yaml.safe_dump({"cam0": {**EUROC_CAM0, "T_cam_imu": np.linalg.inv(T_BS).tolist()}}))
    (cam,) = load_kalibr(path)
    K = cam.intrinsics
    assert (K.width, K.height, K.fx, K.cy) == (752, 480, 458.654, 248.375)
    assert K.distortion == (-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05, 0.0)
    # the optical axis (z_O = x_C) and the image's right (x_O = -y_C) in the IMU/body frame: T_BS's columns
    R_BC = cam.T_BC.R
    np.testing.assert_allclose(R_BC @ R_CO, T_BS[:3, :3], atol=1e-12)
    np.testing.assert_allclose(R_BC[:, 0], T_BS[:3, 2], atol=1e-12)
    np.testing.assert_allclose(cam.T_BC.t, T_BS[:3, 3], atol=1e-12)
    np.testing.assert_allclose(homogeneous(cam.T_BO), T_BS, atol=1e-12)


def test_a_rig_round_trips_through_kalibr_yaml(tmp_path):
    rng = np.random.default_rng(0)
    cams = []
    for i, model in enumerate(("radtan", "equidistant", "radtan")):
        D = tuple(rng.normal(0, 0.05, 4))
        K = CameraIntrinsics(640 + i, 480, 400.0 + i, 401.0, 319.5, 239.5, D, model)
        q = rng.normal(size=4)
        T = Transform(tuple(rng.normal(0, 0.1, 3)), tuple(q / np.linalg.norm(q)))
        cams.append(CameraCalibration(K, T, 0.001 * i, f"cam{i}"))
    T_BI = Transform((0.01, 0.02, -0.03), (np.cos(0.2), 0.0, np.sin(0.2), 0.0))
    path = tmp_path / "rig.yaml"
    dump_kalibr(cams, path, T_BI)
    data = yaml.safe_load(path.read_text())
    assert sorted(data) == ["cam0", "cam1", "cam2"] and data["cam1"]["distortion_model"] == "equidistant"
    assert len(data["cam1"]["distortion_coeffs"]) == 4 and data["cam2"]["timeshift_cam_imu"] == 0.002
    # T_cn_cnm1 chains the cameras: cam1 <- cam0 = T_cam1_imu T_cam0_imu^-1
    chain = np.array(data["cam1"]["T_cn_cnm1"]) @ np.array(data["cam0"]["T_cam_imu"])
    np.testing.assert_allclose(chain, data["cam1"]["T_cam_imu"], atol=1e-12)
    back = load_kalibr(path, T_BI)
    for a, b in zip(cams, back, strict=True):
        assert a.intrinsics == b.intrinsics and a.name == b.name and a.timeshift_s == b.timeshift_s
        np.testing.assert_allclose(homogeneous(a.T_BC), homogeneous(b.T_BC), atol=1e-12)
    # a camera given only by T_cn_cnm1 is chained from the one before
    del data["cam1"]["T_cam_imu"]
    path.write_text(yaml.safe_dump(data))
    np.testing.assert_allclose(homogeneous(load_kalibr(path, T_BI)[1].T_BC), homogeneous(cams[1].T_BC), atol=1e-12)


def test_a_stereo_scenario_camera_takes_a_camchain(tmp_path):
    from cufund.sensors.kinds import StereoCameraParams

    T_BS = _orthonormalised(EUROC_T_BS)
    (tmp_path / "chain.yaml").write_text(
        yaml.safe_dump({"cam0": {**EUROC_CAM0, "T_cam_imu": np.linalg.inv(T_BS).tolist()}})
    )
    rig = StereoCameraParams(calibration="chain.yaml").cameras(str(tmp_path))
    assert len(rig) == 1 and rig[0].intrinsics.fx == 458.654


def test_bad_camchains_get_errors_naming_the_camera_and_key(tmp_path):
    def write(d):
        p = tmp_path / "bad.yaml"
        p.write_text(yaml.safe_dump(d))
        return p

    good = {**EUROC_CAM0, "T_cam_imu": np.eye(4).tolist()}
    with pytest.raises(ValueError, match=r"cam0.T_cam_imu: the 3x3 block must be a rotation"):
        load_kalibr(write({"cam0": {**good, "T_cam_imu": np.diag([2.0, 1.0, 1.0, 1.0]).tolist()}}))
    with pytest.raises(ValueError, match=r"cam0.T_cam_imu must be a 4x4 matrix of finite numbers"):
        load_kalibr(write({"cam0": {**good, "T_cam_imu": [[float("nan")] * 4] * 4}}))
    with pytest.raises(ValueError, match=r"cam0.camera_model must be pinhole"):
        load_kalibr(write({"cam0": {**good, "camera_model": "omni"}}))
    with pytest.raises(ValueError, match=r"cam0.intrinsics"):
        load_kalibr(write({"cam0": {**good, "intrinsics": [1.0, 2.0]}}))
    with pytest.raises(ValueError, match=r"cam0 .. cam1 without gaps"):
        load_kalibr(write({"cam0": good, "cam2": good}))
    with pytest.raises(ValueError, match=r"missing key 'T_cam_imu'"):
        load_kalibr(write({"cam0": {k: v for k, v in good.items() if k != "T_cam_imu"}}))
    with pytest.raises(ValueError, match="no Kalibr camchain file"):
        load_kalibr(tmp_path / "nope.yaml")
    K = CameraIntrinsics(8, 8, 4, 4, 3.5, 3.5, (0.0, 0.0, 0.0, 0.0, 0.1))
    with pytest.raises(ValueError, match="Kalibr's radtan has no k3"):
        dump_kalibr([CameraCalibration(K)], tmp_path / "x.yaml")


def test_hostile_camchains_raise_value_errors_only(tmp_path):
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    leaf = st.one_of(st.none(), st.booleans(), st.floats(), st.integers(), st.text(max_size=5))
    values = st.recursive(leaf, lambda c: st.lists(c, max_size=5) | st.dictionaries(st.text(max_size=8), c, max_size=5))
    keys = st.sampled_from(["cam0", "cam1", "camera_model", "intrinsics", "T_cam_imu", "resolution", "x"])
    field = st.sampled_from(list(EUROC_CAM0) + ["T_cam_imu", "T_cn_cnm1"])

    @settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(st.dictionaries(keys, values, max_size=3), st.dictionaries(field, values, max_size=3))
    def check(top, cam):
        path = tmp_path / "fuzz.yaml"
        for data in (top, {"cam0": {**EUROC_CAM0, "T_cam_imu": np.eye(4).tolist(), **cam}}):
            try:
                path.write_text(yaml.safe_dump(data))
            except (yaml.YAMLError, ValueError):
                continue
            try:
                load_kalibr(path)
            except ValueError:
                pass

    check()


def test_deep_and_alias_bomb_camchains_are_refused_at_once(tmp_path):
    deep = tmp_path / "deep.yaml"
    deep.write_text("cam0: {intrinsics: " + "[" * 5000 + "]" * 5000 + "}\n")  # RecursionError before
    with pytest.raises(ValueError, match=r"deep.yaml: nesting deeper than yaml_max_depth"):
        load_kalibr(deep)
    # intrinsics of 10^9 numbers through aliases (8 levels of ten): minutes and gigabytes before
    levels = "".join(f"  x{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]\n" for i in range(1, 9))
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("cam0:\n  x0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n" + levels + "  intrinsics: *a8\n")
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"bomb.yaml: .*alias"):
        load_kalibr(bomb)
    assert time.perf_counter() - t0 < 5.0
    dup = tmp_path / "dup.yaml"
    dup.write_text(yaml.safe_dump({"cam0": EUROC_CAM0}) + "cam0: {}\n")
    with pytest.raises(ValueError, match=r"cam0 may be given only once"):
        load_kalibr(dup)


def test_camera_info_fields_round_trip_and_are_checked():
    for model, D in (("radtan", (-0.28, 0.07, 0.0002, 1.8e-5, 0.01)), ("equidistant", (0.01, -0.02, 0.003, 0.0))):
        K = CameraIntrinsics(752, 480, 458.6, 457.3, 367.2, 248.4, D, model)
        info = K.camera_info()
        assert info["distortion_model"] == ("plumb_bob" if model == "radtan" else "equidistant")
        assert info["K"] == [458.6, 0.0, 367.2, 0.0, 457.3, 248.4, 0.0, 0.0, 1.0]
        assert CameraIntrinsics.from_camera_info(yaml.safe_load(yaml.safe_dump(info))) == K
    with pytest.raises(ValueError, match=r"camera_info.K must be \[\[fx, 0, cx\]"):
        CameraIntrinsics.from_camera_info({"width": 8, "height": 8, "K": [1, 2, 3, 4, 5, 6, 7, 8, 9]})
    with pytest.raises(ValueError, match="distortion_model must be one of"):
        CameraIntrinsics.from_camera_info(
            {"width": 8, "height": 8, "K": np.eye(3).ravel().tolist(), "distortion_model": "fov"}
        )
