"""The Foxglove well-known schemas cufund logs use, written from their public definitions: ros2msg text (CDR)
for the high-rate views of odometry, JSON Schema for point clouds, images and location fixes.

Foxglove Studio recognises a schema by its name: ``foxglove_msgs/msg/FrameTransform`` in ros2msg, and
``foxglove.PointCloud`` in JSON (https://docs.foxglove.dev/docs/visualization/message-schemas/).
"""

from __future__ import annotations

import json

from .cdr import CdrField, CdrLayout

__all__ = [
    "FRAME_TRANSFORM",
    "LOCATION_FIX_SCHEMA",
    "POINT_CLOUD_SCHEMA",
    "POSE_IN_FRAME",
    "RAW_IMAGE_SCHEMA",
    "NUMERIC_TYPES",
    "frame_transform_layout",
    "pose_in_frame_layout",
]

_SEPARATOR = "=" * 80

_TIME = "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
_VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
_POINT = "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
_QUATERNION = "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
_POSE = "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n"


def _ros2msg(main: str, *dependencies: str) -> str:
    return "".join([main] + [f"{_SEPARATOR}\n{d}" for d in dependencies])


FRAME_TRANSFORM = (
    "foxglove_msgs/msg/FrameTransform",
    _ros2msg(
        "builtin_interfaces/Time timestamp\nstring parent_frame_id\nstring child_frame_id\n"
        "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n",
        _TIME,
        _VECTOR3,
        _QUATERNION,
    ),
)
"""(schema name, ros2msg text) of a transform between two frames."""

POSE_IN_FRAME = (
    "foxglove_msgs/msg/PoseInFrame",
    _ros2msg(
        "builtin_interfaces/Time timestamp\nstring frame_id\ngeometry_msgs/Pose pose\n",
        _TIME,
        _POSE,
        _POINT,
        _QUATERNION,
    ),
)
"""(schema name, ros2msg text) of a timestamped pose in a named frame."""


def frame_transform_layout(parent: str, child: str) -> CdrLayout:
    """CDR layout of a ``FrameTransform`` from ``parent`` to ``child`` (columns ``translation`` (3,) and
    ``rotation`` (4,) as x, y, z, w)."""
    return CdrLayout(
        [
            CdrField("timestamp.sec", "i4"),
            CdrField("timestamp.nanosec", "u4"),
            CdrField("parent_frame_id", "str", const=parent),
            CdrField("child_frame_id", "str", const=child),
            CdrField("translation", "f8", 3),
            CdrField("rotation", "f8", 4),
        ]
    )


def pose_in_frame_layout(frame: str) -> CdrLayout:
    """CDR layout of a ``PoseInFrame`` (columns ``pose.position`` (3,), ``pose.orientation`` (4,) x, y, z, w)."""
    return CdrLayout(
        [
            CdrField("timestamp.sec", "i4"),
            CdrField("timestamp.nanosec", "u4"),
            CdrField("frame_id", "str", const=frame),
            CdrField("pose.position", "f8", 3),
            CdrField("pose.orientation", "f8", 4),
        ]
    )


NUMERIC_TYPES = {"uint8": 1, "int8": 2, "uint16": 3, "int16": 4, "uint32": 5, "int32": 6, "float32": 7, "float64": 8}
"""Foxglove ``NumericType`` of each numpy dtype a packed element field can hold."""

_TIME_JSON = {
    "type": "object",
    "title": "time",
    "properties": {"sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0}},
}
_VEC3_JSON = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}}
_QUAT_JSON = {"type": "object", "properties": {k: {"type": "number"} for k in "xyzw"}}
_EXACT_JSON = {
    "type": "object",
    "description": "cufund: what an exact round trip of the message needs beyond "
    "the Foxglove fields (stamp [s] as a float64, dtypes, shapes)",
}


def _schema(title: str, description: str, properties: dict) -> bytes:
    return json.dumps(
        {
            "title": title,
            "description": description,
            "type": "object",
            "properties": {**properties, "cufund": _EXACT_JSON},
        }
    ).encode()


POINT_CLOUD_SCHEMA = (
    "foxglove.PointCloud",
    _schema(
        "foxglove.PointCloud",
        "A collection of N-dimensional points",
        {
            "timestamp": _TIME_JSON,
            "frame_id": {"type": "string"},
            "pose": {"type": "object", "properties": {"position": _VEC3_JSON, "orientation": _QUAT_JSON}},
            "point_stride": {"type": "integer", "minimum": 0},
            "fields": {
                "type": "array",
                "items": {
                    "type": "object",
                    "properties": {
                        "name": {"type": "string"},
                        "offset": {"type": "integer", "minimum": 0},
                        "type": {"type": "integer", "enum": list(range(9))},
                    },
                },
            },
            "data": {"type": "string", "contentEncoding": "base64"},
        },
    ),
)

RAW_IMAGE_SCHEMA = (
    "foxglove.RawImage",
    _schema(
        "foxglove.RawImage",
        "A raw image",
        {
            "timestamp": _TIME_JSON,
            "frame_id": {"type": "string"},
            "width": {"type": "integer", "minimum": 0},
            "height": {"type": "integer", "minimum": 0},
            "encoding": {"type": "string"},
            "step": {"type": "integer", "minimum": 0},
            "data": {"type": "string", "contentEncoding": "base64"},
        },
    ),
)

LOCATION_FIX_SCHEMA = (
    "foxglove.LocationFix",
    _schema(
        "foxglove.LocationFix",
        "A navigation satellite fix for any Global Navigation Satellite System",
        {
            "timestamp": _TIME_JSON,
            "frame_id": {"type": "string"},
            "latitude": {"type": ["number", "null"]},
            "longitude": {"type": ["number", "null"]},
            "altitude": {"type": ["number", "null"]},
            "position_covariance": {"type": "array", "items": {"type": "number"}, "minItems": 9, "maxItems": 9},
            "position_covariance_type": {"type": "integer", "enum": [0, 1, 2, 3]},
        },
    ),
)
