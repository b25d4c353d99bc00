"""The Foxglove JSON schemas of older cufund logs (point clouds, images and location fixes as JSON, before the
ROS 2 messages of :mod:`cufund.logs.ros2`), kept so that those logs are still read; written from Foxglove's public
definitions (https://docs.foxglove.dev/docs/visualization/message-schemas/).
"""

from __future__ import annotations

import json

__all__ = ["LOCATION_FIX_SCHEMA", "NUMERIC_TYPES", "POINT_CLOUD_SCHEMA", "RAW_IMAGE_SCHEMA"]

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
