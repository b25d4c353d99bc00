"""The camera-only tunnel from the shipped frames model's own boxes (issue 26, item 4a): the model's boxes are off
by several pixels, the bar strips need the frame's edges within one or two. ``measure_frame`` refines each box to
the frame's bars, top and bottom in the pair first (``camera_tunnel_refine``). Rendered pairs lit as the flown rig
is (shadows, ambient 0.35), the shipped ONNX model run on the left image, the result checked against the world's
true frames."""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest

from cufund.core.bus import Bus, BusView
from cufund.core.messages import CameraImage, Detections2D, Odometry, Topics, TunnelEstimate
from cufund.geometry import Transform, quat_to_matrix
from cufund.missions.tunnel_course import TunnelCourseParams, paper_tunnel_course, tunnel_course_layout
from cufund.perception.camera_tunnel import CameraTunnelParams, measure_frame
from cufund.perception.camera_tunnel_component import CameraTunnelDetector
from cufund.perception.camera_tunnel_kind import SHIPPED_FRAMES_MODEL
from cufund.perception.camera_tunnel_refine import refine_frame_box
from cufund.perception.onnx_detector import OnnxDetector
from cufund.sensors.camera import CameraIntrinsics, RgbCamera

pytest.importorskip("onnxruntime")

K = CameraIntrinsics(640, 480, 400.0, 400.0, 319.5, 239.5)  # the stereo_camera kind's default rig
B = 0.11
T_LEFT, T_RIGHT = Transform((0.1, B / 2, 0.0)), Transform((0.1, -B / 2, 0.0))
LEFT = RgbCamera(K, T_LEFT, ambient=0.35, shadows=True)  # lit as the flown rig (sensors.stereo's defaults)
RIGHT = RgbCamera(K, T_RIGHT, ambient=0.35, shadows=True)


@cache
def _detector() -> OnnxDetector:
    return OnnxDetector(str(SHIPPED_FRAMES_MODEL), conf=0.25)


def _course(name: str):
    return paper_tunnel_course() if name == "paper" else tunnel_course_layout(int(name), TunnelCourseParams(n_frames=1))


def _approach(frame, distances):
    """Poses on the frame's axis (5 cm aside, at its centre's height, 0.5 m at least) at ``distances`` before it,
    with a hover's small tilts."""
    rng = np.random.default_rng(1)
    for dist in distances:
        p = np.asarray(frame.centre_W) - dist * frame.axis_W + np.array([0.0, 0.05, 0.0])
        p[2] = max(frame.centre_W[2], 0.5)
        roll, pitch = rng.normal(0.0, 0.02, 2)
        q = np.array([1.0, roll / 2, pitch / 2, 0.0])
        yield p, q / np.linalg.norm(q)


def _angle_deg(n, axis) -> float:
    return math.degrees(math.acos(min(1.0, abs(float(np.dot(n, axis))))))


def _track(name: str, refine: bool) -> tuple[TunnelEstimate, int]:
    """The component fed an approach from 3.5 to 1.5 m (nine pairs) with the shipped model's boxes (score >= 0.25)
    on the bus and the true pose as the estimate; (its last TunnelEstimate, boxes measured)."""
    course = _course(name)
    frame = course.frames[0]
    bus = Bus()
    comp = CameraTunnelDetector(
        K,
        B,
        T_LEFT,
        "/l",
        "/r",
        params=CameraTunnelParams(refine=refine),
        min_score=0.25,
        expected=5,
        origin_W=np.asarray(frame.centre_W) - 4.0 * frame.axis_W,
    )
    view = BusView(bus, comp.name, comp.inputs + comp.optional_inputs, comp.outputs, deny_truth=True)
    comp.reset()
    comp.setup(view)
    out = bus.subscribe(Topics.TUNNEL_ESTIMATE)
    for k, (p, q) in enumerate(_approach(frame, np.linspace(3.5, 1.5, 9))):
        t = 0.1 * (k + 1)
        left, right = LEFT.render(course.world, p, q), RIGHT.render(course.world, p, q)
        d = _detector().detect(left)
        det = Detections2D(t, d.boxes_xyxy, d.scores, d.class_ids, _detector().names, d.latency_ms)
        for s in (t - 0.01, t + 0.01):
            bus.publish(Topics.ESTIMATE, Odometry(s, p, np.zeros(3), q, np.zeros(3)))
        bus.publish("/l", CameraImage(t, left))
        bus.publish("/r", CameraImage(t, right))
        bus.publish(Topics.DETECTIONS_2D, det)
        comp.step(t, view)
    return out.take()[-1], comp.frames_measured


@pytest.mark.parametrize("name", ["paper", "0", "1", "4", "7"])
def test_the_models_boxes_refined_track_the_first_frame_to_3_cm_and_3_deg(name):
    """The shipped model's boxes, refined, over an approach from 3.5 to 1.5 m before the first frame of the paper's
    layout and of generated ones: the tracked frame nearest the true one is within 3 cm and 3 deg, and no tracked
    frame is more than 10 cm from a true one (a refinement that is not sure gives nothing)."""
    est, measured = _track(name, refine=True)
    frame = _course(name).frames[0]
    assert measured >= 4 and est.centres_W.shape[0] >= 1
    err = np.linalg.norm(est.centres_W - np.asarray(frame.centre_W), axis=1)
    k = int(np.argmin(err))
    assert err[k] < 0.03, (err, est.centres_W)
    assert _angle_deg(est.normals_W[k], frame.axis_W) < 3.0
    true = np.array([f.centre_W for f in _course(name).frames])
    assert all(np.min(np.linalg.norm(true - c, axis=1)) < 0.10 for c in est.centres_W)


@pytest.mark.parametrize("name", ["paper", "7"])
def test_without_the_refinement_the_models_boxes_do_not_give_the_frame(name):
    """The same approaches measured on the model's boxes as they are: the first frame is not within 3 cm and
    3 deg, or some track lands more than 10 cm from every frame, or nothing is tracked (these two were tracked
    13 and 25 cm off, against 0.7 and 1.7 cm refined): the refinement is what makes them good. (Seed 4 was tracked
    12 cm off unrefined until a track dropped measurements of another width beside it; now 1.4 cm.)"""
    est, _ = _track(name, refine=False)
    frames = _course(name).frames
    if est.centres_W.shape[0] == 0:
        return
    err = np.linalg.norm(est.centres_W - np.asarray(frames[0].centre_W), axis=1)
    k = int(np.argmin(err))
    good = err[k] < 0.03 and _angle_deg(est.normals_W[k], frames[0].axis_W) < 3.0
    true = np.array([f.centre_W for f in frames])
    stray = any(np.min(np.linalg.norm(true - c, axis=1)) > 0.10 for c in est.centres_W)
    assert not good or stray, (err, est.centres_W)


def test_one_pair_at_two_metres_from_the_models_box():
    """One pair 2 m before the paper layout's first frame: each of the model's boxes of it is refined to the frame's
    silhouette (the outer edges within a pixel and a half of the renderer's instance ids at the middle row), and the
    centre measured from it is within 3 cm across the view (along it a pixel of disparity is 9 cm)."""
    course = paper_tunnel_course()
    frame = course.frames[0]
    p, q = next(_approach(frame, [2.0]))
    left, ids, labels = LEFT.render(course.world, p, q, want_ids=True)
    right = RIGHT.render(course.world, p, q)
    inst = min((i for i in np.unique(ids) if i >= 0 and labels[i] == "tunnel_frame"), key=int)  # the first frame
    rows = np.nonzero((ids == inst).any(axis=1))[0]
    mid = int(rows.mean())
    cols = np.nonzero(ids[mid] == inst)[0]
    d = _detector().detect(left)
    boxes = [b for b, c in zip(d.boxes_xyxy, d.class_ids, strict=True) if _detector().names[int(c)] == "tunnel_frame"]
    near = [b for b in boxes if abs(b[0] - cols.min()) < 25 and abs(b[2] - cols.max() - 1) < 25]
    assert near
    measured = 0
    for box in near:
        m = measure_frame(box, left, right, K, B, T_LEFT, p, quat_to_matrix(q))
        if m is None:
            continue
        measured += 1
        err = m.centre_W - np.asarray(frame.centre_W)
        along = float(err @ frame.axis_W)
        assert np.linalg.norm(err - along * frame.axis_W) < 0.03, err
        assert abs(along) < 0.12, err
    assert measured >= 1
    span = (3.0, 60.0)
    r = refine_frame_box(near[0], left, right, B, 0.05, span, K.fx, K.cx, K.cy)
    assert r is not None
    assert abs(r.box_xyxy[0] - cols.min()) < 1.5 and abs(r.box_xyxy[2] - (cols.max() + 1)) < 1.5


def test_a_box_of_nothing_gives_nothing():
    """A box around plain wall (no bars) gives no measurement, refined or not."""
    course = paper_tunnel_course()
    frame = course.frames[0]
    p, q = next(_approach(frame, [2.0]))
    left, right = LEFT.render(course.world, p, q), RIGHT.render(course.world, p, q)
    wall = np.array([20.0, 20.0, 120.0, 150.0])
    assert measure_frame(wall, left, right, K, B, T_LEFT, p, quat_to_matrix(q)) is None
    assert refine_frame_box(wall, left, right, B, 0.05, (3.0, 60.0), K.fx, K.cx, K.cy) is None


def test_bad_refinement_settings_are_refused_by_name():
    from cufund.core.config import ConfigError
    from cufund.scenarios.schema import load_scenario

    with pytest.raises(ConfigError, match="perception.refine must be true or false"):
        CameraTunnelParams(refine=3)
    with pytest.raises(ConfigError, match="refine_max_yaw_deg"):
        CameraTunnelParams(refine_max_yaw_deg=float("nan"))
    with pytest.raises(ConfigError, match="perception.refine"):
        load_scenario("tunnel", ["perception=camera", "estimator.kind=vio", "perception.refine=3"])
    cfg = load_scenario("tunnel", ["perception=camera", "estimator.kind=vio", "perception.refine=false"])
    assert cfg.perception.params.geometry().refine is False


# Poses of an approach drawn in these orders (each pose's tilts are the next draws of one generator: _approach).
NEAR = (5.0, 4.5, 4.0, 3.0, 2.0)
FAR = (6.0, 5.5, 3.5, 2.5, 1.5)

# (layout, approach, distance before its first frame [m], camera moved across its axis [m], one of the shipped
# model's boxes there): boxes whose refinement finds the bars of two frames, or of a frame behind, that one of the
# refusals (module steps 2-4, and measure_frame's) turns away. Measured without the refusal named, they were off
# every true frame by:
REFUSED = [
    ("1", NEAR, 2.0, 0.0, (277.9, 135.2, 414.6, 313.4)),  # top and bottom corners level: 38 cm
    ("2", NEAR, 4.0, 0.0, (392.9, 180.3, 494.5, 303.9)),  # top bar under the top line, top ends in both images: 28 cm
    ("3", NEAR, 3.0, 0.0, (419.7, 145.3, 493.9, 357.0)),  # top bar under the top line: 57 cm
    ("6", NEAR, 4.0, 0.0, (254.5, 159.3, 342.5, 290.5)),  # bottom bar ending at the outer edges: 30 cm
    ("0", FAR, 3.5, 0.3, (277.9, 186.0, 353.0, 309.4)),  # turned by at most refine_max_yaw_deg: 47 cm
    ("4", FAR, 2.5, 0.3, (138.6, 144.8, 241.5, 310.8)),  # turned by at most refine_max_yaw_deg: 18 cm
    ("paper", FAR, 2.5, 0.3, (330.7, 159.0, 403.6, 290.4)),  # right-image runs one bar wide (strips failed): 17 cm
    ("3", FAR, 3.5, -0.3, (459.8, 179.6, 609.5, 378.4)),  # right-image runs one bar wide (strips failed): 89 cm
    ("1", FAR, 2.5, -0.3, (193.4, 127.3, 264.2, 307.7)),  # edges' and strips' disparities agree: 47 cm
    ("0", FAR, 2.5, 0.0, (218.9, 166.8, 316.2, 315.4)),  # edges' and strips' disparities agree: 26 cm
]


@pytest.mark.parametrize(("name", "order", "dist", "aside", "box"), REFUSED)
def test_boxes_of_two_frames_bars_give_no_phantom_frame(name, order, dist, aside, box):
    """Approaching a layout's first frame (all its frames standing, so frames behind are in view): these boxes of
    the shipped model give no measurement, or one within 10 cm of a true frame, never a frame where there is none
    (each was 17-89 cm off with one of the refusals removed)."""
    course = paper_tunnel_course() if name == "paper" else tunnel_course_layout(int(name))
    frame = course.frames[0]
    p, q = list(_approach(frame, order))[order.index(dist)]
    p = p + aside * np.cross([0.0, 0.0, 1.0], frame.axis_W)
    left, right = LEFT.render(course.world, p, q), RIGHT.render(course.world, p, q)
    m = measure_frame(np.array(box), left, right, K, B, T_LEFT, p, quat_to_matrix(q))
    true = np.array([f.centre_W for f in course.frames])
    assert m is None or np.min(np.linalg.norm(true - m.centre_W, axis=1)) < 0.10, m


def test_a_rig_without_square_pixels_is_refused_while_refining():
    """The refinement takes one focal length for the bars' widths and the corners' level check: a rig whose
    cameras have fx != fy is refused naming perception.refine, and builds with the refinement off."""
    from cufund.core.config import ConfigError
    from cufund.scenarios.build import build_simulation
    from cufund.scenarios.schema import load_scenario

    rig = (
        "sensors.stereo={kind: stereo_camera, color: rgb, hw_sync: true, "
        "intrinsics: {width: 640, height: 480, fx: 400, fy: 380, cx: 319.5, cy: 239.5}}"
    )
    base = ["perception=camera", "estimator.kind=vio", rig]
    with pytest.raises(ConfigError, match=r"perception\.refine: .*square pixels.*fx 400 px, fy 380 px"):
        build_simulation(load_scenario("tunnel", base))
    build_simulation(load_scenario("tunnel", [*base, "perception.refine=false"]))


# A big frame standing just behind a small one (generated layouts): from before the small frame the big one's
# vertical bars and top are seen beside and above the small one's, but the two bottom bars lie across each other
# in the image, so no bottom bar of the big frame is found; measured with the rules' square opening's bottom
# (``partial_min_width``), confirmed at its two corners.


def _on_axis(course, a: int, b: int, dist: float):
    """The camera level on frame a's axis at its opening's height, facing along it, ``dist`` before frame b's
    centre along frame a's heading."""
    fa, fb = course.frames[a], course.frames[b]
    ax = np.asarray(fa.axis_W)
    across = np.cross([0.0, 0.0, 1.0], ax)
    p = np.asarray(fb.centre_W) - dist * ax
    p = p - float((p - np.asarray(fa.centre_W)) @ across) * across
    p[2] = fa.centre_W[2]
    return p, np.array([math.cos(fa.yaw / 2), 0.0, 0.0, math.sin(fa.yaw / 2)])


def _outer_box(frame, p, q) -> np.ndarray:
    """The frame's outer corners projected into the left image: (u0, v0, u1, v1) [px]."""
    from cufund.sensors.camera import R_CO

    R_WB = quat_to_matrix(q)
    R_WO, o_W = R_WB @ T_LEFT.R @ R_CO, p + R_WB @ np.asarray(T_LEFT.t)
    across = np.cross([0.0, 0.0, 1.0], frame.axis_W)
    uv = []
    for i in (-1.0, 1.0):
        for j in (-1.0, 1.0):
            X = R_WO.T @ (
                np.asarray(frame.centre_W)
                + i * (frame.width / 2 + 0.05) * across
                + np.array([0.0, 0.0, j * (frame.height / 2 + 0.05)])
                - o_W
            )
            uv.append([K.fx * X[0] / X[2] + K.cx, K.fy * X[1] / X[2] + K.cy])
    uv = np.array(uv)
    return np.array([uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])


def _pair_on_axis(name: str, a: int, b: int, dist: float):
    course = tunnel_course_layout(int(name))
    p, q = _on_axis(course, a, b, dist)
    return course, p, q, LEFT.render(course.world, p, q), RIGHT.render(course.world, p, q)


@pytest.mark.parametrize(("name", "a", "b", "dist"), [("1", 1, 2, 1.8), ("3", 0, 1, 1.6), ("3", 0, 1, 1.8)])
def test_a_big_frame_behind_a_small_one_is_measured_from_its_bars_and_top(name, a, b, dist):
    """Seed 1's frame 3 (1.5 m opening) stands 0.53 m behind frame 2 (0.5 x 1 m), seed 3's frame 2 0.6 m behind
    frame 1 (0.5 x 1 m, on legs). Seen from before the small frame on its axis, the big frame's projected outline
    and that outline loosened by up to 10 px as a detector's box is (three draws) are measured as partial (the
    bottom bars lie across each other in the image), within 4 cm of the true centre, the opening within 5 cm of
    1.5 x 1.5 m. Without the square bottom (partial_min_width 0), not at all."""
    course, p, q, left, right = _pair_on_axis(name, a, b, dist)
    frame = course.frames[b]
    exact = _outer_box(frame, p, q)
    rng = np.random.default_rng(5)
    off = CameraTunnelParams(partial_min_width=0.0)
    for box in [exact] + [exact + rng.uniform(-10.0, 10.0, 4) for _ in range(3)]:
        m = measure_frame(box, left, right, K, B, T_LEFT, p, quat_to_matrix(q))
        assert m is not None and m.partial, box
        assert np.linalg.norm(m.centre_W - np.asarray(frame.centre_W)) < 0.04, (box, m.centre_W)
        assert abs(m.width - 1.5) < 0.05 and abs(m.height - 1.5) < 0.05, (m.width, m.height)
        assert measure_frame(box, left, right, K, B, T_LEFT, p, quat_to_matrix(q), off) is None


@pytest.mark.parametrize(("name", "a", "b", "dist"), [("1", 1, 2, d) for d in (1.5, 1.8, 2.2)] + [("3", 0, 1, 1.8)])
def test_the_partial_route_gives_no_wrong_frame(name, a, b, dist):
    """Every box of the shipped model (score >= 0.25) in views before a big frame standing behind a small one gives
    no measurement or one within 10 cm of a true frame."""
    course, p, q, left, right = _pair_on_axis(name, a, b, dist)
    true = np.array([f.centre_W for f in course.frames])
    for box in _detector().detect(left).boxes_xyxy:
        m = measure_frame(box, left, right, K, B, T_LEFT, p, quat_to_matrix(q))
        assert m is None or np.min(np.linalg.norm(true - m.centre_W, axis=1)) < 0.10, (box, m)


def test_a_far_partial_frame_is_refused():
    """Seed 1, 2.2 m before frame 3 on frame 2's axis: frame 5 (1 m opening, 4 m away, seen through frames 2-4) is
    measured partial 10 cm or more off its centre from its loosened outline with partial_max_range 6 m (a pixel of
    disparity is 36 cm there); by default (2.5 m) it is not measured partial."""
    course, p, q, left, right = _pair_on_axis("1", 1, 2, 2.2)
    frame = course.frames[4]
    exact = _outer_box(frame, p, q)
    rng = np.random.default_rng(5)
    far = CameraTunnelParams(partial_max_range=6.0)
    worst = 0.0
    for box in [exact] + [exact + rng.uniform(-10.0, 10.0, 4) for _ in range(5)]:
        m = measure_frame(box, left, right, K, B, T_LEFT, p, quat_to_matrix(q), far)
        if m is not None and m.partial:
            worst = max(worst, float(np.linalg.norm(m.centre_W - np.asarray(frame.centre_W))))
        m = measure_frame(box, left, right, K, B, T_LEFT, p, quat_to_matrix(q))
        assert m is None or not m.partial
    assert worst > 0.10


def test_bad_partial_settings_are_refused_by_name():
    from cufund.core.config import ConfigError
    from cufund.scenarios.schema import load_scenario

    with pytest.raises(ConfigError, match="partial_min_width"):
        CameraTunnelParams(partial_min_width=-1.0)
    with pytest.raises(ConfigError, match="perception.partial_max_range"):
        load_scenario("tunnel", ["perception=camera", "estimator.kind=vio", "perception.partial_max_range=nan"])
    cfg = load_scenario("tunnel", ["perception=camera", "estimator.kind=vio", "perception.partial_min_width=0"])
    assert cfg.perception.params.geometry().partial_min_width == 0.0
