"""Labelled detection datasets rendered from a world, with domain randomisation from a seed.

:func:`write_dataset` renders ``frames`` RGB views of the labelled objects of a world (a class is an object
label in ``classes``; see :mod:`cufund.worlds.labelled_objects`) and writes, in ``out``:

- ``images/{train,val}/NNNNNN.png`` and ``labels/{train,val}/NNNNNN.txt`` (ultralytics' YOLO layout: one line
  ``class u_c v_c w h`` per box, normalised to the image) and ``data.yaml`` (``path``, ``train``, ``val``,
  ``names``) — what ``ultralytics`` trains from;
- ``annotations.json`` (COCO: images, categories, annotations with ``bbox`` [x, y, w, h] in pixels, ``area``
  the visible pixels, and a ``cufund`` record per annotation: instance id, occlusion, truncation, 3-D box);
- ``masks/NNNNNN_instance.png`` (16-bit: world object id + 1, 0 for the sky) and ``masks/NNNNNN_class.png``
  (16-bit: class id + 1, 0 for background);
- ``dataset.json``: the seed, the randomisation, the classes and the camera (what makes the dataset again).

Every random draw (camera pose, object colours and textures, light, shadows, exposure, noise, blur) comes from one
``numpy.random.Generator`` seeded with ``seed``: the same call writes the same files. Every tenth frame goes to
``val``. A frame looks at a randomly chosen labelled object from a random distance, height and bearing, with
jitter (the camera inside the world's horizontal bounds and the target visible, up to 20 views cast);
``negative_fraction`` of the frames look anywhere.

With ``views="course"`` (:class:`CourseViews`) a frame is a view the vehicle has flying a course instead: the
world's frames in flying order are given (``course``), a frame k is drawn, and the camera stands on its axis
between 3 m before it and just past frame k-1, at the opening's height, jittered sideways, up and down and in
yaw, pitch and roll, facing along the course. Such views hold what the random views around single objects never
do: frames nested in each other and partly hidden, frames seen through frames, frames cut by the image.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from cufund.core.config import ConfigError
from cufund.geometry import quat_from_matrix
from cufund.sensors.camera import CameraIntrinsics, RgbCamera, d435_rgb, save_png
from cufund.worlds.labelled_objects import CLASSES
from cufund.worlds.materials import Material
from cufund.worlds.world import World

from .dataset_labels import ViewLabeller, ViewLabels

__all__ = ["VIEWS", "Course", "CourseViews", "DatasetParams", "Randomisation", "render_frame", "write_dataset"]

VIEWS = ("random", "course")
"""How the camera poses are drawn: around single labelled objects, or as flying a course."""

VAL_EVERY = 10
"""Every VAL_EVERY-th frame (0, 10, 20, ...) goes to the validation split."""


def _range(name: str, value: Any, lo: float, hi: float) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in value)
    except (TypeError, ValueError):
        raise ConfigError(f"randomisation.{name} must be a pair [min, max], got {value!r}") from None
    if not (np.isfinite(a) and np.isfinite(b) and lo <= a <= b <= hi):
        raise ConfigError(f"randomisation.{name} must be [min, max] with {lo} <= min <= max <= {hi}, got {value!r}")
    return a, b


@dataclass(frozen=True)
class Randomisation:
    """Ranges each frame's draws are uniform in (a range [a, a] fixes the value)."""

    recolour_probability: float = 0.5
    """Chance that an object gets a new colour drawn uniformly in RGB (else its own, jittered) [-]."""
    colour_jitter: tuple[float, float] = (0.7, 1.3)
    """Factor on each RGB channel of a colour kept [-]."""
    texture_probability: float = 0.5
    """Chance that an object gets a procedural texture (checker, noise, brick, concrete or bark, random feature
    size, contrast and seed; :mod:`cufund.worlds.materials`) over its colour [-]."""
    texture_scale_m: tuple[float, float] = (0.05, 1.0)
    """Feature size of a texture, drawn log-uniformly [m]."""
    shadow_probability: float = 0.5
    """Chance that a frame is rendered with hard shadows (one shadow ray per pixel) [-]."""
    light_elevation_deg: tuple[float, float] = (20.0, 90.0)
    """Elevation of the light's direction above the horizon [deg] (its azimuth is uniform)."""
    ambient: tuple[float, float] = (0.15, 0.6)
    """Share of the light that does not depend on the surface's direction [-]."""
    exposure: tuple[float, float] = (0.6, 1.4)
    """Gain on the rendered image [-] (light intensity and exposure time together)."""
    noise_sigma: tuple[float, float] = (0.0, 6.0)
    """Standard deviation of the Gaussian pixel noise [grey levels]."""
    blur_sigma_px: tuple[float, float] = (0.0, 1.2)
    """Standard deviation of the Gaussian blur [px] (0: none)."""
    distance_m: tuple[float, float] = (2.0, 14.0)
    """Camera distance from the target object's centre [m]."""
    height_m: tuple[float, float] = (0.4, 4.0)
    """Camera height above the ground [m]."""
    look_jitter_deg: tuple[float, float] = (0.0, 15.0)
    """Angle the view is turned away from the target (yaw and pitch each up to it) [deg]."""
    roll_deg: tuple[float, float] = (-10.0, 10.0)
    """Camera roll [deg]."""

    def __post_init__(self) -> None:
        for name in ("recolour_probability", "texture_probability", "shadow_probability"):
            p = getattr(self, name)
            if isinstance(p, bool) or not isinstance(p, (int, float)) or not 0.0 <= p <= 1.0:
                raise ConfigError(f"randomisation.{name} must be in [0, 1], got {p!r}")
        limits = {
            "colour_jitter": (0.0, 10.0),
            "texture_scale_m": (1e-3, 1e3),
            "light_elevation_deg": (0.0, 90.0),
            "ambient": (0.0, 1.0),
            "exposure": (0.0, 10.0),
            "noise_sigma": (0.0, 255.0),
            "blur_sigma_px": (0.0, 10.0),
            "distance_m": (0.1, 1e4),
            "height_m": (-1e4, 1e4),
            "look_jitter_deg": (0.0, 90.0),
            "roll_deg": (-180.0, 180.0),
        }
        for name, (lo, hi) in limits.items():
            object.__setattr__(self, name, _range(name, getattr(self, name), lo, hi))


@dataclass(frozen=True)
class CourseViews:
    """Camera poses of ``views="course"``, about frame k of the course (its opening's centre c, axis a: the
    direction flown through). Each range is drawn uniformly."""

    distance_m: tuple[float, float] = (0.3, 3.0)
    """Camera distance before frame k along its axis [m]; the nearest is also at most ``past_previous_m`` past
    frame k-1's plane (the first frame: this range alone)."""
    past_previous_m: float = 0.2
    """How far past frame k-1 the nearest view of frame k stands (where the vehicle rests between frames) [m]."""
    lateral_m: float = 0.25
    """Largest sideways offset from the axis [m]."""
    vertical_m: float = 0.25
    """Largest offset up or down from the opening's centre height [m]."""
    min_height_m: float = 0.3
    """Lowest camera height above the ground [m]."""
    yaw_deg: float = 15.0
    """Largest turn of the view from the axis' heading [deg]."""
    pitch_deg: float = 5.0
    """Largest pitch [deg]."""
    roll_deg: float = 5.0
    """Largest roll [deg]."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "distance_m", _range("course.distance_m", self.distance_m, 0.0, 100.0))
        for name, hi in (
            ("past_previous_m", 10.0),
            ("lateral_m", 10.0),
            ("vertical_m", 10.0),
            ("min_height_m", 100.0),
            ("yaw_deg", 180.0),
            ("pitch_deg", 90.0),
            ("roll_deg", 180.0),
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= hi:
                raise ConfigError(f"course.{name} must be a number in [0, {hi:g}], got {v!r}")


@dataclass(frozen=True)
class DatasetParams:
    frames: int = 100
    """Images rendered [-]."""
    seed: int = 0
    """Seed of every random draw."""
    classes: tuple[str, ...] = CLASSES
    """Object labels that are classes, in class-index order."""
    min_box_px: int = 4
    """Boxes narrower or lower than this are left out of the YOLO and COCO labels (still in the masks) [px]."""
    negative_fraction: float = 0.1
    """Share of frames that look anywhere rather than at an object [-]."""
    randomisation: Randomisation = dataclasses.field(default_factory=Randomisation)
    views: str = "random"
    """How the camera poses are drawn (:data:`VIEWS`): ``random`` around single labelled objects, ``course``
    as the vehicle has them flying the course given to :func:`write_dataset`."""
    course: CourseViews = dataclasses.field(default_factory=CourseViews)
    """The course views' ranges (with ``views="course"``)."""

    def __post_init__(self) -> None:
        if self.views not in VIEWS:
            raise ConfigError(f"views must be one of {', '.join(VIEWS)}, got {self.views!r}")
        if not isinstance(self.course, CourseViews):
            raise ConfigError(f"course must be a CourseViews, got {type(self.course).__name__}")
        for name, lo, hi in (("frames", 1, 1_000_000), ("seed", 0, 2**63 - 1), ("min_box_px", 1, 10_000)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
                raise ConfigError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")
        f = self.negative_fraction
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not 0.0 <= f <= 1.0:
            raise ConfigError(f"negative_fraction must be in [0, 1], got {f!r}")
        if not self.classes or not all(isinstance(c, str) and c for c in self.classes):
            raise ConfigError(f"classes must be non-empty labels, got {self.classes!r}")
        if len(set(self.classes)) != len(self.classes):
            raise ConfigError(f"classes must be distinct, got {self.classes!r}")
        object.__setattr__(self, "classes", tuple(self.classes))


# --- one frame -------------------------------------------------------------------------------------
def _look_at(p_cam: np.ndarray, target: np.ndarray, yaw_off: float, pitch_off: float, roll: float) -> np.ndarray:
    """q_WB of a body (camera, FLU) at ``p_cam`` looking at ``target``, turned by the offsets [rad]."""
    d = target - p_cam
    yaw = float(np.arctan2(d[1], d[0])) + yaw_off
    pitch = float(np.arctan2(-d[2], np.hypot(d[0], d[1]))) + pitch_off  # +pitch about y: nose down
    cy, sy, cp, sp, cr, sr = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    Rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    Ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return np.asarray(quat_from_matrix(Rz @ Ry @ Rx))


def _gaussian_blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur of an (H, W, C) float image, edges repeated."""
    r = int(np.ceil(3 * sigma))
    if sigma <= 0 or r == 0:
        return img
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k /= k.sum()
    for axis in (0, 1):
        pad = [(0, 0)] * img.ndim
        pad[axis] = (r, r)
        p = np.pad(img, pad, mode="edge")
        n = img.shape[axis]
        img = sum(w * np.take(p, np.arange(i, i + n), axis=axis) for i, w in enumerate(k))
    return img


_TEXTURES = ("checker", "noise", "brick", "concrete", "bark")


def _recoloured(world: World, rng: np.random.Generator, rnd: Randomisation) -> World:
    """A copy of ``world`` (same objects, same ids) with each object's colour and texture drawn anew."""
    out = World(world.name)
    for o in world.objects:
        if rng.random() < rnd.recolour_probability:
            colour = rng.random(3)
        else:
            colour = np.clip(np.asarray(o.color) * rng.uniform(*rnd.colour_jitter, size=3), 0.0, 1.0)
        material = None
        if rng.random() < rnd.texture_probability:
            material = Material(
                albedo=tuple(float(c) for c in colour),  # type: ignore[arg-type]
                texture=_TEXTURES[int(rng.integers(len(_TEXTURES)))],
                scale=float(np.exp(rng.uniform(*np.log(rnd.texture_scale_m)))),
                contrast=float(rng.uniform(0.2, 0.8)),
                seed=int(rng.integers(2**32)),
            )
        out.add_mesh(o.vertices, o.triangles, o.label, colour, reflectivity=o.reflectivity, material=material)
    return out


class Course:
    """A course's frames in flying order as the course views need them: each frame's opening centre and
    heading, and the world object that is the frame (the labelled object whose upright box is centred on the
    opening, within 5 cm).

    ``frames``: objects with ``centre_W`` (3 numbers [m]) and ``yaw`` (the heading flown through [rad]), e.g.
    :class:`cufund.missions.tunnel_course.TunnelFrame`."""

    def __init__(self, world: World, frames: Sequence[Any], labeller: ViewLabeller, views: CourseViews) -> None:
        if isinstance(frames, (str, bytes)) or not isinstance(frames, Sequence) or not frames:
            raise ConfigError(f"course must be a non-empty list of frames in flying order, got {frames!r}")
        centres, yaws, ids = [], [], []
        boxes = [(o.id, np.asarray(labeller.box3d(o).centre_W)) for o in world.objects]
        for k, f in enumerate(frames):
            try:
                c = np.asarray(getattr(f, "centre_W", None), dtype=float)
            except (TypeError, ValueError):
                c = np.empty(0)
            yaw = getattr(f, "yaw", None)
            if c.shape != (3,) or not np.all(np.isfinite(c)):
                raise ConfigError(
                    f"course[{k}].centre_W must be 3 finite numbers [m], got {getattr(f, 'centre_W', None)!r}"
                )
            if isinstance(yaw, bool) or not isinstance(yaw, (int, float)) or not np.isfinite(yaw):
                raise ConfigError(f"course[{k}].yaw must be a finite number [rad], got {yaw!r}")
            gaps = [(float(np.linalg.norm(b - c)), oid) for oid, b in boxes]
            gap, oid = min(gaps) if gaps else (np.inf, -1)
            if gap > 0.05:
                raise ConfigError(
                    f"course[{k}] (centre_W {c.round(3).tolist()}) is no object of the world {world.name!r}: "
                    "the course must be the world's own"
                )
            centres.append(c)
            yaws.append(float(yaw))
            ids.append(oid)
        self.centres_W, self.yaws, self.object_ids = np.array(centres), np.array(yaws), ids
        self.views = views

    def __len__(self) -> int:
        return len(self.yaws)

    def pose(self, k: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """(p_W, q_WB) of a camera flying towards frame k (see :class:`CourseViews`)."""
        v = self.views
        c, yaw = self.centres_W[k], self.yaws[k]
        axis, across = np.array([np.cos(yaw), np.sin(yaw), 0.0]), np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        near, far = v.distance_m
        if k > 0:  # not beyond just past the previous frame
            spacing = float((c - self.centres_W[k - 1]) @ axis)
            near = min(max(near, spacing - v.past_previous_m), far)
        p = c - rng.uniform(near, far) * axis + rng.uniform(-v.lateral_m, v.lateral_m) * across
        p[2] = max(c[2] + rng.uniform(-v.vertical_m, v.vertical_m), v.min_height_m)
        heading = yaw + np.deg2rad(rng.uniform(-v.yaw_deg, v.yaw_deg))
        pitch = np.deg2rad(rng.uniform(-v.pitch_deg, v.pitch_deg))
        roll = np.deg2rad(rng.uniform(-v.roll_deg, v.roll_deg))
        return p, _look_at(p, p + np.array([np.cos(heading), np.sin(heading), 0.0]), 0.0, pitch, roll)


def render_frame(
    world: World,
    labeller: ViewLabeller,
    rng: np.random.Generator,
    rnd: Randomisation,
    negative: bool,
    course: Course | None = None,
) -> tuple[np.ndarray, ViewLabels, dict[str, Any]]:
    """One randomised frame: (H, W, 3) uint8 image, its labels, and the draws that made it. With ``course``,
    a course view (of a frame it sees, up to 20 views cast) unless ``negative``."""
    targets = [o for o in world.objects if o.label in labeller.classes]
    lo, hi = world.bounds()
    labels: ViewLabels | None = None
    ids: np.ndarray | None = None
    p = q = None
    casts = 0
    aimed: int | None = None
    for draw in range(200):
        if negative or not targets:
            p = np.array([rng.uniform(lo[0], hi[0]), rng.uniform(lo[1], hi[1]), rng.uniform(*rnd.height_m)])
            yaw, pitch = rng.uniform(-np.pi, np.pi), np.deg2rad(rng.uniform(-10.0, 30.0))
            q = _look_at(
                p, p + np.array([np.cos(yaw), np.sin(yaw), 0.0]), 0.0, pitch, np.deg2rad(rng.uniform(*rnd.roll_deg))
            )
            labels = labeller.label(p, q)
            break
        if course is not None:
            aimed = int(rng.integers(len(course)))
            p, q = course.pose(aimed, rng)
            casts += 1
            ids = labeller.instance_ids(p, q)
            if np.any(ids == course.object_ids[aimed]) or casts >= 20:
                break
            continue
        target = targets[int(rng.integers(len(targets)))]
        c = np.asarray(labeller.box3d(target).centre_W)
        dist, bearing = rng.uniform(*rnd.distance_m), rng.uniform(-np.pi, np.pi)
        p = np.array([c[0] + dist * np.cos(bearing), c[1] + dist * np.sin(bearing), rng.uniform(*rnd.height_m)])
        if casts < 19 and draw < 199 and not np.all((p[:2] > lo[:2]) & (p[:2] < hi[:2])):
            continue  # beyond the world's horizontal bounds (an arena's walls): draw again without casting
        casts += 1
        jitter = np.deg2rad(rng.uniform(*rnd.look_jitter_deg))
        angle = rng.uniform(-np.pi, np.pi)
        q = _look_at(p, c, jitter * np.cos(angle), jitter * np.sin(angle), np.deg2rad(rng.uniform(*rnd.roll_deg)))
        ids = labeller.instance_ids(p, q)
        if np.any(ids == target.id) or casts >= 20:
            break
    if labels is None:  # looking at a target (seen, or the last draw's)
        labels = labeller.label(p, q, ids)
    assert p is not None and q is not None
    elevation = np.deg2rad(rng.uniform(*rnd.light_elevation_deg))
    azimuth = rng.uniform(-np.pi, np.pi)
    light = np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    ambient, exposure = rng.uniform(*rnd.ambient), rng.uniform(*rnd.exposure)
    noise, blur = rng.uniform(*rnd.noise_sigma), rng.uniform(*rnd.blur_sigma_px)
    painted = _recoloured(world, rng, rnd)
    shadows = bool(rng.random() < rnd.shadow_probability)
    camera = RgbCamera(
        labeller.intrinsics, labeller.T_BC, light_W=light, ambient=ambient, nthreads=labeller.nthreads, shadows=shadows
    )
    rendered = camera.render(painted, p, q)
    assert isinstance(rendered, np.ndarray)  # no ids asked for: the image alone
    img = rendered.astype(np.float64) * exposure
    img = _gaussian_blur(img, blur) + rng.standard_normal(img.shape) * noise
    image = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    draws = {
        "p_W": p.tolist(),
        "q_WB": np.asarray(q).tolist(),
        "light_W": light.tolist(),
        "ambient": ambient,
        "exposure": exposure,
        "noise_sigma": noise,
        "blur_sigma_px": blur,
        "shadows": shadows,
        "negative": bool(negative or not targets),
    }
    if aimed is not None:
        draws["course_frame"] = aimed
    return image, labels, draws


def _course_meta(params: DatasetParams, course: Course) -> dict[str, Any]:
    """dataset.json's record of course views (absent from a dataset of random views, whose files stay as they
    were before course views existed)."""
    frames = [{"centre_W": c.tolist(), "yaw": float(y)} for c, y in zip(course.centres_W, course.yaws, strict=True)]
    return {"views": params.views, "course": dataclasses.asdict(params.course), "course_frames": frames}


# --- the dataset -----------------------------------------------------------------------------------
def write_dataset(
    world: World,
    out: str | Path,
    params: DatasetParams,
    intrinsics: CameraIntrinsics | None = None,
    source: str = "",
    nthreads: int = 0,
    progress: Any = None,
    course: Sequence[Any] | None = None,
) -> dict[str, Any]:
    """Writes the dataset of ``world`` into ``out`` (created; must be empty if it exists) and returns a summary
    (frames per split, boxes per class). ``source`` is recorded (e.g. the scenario's name); ``progress``, if
    given, is called with the number of frames done. ``course``: with ``params.views == "course"``, the world's
    frames in flying order (see :class:`Course`), e.g. ``TunnelCourse.frames``."""
    if not isinstance(params, DatasetParams):
        raise ValueError(f"params must be a DatasetParams, got {type(params).__name__}")
    if params.views == "course" and course is None:
        raise ConfigError("views: course needs the world's course (its frames in flying order), and none was given")
    if params.views != "course" and course is not None:
        raise ConfigError(f"a course was given, but views is {params.views!r}: set views to 'course' to use it")
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"--out {str(out)!r} exists and is not an empty folder")
    intrinsics = intrinsics or d435_rgb()
    if not any(o.label in params.classes for o in world.objects):
        raise ConfigError(
            f"the world {world.name!r} holds no object labelled {', '.join(params.classes)}: nothing to label"
        )
    for split in ("train", "val"):
        (out / "images" / split).mkdir(parents=True, exist_ok=True)
        (out / "labels" / split).mkdir(parents=True, exist_ok=True)
    (out / "masks").mkdir(exist_ok=True)
    rng = np.random.default_rng(params.seed)
    labeller = ViewLabeller(world, intrinsics, params.classes, nthreads=nthreads)
    flown = None if course is None else Course(world, course, labeller, params.course)
    W, H = intrinsics.width, intrinsics.height
    coco: dict[str, Any] = {
        "info": {"description": f"cufund dataset of {source or world.name}", "seed": params.seed},
        "images": [],
        "annotations": [],
        "categories": [{"id": i + 1, "name": n} for i, n in enumerate(params.classes)],
    }
    counts = dict.fromkeys(params.classes, 0)
    frames_meta = []
    for k in range(params.frames):
        negative = bool(rng.random() < params.negative_fraction)
        image, labels, draws = render_frame(world, labeller, rng, params.randomisation, negative, flown)
        split = "val" if k % VAL_EVERY == 0 else "train"
        stem = f"{k:06d}"
        save_png(out / "images" / split / f"{stem}.png", image)
        save_png(out / "masks" / f"{stem}_instance.png", labels.instance_ids.astype(np.float64) + 1, depth_scale=1.0)
        save_png(out / "masks" / f"{stem}_class.png", labels.class_ids.astype(np.float64) + 1, depth_scale=1.0)
        coco["images"].append({"id": k + 1, "file_name": f"images/{split}/{stem}.png", "width": W, "height": H})
        lines = []
        for o in labels.objects:
            u0, v0, u1, v1 = o.box_xyxy
            if u1 - u0 < params.min_box_px or v1 - v0 < params.min_box_px:
                continue
            counts[o.class_name] += 1
            lines.append(
                f"{o.class_id} {(u0 + u1) / 2 / W:.6f} {(v0 + v1) / 2 / H:.6f} {(u1 - u0) / W:.6f} {(v1 - v0) / H:.6f}"
            )
            b = o.box3d
            coco["annotations"].append(
                {
                    "id": len(coco["annotations"]) + 1,
                    "image_id": k + 1,
                    "category_id": o.class_id + 1,
                    "bbox": [u0, v0, u1 - u0, v1 - v0],
                    "area": o.visible_px,
                    "iscrowd": 0,
                    "cufund": {
                        "instance_id": o.instance_id,
                        "occlusion": o.occlusion,
                        "truncation": o.truncation,
                        "visible_px": o.visible_px,
                        "unoccluded_px": o.unoccluded_px,
                        "box3d": {"centre_W": list(b.centre_W), "size": list(b.size), "yaw": b.yaw},
                    },
                }
            )
        (out / "labels" / split / f"{stem}.txt").write_text("".join(line + "\n" for line in lines))
        frames_meta.append({"frame": stem, "split": split, **draws})
        if progress is not None:
            progress(k + 1)
    (out / "annotations.json").write_text(json.dumps(coco, indent=1))
    data = {
        "path": str(out.resolve()),
        "train": "images/train",
        "val": "images/val",
        "names": dict(enumerate(params.classes)),
    }
    (out / "data.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
    summary = {
        "frames": params.frames,
        "train": sum(1 for f in frames_meta if f["split"] == "train"),
        "val": sum(1 for f in frames_meta if f["split"] == "val"),
        "boxes": counts,
    }
    meta = {
        "source": source or world.name,
        "seed": params.seed,
        "classes": list(params.classes),
        "min_box_px": params.min_box_px,
        "negative_fraction": params.negative_fraction,
        "randomisation": dataclasses.asdict(params.randomisation),
        **({} if flown is None else _course_meta(params, flown)),
        "camera": dataclasses.asdict(intrinsics),
        "summary": summary,
        "frames": frames_meta,
    }
    (out / "dataset.json").write_text(json.dumps(meta, indent=1))
    return summary
