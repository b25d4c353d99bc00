"""Camera images against independent references: the checker of a fronto-parallel plane at the analytic pixel scale,
a cube's shadow inside the polygon the sun direction gives, rolling-shutter rows at their own times, depth and RGB
silhouettes, OpenCV's projectPoints for both lens models, image textures through OBJ UVs, noise statistics, bad
input."""

import numpy as np
import pytest
from matplotlib.path import Path as MplPath
from scipy.spatial import ConvexHull

import cufund
from cufund.geometry import Transform
from cufund.sensors.camera import DepthCamera, RgbCamera, save_png
from cufund.sensors.camera_models import CameraCalibration, CameraIntrinsics
from cufund.worlds.materials import Material

IDENTITY = (1.0, 0.0, 0.0, 0.0)
DOWN = (np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0)  # body x (the camera's axis) pointing at world -z


def test_fronto_parallel_checker_has_the_analytic_pixel_scale():
    d, s = 4.0, 0.25  # plane 4 m ahead, 25 cm squares
    K = CameraIntrinsics(160, 120, 150.0, 150.0, 79.5, 59.5)
    w = cufund.World()
    checker = Material((1.0, 1.0, 1.0), "checker", scale=s, albedo2=(0.0, 0.0, 0.0))
    w.add_box((0.1, 20.0, 20.0), (d + 0.05, 0.0, 0.0), label="board", material=checker)
    img = RgbCamera(K, ambient=1.0, grayscale=True).render(w, (0.0, 0.0, 0.0), IDENTITY)
    # pixel (u, v) sees y = -(u - cx) d / fx, z = -(v - cy) d / fy on the plane: squares are fx s / d = 9.375 px wide
    u, v = np.meshgrid(np.arange(160.0), np.arange(120.0))
    y, z = -(u - K.cx) * d / K.fx, -(v - K.cy) * d / K.fy
    expect = np.where((np.floor(y / s) + np.floor(z / s)) % 2 == 0, 255, 0)
    px = s / (K.fx * s / d)  # metres per pixel
    away = (np.abs(y / s - np.round(y / s)) * s > px) & (np.abs(z / s - np.round(z / s)) * s > px)
    assert away.sum() > 0.5 * away.size
    np.testing.assert_array_equal(img[away], expect[away])
    # the row through the centre changes colour every 9.375 px
    edges = np.nonzero(np.diff(img[60].astype(int)))[0] + 0.5
    np.testing.assert_allclose(np.diff(edges), K.fx * s / d, atol=1.01)


def test_a_cube_shadows_the_floor_inside_the_polygon_the_sun_gives():
    n = 300
    K = CameraIntrinsics(n, n, 200.0, 200.0, (n - 1) / 2, (n - 1) / 2)
    w = cufund.World()
    w.add_plane((40.0, 40.0), (0.0, 0.0, 0.0), label="floor", color=(1.0, 1.0, 1.0))
    w.add_box((1.0, 1.0, 1.0), (0.0, 0.0, 0.5), label="cube", color=(1.0, 1.0, 1.0))
    sun = np.array([1.0, 0.5, 0.8]) / np.linalg.norm([1.0, 0.5, 0.8])
    cam = RgbCamera(K, light_W=sun, ambient=0.2, shadows=True, grayscale=True)
    h = 5.0
    img, ids, _ = cam.render(w, (0.0, 0.0, h), DOWN, want_ids=True)
    # the shadow: hull of the cube's footprint and its top corners moved along -sun down to z = 0
    corners = np.array([[x, y] for x in (-0.5, 0.5) for y in (-0.5, 0.5)])
    top = corners - sun[:2] * (1.0 / sun[2])
    pts = np.vstack([corners, top])
    poly = MplPath(pts[ConvexHull(pts).vertices])
    # looking straight down from h: pixel (u, v) sees the floor at x = -(v - cy) h / fy, y = -(u - cx) h / fx
    u, v = np.meshgrid(np.arange(float(n)), np.arange(float(n)))
    floor_xy = np.column_stack([(-(v - K.cy) * h / K.fy).ravel(), (-(u - K.cx) * h / K.fx).ravel()])
    margin = 2.0 * h / K.fx  # two pixels
    # matplotlib grows or shrinks the path by |radius| depending on its orientation: take both and order them
    a = poly.contains_points(floor_xy, radius=margin).reshape(n, n)
    b = poly.contains_points(floor_xy, radius=-margin).reshape(n, n)
    inside, outside = (a, ~b) if a.sum() < b.sum() else (b, ~a)
    floor = ids == 0
    lit = round(255 * (0.2 + 0.8 * sun[2]))
    assert (floor & inside).sum() > 1000 and (floor & outside).sum() > 0.5 * n * n
    np.testing.assert_array_equal(img[floor & inside], round(255 * 0.2))
    np.testing.assert_array_equal(img[floor & outside], lit)
    # without shadows the same floor is lit everywhere (the legacy two-sided look)
    flat = RgbCamera(K, light_W=sun, ambient=0.2, grayscale=True).render(w, (0.0, 0.0, h), DOWN)
    np.testing.assert_array_equal(flat[floor], lit)


def test_rolling_shutter_rows_see_the_scene_at_their_own_time():
    K = CameraIntrinsics(120, 90, 100.0, 100.0, 59.5, 44.5)
    d, speed, line = 5.0, 4.0, 1e-3  # wall 5 m ahead, 4 m/s sideways, 1 ms per row (a slow readout)
    w = cufund.World()
    # a white wall (a flat quad, no sides to see) on the world's y < 0 half (the image's right half): edge at y = 0
    quad = np.array([[d, 0.0, -10.0], [d, -20.0, -10.0], [d, -20.0, 10.0], [d, 0.0, 10.0]])
    w.add_mesh(quad, np.array([[0, 1, 2], [0, 2, 3]]), label="wall", color=(1.0, 1.0, 1.0))
    cam = RgbCamera(K, ambient=1.0, grayscale=True, sky=(0.0, 0.0, 0.0), line_time_s=line)
    np.testing.assert_allclose(cam.row_times(1.0), 1.0 + (np.arange(90) - 44.5) * line)
    img = cam.render(w, (0.0, 0.0, 0.0), IDENTITY, v_W=(0.0, speed, 0.0))
    first_bright = np.argmax(img > 127, axis=1)
    # row r is taken at t_r = (r - 44.5) line: the camera is at y = speed t_r, the edge at u = cx + fx y / d
    u_edge = K.cx + K.fx * speed * (np.arange(90) - 44.5) * line / d
    # the first bright pixel is the first pixel centre at or beyond the edge
    assert np.all(first_bright >= u_edge - 1e-3) and np.all(first_bright < u_edge + 1.0)  # float32 rays
    assert first_bright[-1] - first_bright[0] >= 6  # the skew is visible
    still = RgbCamera(K, ambient=1.0, grayscale=True, sky=(0.0, 0.0, 0.0)).render(w, (0, 0, 0), IDENTITY)
    assert len(set(np.argmax(still > 127, axis=1))) == 1  # a global shutter: one edge column
    # turning at 2 rad/s about z instead: row r looks along yaw = 2 t_r, the edge at u = cx + fx tan(yaw)
    img = cam.render(w, (0.0, 0.0, 0.0), IDENTITY, w_B=(0.0, 0.0, 2.0))
    first_bright = np.argmax(img > 127, axis=1)
    u_edge = K.cx + K.fx * np.tan(2.0 * (np.arange(90) - 44.5) * line)
    assert np.all(first_bright >= u_edge - 1e-3) and np.all(first_bright < u_edge + 1.0)  # float32 rays


def test_motion_blur_is_the_mean_of_the_images_over_the_exposure():
    K = CameraIntrinsics(120, 20, 100.0, 100.0, 59.5, 9.5)
    d, speed, exposure, n = 5.0, 2.0, 0.1, 9  # 0.2 m in the exposure = 4 px at 5 m
    w = cufund.World()
    quad = np.array([[d, 0.0, -10.0], [d, -20.0, -10.0], [d, -20.0, 10.0], [d, 0.0, 10.0]])
    w.add_mesh(quad, np.array([[0, 1, 2], [0, 2, 3]]), color=(1.0, 1.0, 1.0))
    cam = RgbCamera(K, ambient=1.0, grayscale=True, sky=(0.0, 0.0, 0.0), exposure_s=exposure, blur_samples=n)
    row = cam.render(w, (0, 0, 0), IDENTITY, v_W=(0.0, speed, 0.0))[10].astype(float)
    # sub-frame k at t_k = exposure ((k + 1/2) / n - 1/2) sees the edge at u = cx + fx speed t_k / d
    t_k = exposure * ((np.arange(n) + 0.5) / n - 0.5)
    u = np.arange(120.0)
    expect = np.mean([u >= K.cx + K.fx * speed * t / d for t in t_k], axis=0) * 255
    np.testing.assert_allclose(row, expect, atol=0.51)
    assert np.count_nonzero((row > 0) & (row < 255)) >= 3  # blurred over several pixels


def test_depth_and_rgb_of_one_camera_agree_on_silhouettes():
    K = CameraIntrinsics(96, 72, 60.0, 60.0, 47.5, 35.5, distortion=(-0.2, 0.05, 0.001, 0.0, 0.0))
    w = cufund.worlds.load("imav2025_tunnel")
    pose = ((-1.5, 0.3, 0.6), (np.cos(0.1), 0.0, 0.0, np.sin(0.1)))
    depth, d_ids, _ = DepthCamera(K, depth_max=1000.0, depth_min=0.0).render(w, *pose, want_ids=True)
    img, ids, labels = RgbCamera(K, shadows=True).render(w, *pose, want_ids=True)
    np.testing.assert_array_equal(np.isfinite(depth), ids >= 0)
    np.testing.assert_array_equal(d_ids, ids)
    assert "tunnel_frame" in {labels[i] for i in np.unique(ids[ids >= 0])}


@pytest.mark.parametrize("model", ["radtan", "equidistant"])
def test_projections_equal_opencv(model):
    cv2 = pytest.importorskip("cv2")
    rng = np.random.default_rng(4)
    if model == "radtan":
        D = (-0.28, 0.074, 0.0002, 1.8e-5, 0.01)
    else:
        D = (-0.01, 0.02, -0.005, 0.001)
    K = CameraIntrinsics(752, 480, 458.6, 457.3, 367.2, 248.4, D, model)
    # corners of boxes in front of the camera (optical frame), up to ~50 degrees off axis
    p_O = np.column_stack([rng.uniform(-1.2, 1.2, 200), rng.uniform(-0.8, 0.8, 200), rng.uniform(1.0, 5.0, 200)])
    uv = K.project(p_O)
    if model == "radtan":
        ref, _ = cv2.projectPoints(p_O, np.zeros(3), np.zeros(3), K.K, np.array(D))
    else:
        ref, _ = cv2.fisheye.projectPoints(p_O[:, None, :], np.zeros(3), np.zeros(3), K.K, np.array(D))
    np.testing.assert_allclose(uv, ref.reshape(-1, 2), atol=0.05)
    # and the rendered rays go where the model projects them: each pixel's direction projects onto that pixel
    u, v = np.meshgrid(np.arange(752.0), np.arange(480.0))
    back = K.project(K.pixel_directions().reshape(-1, 3))
    np.testing.assert_allclose(back, np.column_stack([u.ravel(), v.ravel()]), atol=1e-4)


def _quad_obj(tmp_path, texture_name="tex.png"):
    (tmp_path / "quad.obj").write_text(
        "mtllib materials.mtl\n"
        "v 0 1 -1\nv 0 -1 -1\nv 0 -1 1\nv 0 1 1\n"  # a 2 m square in the x = 0 plane facing -x
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "usemtl m\nf 1/1 3/3 2/2\nf 1/1 4/4 3/3\n"
    )
    (tmp_path / "materials.mtl").write_text(f"newmtl m\nKd 1 1 1\nmap_Kd {texture_name}\n")  # as mtllib names it


def test_an_image_texture_is_read_through_the_obj_uvs(tmp_path):
    tex = np.zeros((2, 2, 3), np.uint8)
    tex[0, 0], tex[0, 1], tex[1, 0], tex[1, 1] = (255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 255)
    save_png(tmp_path / "tex.png", tex)
    _quad_obj(tmp_path)
    w = cufund.World()
    obj = w.load_mesh(tmp_path / "quad.obj", position=(3.0, 0.0, 0.0))
    assert obj.uvs is not None and obj.material is not None and obj.material.texture == "image"
    K = CameraIntrinsics(41, 41, 20.0, 20.0, 20.0, 20.0)
    img = RgbCamera(K, ambient=1.0).render(w, (0.0, 0.0, 0.0), IDENTITY)
    # u (vt's first) runs from world y = +1 (image left) to -1, v (second) from z = -1 (bottom) to +1 (top);
    # the PNG's first row is the top of the texture (v = 1)
    np.testing.assert_array_equal(img[14, 14], (255, 0, 0))  # top left
    np.testing.assert_array_equal(img[14, 26], (0, 255, 0))  # top right
    np.testing.assert_array_equal(img[26, 14], (0, 0, 255))  # bottom left
    np.testing.assert_array_equal(img[26, 26], (255, 255, 255))


def test_an_obj_naming_a_file_outside_its_folder_is_refused(tmp_path):
    save_png(tmp_path / "outside.png", np.full((2, 2, 3), 200, np.uint8))
    (tmp_path / "outside.mtl").write_text("newmtl m\nmap_Kd tex.png\n")
    mesh = tmp_path / "mesh"
    mesh.mkdir()
    save_png(mesh / "tex.png", np.zeros((2, 2, 3), np.uint8))
    for name in ("../outside.png", str(tmp_path / "outside.png")):  # up and out, and an absolute path
        _quad_obj(mesh, name)
        with pytest.raises(ValueError, match=r"quad.obj.*map_Kd .* lies outside the mesh's folder"):
            cufund.World().load_mesh(mesh / "quad.obj")
    _quad_obj(mesh)
    for name in ("../outside.mtl", str(tmp_path / "outside.mtl")):
        (mesh / "quad.obj").write_text((mesh / "quad.obj").read_text().replace("materials.mtl", name))
        with pytest.raises(ValueError, match=r"quad.obj.*mtllib .* lies outside the mesh's folder"):
            cufund.World().load_mesh(mesh / "quad.obj")
        _quad_obj(mesh)
    assert cufund.World().load_mesh(mesh / "quad.obj").material is not None  # inside: read


def test_an_obj_whose_mtl_or_texture_is_a_fifo_loads_at_once(tmp_path):
    import os
    import threading
    import time

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    done = threading.Event()

    def unblock():  # after 10 s, readers blocked on the FIFO get end-of-file (nothing happens if none waits)
        wait = 10.0
        while not done.wait(wait):
            wait = 0.1
            try:
                os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
            except OSError:
                pass

    threading.Thread(target=unblock, daemon=True).start()
    try:
        _quad_obj(tmp_path, "fifo")  # map_Kd names the FIFO
        t0 = time.monotonic()
        with pytest.raises(ValueError, match=r"quad.obj.*map_Kd.*no image file"):
            cufund.World().load_mesh(tmp_path / "quad.obj")
        (tmp_path / "quad.obj").write_text((tmp_path / "quad.obj").read_text().replace("materials.mtl", "fifo"))
        assert cufund.World().load_mesh(tmp_path / "quad.obj").material is None  # mtllib names it: no MTL
        assert time.monotonic() - t0 < 5.0  # trimesh opened the FIFO and waited (for ever without a writer)
    finally:
        done.set()


def test_shot_and_read_noise_have_the_expected_spread_and_are_seeded():
    K = CameraIntrinsics(100, 100, 50.0, 50.0, 49.5, 49.5)
    w = cufund.World()
    w.add_box((0.1, 50.0, 50.0), (4.0, 0.0, 0.0), color=(0.5, 0.5, 0.5))
    kw = {"ambient": 1.0, "grayscale": True, "full_well_e": 2000.0, "read_noise_dn": 1.5, "seed": 3}
    a = RgbCamera(K, **kw).render(w, (0, 0, 0), IDENTITY).astype(float)
    b = RgbCamera(K, **kw).render(w, (0, 0, 0), IDENTITY).astype(float)
    np.testing.assert_array_equal(a, b)
    # Poisson: sigma = sqrt(0.5 * 2000) electrons = sqrt(1000) / 2000 * 255 DN, plus read noise, plus quantisation
    expect = np.sqrt((np.sqrt(1000.0) / 2000.0 * 255) ** 2 + 1.5**2 + 1 / 12)
    assert np.std(a) == pytest.approx(expect, rel=0.05)
    assert np.mean(a) == pytest.approx(127.5, abs=0.5)


def test_bad_input_gets_clear_errors(tmp_path):
    from PIL import Image

    Image.new("RGB", (9000, 1)).save(tmp_path / "wide.png")
    with pytest.raises(ValueError, match=r"must be between 1x1 and 8192x8192 px, got 9000x1"):
        Material(texture="image", image=str(tmp_path / "wide.png"))
    (tmp_path / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    with pytest.raises(ValueError, match="is not a readable PNG"):
        Material(texture="image", image=str(tmp_path / "broken.png"))
    _quad_obj(tmp_path, "missing.png")
    with pytest.raises(ValueError, match=r"quad.obj.*map_Kd.*no image file"):
        cufund.World().load_mesh(tmp_path / "quad.obj")
    with pytest.raises(ValueError, match="material.texture must be one of"):
        Material(texture="marble")
    with pytest.raises(ValueError, match=r"cam0.T_BC: t must be 3 finite numbers"):
        CameraCalibration(CameraIntrinsics(8, 8, 4, 4, 3.5, 3.5), {"p": [0.0, float("nan"), 0.0]})
    with pytest.raises(ValueError, match=r"q must be a finite unit quaternion"):
        CameraCalibration(CameraIntrinsics(8, 8, 4, 4, 3.5, 3.5), {"q": [1.0, 1.0, 0.0, 0.0]})
    with pytest.raises(ValueError, match="distortion must be 4 finite numbers"):
        CameraIntrinsics(8, 8, 4, 4, 3.5, 3.5, (0.1, 0.0, 0.0, 0.0, 0.0), "equidistant")
    with pytest.raises(ValueError, match="T_BC must be a cufund.geometry.Transform"):
        RgbCamera(CameraIntrinsics(8, 8, 4, 4, 3.5, 3.5), T_BC=np.eye(4))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="v_W must be 3 finite numbers"):
        RgbCamera(CameraIntrinsics(8, 8, 4, 4, 3.5, 3.5)).render(
            cufund.World(), (0, 0, 0), IDENTITY, v_W=(np.nan, 0, 0)
        )
    assert Transform() == CameraCalibration(CameraIntrinsics(8, 8, 4, 4, 3.5, 3.5)).T_BC


def test_world_yaml_materials_and_their_errors(tmp_path):
    from cufund.core.config import ConfigError
    from cufund.worlds.description import world_from_yaml

    tex = np.full((4, 4, 3), 200, np.uint8)
    save_png(tmp_path / "poster.png", tex)
    (tmp_path / "w.yaml").write_text(
        "objects:\n"
        "  - {type: box, size: [0.1, 4, 4], position: [3, 0, 0], material: {texture: image, image: poster.png, albedo: [1, 1, 1]}}\n"
        "  - {type: plane, size: [4, 4], position: [0, 0, -1], material: {texture: brick, scale: 0.25, seed: 2}}\n"
    )
    w = world_from_yaml(tmp_path / "w.yaml")
    assert w.objects[0].material.image == str(tmp_path / "poster.png")
    assert w.objects[1].material.texture == "brick"
    img = RgbCamera(CameraIntrinsics(9, 9, 5.0, 5.0, 4.0, 4.0), ambient=1.0).render(w, (0, 0, 0), IDENTITY)
    np.testing.assert_array_equal(img[4, 4], (200, 200, 200))  # the PNG tiled on the box face
    (tmp_path / "bad.yaml").write_text(
        "objects:\n  - {type: box, size: [1, 1, 1], position: [0, 0, 0], material: {shine: 1}}\n"
    )
    with pytest.raises(ConfigError, match=r"objects\[0\] \(box\): unknown key 'shine' in material"):
        world_from_yaml(tmp_path / "bad.yaml")


@pytest.mark.parametrize("texture", ["noise", "brick", "bark", "concrete"])
@pytest.mark.parametrize("object_id", [0, 3])
def test_rendered_textures_equal_the_material_at_the_hit_points(texture, object_id):
    K = CameraIntrinsics(64, 48, 40.0, 40.0, 31.5, 23.5)
    mat = Material((0.9, 0.6, 0.3), texture, scale=0.2, contrast=0.8, seed=5)
    w = cufund.World()
    for _ in range(object_id):  # out of sight, behind the camera
        w.add_box((0.1, 0.1, 0.1), (-5.0, 0.0, 1.0), material=mat)
    w.add_box((0.1, 20.0, 20.0), (3.05, 0.0, 1.0), material=mat)
    # each object's texture is shifted by its id (object 0: not at all)
    offset = np.asarray(object_id * np.array([7.31, 3.17]) % 97.0)
    img = RgbCamera(K, ambient=1.0).render(w, (0.0, 0.0, 1.0), IDENTITY)
    depth = DepthCamera(K, depth_max=100.0).render(w, (0.0, 0.0, 1.0), IDENTITY)
    # hit points from the depth image: optical (x, y, 1) * depth -> world (z_O, -x_O, -y_O) + camera position
    d_O = K.pixel_directions() * depth[..., None]
    p_W = np.stack([d_O[..., 2], -d_O[..., 0], 1.0 - d_O[..., 1]], -1).reshape(-1, 3)
    expect = mat.albedo_at(p_W, np.tile([-1.0, 0.0, 0.0], (len(p_W), 1)), offset=offset)
    np.testing.assert_allclose(img.reshape(-1, 3) / 255.0, expect, atol=1.0 / 255 + 1e-3)
    assert np.std(img) > 10  # a texture, not a flat colour


def test_an_image_texture_is_kept_at_three_bytes_a_texel(tmp_path):
    from PIL import Image

    from cufund.worlds.materials import _load_image

    big = tmp_path / "big.png"
    Image.new("RGB", (2048, 2048), (10, 20, 255)).save(big)  # a few kB on disk: 48 MB as float32
    assert big.stat().st_size < 100_000
    m = Material(texture="image", image=str(big), albedo=(1.0, 1.0, 1.0))
    assert _load_image(str(big)).nbytes == 2048 * 2048 * 3
    rgb = m.albedo_at(np.zeros((2, 3)), np.array([[1.0, 0, 0]] * 2), np.array([[0.1, 0.2], [0.9, 0.7]]))
    np.testing.assert_array_equal(rgb, np.float32([10, 20, 255]) / np.float32(255.0) * np.ones((2, 1)))


def test_hostile_png_textures_raise_value_errors_only(tmp_path):
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    good = tmp_path / "good.png"
    save_png(good, np.zeros((3, 5, 3), np.uint8))
    png = good.read_bytes()

    @settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(st.integers(0, len(png)), st.binary(max_size=40), st.integers(0, len(png)))
    def check(at, junk, cut):
        path = tmp_path / f"t{at}_{cut}_{len(junk)}.png"
        path.write_bytes((png[:at] + junk + png[at:])[: max(cut, 1)])
        try:
            Material(texture="image", image=str(path))
        except ValueError:
            pass

    check()
