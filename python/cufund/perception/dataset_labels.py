"""Labels of one camera view from the ray caster: per-pixel instance and class ids, 2-D boxes from the instance
masks, 3-D boxes, and how much of each object is occluded and truncated.

A pixel's instance id is the world object its ray hits first (the Embree geometry id, which is the object's index
in :attr:`cufund.World.objects`); its class id is the index of that object's label in ``classes`` (-1 for an
unlabelled object or the sky). For each labelled object seen:

- ``box_xyxy``: the tightest box around its visible pixels, in pixel edges (u_min, v_min, u_max, v_max) — the
  pixel (u, v) covers [u, u + 1) × [v, v + 1), so a one-pixel object's box is 1 px wide;
- ``occlusion = 1 - visible_px / unoccluded_px``, ``unoccluded_px`` being its pixels in the object rendered alone
  from the same camera;
- ``truncation = 1 - in_image_px / all_px`` on a pinhole canvas three times the image's width and height centred
  on it (the object alone, no distortion): the share of the object's image outside the frame (parts more than one
  image width or height beyond the frame are not counted).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cufund import _core
from cufund.geometry import Transform, quat_to_matrix
from cufund.sensors.camera import R_CO, CameraIntrinsics
from cufund.worlds.world import World, WorldObject

INVALID = -1
"""Instance or class id of a pixel with no (labelled) object."""


@dataclass(frozen=True)
class Box3D:
    """A box around an object's vertices, upright (turned about z only), in the world frame."""

    centre_W: tuple[float, float, float]
    """Centre [m]."""
    size: tuple[float, float, float]
    """Extent along the box's own x, y and z [m] (x the longer horizontal side)."""
    yaw: float
    """Heading of the box's x axis from the world's x axis, in [-π/2, π/2) [rad]."""

    def corners_W(self) -> np.ndarray:
        """(8, 3) corners [m]."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        signs = np.array([[(i & 1) * 2 - 1, ((i >> 1) & 1) * 2 - 1, ((i >> 2) & 1) * 2 - 1] for i in range(8)])
        return np.asarray(self.centre_W) + (signs * np.asarray(self.size) / 2) @ R.T


def upright_box(vertices_W: np.ndarray) -> Box3D:
    """The smallest-footprint upright box around ``vertices_W`` (heading searched in 0.5° steps)."""
    v = np.asarray(vertices_W, dtype=float)
    xy = v[:, :2] - v[:, :2].mean(0)
    best: tuple[float, float] | None = None
    for yaw in np.deg2rad(np.arange(-90.0, 90.0, 0.5)):
        c, s = np.cos(yaw), np.sin(yaw)
        u = xy @ np.array([c, s])
        w = xy @ np.array([-s, c])
        area = float(np.ptp(u) * np.ptp(w))
        if best is None or area < best[0] - 1e-12:
            best = (area, float(yaw))
    assert best is not None
    yaw = best[1]
    c, s = np.cos(yaw), np.sin(yaw)
    u, w = v[:, :2] @ np.array([c, s]), v[:, :2] @ np.array([-s, c])
    if np.ptp(w) > np.ptp(u):  # x along the longer side
        yaw = yaw + np.pi / 2 if yaw < 0 else yaw - np.pi / 2
        c, s = np.cos(yaw), np.sin(yaw)
        u, w = v[:, :2] @ np.array([c, s]), v[:, :2] @ np.array([-s, c])
    mid_u, mid_w = (u.min() + u.max()) / 2, (w.min() + w.max()) / 2
    centre = (mid_u * c - mid_w * s, mid_u * s + mid_w * c, (v[:, 2].min() + v[:, 2].max()) / 2)
    return Box3D(
        (float(centre[0]), float(centre[1]), float(centre[2])),
        (float(np.ptp(u)), float(np.ptp(w)), float(np.ptp(v[:, 2]))),
        float(yaw),
    )


@dataclass(frozen=True)
class ObjectLabel:
    """One labelled object seen in a view."""

    instance_id: int
    """The world object's id (its index in ``World.objects``)."""
    class_id: int
    """Index of its label in the classes."""
    class_name: str
    box_xyxy: tuple[int, int, int, int]
    """(u_min, v_min, u_max, v_max) of its visible pixels, pixel edges [px]."""
    visible_px: int
    """Pixels in which it is the first hit."""
    unoccluded_px: int
    """Pixels it covers rendered alone (nothing in front of it)."""
    occlusion: float
    """1 - visible_px / unoccluded_px, in [0, 1]."""
    truncation: float
    """Share of its (unoccluded, pinhole) image beyond the frame, in [0, 1)."""
    box3d: Box3D
    """Its upright 3-D box in the world frame."""


@dataclass(frozen=True)
class ViewLabels:
    """The labels of one view."""

    instance_ids: np.ndarray
    """(H, W) int32 world object id hit first at each pixel, -1 where nothing is hit."""
    class_ids: np.ndarray
    """(H, W) int16 class of that object, -1 where it is unlabelled or nothing is hit."""
    objects: tuple[ObjectLabel, ...]
    """The labelled objects seen (at least one visible pixel), by instance id."""


def camera_pose(T_BC: Transform | None, p_W: object, q_WB: object) -> tuple[np.ndarray, np.ndarray]:
    """(p_WC, R_WO): the camera's centre and the rotation of its optical frame O into the world."""
    p = np.asarray(p_W, dtype=float)
    q = np.asarray(q_WB, dtype=float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f"p_W must be 3 finite numbers [m], got {p_W!r}")
    if q.shape != (4,) or not np.all(np.isfinite(q)) or np.linalg.norm(q) < 1e-9:
        raise ValueError(f"q_WB must be a non-zero quaternion [w, x, y, z], got {q_WB!r}")
    T = T_BC or Transform()
    R_WB = quat_to_matrix(q / np.linalg.norm(q))
    return p + R_WB @ np.asarray(T.t), R_WB @ T.R @ R_CO


def _rays(origin: np.ndarray, dirs_O: np.ndarray, R_WO: np.ndarray) -> np.ndarray:
    rays = np.empty((len(dirs_O), 6), np.float32)
    rays[:, :3] = origin
    rays[:, 3:] = np.einsum("ij,kj->ik", dirs_O, R_WO)  # dirs_O @ R_WO.T (a skinny matmul is slow in BLAS)
    return rays


def _pinhole_rays(
    origin: np.ndarray, K: CameraIntrinsics, u: np.ndarray, v: np.ndarray, R_WO: np.ndarray
) -> np.ndarray:
    """(len(v) * len(u), 6) rays through the pixel centres (u, v), any integers (also beyond the image), along the
    undistorted directions (x_n, y_n, 1) as the intrinsics' own pixel_directions computes them, turned into the
    world: R_WO (x_n, y_n, 1) = x_n R_WO[:, 0] + y_n R_WO[:, 1] + R_WO[:, 2] (separable: no per-pixel directions
    built and rotated: 2.5x faster than :func:`_rays` on them, the same numbers)."""
    x = ((u.astype(float) - K.cx) / K.fx)[None, :, None]
    y = ((v.astype(float) - K.cy) / K.fy)[:, None, None]
    d = np.add(R_WO[:, 0] * x, R_WO[:, 1] * y)
    d += R_WO[:, 2]
    rays = np.empty((len(v), len(u), 6), np.float32)
    rays[..., :3] = origin
    rays[..., 3:] = d
    return rays.reshape(-1, 6)


class ViewLabeller:
    """Labels views of ``world`` through a camera of ``intrinsics`` mounted at ``T_BC`` (frame C, FLU) on the body.

    ``classes``: the labels that are classes (an object with another label is background).
    """

    def __init__(
        self,
        world: World,
        intrinsics: CameraIntrinsics,
        classes: tuple[str, ...],
        T_BC: Transform | None = None,
        nthreads: int = 0,
    ) -> None:
        if not isinstance(world, World):
            raise ValueError(f"world must be a cufund.World, got {type(world).__name__}")
        if not classes or len(set(classes)) != len(classes):
            raise ValueError(f"classes must be distinct labels, got {classes!r}")
        self.world, self.intrinsics, self.T_BC, self.nthreads = world, intrinsics, T_BC, int(nthreads)
        self.classes = tuple(classes)
        index = {name: i for i, name in enumerate(self.classes)}
        self._class_of = np.array([index.get(o.label, INVALID) for o in world.objects] + [INVALID], dtype=np.int16)
        self._dirs_O = intrinsics.pixel_directions().reshape(-1, 3)
        self._pinhole = not any(intrinsics.distortion)
        """Without distortion the 3x canvas's middle is the image, ray for ray: one cast per object gives both its
        unoccluded pixels and its truncation."""
        self._alone: dict[int, _core.lidar.RaycastScene] = {}
        self._boxes: dict[int, Box3D] = {}

    def _scene_alone(self, obj: WorldObject) -> _core.lidar.RaycastScene:
        if obj.id not in self._alone:
            scene = _core.lidar.RaycastScene()
            scene.add_triangles(obj.vertices.astype(np.float32), obj.triangles)
            self._alone[obj.id] = scene
        return self._alone[obj.id]

    def box3d(self, obj: WorldObject) -> Box3D:
        """The upright 3-D box of ``obj`` (computed once)."""
        if obj.id not in self._boxes:
            self._boxes[obj.id] = upright_box(obj.vertices)
        return self._boxes[obj.id]

    def instance_ids(self, p_W: object, q_WB: object) -> np.ndarray:
        """(H, W) int32 id of the world object hit first at each pixel (-1: nothing) from body pose (p_W, q_WB)."""
        origin, R_WO = camera_pose(self.T_BC, p_W, q_WB)
        hit = self.world.raycast_scene.cast_rays(_rays(origin, self._dirs_O, R_WO), nthreads=self.nthreads)
        ids = hit["geometry_ids"].astype(np.int64)
        ids[ids == _core.lidar.INVALID_ID] = INVALID
        return ids.reshape(self.intrinsics.height, self.intrinsics.width).astype(np.int32)

    def label(self, p_W: object, q_WB: object, instance_ids: np.ndarray | None = None) -> ViewLabels:
        """The labels of the view from body pose (p_W, q_WB); ``instance_ids``: that view's
        :meth:`instance_ids` if already cast."""
        origin, R_WO = camera_pose(self.T_BC, p_W, q_WB)
        instance = self.instance_ids(p_W, q_WB) if instance_ids is None else instance_ids
        classes = self._class_of[instance]
        objects = []
        for oid in np.unique(instance[classes >= 0]):
            obj = self.world.objects[int(oid)]
            mask = instance == oid
            rows, cols = np.nonzero(mask.any(1))[0], np.nonzero(mask.any(0))[0]
            box = (int(cols[0]), int(rows[0]), int(cols[-1]) + 1, int(rows[-1]) + 1)
            visible = int(mask.sum())
            scene = self._scene_alone(obj)
            inside, total = self._alone_on_canvas(obj, scene, origin, R_WO)
            if self._pinhole:
                unoccluded = inside
            else:  # the image's own (distorted) rays
                hits = scene.cast_rays(_rays(origin, self._dirs_O, R_WO), nthreads=self.nthreads)["t_hit"]
                unoccluded = int(np.isfinite(hits).sum())
            objects.append(
                ObjectLabel(
                    int(oid),
                    int(self._class_of[oid]),
                    obj.label,
                    box,
                    visible,
                    unoccluded,
                    float(1.0 - visible / unoccluded) if unoccluded else 0.0,
                    float(1.0 - inside / total) if total else 0.0,
                    self.box3d(obj),
                )
            )
        return ViewLabels(instance, classes, tuple(objects))

    def _alone_on_canvas(
        self, obj: WorldObject, scene: _core.lidar.RaycastScene, origin: np.ndarray, R_WO: np.ndarray
    ) -> tuple[int, int]:
        """(pixels inside the frame, pixels on the 3x pinhole canvas) of the object cast alone."""
        K = self.intrinsics
        w, h = K.width, K.height
        p_O = (obj.vertices - origin) @ R_WO
        # canvas pixel range [-w, 2w) x [-h, 2h) in image pixel coordinates
        u0, v0, u1, v1 = -w, -h, 2 * w, 2 * h
        if np.all(p_O[:, 2] > 1e-6):  # all in front: its image lies within its vertices' pinhole projections
            u = K.cx + K.fx * p_O[:, 0] / p_O[:, 2]
            v = K.cy + K.fy * p_O[:, 1] / p_O[:, 2]
            u0, u1 = int(np.clip(np.floor(u.min()) - 1, -w, 2 * w)), int(np.clip(np.ceil(u.max()) + 2, -w, 2 * w))
            v0, v1 = int(np.clip(np.floor(v.min()) - 1, -h, 2 * h)), int(np.clip(np.ceil(v.max()) + 2, -h, 2 * h))
        if u1 <= u0 or v1 <= v0:
            return 0, 0
        rays = _pinhole_rays(origin, K, np.arange(u0, u1), np.arange(v0, v1), R_WO)
        alone = np.isfinite(scene.cast_rays(rays, nthreads=self.nthreads)["t_hit"])
        alone = alone.reshape(v1 - v0, u1 - u0)
        inside = alone[max(-v0, 0) : max(h - v0, 0), max(-u0, 0) : max(w - u0, 0)]
        return int(inside.sum()), int(alone.sum())
