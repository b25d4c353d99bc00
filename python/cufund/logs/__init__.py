"""Run logs as MCAP files that Foxglove Studio and the ``mcap`` tools open without ROS.

:class:`McapLogger` writes any cufund message (and user dataclasses) while a run goes, in bounded memory: its
``write`` is one C call that copies a fixed-size message into a CDR row (a few tenths of a microsecond), and a C++
thread encodes, compresses and writes the chunks without the GIL; :func:`read_mcap` gives the same message
objects back, bit for bit.

What a log holds (one channel per topic, named as the topic):

- Fixed-size messages (odometry, IMU, magnetometer, barometer, setpoints, actuator commands; any dataclass of
  numbers and fixed-shape numeric arrays): CDR with a ros2msg schema ``cufund_msgs/msg/<Class>`` (field names
  lower-cased, an optional array adds ``has_<name>``), plottable in Foxglove.
- Each odometry topic also gets two Foxglove views: ``<topic>/pose`` (``foxglove_msgs/msg/PoseInFrame`` in
  ``world``) and ``<topic>/tf`` (``foxglove_msgs/msg/FrameTransform`` ``world`` -> ``base_link`` for
  ``/truth/odometry``, ``base_link_estimate`` for ``/estimator/odometry``).
- Point clouds (``foxglove.PointCloud``: in frame ``lidar`` with x, y, z, dt, range, intensity, channel packed;
  LiDAR truth in ``world`` with object_id), camera images (``foxglove.RawImage``, frame ``camera``) and GPS fixes
  (``foxglove.LocationFix``): JSON with JSON Schema; the float64 stamp, dtypes and other fields ride along in a
  ``cufund`` field for the exact round trip.
- Anything else (enums, strings, nested dataclasses): JSON of the fields (``cufund.<Class>``).

Chunks are lz4 (or zstd) with CRCs, indexed; the same messages give the same file byte for byte; the ``cufund`` metadata record holds what the logger was given.

Reading a log never imports or calls a class the file names: only cufund's messages, classes this process logged
and classes given to :func:`register_message_class` are rebuilt (anything else is a :class:`McapReadError`
naming the channel). A log whose run was killed (no summary) is read up to its last complete chunk, with one
:class:`TruncatedLogWarning`.
"""

from .log_player import LogPlayer
from .mcap_reader import LogRecord, McapReadError, TruncatedLogWarning, log_metadata, log_topics, read_mcap
from .mcap_writer import McapLogger
from .message_classes import register_message_class

__all__ = [
    "LogPlayer",
    "LogRecord",
    "McapLogger",
    "McapReadError",
    "TruncatedLogWarning",
    "log_metadata",
    "log_topics",
    "read_mcap",
    "register_message_class",
]
