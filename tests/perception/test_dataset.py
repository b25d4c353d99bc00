"""Labelled data from the renderer (issue 26 item 1): boxes enclose exactly their instance masks, occlusion and
truncation fractions match pixel counts worked out by hand from the pinhole model (and the object rendered alone
by the depth camera), and `cufund dataset` writes the same YOLO/COCO files for the same seed."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from cufund.apps.cli import main
from cufund.geometry import yaw_quaternion
from cufund.perception.dataset import DatasetParams, Randomisation, write_dataset
from cufund.perception.dataset_labels import ViewLabeller, upright_box
from cufund.sensors.camera import CameraIntrinsics, DepthCamera
from cufund.worlds import labelled_objects as lo
from cufund.worlds.world import World

# 64 x 48 pinhole, principal point between pixel centres (no pixel centre lies on the axis)
K = CameraIntrinsics(64, 48, 80.0, 80.0, 31.5, 23.5)
EYE = (0.0, 0.0, 1.0)  # camera at 1 m looking along +x (the body is the camera: T_BC identity)


def _columns(y_left: float, y_right: float, x: float) -> np.ndarray:
    """Pixel columns whose centre ray (u = cx - fx y / x) meets y in [y_right, y_left] at distance x."""
    u_lo, u_hi = K.cx - K.fx * y_left / x, K.cx - K.fx * y_right / x
    return np.arange(math.ceil(u_lo), math.floor(u_hi) + 1)


def _rows(z_top: float, z_bottom: float, x: float) -> np.ndarray:
    v_lo, v_hi = K.cy - K.fy * (z_top - EYE[2]) / x, K.cy - K.fy * (z_bottom - EYE[2]) / x
    return np.arange(math.ceil(v_lo), math.floor(v_hi) + 1)


def _plate(world: World, y: tuple[float, float], z: tuple[float, float], x: float, label: str):
    """A thin box facing the camera: its near face at distance x, spanning y and z."""
    size = (0.02, y[1] - y[0], z[1] - z[0])
    return world.add_box(size, (x + 0.01, (y[0] + y[1]) / 2, (z[0] + z[1]) / 2), label=label)


def test_box_and_mask_of_a_plate_from_the_pinhole_model():
    w = World()
    target = _plate(w, (-0.53, 0.71), (0.62, 1.37), 10.0, "gate")
    (obj,) = ViewLabeller(w, K, lo.CLASSES).label(EYE, yaw_quaternion(0.0)).objects
    cols, rows = _columns(0.71, -0.53, 10.0), _rows(1.37, 0.62, 10.0)
    assert obj.instance_id == target.id and obj.class_name == "gate" and obj.class_id == lo.CLASSES.index("gate")
    assert obj.box_xyxy == (cols[0], rows[0], cols[-1] + 1, rows[-1] + 1)
    assert obj.visible_px == obj.unoccluded_px == len(cols) * len(rows)
    assert obj.occlusion == 0.0 and obj.truncation == 0.0


def test_occlusion_is_the_share_of_the_unoccluded_pixels_hidden():
    """An unlabelled wall at 5 m covering y in [0.1, 3] hides the target's columns left of u = cx - fx 0.1 / 5."""
    w = World()
    target = _plate(w, (-1.0, 1.0), (0.5, 1.5), 10.0, "person")
    _plate(w, (0.1, 3.0), (0.0, 3.0), 5.0, "wall")
    labels = ViewLabeller(w, K, lo.CLASSES).label(EYE, yaw_quaternion(0.0))
    (obj,) = labels.objects  # the wall is no class
    cols, rows = _columns(1.0, -1.0, 10.0), _rows(1.5, 0.5, 10.0)
    hidden = cols[cols <= K.cx - K.fx * 0.1 / 5.0]
    assert 0 < len(hidden) < len(cols)
    assert obj.unoccluded_px == len(cols) * len(rows)
    assert obj.visible_px == (len(cols) - len(hidden)) * len(rows) == int((labels.instance_ids == target.id).sum())
    assert obj.occlusion == pytest.approx(len(hidden) / len(cols), abs=1e-12)
    # the unoccluded count is what the depth camera sees of the target alone
    alone = World()
    _plate(alone, (-1.0, 1.0), (0.5, 1.5), 10.0, "person")
    depth = DepthCamera(K, depth_max=100.0).render(alone, EYE, yaw_quaternion(0.0))
    assert isinstance(depth, np.ndarray)
    assert obj.unoccluded_px == int(np.isfinite(depth).sum())
    # the box is around the visible part only
    visible_cols = cols[cols > K.cx - K.fx * 0.1 / 5.0]
    assert obj.box_xyxy == (visible_cols[0], rows[0], visible_cols[-1] + 1, rows[-1] + 1)
    assert np.all(labels.class_ids[labels.instance_ids == target.id] == lo.CLASSES.index("person"))
    assert np.all(labels.class_ids[labels.instance_ids != target.id] == -1)


def test_truncation_is_the_share_of_the_object_beyond_the_frame():
    """A plate spanning u from inside the frame to beyond its right edge (u = 63 is the last column)."""
    w = World()
    _plate(w, (-6.0, -2.2), (0.8, 1.2), 10.0, "car")
    (obj,) = ViewLabeller(w, K, lo.CLASSES).label(EYE, yaw_quaternion(0.0)).objects
    cols = _columns(-2.2, -6.0, 10.0)
    inside = cols[cols < K.width]
    assert 0 < len(inside) < len(cols) and cols[-1] < 2 * K.width  # within the 3x canvas
    assert obj.truncation == pytest.approx(1 - len(inside) / len(cols), abs=1e-12)
    assert obj.box_xyxy[2] == K.width and obj.occlusion == 0.0


def test_upright_box_of_a_turned_car():
    w = World()
    car = lo.add_car(w, (3.0, -2.0, 0.0), yaw=0.4)
    b = upright_box(car.vertices)
    np.testing.assert_allclose(b.centre_W[:2], (3.0, -2.0), atol=0.02)
    assert b.yaw == pytest.approx(0.4, abs=np.deg2rad(0.5))
    np.testing.assert_allclose(b.size, (4.2, 1.8, 1.45), atol=0.05)
    corners = b.corners_W()
    assert corners.shape == (8, 3) and corners[:, 2].min() == pytest.approx(0.0, abs=1e-9)


def _world() -> World:
    w = World("test")
    w.add_plane((30.0, 30.0), (0.0, 0.0, 0.0))
    for k in range(3):
        lo.add_tunnel_frame(w, (4.0 + 2 * k, 0.0, 0.0))
    w.add_cylinder(0.3, 4.0, (6.0, 3.0, 2.0), label="tree")
    lo.scatter(w, np.random.default_rng(3), 6)
    return w


def _png(path: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path))


SMALL = CameraIntrinsics.from_fov(160, 120, 1.2)
FEW = DatasetParams(frames=6, seed=7, min_box_px=1, randomisation=Randomisation(distance_m=(3.0, 9.0)))


def test_dataset_boxes_enclose_exactly_their_instance_masks(tmp_path):
    w = _world()
    summary = write_dataset(w, tmp_path / "d", FEW, SMALL, source="test")
    d = tmp_path / "d"
    coco = json.loads((d / "annotations.json").read_text())
    assert summary["frames"] == 6 and summary["val"] == 1 and sum(summary["boxes"].values()) == len(coco["annotations"])
    assert [c["name"] for c in coco["categories"]] == list(lo.CLASSES)
    assert len(coco["annotations"]) >= 10
    by_image: dict[int, list[dict]] = {}
    for a in coco["annotations"]:
        by_image.setdefault(a["image_id"], []).append(a)
    for im in coco["images"]:
        stem = Path(im["file_name"]).stem
        instance = _png(d / "masks" / f"{stem}_instance.png").astype(np.int64) - 1
        classes = _png(d / "masks" / f"{stem}_class.png").astype(np.int64) - 1
        assert instance.shape == (120, 160)
        anns = by_image.get(im["id"], [])
        lines = (d / im["file_name"].replace("images/", "labels/").replace(".png", ".txt")).read_text().splitlines()
        assert len(lines) == len(anns)
        for a, line in zip(anns, lines, strict=True):
            mask = instance == a["cufund"]["instance_id"]
            rows, cols = np.nonzero(mask)
            x, y, bw, bh = a["bbox"]
            assert (x, y, x + bw, y + bh) == (cols.min(), rows.min(), cols.max() + 1, rows.max() + 1)
            assert a["area"] == int(mask.sum()) == a["cufund"]["visible_px"]
            assert np.all(classes[mask] == a["category_id"] - 1)
            occ = 1 - a["area"] / a["cufund"]["unoccluded_px"]
            assert a["cufund"]["occlusion"] == pytest.approx(occ, abs=1e-12)
            assert w.objects[a["cufund"]["instance_id"]].label == lo.CLASSES[a["category_id"] - 1]
            c, uc, vc, ww, hh = line.split()
            assert int(c) == a["category_id"] - 1
            np.testing.assert_allclose(
                [float(uc) * 160, float(vc) * 120, float(ww) * 160, float(hh) * 120],
                [x + bw / 2, y + bh / 2, bw, bh],
                atol=1e-3,
            )
        # every labelled object seen has an annotation (min_box_px = 1)
        seen = {int(i) for i in np.unique(instance[classes >= 0])}
        assert seen == {a["cufund"]["instance_id"] for a in anns}
    data = yaml.safe_load((d / "data.yaml").read_text())
    assert data["train"] == "images/train" and data["names"] == dict(enumerate(lo.CLASSES))
    assert len(list((d / "images" / "val").glob("*.png"))) == 1


def test_the_labels_are_the_rendered_images_own_pixels():
    """The labels come from the labeller's own cast, the image from the renderer (the recoloured copy of the
    world): the renderer's object id at every pixel is the label's instance id, for views at targets and
    negatives."""
    from cufund.perception.dataset import render_frame
    from cufund.sensors.camera import RgbCamera

    w = _world()
    labeller = ViewLabeller(w, SMALL, lo.CLASSES)
    rng = np.random.default_rng(5)
    seen = 0
    for k in range(4):
        _, labels, draws = render_frame(w, labeller, rng, Randomisation(), negative=k == 0)
        out = RgbCamera(SMALL).render(w, draws["p_W"], draws["q_WB"], want_ids=True)
        assert isinstance(out, tuple)
        np.testing.assert_array_equal(out[1], labels.instance_ids)
        seen += len(labels.objects)
    assert seen >= 4


def test_dataset_is_the_same_for_the_same_seed(tmp_path):
    w = _world()
    write_dataset(w, tmp_path / "a", FEW, SMALL)
    write_dataset(w, tmp_path / "b", FEW, SMALL)
    files = sorted(p.relative_to(tmp_path / "a") for p in (tmp_path / "a").rglob("*") if p.is_file())
    assert len(files) > 20
    for f in files:
        if f.name != "data.yaml":  # its 'path' is the folder
            assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes(), f
    other = DatasetParams(frames=6, seed=8, min_box_px=1, randomisation=FEW.randomisation)
    write_dataset(w, tmp_path / "c", other, SMALL)
    assert (tmp_path / "a/images/train/000001.png").read_bytes() != (
        tmp_path / "c/images/train/000001.png"
    ).read_bytes()


def test_a_flat_world_is_seen_from_above_its_objects(tmp_path):
    """A ground with landing pads (the world 6 cm high) and a car: cameras at 0.4-4 m are above the world's
    top, which is no wall (every draw was refused, and the frame failed with no camera pose), so heights above
    the car's roof are drawn too."""
    w = World("flat")
    w.add_plane((30.0, 30.0), (0.0, 0.0, 0.0))
    lo.add_landing_pad(w, (2.0, 1.0, 0.0))
    lo.add_landing_pad(w, (-3.0, -2.0, 0.0))
    params = DatasetParams(frames=4, seed=1, negative_fraction=0.0, min_box_px=1)
    summary = write_dataset(w, tmp_path / "pads", params, SMALL)
    assert summary["boxes"]["landing_pad"] >= 4
    lo.add_car(w, (6.0, 5.0, 0.0))
    many = DatasetParams(frames=12, seed=2, negative_fraction=0.0, min_box_px=1)
    write_dataset(w, tmp_path / "car", many, SMALL)
    heights = [f["p_W"][2] for f in json.loads((tmp_path / "car" / "dataset.json").read_text())["frames"]]
    assert max(heights) > 1.45  # above the car's roof, the world's top


def test_ultralytics_reads_the_dataset(tmp_path, monkeypatch):
    pytest.importorskip("ultralytics")
    monkeypatch.setenv("YOLO_OFFLINE", "1")
    monkeypatch.setenv("YOLO_CONFIG_DIR", str(tmp_path / "settings"))
    write_dataset(_world(), tmp_path / "d", FEW, SMALL)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from ultralytics.data.utils import check_det_dataset, verify_image_label

        data = check_det_dataset(str(tmp_path / "d" / "data.yaml"), autodownload=False)
        assert data["nc"] == len(lo.CLASSES) and list(data["names"].values()) == list(lo.CLASSES)
        for img in sorted((tmp_path / "d" / "images" / "train").glob("*.png")):
            label = Path(str(img).replace("/images/", "/labels/")).with_suffix(".txt")
            out = verify_image_label((str(img), str(label), "", False, len(lo.CLASSES), 0, 0, False))
            assert out[-1] == "" or "WARNING" not in out[-1], out[-1]  # its message: '' when the pair is valid
            assert out[0] is not None


def test_cli_writes_a_dataset_and_refuses_bad_arguments(tmp_path, capsys):
    out = tmp_path / "tun"
    args = ["dataset", "tunnel", "--out", str(out), "--frames", "2", "--width", "96", "--height", "72"]
    assert main([*args, "--scatter", "2", "--no-progress"]) == 0
    assert json.loads((out / "dataset.json").read_text())["seed"] == 0
    assert len(list((out / "images").rglob("*.png"))) == 2
    assert main(args) == 2
    assert "exists and is not an empty folder" in capsys.readouterr().err
    assert main(["dataset", "tunnel", "--out", str(tmp_path / "x"), "--frames", "0"]) == 2
    assert "frames must be an integer in [1, 1000000], got 0" in capsys.readouterr().err
    assert main(["dataset", "nowhere", "--out", str(tmp_path / "y")]) == 2
    assert "unknown scenario 'nowhere'" in capsys.readouterr().err
    assert main(["dataset", "tunnel", "--out", str(tmp_path / "z"), "--classes", "car"]) == 2
    assert "holds no object labelled car" in capsys.readouterr().err


def test_params_are_checked_naming_the_field():
    with pytest.raises(ValueError, match=r"randomisation.exposure must be \[min, max\]"):
        Randomisation(exposure=(2.0, 1.0))
    with pytest.raises(ValueError, match="negative_fraction must be in"):
        DatasetParams(negative_fraction=2)
    with pytest.raises(ValueError, match="classes must be distinct"):
        DatasetParams(classes=("a", "a"))
    with pytest.raises(ValueError, match="leg_swing must be 2 angles"):
        lo.person_mesh(leg_swing=(0.0, 3.0))


def test_scattered_objects_stand_on_free_ground():
    w = World()
    w.add_plane((20.0, 20.0), (0.0, 0.0, 0.0))
    trees = [w.add_cylinder(0.4, 6.0, (x, y, 3.0), label="tree") for x in (-4.0, 0.0, 4.0) for y in (-4.0, 0.0, 4.0)]
    added = lo.scatter(w, np.random.default_rng(0), 8, kinds=("person", "landing_pad"))
    assert len(added) == 8 and {o.label for o in added} <= {"person", "landing_pad"}
    for o in added:
        assert o.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-9)
        for t in trees:
            gap = np.hypot(*(o.vertices[:, :2] - t.vertices[:, :2].mean(0)).T).min()
            assert gap > 0.4  # outside every trunk


def test_a_distorted_camera_counts_the_unoccluded_pixels_through_its_own_rays():
    """With lens distortion the canvas is not the image: the object alone is cast through the image's own rays,
    which the depth camera (the same lens) sees too."""
    Kd = CameraIntrinsics(64, 48, 80.0, 80.0, 31.5, 23.5, distortion=(-0.2, 0.05, 0.001, -0.001, 0.0))
    w = World()
    _plate(w, (-1.0, 1.0), (0.5, 1.5), 10.0, "person")
    _plate(w, (0.1, 3.0), (0.0, 3.0), 5.0, "wall")
    (obj,) = ViewLabeller(w, Kd, lo.CLASSES).label(EYE, yaw_quaternion(0.0)).objects
    alone = World()
    _plate(alone, (-1.0, 1.0), (0.5, 1.5), 10.0, "person")
    depth = DepthCamera(Kd, depth_max=100.0).render(alone, EYE, yaw_quaternion(0.0))
    assert isinstance(depth, np.ndarray)
    assert obj.unoccluded_px == int(np.isfinite(depth).sum()) > obj.visible_px > 0
    assert obj.occlusion == pytest.approx(1 - obj.visible_px / obj.unoccluded_px)


# --- course views ------------------------------------------------------------------------------------------
FLIGHT_SMALL = CameraIntrinsics(160, 120, 100.0, 100.0, 79.5, 59.5)
"""The flight camera (640 x 480, fx = fy = 400 px) at a quarter of its size: the same field of view."""


def _course_dataset(tmp_path: Path, seed: int = 301, frames: int = 10, **kwargs):
    from cufund.missions.tunnel_course import tunnel_course_layout

    layout = tunnel_course_layout(seed)
    params = DatasetParams(frames=frames, seed=4, min_box_px=1, negative_fraction=0.0, views="course", **kwargs)
    out = tmp_path / f"course_{seed}"
    write_dataset(layout.world, out, params, FLIGHT_SMALL, course=layout.frames)
    return layout, out


def test_a_course_view_sees_the_frame_it_aims_at_from_where_the_vehicle_flies(tmp_path):
    """Each view stands on frame k's axis (within the jitter) between 3 m before it and 0.2 m past frame k-1, at
    the opening's height, facing along the course; frame k is in the image (the renderer's own ids at that pose)
    and in the labels; the views hold nested frames (more than one frame in most images)."""
    from cufund.geometry import quat_to_matrix
    from cufund.sensors.camera import RgbCamera

    layout, out = _course_dataset(tmp_path)
    meta = json.loads((out / "dataset.json").read_text())
    coco = json.loads((out / "annotations.json").read_text())
    assert meta["views"] == "course" and len(meta["course_frames"]) == len(layout.frames) == 5
    aimed = set()
    several = 0
    for i, f in enumerate(meta["frames"]):
        k = f["course_frame"]
        aimed.add(k)
        frame = layout.frames[k]
        c, axis = np.asarray(frame.centre_W), frame.axis_W
        across = np.array([-axis[1], axis[0], 0.0])
        p = np.asarray(f["p_W"])
        before = float((c - p) @ axis)
        near = 0.3 if k == 0 else max(0.3, float((c - np.asarray(layout.frames[k - 1].centre_W)) @ axis) - 0.2)
        assert near - 1e-9 <= before <= 3.0 + 1e-9
        assert abs(float((p - c) @ across)) <= 0.25 + 1e-9
        assert abs(p[2] - c[2]) <= 0.25 + 1e-9
        x_B = quat_to_matrix(np.asarray(f["q_WB"]))[:, 0]  # the camera's view direction
        heading = math.atan2(x_B[1], x_B[0])
        assert abs(math.remainder(heading - frame.yaw, 2 * math.pi)) <= math.radians(15.0) + 1e-6
        assert abs(x_B[2]) <= math.sin(math.radians(5.0)) + 1e-9
        # the frame aimed at: its mesh is the world object centred on its opening
        oid = min(layout.world.objects, key=lambda o: np.linalg.norm(o.vertices.mean(0) - c)).id
        rendered = RgbCamera(FLIGHT_SMALL).render(layout.world, p, f["q_WB"], want_ids=True)
        assert isinstance(rendered, tuple) and np.any(rendered[1] == oid)
        instances = {a["cufund"]["instance_id"] for a in coco["annotations"] if a["image_id"] == i + 1}
        assert oid in instances
        frames_seen = {j for j in instances if layout.world.objects[j].vertices[:, 2].max() > 0.4}
        several += len(frames_seen) > 1
    assert len(aimed) >= 3 and several >= 7


def test_random_views_are_unchanged_by_course_views(tmp_path):
    """views='random' (the default) writes the files it wrote before course views existed: the same as the
    default parameters, with no course record in dataset.json."""
    w = _world()
    write_dataset(w, tmp_path / "a", FEW, SMALL)
    explicit = DatasetParams(frames=6, seed=7, min_box_px=1, randomisation=FEW.randomisation, views="random")
    write_dataset(w, tmp_path / "b", explicit, SMALL)
    files = sorted(p.relative_to(tmp_path / "a") for p in (tmp_path / "a").rglob("*") if p.is_file())
    for f in files:
        if f.name != "data.yaml":
            assert (tmp_path / "a" / f).read_bytes() == (tmp_path / "b" / f).read_bytes(), f
    meta = json.loads((tmp_path / "a" / "dataset.json").read_text())
    assert "views" not in meta and "course_frames" not in meta
    assert all("course_frame" not in f for f in meta["frames"])


def test_course_views_refuse_bad_values_naming_them(tmp_path, capsys):
    from cufund.core.config import ConfigError
    from cufund.missions.tunnel_course import TunnelFrame, tunnel_course_layout
    from cufund.perception.dataset import CourseViews

    with pytest.raises(ConfigError, match="views must be one of random, course, got 'orbit'"):
        DatasetParams(views="orbit")
    with pytest.raises(ConfigError, match=r"randomisation.course.distance_m must be \[min, max\]"):
        CourseViews(distance_m=(3.0, 1.0))
    with pytest.raises(ConfigError, match=r"course.lateral_m must be a number in \[0, 10\], got -0.1"):
        CourseViews(lateral_m=-0.1)
    layout = tunnel_course_layout(301)
    params = DatasetParams(frames=1, views="course")
    with pytest.raises(ConfigError, match="views: course needs the world's course"):
        write_dataset(layout.world, tmp_path / "a", params, FLIGHT_SMALL)
    with pytest.raises(ConfigError, match="a course was given, but views is 'random'"):
        write_dataset(layout.world, tmp_path / "b", DatasetParams(frames=1), FLIGHT_SMALL, course=layout.frames)
    elsewhere = [TunnelFrame((20.0, 0.0, 1.0), 0.0, 0.5, 0.5)]
    with pytest.raises(ConfigError, match=r"course\[0\] \(centre_W \[20.0, 0.0, 1.0\]\) is no object of the world"):
        write_dataset(layout.world, tmp_path / "c", params, FLIGHT_SMALL, course=elsewhere)
    with pytest.raises(ConfigError, match=r"course\[0\].yaw must be a finite number"):
        write_dataset(layout.world, tmp_path / "d", params, FLIGHT_SMALL, course=[TunnelFrame((0, 0, 1), None, 1, 1)])
    assert main(["dataset", "square_lio", "--out", str(tmp_path / "e"), "--views", "course", "--no-progress"]) == 2
    assert "--views course needs a scenario on the tunnel_course world; 'square_lio' is not" in capsys.readouterr().err


def test_cli_course_views_use_the_flight_camera(tmp_path):
    out = tmp_path / "c"
    args = ["dataset", "tunnel", "--out", str(out), "--frames", "1", "--views", "course", "--no-progress"]
    assert main([*args, "--set", "world.seed=301"]) == 0
    meta = json.loads((out / "dataset.json").read_text())
    cam = meta["camera"]
    assert (cam["width"], cam["height"], cam["fx"], cam["fy"]) == (640, 480, 400.0, 400.0)
    assert meta["views"] == "course" and len(meta["course_frames"]) == 5
