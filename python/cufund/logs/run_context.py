"""What a run's log holds beside its messages: the static transforms (``/tf_static``) that tie every frame a
message names to ``world``, and the world's meshes (``/world/scene``, a ``foxglove.SceneUpdate``).

The frame tree of a cufund log::

    world ─┬─ odom ── base_link ─┬─ <sensor> (imu, lidar, camera, ...: base_link -> sensor from the scenario's
           │        (estimate)   │             extrinsic T_B<X>, identity when the sensor has none)
           └─ base_link_truth    └─ ...
              (truth, /tf)

``world`` -> ``odom`` is the identity (cufund's estimators estimate in the world frame); ``odom`` -> ``base_link``
comes from ``/estimator/odometry`` and ``world`` -> ``base_link_truth`` from ``/truth/odometry`` (both on
``/tf``). A scenario without an estimator flies on truth: ``base_link_truth`` -> ``base_link`` is then a static
identity, so the sensors' frames still resolve.

A reference known before the run (the ``waypoints`` planner's) goes to ``/planner/path`` (``nav_msgs/msg/Path``);
replanned trajectories go to ``/planner/trajectory`` as paths when they are logged.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from . import codecs, ros2, scene

__all__ = ["write_run_context"]

_IDENTITY = ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0))


def static_transforms(
    sensors: Iterable[tuple[str, Any, Any]], has_estimator: bool, vehicle: str = ""
) -> list[tuple[str, str, Any, Any]]:
    """(parent, child, translation, q [w, x, y, z]) of ``/tf_static`` for ``sensors`` (frame name, translation
    (3,) or None, q_BX or None); a fleet ``vehicle``'s frames under its name (``uav1/odom``, ``uav1/base_link``,
    as :func:`cufund.logs.codecs.odometry_frames` names them)."""
    ns = f"{vehicle}/" if vehicle else ""
    transforms: list[tuple[str, str, Any, Any]] = [("world", f"{ns}odom", *_IDENTITY)]
    if not has_estimator:
        transforms.append((f"{ns}base_link_truth", f"{ns}base_link", *_IDENTITY))
    for frame, p, q in sensors:
        transforms.append(
            (f"{ns}base_link", frame, _IDENTITY[0] if p is None else tuple(p), _IDENTITY[1] if q is None else tuple(q))
        )
    return transforms


def write_run_context(
    logger: Any,
    sensors: Iterable[tuple[str, Any, Any]],
    has_estimator: bool,
    world: Any = None,
    reference: Any = None,
    transforms: list[tuple[str, str, Any, Any]] | None = None,
) -> None:
    """Writes ``/tf_static`` (``transforms``, default :func:`static_transforms` of ``sensors``), (with a ``world``,
    a :class:`cufund.worlds.World`) ``/world/scene`` and (with a ``reference`` trajectory known before the run)
    ``/planner/path`` at time 0."""
    if reference is not None and hasattr(reference, "sample"):
        logger.write_encoded("/planner/path", ros2.PATH, codecs.path_of(reference, 0.0), 0)
    if transforms is None:
        transforms = static_transforms(sensors, has_estimator)
    logger.write_encoded("/tf_static", ros2.TF_MESSAGE, ros2.tf_message(0.0, transforms), 0)
    if world is not None and len(world.objects):
        logger.write_encoded(
            "/world/scene",
            scene.SCENE_UPDATE,
            scene.world_scene_update(world),
            0,
            schema_encoding="jsonschema",
            message_encoding="json",
        )
