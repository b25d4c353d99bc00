"""Drawing a quadrotor run in a MeshCat scene: vehicle body and rotors, planned path, flown path, setpoint."""

from __future__ import annotations

from typing import Any

import numpy as np

from cufund.geometry import quat_to_matrix
from cufund.vehicle.params import QuadrotorParams

__all__ = ["draw_vehicle", "draw_path", "import_meshcat", "pose_matrix", "VEHICLE", "SETPOINT", "PLANNED", "FLOWN"]

VEHICLE, SETPOINT, PLANNED, FLOWN = "vehicle", "setpoint", "planned", "flown"


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


def draw_vehicle(vis: Any, params: QuadrotorParams) -> None:
    """A body box and one disc per rotor (counter-clockwise rotors blue, clockwise orange) under ``vehicle``,
    and a small sphere under ``setpoint``."""
    meshcat = import_meshcat()
    g, tf = meshcat.geometry, meshcat.transformations

    d = params.arm_length
    body = vis[VEHICLE]
    body["body"].set_object(g.Box([0.6 * d, 0.6 * d, 0.3 * d]), g.MeshLambertMaterial(color=0x404040))
    body["nose"].set_object(g.Box([0.4 * d, 0.1 * d, 0.1 * d]), g.MeshLambertMaterial(color=0xD62728))
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
    vis[SETPOINT].set_object(g.Sphere(0.03), g.MeshLambertMaterial(color=0x2CA02C))


def draw_path(vis: Any, name: str, points_W: np.ndarray, color: int) -> None:
    """A polyline through ``points_W`` (N, 3) under ``name``."""
    g = import_meshcat().geometry

    pts = np.ascontiguousarray(np.asarray(points_W, dtype=np.float32).T)
    vis[name].set_object(g.Line(g.PointsGeometry(pts), g.LineBasicMaterial(color=color, linewidth=2)))
