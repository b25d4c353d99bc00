"""Pinhole depth and RGB cameras: projection of known boxes, distortion, shading, PNG output."""

import numpy as np
import pytest

import cufund
from cufund.sensors import CameraIntrinsics, DepthCamera, RgbCamera, Transform, save_png
from cufund.sensors.camera import R_CO

IDENTITY = (1.0, 0.0, 0.0, 0.0)


def box_world(size=(1.0, 1.0, 1.0), centre=(5.0, 0.0, 0.0), color=(1.0, 0.0, 0.0)):
    w = cufund.World()
    w.add_box(size, centre, label="target", color=color)
    return w


def test_depth_image_of_a_box_matches_its_pinhole_projection():
    K = CameraIntrinsics(160, 120, 100.0, 110.0, 80.0, 55.0)
    cam = DepthCamera(K, depth_max=20.0)
    depth = cam.render(box_world(), (0.0, 0.0, 0.0), IDENTITY)
    assert depth.shape == (120, 160) and depth.dtype == np.float32
    seen = np.isfinite(depth)
    np.testing.assert_allclose(depth[seen], 4.5, rtol=1e-6)  # front face at x = 4.5 m
    # Face corners (y, z = ±0.5 at depth 4.5) project to u = cx ∓ fx*y/x, v = cy ∓ fy*z/x.
    half_u, half_v = 100.0 * 0.5 / 4.5, 110.0 * 0.5 / 4.5
    cols, rows = np.nonzero(seen.any(0))[0], np.nonzero(seen.any(1))[0]
    assert cols.min() == int(np.ceil(80.0 - half_u)) and cols.max() == int(np.floor(80.0 + half_u))
    assert rows.min() == int(np.ceil(55.0 - half_v)) and rows.max() == int(np.floor(55.0 + half_v))


def test_camera_mount_and_body_pose_move_the_image():
    K = CameraIntrinsics(101, 101, 50.0, 50.0, 50.0, 50.0)
    w = box_world(size=(0.2, 0.2, 0.2), centre=(0.0, 4.0, 1.0))
    # Body yawed +90° looks along +y; the camera 1 m above the body looks straight at the box.
    q_yaw90 = (np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4))
    cam = DepthCamera(K, T_BC=Transform((0.0, 0.0, 1.0)))
    depth = cam.render(w, (0.0, 0.0, 0.0), q_yaw90)
    assert depth[50, 50] == pytest.approx(3.9, rel=1e-6)
    assert np.isnan(depth[0, 0])


def test_distortion_inverse_is_consistent_with_the_forward_model():
    K = CameraIntrinsics(64, 48, 40.0, 42.0, 31.5, 23.5, distortion=(-0.25, 0.08, 0.001, -0.002, 0.0))
    d = K.pixel_directions().reshape(-1, 3)
    uv = K.project(d)
    u, v = np.meshgrid(np.arange(64.0), np.arange(48.0))
    np.testing.assert_allclose(uv, np.column_stack([u.ravel(), v.ravel()]), atol=1e-6)


def test_distorted_camera_sees_a_small_box_where_the_forward_model_puts_it():
    K = CameraIntrinsics(200, 150, 120.0, 120.0, 99.5, 74.5, distortion=(-0.3, 0.1, 0.0, 0.0, 0.0))
    centre = np.array([4.0, -1.5, 1.2])  # body/camera frame FLU
    depth = DepthCamera(K).render(box_world(size=(0.1, 0.1, 0.1), centre=centre), (0, 0, 0), IDENTITY)
    rows, cols = np.nonzero(np.isfinite(depth))
    expect = K.project((R_CO.T @ centre)[None])[0]
    assert abs(cols.mean() - expect[0]) < 0.75 and abs(rows.mean() - expect[1]) < 0.75
    undistorted = CameraIntrinsics(200, 150, 120.0, 120.0, 99.5, 74.5).project((R_CO.T @ centre)[None])[0]
    assert np.hypot(*(expect - undistorted)) > 3.0  # the distortion visibly moves it


def test_depth_noise_grows_with_depth_squared_and_is_seeded():
    K = CameraIntrinsics(80, 60, 50.0, 50.0, 39.5, 29.5)
    w = cufund.World()
    w.add_box((0.1, 50.0, 50.0), (4.05, 0.0, 0.0))
    a = DepthCamera(K, noise_coeff=0.005, seed=3).render(w, (0, 0, 0), IDENTITY)
    b = DepthCamera(K, noise_coeff=0.005, seed=3).render(w, (0, 0, 0), IDENTITY)
    np.testing.assert_array_equal(a, b)
    clean = DepthCamera(K).render(w, (0, 0, 0), IDENTITY)
    rel = (a - clean) / clean**2
    assert np.std(rel) == pytest.approx(0.005, rel=0.1)


def test_rgb_lambert_shading_and_sky():
    K = CameraIntrinsics(40, 30, 30.0, 30.0, 19.5, 14.5)
    w = box_world(color=(0.8, 0.4, 0.0))
    light = np.array([-1.0, 0.0, 1.0]) / np.sqrt(2)
    cam = RgbCamera(K, light_W=light, ambient=0.2, sky=(0.0, 0.0, 1.0))
    img = cam.render(w, (0.0, 0.0, 0.0), IDENTITY)
    assert img.shape == (30, 40, 3) and img.dtype == np.uint8
    shade = 0.2 + 0.8 * abs(np.dot([-1.0, 0.0, 0.0], light))  # front face normal -x
    np.testing.assert_array_equal(img[15, 20], np.round(np.array([0.8, 0.4, 0.0]) * shade * 255))
    np.testing.assert_array_equal(img[0, 0], [0, 0, 255])


def test_png_round_trip(tmp_path):
    o3d = pytest.importorskip("open3d")
    K = CameraIntrinsics(64, 48, 40.0, 40.0, 31.5, 23.5)
    w = cufund.worlds.load("imav2025_tunnel")
    rgb = RgbCamera(K).render(w, (-1.0, 0.0, 0.55), IDENTITY)
    depth = DepthCamera(K).render(w, (-1.0, 0.0, 0.55), IDENTITY)
    save_png(tmp_path / "rgb.png", rgb)
    save_png(tmp_path / "depth.png", depth)
    np.testing.assert_array_equal(np.asarray(o3d.io.read_image(str(tmp_path / "rgb.png"))), rgb)
    mm = np.asarray(o3d.io.read_image(str(tmp_path / "depth.png")))
    np.testing.assert_array_equal(mm, np.round(np.nan_to_num(depth.astype(np.float64) * 1000)).astype(np.uint16))


def test_intrinsics_from_field_of_view_and_the_d435_presets():
    K = CameraIntrinsics.from_fov(640, 480, np.deg2rad(90.0))
    assert K.fx == pytest.approx(320.0) and K.fy == K.fx and (K.cx, K.cy) == (319.5, 239.5)
    for K, (h, v) in ((cufund.sensors.d435_depth(), (79.5, 63.9)), (cufund.sensors.d435_rgb(), (55.0, 42.6))):
        assert (K.width, K.height) == (640, 480)
        assert 2 * np.degrees(np.arctan(K.width / 2 / K.fx)) == pytest.approx(h, abs=0.1)
        assert 2 * np.degrees(np.arctan(K.height / 2 / K.fy)) == pytest.approx(v, abs=0.1)


def test_bad_camera_input():
    with pytest.raises(ValueError, match="fx must be a finite number > 0"):
        CameraIntrinsics(10, 10, 0.0, 1.0, 5.0, 5.0)
    with pytest.raises(ValueError, match="width must be a positive integer"):
        CameraIntrinsics(0, 10, 1.0, 1.0, 5.0, 5.0)
    with pytest.raises(ValueError, match="distortion must be 5 finite numbers"):
        CameraIntrinsics(10, 10, 1.0, 1.0, 5.0, 5.0, distortion=(0.1, 0.2))
    cam = DepthCamera(CameraIntrinsics(10, 10, 5.0, 5.0, 4.5, 4.5))
    with pytest.raises(ValueError, match="p_W must be 3 finite numbers"):
        cam.render(box_world(), (0.0, np.nan, 0.0), IDENTITY)
    with pytest.raises(ValueError, match="q_WB must be a non-zero quaternion"):
        cam.render(box_world(), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="world must be a cufund.World"):
        RgbCamera(CameraIntrinsics(10, 10, 5.0, 5.0, 4.5, 4.5)).render(box_world().raycast_scene, (0, 0, 0), IDENTITY)
    with pytest.raises(ValueError, match="image must be"):
        save_png("/tmp/x.png", np.zeros((3, 3, 3), np.float32))


def test_camera_component_publishes_images_at_its_rate():
    quad = cufund.Quadrotor(cufund.vehicle.presets.cu_astro())
    quad.hover([0.0, 0.0, 0.0])
    sim = cufund.Simulator(quad, physics_rate_hz=1000, record_topics=("/sensors/depth_image",))
    K = CameraIntrinsics(32, 24, 20.0, 20.0, 15.5, 11.5)
    sim.add(cufund.sensors.CameraComponent(DepthCamera(K), box_world(), rate_hz=50.0))
    result = sim.run(0.1)
    images = result.topics["/sensors/depth_image"]
    np.testing.assert_allclose(images["t"], np.arange(5) * 0.02, atol=1e-12)
    assert images["image"].shape == (5, 24, 32)
    np.testing.assert_allclose(images["image"][:, 12, 16], 4.5, rtol=1e-5)  # hovering, box face 4.5 m ahead
    with pytest.raises(ValueError, match="camera must be a DepthCamera or RgbCamera"):
        cufund.sensors.CameraComponent(object(), box_world())
