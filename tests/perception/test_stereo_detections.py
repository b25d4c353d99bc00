"""Detections3D from a stereo pair (issue 26): each box's depth from its disparity in the right image, checked
against the renderer's own depth image of the same scene and against the known position of the object."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
from onnx import TensorProto, helper, numpy_helper  # noqa: E402

from cufund.core.bus import Bus, BusView  # noqa: E402
from cufund.core.config import ConfigError  # noqa: E402
from cufund.core.messages import CameraImage, Detections3D, Odometry, Topics  # noqa: E402
from cufund.geometry import Transform, quat_to_matrix, yaw_quaternion  # noqa: E402
from cufund.perception.onnx_detector import OnnxDetector  # noqa: E402
from cufund.perception.onnx_detector_component import (  # noqa: E402
    OnnxDetectorComponent,
    box_depths,
    stereo_box_depths,
    stereo_boxes_to_world,
)
from cufund.perception.stereo_depth import box_disparities, stereo_baseline  # noqa: E402
from cufund.sensors.camera import CameraIntrinsics, DepthCamera, RgbCamera  # noqa: E402
from cufund.worlds.builtin import textured  # noqa: E402
from cufund.worlds.labelled_objects import add_person  # noqa: E402
from cufund.worlds.world import World  # noqa: E402

K = CameraIntrinsics(320, 240, 300.0, 300.0, 159.5, 119.5)
B = 0.3
Q_DOWN = (0.9659258, 0.0, 0.258819, 0.0)  # pitched 30 deg down about body y
T_LEFT = Transform((0.1, B / 2, -0.05), Q_DOWN)
T_RIGHT = Transform((0.1, -B / 2, -0.05), Q_DOWN)
PERSON = np.array([10.0, 0.4, 0.0])  # the person's feet [m]
NAMES = {0: "tunnel_frame", 1: "gate", 2: "landing_pad", 3: "person", 4: "car"}


def _scene() -> tuple[World, int]:
    world = World("stereo")
    ground = textured((0.35, 0.3, 0.2), "noise", 0.05, 21)
    world.add_plane((80.0, 80.0), (0.0, 0.0, 0.0), label="ground", color=(0.35, 0.3, 0.2), material=ground)
    bark = textured((0.4, 0.25, 0.1), "bark", 0.3, 22)
    world.add_cylinder(0.25, 8.0, (16.0, -2.0, 4.0), label="tree", color=(0.4, 0.25, 0.1), material=bark)
    person = add_person(world, PERSON, yaw=0.7, arm_swing=(0.3, -0.2))
    return world, person.id


def _views(world: World, pid: int, p_WB: np.ndarray) -> tuple[np.ndarray, ...]:
    """(left, right, depth, box of the person from its instance mask) seen from body position p_WB, level."""
    q = np.array([1.0, 0.0, 0.0, 0.0])
    left, ids, _ = RgbCamera(K, T_LEFT).render(world, p_WB, q, want_ids=True)
    right = RgbCamera(K, T_RIGHT).render(world, p_WB, q)
    depth = DepthCamera(K, T_LEFT, 0.1, 100.0).render(world, p_WB, q)
    ys, xs = np.nonzero(ids == pid)
    assert len(xs) > 50, "the person must be in view"
    box = np.array([[xs.min(), ys.min(), xs.max() + 1, ys.max() + 1]], float)  # pixel edges
    return left, right, depth, box


@pytest.mark.parametrize("back, height", [(4.0, 3.0), (8.0, 5.0), (12.0, 6.0)])
def test_stereo_depth_of_a_person_matches_the_rendered_depth_and_its_position(back, height):
    """A person seen 6-15 m away by a 0.3 m stereo pair: the depth from the box's disparity is within 3 % of the
    median of the renderer's own depth image over the same box's middle, and the box placed at it lies on the
    person: within 0.35 m of its vertical axis horizontally, between its feet and head."""
    world, pid = _scene()
    p_WB = np.array([PERSON[0] - back, PERSON[1] - 0.3, height])
    left, right, depth, box = _views(world, pid, p_WB)
    z_stereo = stereo_box_depths(box, left, right, K, B)
    z_render = box_depths(box, depth, K, K)
    assert np.isfinite(z_stereo[0]) and np.isfinite(z_render[0])
    assert abs(z_stereo[0] - z_render[0]) < 0.03 * z_render[0], (z_stereo, z_render)
    centres, sizes, ok = stereo_boxes_to_world(box, left, right, K, B, T_LEFT, p_WB, np.eye(3))
    assert ok[0]
    assert np.linalg.norm(centres[0, :2] - PERSON[:2]) < 0.35, centres[0]
    assert 0.0 < centres[0, 2] < 1.75
    assert 0.2 < sizes[0, 0] < 1.5 and 1.0 < sizes[0, 1] < 3.0  # the box at the person's depth: a person's size


def test_disparity_of_a_shifted_image_is_the_shift():
    """A textured image and its copy shifted left by 7.25 px (linear interpolation): every box's disparity is
    7.25 px to within 0.15 px; a flat box (no texture) and a box off the image have none."""
    rng = np.random.default_rng(3)
    left = (rng.random((120, 200)) * 255).astype(np.float32)
    left = (left + np.roll(left, 1, 1) + np.roll(left, 1, 0)) / 3  # some correlation between neighbours
    shift = 7.25
    cols = np.arange(200) + shift
    right = np.array([np.interp(cols, np.arange(200), row) for row in left], np.float32)
    boxes = np.array([[60, 30, 100, 70], [120, 50, 170, 110], [-40, 0, -10, 20]], float)
    d, ok = box_disparities(left, right, boxes, max_disparity=32)
    assert ok.tolist() == [True, True, False]
    np.testing.assert_allclose(d[:2], shift, atol=0.15)
    flat = np.full((120, 200), 90.0, np.float32)
    d, ok = box_disparities(flat, flat, boxes[:1])
    assert not ok[0] and np.isnan(d[0])
    with pytest.raises(ValueError, match="same size"):
        box_disparities(left, right[:, :100], boxes)


def test_stereo_baseline_accepts_only_a_rectified_pair():
    assert stereo_baseline(K, K, T_LEFT, T_RIGHT) == pytest.approx(B)
    with pytest.raises(ValueError, match="same pinhole"):
        stereo_baseline(K, CameraIntrinsics(320, 240, 310.0, 300.0, 159.5, 119.5), T_LEFT, T_RIGHT)
    with pytest.raises(ValueError, match="parallel"):
        stereo_baseline(K, K, T_LEFT, Transform(T_RIGHT.t, tuple(yaw_quaternion(0.05))))
    with pytest.raises(ValueError, match="right of the left one"):
        stereo_baseline(K, K, T_RIGHT, T_LEFT)  # swapped
    with pytest.raises(ValueError, match="right of the left one"):
        stereo_baseline(K, K, T_LEFT, Transform((0.1, -B / 2, 0.05), Q_DOWN))  # also 0.1 m above
    distorted = CameraIntrinsics(320, 240, 300.0, 300.0, 159.5, 119.5, distortion=(0.1, 0.0, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="undistorted"):
        stereo_baseline(distorted, distorted, T_LEFT, T_RIGHT)


def _model(rows: np.ndarray, path: Path, size: int) -> Path:
    """A model of input (1, 3, size, size) whose output0 is ``rows`` (plus 0 x the input's mean)."""
    nodes = [
        helper.make_node("ReduceMean", ["images"], ["m"], keepdims=0),
        helper.make_node("Mul", ["m", "zero"], ["z"]),
        helper.make_node("Add", ["c", "z"], ["output0"]),
    ]
    inits = [numpy_helper.from_array(np.zeros((), np.float32), "zero"), numpy_helper.from_array(rows, "c")]
    graph = helper.make_graph(
        nodes,
        "g",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, size, size])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, list(rows.shape))],
        inits,
    )
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    model.metadata_props.add(key="names", value=repr(NAMES))
    path.write_bytes(model.SerializeToString())
    return path


def test_component_places_stereo_boxes_with_the_estimate_at_the_capture_time(tmp_path):
    """The component on a stereo pair: the box (a model returning the person's box; 320 x 240 letterboxed into
    320 x 320, 40 px bars) is placed at its stereo depth with the estimate interpolated to the image's stamp and
    the left camera's mounting, as :func:`stereo_boxes_to_world` places it with the true pose; without the right
    image of the same stamp no Detections3D is published."""
    world, pid = _scene()
    p_WB = np.array([PERSON[0] - 8.0, PERSON[1] - 0.3, 5.0])
    left, right, _, box = _views(world, pid, p_WB)
    rows = np.array([[[*(box[0] + [0, 40, 0, 40]), 0.9, 3]]], np.float32)  # end-to-end layout, letterbox bars
    det = OnnxDetector(_model(rows, tmp_path / "m.onnx", 320))
    comp = OnnxDetectorComponent(
        det, image_topic="/l", right_topic="/r", image_intrinsics=K, T_BC=T_LEFT, baseline_m=B, max_disparity=64
    )
    bus = Bus()
    view = BusView(bus, comp.name, comp.inputs + comp.optional_inputs, comp.outputs, deny_truth=True)
    comp.reset()
    comp.setup(view)
    q = np.array([1.0, 0.0, 0.0, 0.0])
    for t, dx in ((0.0, -0.2), (0.2, 0.2)):  # at the stamp 0.1: p_WB, interpolated
        bus.publish(Topics.ESTIMATE, Odometry(t, p_WB + [dx, 0.0, 0.0], np.zeros(3), q, np.zeros(3)))
    sub3 = bus.subscribe(Topics.DETECTIONS_3D)
    bus.publish("/l", CameraImage(0.1, left))
    bus.publish("/r", CameraImage(0.1, right))
    comp.step(0.2, view)
    (d3,) = sub3.take()
    assert isinstance(d3, Detections3D) and d3.t == 0.1 and d3.class_ids.tolist() == [3]
    expected, _, _ = stereo_boxes_to_world(box, left, right, K, B, T_LEFT, p_WB, quat_to_matrix(q), 64)
    np.testing.assert_allclose(d3.centres_W, expected, atol=1e-6)
    assert np.linalg.norm(d3.centres_W[0, :2] - PERSON[:2]) < 0.35
    bus.publish("/l", CameraImage(0.15, left))  # no right image at 0.15
    comp.step(0.25, view)
    assert sub3.take() == []
    with pytest.raises(ValueError, match="not both"):
        OnnxDetectorComponent(det, depth_topic="/d", right_topic="/r", image_intrinsics=K, depth_intrinsics=K)
    with pytest.raises(ValueError, match="baseline_m"):
        OnnxDetectorComponent(det, right_topic="/r", image_intrinsics=K)


def test_scenario_part_on_a_stereo_rig(tmp_path):
    """``perception: {kind: onnx_detector, stereo_camera: stereo}``: the left camera's images and mounting, the
    rig's baseline, the right camera's topic; a grey rig, a rig and a camera together, or a rig that is not
    rectified are ConfigErrors naming the part."""
    from cufund.scenarios.build import build_simulation
    from cufund.scenarios.schema import load_scenario

    _model(np.array([[[300, 220, 340, 260, 0.9, 3]]], np.float32), tmp_path / "m.onnx", 640)
    (tmp_path / "s.yaml").write_text(
        "name: detect\nworld: {kind: imav2025_tunnel}\nvehicle: cu_astro\n"
        "sensors:\n  imu: {kind: icm42688p}\n  pose: {kind: pose, rate_hz: 100.0}\n"
        "  stereo: {kind: stereo_camera, rate_hz: 5, color: rgb, baseline: 0.2}\n"
        "estimator: {kind: imu_propagator}\n"
        "perception: {kind: onnx_detector, model: m.onnx, stereo_camera: stereo, rate_hz: 5}\n"
        "trajectory: {waypoints: [[-2, 0, 1], [-1.5, 0, 1]]}\nstart_p_W: [-2, 0, 0]\nduration: 1.0\n"
        "realism: ideal\n"
    )
    built = build_simulation(load_scenario(tmp_path / "s.yaml"))
    (comp,) = [c for c in built.simulator.components if isinstance(c, OnnxDetectorComponent)]
    assert comp.image_topic == "/sensors/cam0/image" and comp.right_topic == "/sensors/cam1/image"
    assert comp.baseline_m == pytest.approx(0.2) and comp.T_BC.t[1] == pytest.approx(0.1)
    assert comp.state_topic == Topics.ESTIMATE and Topics.DETECTIONS_3D in comp.outputs
    with pytest.raises(ConfigError, match="needs colour images"):
        build_simulation(load_scenario(tmp_path / "s.yaml", ["sensors.stereo.color=gray"]))
    with pytest.raises(ConfigError, match="not both"):
        build_simulation(load_scenario(tmp_path / "s.yaml", ["perception.camera=stereo"]))
    tilted = "sensors.stereo.extrinsics=[{p: [0.1, 0.1, 0], q: [1, 0, 0, 0]}, {p: [0.1, -0.1, 0], q: [0.9998000067, 0, 0, 0.0199986667]}]"
    with pytest.raises(ConfigError, match="perception.stereo_camera .*parallel"):
        build_simulation(load_scenario(tmp_path / "s.yaml", [tilted]))
