"""Drawing a quadrotor run in a MeshCat scene: vehicle body and rotors, paths, setpoint, and the camera framed on
the flight (one scene layout for ``replay.html``, ``cufund replay`` and the live viewer)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.geometry import quat_to_matrix
from cufund.vehicle.params import QuadrotorParams

__all__ = [
    "ESTIMATE_COLOR",
    "ESTIMATED",
    "ESTIMATE_VEHICLE",
    "FLOWN",
    "PLANNED",
    "PLANNED_COLOR",
    "SETPOINT",
    "TRUTH_COLOR",
    "VEHICLE",
    "View",
    "apply_view",
    "draw_estimate_marker",
    "draw_path",
    "draw_vehicle",
    "frame_view",
    "import_meshcat",
    "pose_matrix",
    "vehicle_scale",
]

VEHICLE, SETPOINT, PLANNED, FLOWN = "vehicle", "setpoint", "planned", "flown"
ESTIMATE_VEHICLE, ESTIMATED = "estimate", "estimated"
"""MeshCat paths of the estimated pose (a translucent box) and the estimated path."""
TRUTH_COLOR, ESTIMATE_COLOR, PLANNED_COLOR = 0xD62728, 0x1F77B4, 0x2CA02C
"""The colours of every cufund figure and replay: truth red, estimate blue, setpoints / planned path green."""
FOV_DEG = 75.0
"""MeshCat's default camera's vertical field of view [deg]."""


def import_meshcat() -> Any:
    """``import meshcat``, silencing the DeprecationWarning its server module raises on import with pyzmq >= 17
    (meshcat 0.3.2 imports ``zmq.eventloop.ioloop``; nothing of ours uses it)."""
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="zmq.eventloop.ioloop is deprecated", category=DeprecationWarning)
        import meshcat
        import meshcat.animation
        import meshcat.geometry
        import meshcat.transformations
    return meshcat


def pose_matrix(p_W: np.ndarray, q_WB: np.ndarray) -> np.ndarray:
    """T_WB (4, 4) from a position and a [w, x, y, z] quaternion."""
    T = np.eye(4)
    T[:3, :3] = quat_to_matrix(np.asarray(q_WB, dtype=float))
    T[:3, 3] = p_W
    return T


def _span(params: QuadrotorParams) -> float:
    """The drawn vehicle's width tip to tip [m] (arms plus rotor discs)."""
    return 2.0 * 1.45 * params.arm_length


def vehicle_scale(params: QuadrotorParams, view: View | None) -> float:
    """How much to enlarge the drawn vehicle so that it spans at least 15 % of the framed flight's half-diagonal
    (1: drawn to scale). A 0.5 m quadrotor over a 30 m flight is otherwise a few pixels."""
    if view is None:
        return 1.0
    return float(max(1.0, 0.15 * view.radius / _span(params)))


def draw_vehicle(vis: Any, params: QuadrotorParams, scale: float = 1.0) -> None:
    """A body box and one disc per rotor (counter-clockwise rotors blue, clockwise orange) under ``vehicle/model``
    (enlarged ``scale`` times about the body origin), and a small sphere under ``setpoint``."""
    meshcat = import_meshcat()
    g, tf = meshcat.geometry, meshcat.transformations

    d = params.arm_length
    body = vis[VEHICLE]["model"]
    if scale != 1.0:
        body.set_transform(tf.scale_matrix(scale))
    body["body"].set_object(g.Box([0.6 * d, 0.6 * d, 0.3 * d]), g.MeshLambertMaterial(color=0x404040))
    body["nose"].set_object(g.Box([0.4 * d, 0.1 * d, 0.1 * d]), g.MeshLambertMaterial(color=TRUTH_COLOR))
    body["nose"].set_transform(tf.translation_matrix([0.45 * d, 0.0, 0.0]))
    radius = 0.45 * d
    for i, (pos, spin) in enumerate(zip(params.rotor_positions(), params.rotor_spins(), strict=True)):
        color = 0x1F77B4 if spin > 0 else 0xFF7F0E
        rotor = body[f"rotor{i + 1}"]
        rotor.set_object(g.Cylinder(0.01, radius), g.MeshLambertMaterial(color=color, opacity=0.8, transparent=True))
        # meshcat cylinders lie along y; turn the axis to body z and lift the disc above the arm
        rotor.set_transform(tf.translation_matrix(pos + [0, 0, 0.02]) @ tf.rotation_matrix(np.pi / 2, [1, 0, 0]))
        body[f"arm{i + 1}"].set_object(g.Box([d, 0.08 * d, 0.08 * d]), g.MeshLambertMaterial(color=0x202020))
        ang = np.arctan2(pos[1], pos[0])
        body[f"arm{i + 1}"].set_transform(tf.rotation_matrix(ang, [0, 0, 1]) @ tf.translation_matrix([d / 2, 0, 0]))
    vis[SETPOINT].set_object(g.Sphere(0.03 * scale), g.MeshLambertMaterial(color=PLANNED_COLOR))


def draw_estimate_marker(vis: Any, params: QuadrotorParams, scale: float = 1.0) -> None:
    """The estimated pose: a translucent blue box the vehicle's size under ``estimate``."""
    g = import_meshcat().geometry
    d = params.arm_length * scale
    vis[ESTIMATE_VEHICLE].set_object(
        g.Box([2 * d, 2 * d, 0.3 * d]), g.MeshLambertMaterial(color=ESTIMATE_COLOR, opacity=0.4, transparent=True)
    )


def draw_path(vis: Any, name: str, points_W: np.ndarray, color: int) -> None:
    """A polyline through ``points_W`` (N, 3) under ``name``."""
    g = import_meshcat().geometry

    pts = np.ascontiguousarray(np.asarray(points_W, dtype=np.float32).T)
    vis[name].set_object(g.Line(g.PointsGeometry(pts), g.LineBasicMaterial(color=color, linewidth=2)))


@dataclass(frozen=True)
class View:
    """Where the camera looks from and at (world frame, ENU) [m]."""

    target_W: np.ndarray
    """The centre of the flight's bounding box; the camera orbits about it."""
    eye_W: np.ndarray
    """The camera's position."""
    radius: float
    """Half the bounding box's diagonal [m] (at least 1 m)."""
    fov_deg: float = FOV_DEG
    """Vertical field of view."""

    @property
    def far(self) -> float:
        """The far clipping distance: the world around the flight stays in view."""
        return max(100.0, 6.0 * float(np.linalg.norm(self.eye_W - self.target_W)))

    def to_dict(self) -> dict[str, Any]:
        return {
            "target_W": [float(x) for x in self.target_W],
            "eye_W": [float(x) for x in self.eye_W],
            "up_W": [0.0, 0.0, 1.0],
            "fov_deg": self.fov_deg,
        }


def frame_view(points_W: np.ndarray, aspect: float = 4.0 / 3.0) -> View:
    """A camera that shows every point of ``points_W`` (N, 3), e.g. the flown and planned paths: it looks at the
    centre of their bounding box, from the side of its longer horizontal axis, 50 degrees up (over trees and walls) and 30 degrees
    round, far enough that a sphere about the box fits the narrower field of view of a ``aspect`` window."""
    pts = np.asarray(points_W, dtype=float).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) == 0:
        pts = np.zeros((1, 3))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre = (lo + hi) / 2.0
    radius = max(1.0, float(np.linalg.norm(hi - lo)) / 2.0)
    ext = hi - lo
    # look across the longer horizontal axis: along x -> from -y (south); along y -> from +x (east)
    azimuth = -np.pi / 2 if ext[0] >= ext[1] else 0.0
    azimuth += np.radians(30.0)
    elevation = np.radians(50.0)
    half = np.radians(FOV_DEG) / 2.0
    half = min(half, np.arctan(np.tan(half) * aspect))
    distance = 1.1 * radius / np.sin(half)
    direction = np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    return View(centre, centre + distance * direction, radius)


def apply_view(vis: Any, view: View, ground_z: float = 0.0) -> None:
    """Frames the scene on ``view``: MeshCat's camera orbits about the scene origin, so the drawn scene (under
    ``vis``, the viewer's root) is moved by ``-target_W`` and the camera placed at ``eye_W - target_W``
    (MeshCat's camera frame is y-up: (x, z, -y)). The ground grid is put 1 cm below ``ground_z`` (under the floor
    and the path, never across them), centred under the flight and grown to cover it; the axes stay at the world
    origin."""
    tf = import_meshcat().transformations
    c = np.asarray(view.target_W, dtype=float)
    vis.set_transform(tf.translation_matrix(-c))
    o = np.asarray(view.eye_W, dtype=float) - c
    camera = vis["/Cameras/default/rotated/<object>"]
    camera.set_property("position", [float(o[0]), float(o[2]), float(-o[1])])
    camera.set_property("far", view.far)
    grid_scale = float(max(1.0, np.ceil(2.2 * view.radius / 20.0)))  # MeshCat's grid is 20 m wide
    vis["/Grid"].set_transform(tf.translation_matrix([0.0, 0.0, ground_z - 0.01 - c[2]]) @ tf.scale_matrix(grid_scale))
    vis["/Axes"].set_transform(tf.translation_matrix(-c))
