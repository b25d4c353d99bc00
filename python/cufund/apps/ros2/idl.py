# mypy: disable-error-code="type-arg,valid-type,assignment"
"""The ROS 2 message types the bridge speaks, as Cyclone DDS IDL structs named as ROS 2 names them on the wire
(``sensor_msgs/msg/Imu`` -> ``sensor_msgs::msg::dds_::Imu_``).

They give each DDS topic its type (name and XTypes type information, what a Fast DDS or rmw_cyclonedds peer matches
against) and decode what ROS 2 nodes publish to cufund (goals, paths, trajectories, PX4 offboard topics). What
cufund publishes is serialised once, by :mod:`cufund.logs` (the CDR a run log holds); the bridge writes those bytes
as they are, and the tests check that these independent structs decode them.

``px4_msgs`` as of PX4 v1.15 (``TrajectorySetpoint`` with ``position[3]``..., ``OffboardControlMode`` with
``thrust_and_torque``); ``quadrotor_msgs/PositionCommand`` as EGO-Planner's ROS 2 port defines it (with ``jerk``).
"""

from dataclasses import dataclass, field

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float32, float64, int32, sequence, uint8, uint16, uint32, uint64

__all__ = [
    "TYPES",
    "CameraInfo",
    "Clock",
    "Header",
    "Image",
    "Imu",
    "MultiDOFJointTrajectory",
    "OffboardControlMode",
    "Odometry",
    "Path",
    "PointCloud2",
    "PoseStamped",
    "PositionCommand",
    "TFMessage",
    "Time",
    "TrajectorySetpoint",
    "VehicleCommand",
    "dds_type_name",
]


def dds_type_name(ros_type: str) -> str:
    """``pkg/msg/Name`` -> ``pkg::msg::dds_::Name_`` (ROS 2's type name mapping onto DDS)."""
    pkg, kind, name = ros_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def _n(ros_type: str) -> str:
    return dds_type_name(ros_type)


@dataclass
class Time(IdlStruct, typename=_n("builtin_interfaces/msg/Time")):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Duration(IdlStruct, typename=_n("builtin_interfaces/msg/Duration")):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header(IdlStruct, typename=_n("std_msgs/msg/Header")):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Clock(IdlStruct, typename=_n("rosgraph_msgs/msg/Clock")):
    clock: Time = field(default_factory=Time)


@dataclass
class Vector3(IdlStruct, typename=_n("geometry_msgs/msg/Vector3")):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Point(IdlStruct, typename=_n("geometry_msgs/msg/Point")):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename=_n("geometry_msgs/msg/Quaternion")):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Pose(IdlStruct, typename=_n("geometry_msgs/msg/Pose")):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseStamped(IdlStruct, typename=_n("geometry_msgs/msg/PoseStamped")):
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


@dataclass
class PoseWithCovariance(IdlStruct, typename=_n("geometry_msgs/msg/PoseWithCovariance")):
    pose: Pose = field(default_factory=Pose)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class Twist(IdlStruct, typename=_n("geometry_msgs/msg/Twist")):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TwistWithCovariance(IdlStruct, typename=_n("geometry_msgs/msg/TwistWithCovariance")):
    twist: Twist = field(default_factory=Twist)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class Transform(IdlStruct, typename=_n("geometry_msgs/msg/Transform")):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped(IdlStruct, typename=_n("geometry_msgs/msg/TransformStamped")):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass
class TFMessage(IdlStruct, typename=_n("tf2_msgs/msg/TFMessage")):
    transforms: sequence[TransformStamped] = field(default_factory=list)


@dataclass
class Imu(IdlStruct, typename=_n("sensor_msgs/msg/Imu")):
    header: Header = field(default_factory=Header)
    orientation: Quaternion = field(default_factory=Quaternion)
    orientation_covariance: array[float64, 9] = field(default_factory=lambda: [0.0] * 9)
    angular_velocity: Vector3 = field(default_factory=Vector3)
    angular_velocity_covariance: array[float64, 9] = field(default_factory=lambda: [0.0] * 9)
    linear_acceleration: Vector3 = field(default_factory=Vector3)
    linear_acceleration_covariance: array[float64, 9] = field(default_factory=lambda: [0.0] * 9)


@dataclass
class PointField(IdlStruct, typename=_n("sensor_msgs/msg/PointField")):
    name: str = ""
    offset: uint32 = 0
    datatype: uint8 = 0
    count: uint32 = 0


@dataclass
class PointCloud2(IdlStruct, typename=_n("sensor_msgs/msg/PointCloud2")):
    header: Header = field(default_factory=Header)
    height: uint32 = 0
    width: uint32 = 0
    fields: sequence[PointField] = field(default_factory=list)
    is_bigendian: bool = False
    point_step: uint32 = 0
    row_step: uint32 = 0
    data: sequence[uint8] = field(default_factory=list)
    is_dense: bool = False


@dataclass
class Image(IdlStruct, typename=_n("sensor_msgs/msg/Image")):
    header: Header = field(default_factory=Header)
    height: uint32 = 0
    width: uint32 = 0
    encoding: str = ""
    is_bigendian: uint8 = 0
    step: uint32 = 0
    data: sequence[uint8] = field(default_factory=list)


@dataclass
class RegionOfInterest(IdlStruct, typename=_n("sensor_msgs/msg/RegionOfInterest")):
    x_offset: uint32 = 0
    y_offset: uint32 = 0
    height: uint32 = 0
    width: uint32 = 0
    do_rectify: bool = False


@dataclass
class CameraInfo(IdlStruct, typename=_n("sensor_msgs/msg/CameraInfo")):
    header: Header = field(default_factory=Header)
    height: uint32 = 0
    width: uint32 = 0
    distortion_model: str = ""
    d: sequence[float64] = field(default_factory=list)
    k: array[float64, 9] = field(default_factory=lambda: [0.0] * 9)
    r: array[float64, 9] = field(default_factory=lambda: [0.0] * 9)
    p: array[float64, 12] = field(default_factory=lambda: [0.0] * 12)
    binning_x: uint32 = 0
    binning_y: uint32 = 0
    roi: RegionOfInterest = field(default_factory=RegionOfInterest)


@dataclass
class Odometry(IdlStruct, typename=_n("nav_msgs/msg/Odometry")):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@dataclass
class Path(IdlStruct, typename=_n("nav_msgs/msg/Path")):
    header: Header = field(default_factory=Header)
    poses: sequence[PoseStamped] = field(default_factory=list)


@dataclass
class MultiDOFJointTrajectoryPoint(IdlStruct, typename=_n("trajectory_msgs/msg/MultiDOFJointTrajectoryPoint")):
    transforms: sequence[Transform] = field(default_factory=list)
    velocities: sequence[Twist] = field(default_factory=list)
    accelerations: sequence[Twist] = field(default_factory=list)
    time_from_start: Duration = field(default_factory=Duration)


@dataclass
class MultiDOFJointTrajectory(IdlStruct, typename=_n("trajectory_msgs/msg/MultiDOFJointTrajectory")):
    header: Header = field(default_factory=Header)
    joint_names: sequence[str] = field(default_factory=list)
    points: sequence[MultiDOFJointTrajectoryPoint] = field(default_factory=list)


@dataclass
class PositionCommand(IdlStruct, typename=_n("quadrotor_msgs/msg/PositionCommand")):
    header: Header = field(default_factory=Header)
    position: Point = field(default_factory=Point)
    velocity: Vector3 = field(default_factory=Vector3)
    acceleration: Vector3 = field(default_factory=Vector3)
    jerk: Vector3 = field(default_factory=Vector3)
    yaw: float64 = 0.0
    yaw_dot: float64 = 0.0
    kx: array[float64, 3] = field(default_factory=lambda: [0.0] * 3)
    kv: array[float64, 3] = field(default_factory=lambda: [0.0] * 3)
    trajectory_id: uint32 = 0
    trajectory_flag: uint8 = 0


@dataclass
class TrajectorySetpoint(IdlStruct, typename=_n("px4_msgs/msg/TrajectorySetpoint")):
    timestamp: uint64 = 0
    position: array[float32, 3] = field(default_factory=lambda: [float("nan")] * 3)
    velocity: array[float32, 3] = field(default_factory=lambda: [float("nan")] * 3)
    acceleration: array[float32, 3] = field(default_factory=lambda: [float("nan")] * 3)
    jerk: array[float32, 3] = field(default_factory=lambda: [float("nan")] * 3)
    yaw: float32 = float("nan")
    yawspeed: float32 = float("nan")


@dataclass
class OffboardControlMode(IdlStruct, typename=_n("px4_msgs/msg/OffboardControlMode")):
    timestamp: uint64 = 0
    position: bool = False
    velocity: bool = False
    acceleration: bool = False
    attitude: bool = False
    body_rate: bool = False
    thrust_and_torque: bool = False
    direct_actuator: bool = False


@dataclass
class VehicleCommand(IdlStruct, typename=_n("px4_msgs/msg/VehicleCommand")):
    timestamp: uint64 = 0
    param1: float32 = 0.0
    param2: float32 = 0.0
    param3: float32 = 0.0
    param4: float32 = 0.0
    param5: float64 = 0.0
    param6: float64 = 0.0
    param7: float32 = 0.0
    command: uint32 = 0
    target_system: uint8 = 0
    target_component: uint8 = 0
    source_system: uint8 = 0
    source_component: uint16 = 0
    confirmation: uint8 = 0
    from_external: bool = False


TYPES: dict[str, type] = {
    "rosgraph_msgs/msg/Clock": Clock,
    "std_msgs/msg/Header": Header,
    "sensor_msgs/msg/Imu": Imu,
    "sensor_msgs/msg/PointCloud2": PointCloud2,
    "sensor_msgs/msg/Image": Image,
    "sensor_msgs/msg/CameraInfo": CameraInfo,
    "tf2_msgs/msg/TFMessage": TFMessage,
    "nav_msgs/msg/Odometry": Odometry,
    "nav_msgs/msg/Path": Path,
    "geometry_msgs/msg/PoseStamped": PoseStamped,
    "trajectory_msgs/msg/MultiDOFJointTrajectory": MultiDOFJointTrajectory,
    "quadrotor_msgs/msg/PositionCommand": PositionCommand,
    "px4_msgs/msg/TrajectorySetpoint": TrajectorySetpoint,
    "px4_msgs/msg/OffboardControlMode": OffboardControlMode,
    "px4_msgs/msg/VehicleCommand": VehicleCommand,
}
"""The ROS 2 types the bridge knows, by ROS 2 name."""
