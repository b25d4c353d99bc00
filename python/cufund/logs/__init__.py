"""Run logs as MCAP files that Foxglove, the ``mcap`` tools and ROS 2 tools (``mcap-ros2-support``, ``rosbags``)
open as they open a real robot's ROS 2 bag.

:class:`McapLogger` writes any cufund message (and user dataclasses) while a run goes, in bounded memory: its
``write`` is one C call that copies a fixed-size message into a CDR row (a few tenths of a microsecond), and a C++
thread encodes, compresses and writes the chunks without the GIL; :func:`read_mcap` gives the same message
objects back.

What a log holds (one channel per topic, named as the topic; every standard message CDR with a ros2msg schema):

- Fixed-size messages (odometry, IMU, magnetometer, barometer, GPS, setpoints, actuator commands; any dataclass of
  numbers and fixed-shape numeric arrays): exact CDR ``cufund_msgs/msg/<Class>`` (field names lower-cased, an
  optional array adds ``has_<name>``), read back bit for bit. Beside them, standard views the writer thread
  derives from the same bytes: ``nav_msgs/msg/Odometry`` and ``geometry_msgs/msg/PoseStamped`` of the estimate,
  ``/tf`` (``odom`` -> ``base_link`` from the estimate, ``world`` -> ``base_link_truth`` from the truth),
  ``/clock``, ``sensor_msgs/msg/Imu``, ``sensor_msgs/msg/NavSatFix`` (:mod:`cufund.logs.ros2`).
- LiDAR frames as ``sensor_msgs/msg/PointCloud2`` in livox_ros_driver2's point layout, images as
  ``sensor_msgs/msg/Image``, read back with their stamps to the nanosecond (:class:`cufund.logs.codecs.PointCloud2Codec`).
- Planned trajectories as ``nav_msgs/msg/Path``; the world and the detected tunnel frames as
  ``foxglove.SceneUpdate`` (JSON); ``/tf_static`` from the scenario's extrinsics (:mod:`cufund.logs.run_context`).
  These are for viewers and are not read back.
- Anything else (enums, strings, variable-size messages): JSON of the fields (``cufund.<Class>``).

Logs written before the ROS 2 messages (JSON ``foxglove.PointCloud`` clouds) are still read. Chunks are zstd or
lz4 with CRCs, indexed; the same messages give the same file byte for byte; the ``cufund`` metadata record holds
what the logger was given.

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
