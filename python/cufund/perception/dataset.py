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
"""

from __future__ import annotations

import dataclasses
import json
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

__all__ = ["DatasetParams", "Randomisation", "render_frame", "write_dataset"]

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

    def __post_init__(self) -> None:
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


def render_frame(
    world: World,
    labeller: ViewLabeller,
    rng: np.random.Generator,
    rnd: Randomisation,
    negative: bool,
) -> tuple[np.ndarray, ViewLabels, dict[str, Any]]:
    """One randomised frame: (H, W, 3) uint8 image, its labels, and the draws that made it."""
    targets = [o for o in world.objects if o.label in labeller.classes]
    lo, hi = world.bounds()
    labels: ViewLabels | None = None
    ids: np.ndarray | None = None
    p = q = None
    casts = 0
    for draw in range(200):
        if negative or not targets:
            p = np.array([rng.uniform(lo[0], hi[0]), rng.uniform(lo[1], hi[1]), rng.uniform(*rnd.height_m)])
            yaw, pitch = rng.uniform(-np.pi, np.pi), np.deg2rad(rng.uniform(-10.0, 30.0))
            q = _look_at(
                p, p + np.array([np.cos(yaw), np.sin(yaw), 0.0]), 0.0, pitch, np.deg2rad(rng.uniform(*rnd.roll_deg))
            )
            labels = labeller.label(p, q)
            break
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
    return image, labels, draws


# --- the dataset -----------------------------------------------------------------------------------
def write_dataset(
    world: World,
    out: str | Path,
    params: DatasetParams,
    intrinsics: CameraIntrinsics | None = None,
    source: str = "",
    nthreads: int = 0,
    progress: Any = None,
) -> dict[str, Any]:
    """Writes the dataset of ``world`` into ``out`` (created; must be empty if it exists) and returns a summary
    (frames per split, boxes per class). ``source`` is recorded (e.g. the scenario's name); ``progress``, if
    given, is called with the number of frames done."""
    if not isinstance(params, DatasetParams):
        raise ValueError(f"params must be a DatasetParams, got {type(params).__name__}")
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
        image, labels, draws = render_frame(world, labeller, rng, params.randomisation, negative)
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
        "camera": dataclasses.asdict(intrinsics),
        "summary": summary,
        "frames": frames_meta,
    }
    (out / "dataset.json").write_text(json.dumps(meta, indent=1))
    return summary
