"""The camera-only tunnel from inside the course (issue 26, item 4a): the stepwise mission rests between frames k and
k+1 and waits there for the next frames. Rendered pairs from such viewpoints (lit as the flown rig is), the shipped
model's own boxes fed to the component, every measurement checked against the world's true frames and the
true frames' corners projected (which frame is whole in view).

Found on a flown paper layout's logged pairs: from inside the course the shipped model labels the frames ``gate``
(every box past the first frame was), so a component reading only ``tunnel_frame`` boxes measured nothing there;
and frame k+2 of the paper layout (1.1 m tall on the floor, 0.4-0.9 m away) is cut by the image at its top and
bottom from anywhere between frames k and k+1, so it gives no box and no measurement (the whole frames there are
k+3 and k+4, nested inside it)."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest

from cufund.core.messages import Detections2D
from cufund.geometry import Transform, quat_to_matrix
from cufund.missions.tunnel_course import paper_tunnel_course, tunnel_course_layout
from cufund.perception.camera_tunnel_component import CameraTunnelDetector
from cufund.perception.camera_tunnel_kind import SHIPPED_FRAMES_MODEL
from cufund.perception.onnx_detector import OnnxDetector
from cufund.sensors.camera import R_CO, CameraIntrinsics, RgbCamera

pytest.importorskip("onnxruntime")

K = CameraIntrinsics(640, 480, 400.0, 400.0, 319.5, 239.5)  # the stereo_camera kind's default rig
B = 0.11
T_LEFT, T_RIGHT = Transform((0.1, B / 2, 0.0)), Transform((0.1, -B / 2, 0.0))
LEFT = RgbCamera(K, T_LEFT, ambient=0.35, shadows=True)
RIGHT = RgbCamera(K, T_RIGHT, ambient=0.35, shadows=True)
BAR = 0.05  # the courses' bars [m]


@cache
def _detector() -> OnnxDetector:
    return OnnxDetector(str(SHIPPED_FRAMES_MODEL), conf=0.25)


@cache
def _course(name: str):
    return paper_tunnel_course() if name == "paper" else tunnel_course_layout(int(name))


@cache
def _view(name: str, k: int, s: float):
    """The pair, the model's boxes and the pose, with the camera ``s`` of the way from
    frame k's opening centre to frame k+1's (0-based), facing along frame k's heading."""
    frames = _course(name).frames
    a, b = np.asarray(frames[k].centre_W), np.asarray(frames[k + 1].centre_W)
    p = a + s * (b - a)
    q = np.array([math.cos(frames[k].yaw / 2), 0.0, 0.0, math.sin(frames[k].yaw / 2)])
    left, right = LEFT.render(_course(name).world, p, q), RIGHT.render(_course(name).world, p, q)
    d = _detector().detect(left)
    det = Detections2D(0.0, d.boxes_xyxy, d.scores, d.class_ids, _detector().names, d.latency_ms)
    return left, right, det, p, q


def _measure(name: str, k: int, s: float, classes, min_score: float):
    left, right, det, p, q = _view(name, k, s)
    comp = CameraTunnelDetector(K, B, T_LEFT, "/l", "/r", class_name=classes, min_score=min_score)
    return comp.measure(det, left, right, p, quat_to_matrix(q))


def _nearest(name: str, centre: np.ndarray) -> tuple[int, float]:
    true = np.array([f.centre_W for f in _course(name).frames])
    err = np.linalg.norm(true - centre, axis=1)
    return int(np.argmin(err)), float(np.min(err))


def _angle_deg(n, axis) -> float:
    return math.degrees(math.acos(min(1.0, abs(float(np.dot(n, axis))))))


def _frame_extent(name: str, k: int, s: float, j: int) -> tuple[float, float, float, float] | None:
    """Frame j's outer corners projected into the left image (u0, v0, u1, v1; its bars' outer edges), or None when
    one is behind the camera."""
    *_, p, q = _view(name, k, s)
    f = _course(name).frames[j]
    half_w, half_h = 0.5 * f.width + BAR, 0.5 * f.height + BAR
    across = np.array([-math.sin(f.yaw), math.cos(f.yaw), 0.0])
    R_WB = quat_to_matrix(q)
    o_W = np.asarray(p) + R_WB @ np.asarray(T_LEFT.t)
    R_WO = R_WB @ T_LEFT.R @ R_CO
    uv = []
    for a in (-1.0, 1.0):
        for b in (-1.0, 1.0):
            x_O = R_WO.T @ (np.asarray(f.centre_W) + a * half_w * across + np.array([0.0, 0.0, b * half_h]) - o_W)
            if x_O[2] <= 0.05:
                return None
            uv.append((K.fx * x_O[0] / x_O[2] + K.cx + 0.5, K.fy * x_O[1] / x_O[2] + K.cy + 0.5))
    us, vs = zip(*uv, strict=True)
    return min(us), min(vs), max(us), max(vs)


VIEWS = [("paper", 0, 0.35), ("paper", 1, 0.35), ("1", 2, 0.35), ("2", 1, 0.35), ("3", 2, 0.35), ("3", 0, 0.6)]


@pytest.mark.parametrize(("name", "k", "s"), VIEWS)
def test_no_measurement_from_inside_the_course_is_off_a_true_frame(name, k, s):
    """Every box of the model (score >= 0.25, frames and gates) measured from between frames k and k+1: each
    measurement lies within 10 cm of a true frame's centre, its normal within 20 deg of that frame's axis (a wrong
    frame is worse than none: nothing is placed where there is no frame)."""
    found = _measure(name, k, s, ("tunnel_frame", "gate"), 0.25)
    assert found  # a frame ahead is measured from every one of these views
    for m in found:
        j, err = _nearest(name, m.centre_W)
        assert err < 0.10, (j, err, m.centre_W)
        assert _angle_deg(m.normal_W, _course(name).frames[j].axis_W) < 20.0
        assert j > k, (j, k)  # ahead of the camera


# (layout, k, s) -> the frame (0-based) measured from there that is k+2 or, where k+2 is cut by the image, the
# first whole one behind it; its accuracy [m, deg]
AHEAD = [
    ("paper", 0, 0.35, 3),  # frame 3 (index 2) cut at top and bottom; frame 4 whole
    ("1", 2, 0.35, 4),  # k+2
    ("2", 1, 0.35, 3),  # k+2
    ("3", 2, 0.35, 4),  # k+2
]


@pytest.mark.parametrize(("name", "k", "s", "j"), AHEAD)
def test_the_next_whole_frame_is_measured_from_between_the_last_two(name, k, s, j):
    """From between frames k and k+1, frame k+2 (or, where it is cut by the image, the first whole frame behind it)
    is measured from the model's boxes, frames and gates: the measurement nearest it within 3 cm and 4 deg. (The
    model shipped before 18b418c labelled these frames ``gate`` only, so ``tunnel_frame`` boxes alone measured none
    of them; the fine-tuned model labels most of them ``tunnel_frame``.)"""
    frame = _course(name).frames[j]
    extent = _frame_extent(name, k, s, j)
    assert extent is not None
    u0, v0, u1, v1 = extent
    assert u0 > 2 and v0 > 2 and u1 < K.width - 2 and v1 < K.height - 2, extent  # whole in view
    found = _measure(name, k, s, ("tunnel_frame", "gate"), 0.25)
    errs = [float(np.linalg.norm(m.centre_W - np.asarray(frame.centre_W))) for m in found]
    assert errs, "frame not measured"
    m = found[int(np.argmin(errs))]
    assert min(errs) < 0.03, (errs, m.centre_W, frame.centre_W)
    assert _angle_deg(m.normal_W, frame.axis_W) < 4.0


def test_the_paper_layouts_frame_k_plus_2_is_cut_by_the_image_and_not_measured():
    """From between frames 1 and 2 of the paper layout, frame 3 fills the image's height (1.1 m tall on the
    floor, 0.8 m away: the camera sees 0.54 m up +- 0.6 of its distance): its corners project above and below
    the image. No measurement is placed at it (a truncated frame gives none), and none at frame 2."""
    extent = _frame_extent("paper", 0, 0.35, 2)
    assert extent is not None and extent[1] < 0 and extent[3] > K.height
    found = _measure("paper", 0, 0.35, ("tunnel_frame", "gate"), 0.25)
    assert found
    assert all(_nearest("paper", m.centre_W)[0] >= 3 for m in found)


def test_the_classes_measured_are_settings_refused_by_name():
    """``perception.also_classes`` (default: the shipped model's ``gate``) is a list of class names; the component's
    ``class_name`` a name or a tuple of them."""
    from cufund.core.config import ConfigError
    from cufund.scenarios.schema import load_scenario

    base = ["perception=camera", "estimator.kind=vio"]
    assert load_scenario("tunnel", base).perception.params.also_classes == ("gate",)
    assert load_scenario("tunnel", [*base, "perception.also_classes=[]"]).perception.params.also_classes == ()
    with pytest.raises(ConfigError, match="perception.also_classes must be a list of class names"):
        load_scenario("tunnel", [*base, "perception.also_classes=3"])
    with pytest.raises(ValueError, match="class_name must be a class name or a tuple"):
        CameraTunnelDetector(K, B, T_LEFT, "/l", "/r", class_name=())
    with pytest.raises(ValueError, match="class_name must be a class name or a tuple"):
        CameraTunnelDetector(K, B, T_LEFT, "/l", "/r", class_name=("tunnel_frame", 3))
