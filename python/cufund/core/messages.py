"""Typed messages that components exchange on typed topics (the paper's ROS messages, without ROS).

Every message carries its measurement stamp ``t`` [s]: the simulated time the measured quantity refers to
(the bus records separately when a message became visible). Arrays are float64 numpy arrays unless a field
says otherwise; frames follow the names (``_W`` world ENU, ``_B`` body FLU), quaternions are ``[w, x, y, z]``.
Messages are frozen and their arrays read-only: a component that wants to change one publishes a new one, and
a publisher cannot change a message after publishing it. Ground truth travels only on ``/truth/...`` topics
(:class:`Odometry` and :class:`LidarTruth`); no sensor message carries a true value.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import MISSING, dataclass, fields
from typing import Any, ClassVar, TypeVar, dataclass_transform

import numpy as np

from .topics import Topic

_M = TypeVar("_M", bound="Message")


def _readonly(value: Any) -> Any:
    """``value`` as a read-only array: a fresh array the publisher owns is frozen in place (no copy); a view or a
    list is copied first, so no one keeps a writable alias of a published array."""
    if value is None:
        return None
    if isinstance(value, np.ndarray):
        if value.base is not None:
            value = value.copy()
    else:
        value = np.array(value, dtype=float)
    value.setflags(write=False)
    return value


class Message:
    """Base of cufund's message types (no fields, no instance dict): declares what :func:`message` adds."""

    __slots__ = ()
    trusted: ClassVar[Callable[..., Any]]
    """``Cls.trusted(*fields)``: the message from arrays the caller guarantees read-only and unshared."""


@dataclass_transform(frozen_default=True)
def message(cls: type[_M]) -> type[_M]:
    """Makes ``cls`` a frozen, slotted dataclass whose ``np.ndarray`` fields are read-only after construction."""
    array_fields = tuple(name for name, kind in cls.__annotations__.items() if "ndarray" in str(kind))
    if array_fields:
        setter = object.__setattr__

        ndarray = np.ndarray

        def __post_init__(self: Any) -> None:
            for name in array_fields:
                value = getattr(self, name)
                if value.__class__ is ndarray and value.base is None:  # fresh: freeze in place
                    value.setflags(write=False)
                else:
                    setter(self, name, _readonly(value))

        cls.__post_init__ = __post_init__  # type: ignore[attr-defined]
    cls = dataclass(frozen=True, slots=True)(cls)
    all_fields = fields(cls)  # type: ignore[arg-type]  # a dataclass from the line above
    names = [f.name for f in all_fields]
    # trusted(...): the message from arrays the caller guarantees are read-only and unshared (no checks, no
    # copies), for producers of many messages per second like the simulator's ground truth. Generated with one
    # plain assignment per field: a loop over the fields costs more than the message itself. Fields with a
    # default (None, a number) keep it.
    env: dict[str, Any] = {"_new": object.__new__, "_set": object.__setattr__, "_cls": cls}
    params = []
    for i, f in enumerate(all_fields):
        if f.default is MISSING:
            params.append(f.name)
        else:
            env[f"_d{i}"] = f.default
            params.append(f"{f.name}=_d{i}")
    src = (
        f"def trusted({', '.join(params)}):\n    obj = _new(_cls)\n"
        + "".join(f"    _set(obj, {n!r}, {n})\n" for n in names)
        + "    return obj\n"
    )
    exec(src, env)
    cls.trusted = staticmethod(env["trusted"])
    return cls


class FlightMode(enum.Enum):
    """Which references the flight controller tracks (paper §2.3)."""

    POSITION = "position"
    """Position, with velocity, acceleration and yaw-rate feed-forward."""
    VELOCITY = "velocity"
    """Velocity, with acceleration feed-forward; position is not controlled."""
    ATTITUDE = "attitude"
    """Attitude and collective thrust."""


@message
class Odometry(Message):
    """Vehicle state estimate (or ground truth)."""

    t: float
    p_W: np.ndarray
    """Position [m], (3,)."""
    v_W: np.ndarray
    """Velocity [m/s], (3,)."""
    q_WB: np.ndarray
    """Attitude, body to world, [w, x, y, z]."""
    w_B: np.ndarray
    """Body rate [rad/s], (3,)."""
    a_W: np.ndarray | None = None
    """Acceleration [m/s^2], (3,): set on ground truth (the model's true acceleration, which inertial sensors
    read); None where the source does not know it."""
    alpha_B: np.ndarray | None = None
    """Angular acceleration [rad/s^2], (3,): set on ground truth, else None."""
    rotor_speeds: np.ndarray | None = None
    """True rotor speeds [rad/s], (4,) in PX4's numbering: set on ground truth (what shakes an IMU), else None."""
    pose_cov_W: np.ndarray | None = None
    """(6, 6) covariance of the pose an estimator claims: position p_W [m] and attitude error as a rotation vector
    about the world axes [rad] (true q_WB = Exp(dtheta_W) * q_WB), in ROS's ``PoseWithCovariance`` order (x, y, z,
    rotation about x, y, z: fixed axes of the parent frame); None: unknown (the truth, an estimator without one)."""
    twist_cov_B: np.ndarray | None = None
    """(6, 6) covariance of the velocity and body rate in the body frame: v_B = R_WB^T v_W [m/s] then w_B [rad/s],
    ROS's ``TwistWithCovariance`` in the child frame (REP 105); None: unknown."""


@message
class Pose(Message):
    """A measured pose, what motion capture (or a slow odometry) reports: position and attitude only. Motion
    capture measures no velocity and no body rate; an estimator derives them (:class:`Odometry` is the state)."""

    t: float
    """Measurement time [s] (the message arrives the source's latency later)."""
    p_W: np.ndarray
    """Position [m], (3,)."""
    q_WB: np.ndarray
    """Attitude, body to world, [w, x, y, z]."""


@message
class Imu(Message):
    """Specific force and angular rate in the IMU's own frame I (the body frame when the IMU is mounted
    without rotation; its mounting, ``q_BI`` and lever arm ``p_BI``, is the estimator's extrinsic)."""

    t: float
    f_I: np.ndarray
    """Specific force (accelerometer) [m/s^2], (3,)."""
    w_I: np.ndarray
    """Angular rate (gyroscope) [rad/s], (3,)."""


@message
class MagneticField(Message):
    """Magnetometer sample in the body frame (the magnetometer is mounted along the body axes)."""

    t: float
    m_B: np.ndarray
    """Magnetic flux density [T], (3,)."""


@message
class AirPressure(Message):
    """Barometer sample."""

    t: float
    pressure_pa: float
    """Static pressure [Pa]."""
    altitude_m: float
    """Height above the world origin from the pressure, by the standard atmosphere [m]."""
    temperature_k: float
    """Air temperature [K]."""


@message
class GpsFix(Message):
    """One GNSS receiver output (like PX4's ``sensor_gps``)."""

    t: float
    """Measurement time [s] (the message arrives the receiver's latency later)."""
    latitude_deg: float
    longitude_deg: float
    altitude_m: float
    """WGS-84 ellipsoidal height [m]."""
    v_W: np.ndarray
    """Velocity, east-north-up [m/s], (3,)."""
    fix_type: int
    """0: no fix (position and velocity NaN), 3: 3-D fix."""
    satellites: int
    eph: float
    """Horizontal position accuracy (1 sigma) the receiver claims [m]."""
    epv: float
    """Vertical position accuracy (1 sigma) [m]."""


@message
class PointCloud(Message):
    """One LiDAR frame as a driver reports it: the valid returns, one stamp for the frame and a time offset
    per point (what :class:`cufund.sensors.LidarComponent` publishes). No ground truth: the true hit points
    travel separately as :class:`LidarTruth` on ``/truth/point_cloud``."""

    t: float
    """Frame stamp: the start of the frame [s]."""
    dt: np.ndarray
    """(N,) firing time of each point after ``t`` [s] (0 <= dt < frame period)."""
    points_L: np.ndarray
    """(N, 3) float32 points in the LiDAR frame, each at its own firing time (motion-distorted when the sensor
    moves during the frame) [m]."""
    ranges: np.ndarray
    """(N,) measured ranges, noise included [m]."""
    intensity: np.ndarray
    """(N,) reflectivity x |cos(incidence angle)| in [0, 1]."""
    channel: np.ndarray
    """(N,) laser channel (ring) index."""
    frame: int
    """Frame index of the scan pattern."""

    def __len__(self) -> int:
        return len(self.dt)


@message
class LidarTruth(Message):
    """Ground truth of one LiDAR frame, point for point with its :class:`PointCloud` (a ``/truth/`` topic)."""

    t: float
    """The frame's stamp [s]."""
    points_W: np.ndarray
    """(N, 3) float32 noise-free hit points in the world frame [m]."""
    object_ids: np.ndarray
    """(N,) id of the world object each ray hit (geometry id of the scene)."""


@message
class CameraImage(Message):
    """One camera frame. A rig's cameras (``stereo_camera``) publish one each per trigger, with equal stamps; their
    calibration is in the sensor's scenario params, not in the message."""

    t: float
    """Capture time [s]: the centre of the exposure (of the middle row's, under a rolling shutter)."""
    image: np.ndarray
    """(H, W) float32 depth [m] (NaN = no return), (H, W, 3) uint8 RGB or (H, W) uint8 grey."""


class EstimatorDiagnostics(Message):
    """Base of an odometry's per-frame report on ``/estimator/diagnostics`` (:class:`OdometryDiagnostics` a LiDAR
    one's, :class:`VioDiagnostics` a visual-inertial one's). Every kind has ``t`` [s], ``time_ms``, ``cpu_ms``,
    ``skipped`` ('' when the frame added a constraint), ``healthy`` and ``reason``: what failsafes, the ground
    station and the run's metrics read."""

    __slots__ = ()


@message
class OdometryDiagnostics(EstimatorDiagnostics):
    """How an odometry processed one LiDAR frame (published per frame next to the estimate)."""

    variable_length = True
    """``degenerate_directions`` has a row per weak direction: logs store it as JSON, not as a fixed-size record."""

    t: float
    """The frame's estimate stamp [s]."""
    points: int
    """Points used after deskewing, range filtering and downsampling."""
    inliers: int
    """Correspondences kept by the registration."""
    iterations: int
    """Registration iterations."""
    eigenvalues: np.ndarray
    """(6,) normalised eigenvalues of the registration Hessian, ascending (small: weakly observable)."""
    degenerate_directions: np.ndarray
    """(k, 6) weakly observable directions in the world frame, each [rotation (3), translation (3)]."""
    time_ms: float
    """Wall time spent on the frame [ms]."""
    cpu_ms: float
    """Process CPU time spent on the frame (all threads) [ms]."""
    skipped: str
    """Why the frame added no LiDAR constraint ('' when it did)."""
    healthy: bool = True
    """False while the estimate should not be trusted for precise flight (no LiDAR constraint for a while, the
    IMU and the LiDAR disagreeing, re-locking after either): hold position or land."""
    reason: str = ""
    """Why it is not healthy ('' when it is)."""


@message
class VioDiagnostics(EstimatorDiagnostics):
    """How a visual-inertial odometry processed one stereo frame (published per frame next to the estimate, on the
    topic a LiDAR odometry's :class:`OdometryDiagnostics` use: ``t``, ``time_ms``, ``cpu_ms``, ``skipped``,
    ``healthy`` and ``reason`` mean the same in both)."""

    t: float
    """The frame's stamp on the IMU's clock [s]."""
    tracked: int
    """Features carried over from the previous frame (after the temporal RANSAC)."""
    inliers: int
    """Temporal RANSAC inliers."""
    stereo: int
    """Features with a stereo match on the epipolar line."""
    parallax_px: float
    """Mean displacement of the tracked features since the last keyframe [px]."""
    keyframe: bool
    """Whether the frame became a keyframe of the smoother."""
    landmarks: int
    """Landmarks in the smoother's window."""
    time_ms: float
    """Wall time spent on the frame [ms]."""
    cpu_ms: float
    """Process CPU time spent on the frame (all threads) [ms]."""
    time_offset_s: float
    """Online camera-IMU time offset estimate [s] (t_imu = t_cam + offset; 0 until observable)."""
    sigma_p_m: float
    """Position standard deviation of the newest keyframe (largest axis) [m] (NaN when not computed)."""
    skipped: str = ""
    """Why the frame added no visual constraint ('' when it did)."""
    healthy: bool = True
    """False while the estimate should not be trusted for precise flight (no visual constraint for a while,
    re-locking after it, a smoother restart): hold position or land."""
    reason: str = ""
    """Why it is not healthy ('' when it is)."""


@message
class MapUpdate(Message):
    """A map a mapper maintains, announced after each update: planners read the map object itself (it stays
    owned and updated by the mapper; read it only inside a component's step)."""

    t: float
    """Stamp of the newest measurement integrated [s]."""
    map: Any
    """The map (e.g. :class:`cufund.mapping.EsdfMap`)."""
    frames: int
    """Measurements integrated so far."""


@message
class TrajectorySetpoint(Message):
    """A point of a trajectory, PX4's ``trajectory_setpoint``: position mode uses all fields, velocity mode
    ignores ``p_W``."""

    t: float
    p_W: np.ndarray
    """Position [m], (3,)."""
    v_W: np.ndarray
    """Velocity [m/s], (3,)."""
    a_W: np.ndarray
    """Acceleration feed-forward [m/s^2], (3,)."""
    j_W: np.ndarray
    """Jerk feed-forward [m/s^3], (3,); used by the geometric controller for the desired body rate."""
    yaw: float
    """Heading [rad]."""
    yaw_rate: float
    """Heading rate feed-forward [rad/s]."""


@message
class TrajectoryUpdate(Message):
    """A new trajectory from a (re)planner, to be followed from ``trajectory.t_start`` on; a follower keeps
    the trajectory it had before that time (the planner makes the two join)."""

    t: float
    """When the plan was made [s]."""
    trajectory: Any
    """The new :class:`cufund.planning.Trajectory`."""


@message
class AttitudeSetpoint(Message):
    """Attitude and collective thrust, PX4's ``vehicle_attitude_setpoint``."""

    t: float
    q_WB: np.ndarray
    """Desired attitude [w, x, y, z]."""
    thrust: float
    """Collective thrust [N] along body +z."""
    yaw_rate: float = 0.0
    """Yaw-rate feed-forward [rad/s]."""


@message
class RateSetpoint(Message):
    """Body rates and collective thrust, PX4's ``vehicle_rates_setpoint``."""

    t: float
    w_B: np.ndarray
    """Desired body rate [rad/s], (3,)."""
    thrust: float
    """Collective thrust [N]."""


@message
class ThrustTorqueSetpoint(Message):
    """Collective thrust and body torque, the input of control allocation."""

    t: float
    thrust: float
    """[N] along body +z."""
    torque_B: np.ndarray
    """[N m], (3,)."""


@message
class ActuatorCommand(Message):
    """Rotor speed commands, PX4 numbering; the simulator holds the latest one over each physics step."""

    t: float
    rotor_speeds: np.ndarray
    """[rad/s], (4,)."""


@message
class FlightModeCommand(Message):
    """Switches the flight controller's mode."""

    t: float
    mode: FlightMode


@message
class TunnelEstimate(Message):
    """What a tunnel detector knows of the course's frames so far, in the estimated world frame; it improves as
    frames accumulate (paper §3.2, Fig. 9). Frames are ordered along the course (nearest the start first)."""

    variable_length = True
    """Its arrays grow as frames are found: logs store it as JSON, not as a fixed-size record."""

    t: float
    """Stamp of the newest scan used [s]."""
    centres_W: np.ndarray
    """(k, 3) centre of each frame's opening [m]."""
    normals_W: np.ndarray
    """(k, 3) unit normal of each frame's plane, pointing along the course (the direction of flight) [-]."""
    opening_sizes: np.ndarray
    """(k, 2) width (horizontal, in the frame's plane) and height of each opening [m]."""
    confidence: np.ndarray
    """(k,) confidence of each frame in [0, 1] (grows with the points and scans supporting it)."""
    scans: int
    """Scans accumulated so far."""


@message
class VehicleStatus(Message):
    """The vehicle's command state as a commander keeps it: what ground stations, MAVLink and the web GCS show."""

    t: float
    armed: bool
    """Rotors may spin."""
    mode: str
    """Command mode: 'idle', 'takeoff', 'hold', 'goto', 'mission', 'offboard', 'land', 'rtl', 'external'."""
    landed: bool
    """On the ground (PX4's landed state)."""
    flight_mode: FlightMode
    """The controller's reference mode (position, velocity, attitude)."""
    controller: str
    """The active controller kind ('pid' or 'geometric')."""
    mission_current: int
    """Index of the mission item being flown (-1: none)."""
    mission_count: int
    """Items in the uploaded mission."""
    home_p_W: np.ndarray
    """Home (where the vehicle was armed) [m], (3,)."""
    target_p_W: np.ndarray
    """Where the vehicle is going [m], (3,) (the current position when it holds)."""
    message: str
    """The latest event ('' if none): a mode change, a refusal, a warning."""


@message
class MissionState(Message):
    """A mission state machine's state (published on each transition and at its rate)."""

    t: float
    state: str
    """The state's name (e.g. 'initialise', 'takeoff', 'detect', 'fly', 'land', 'done', 'aborted')."""
    reason: str
    """Why it is in this state ('' if nothing to say; the abort reason when aborted)."""
    progress: int
    """Mission items (frames, waypoints) completed."""


@message
class PlannerDiagnostics(Message):
    """One (re)plan of a planner."""

    t: float
    """Simulated time of the replan [s]."""
    planner: str
    """The planner's kind ("local", "global")."""
    status: str
    """"ok", or why the plan was rejected ("collision", a path-search status, ...); "at_goal"."""
    plan_ms: float
    """Wall time of the replan [ms]."""
    plan_cpu_ms: float
    """CPU time of the replan [ms] (the wall time less preemption by other processes)."""
    min_clearance_m: float
    """Smallest certified map clearance of the candidate trajectory [m]."""
    path_length_m: float
    """Length of the accepted trajectory [m] (0 when rejected)."""


@message
class Detections2D(Message):
    """Objects an image detector found in one camera frame (pixel boxes in that frame's image)."""

    variable_length = True
    """Its arrays have a row per detection: logs store it as JSON, not as a fixed-size record."""

    t: float
    """Capture time of the image [s]."""
    boxes_xyxy: np.ndarray
    """(k, 4) float32 boxes (u_min, v_min, u_max, v_max) [px], pixel edges (the image spans [0, W] × [0, H])."""
    scores: np.ndarray
    """(k,) float32 confidence of each box in [0, 1]."""
    class_ids: np.ndarray
    """(k,) int64 class index of each box (into ``class_names``)."""
    class_names: tuple[str, ...]
    """The model's class names, by index."""
    latency_ms: float
    """Wall time from the image's arrival to this message (pre-processing, inference, NMS) [ms]."""


@message
class Detections3D(Message):
    """Detected objects placed in the estimated world frame from a depth image (never from ground truth)."""

    variable_length = True
    """Its arrays have a row per detection: logs store it as JSON, not as a fixed-size record."""

    t: float
    """Capture time of the image [s]."""
    centres_W: np.ndarray
    """(k, 3) centre of each object's visible surface in the world frame [m]."""
    sizes_m: np.ndarray
    """(k, 2) width and height of each box at the object's depth [m]."""
    scores: np.ndarray
    """(k,) float32 confidence of each detection in [0, 1]."""
    class_ids: np.ndarray
    """(k,) int64 class index of each detection (into ``class_names``)."""
    class_names: tuple[str, ...]
    """The model's class names, by index."""


@message
class BatteryStatus(Message):
    """A power module's reading of the flight battery (like PX4's ``battery_status``)."""

    t: float
    voltage_v: float
    """Terminal voltage of the pack [V]."""
    current_a: float
    """Current drawn from the pack [A] (> 0 discharging)."""
    remaining: float
    """State of charge in [0, 1] (1: full)."""
    consumed_mah: float
    """Charge drawn since the start of the run [mAh]."""
    cells: int
    """Cells in series."""


class Topics:
    """The topics of the built-in components, each typed with its message. Ground truth lies under ``/truth/``."""

    TRUTH_ODOMETRY = Topic("/truth/odometry", Odometry)
    """Exact vehicle state with its true accelerations, published by the simulator at every instant at which a
    component runs."""
    GROUND_TRUTH = TRUTH_ODOMETRY
    """Alias of ``TRUTH_ODOMETRY``."""
    TRUTH_POINT_CLOUD = Topic("/truth/point_cloud", LidarTruth)
    """The true hit points of each frame of the LiDAR on ``POINT_CLOUD``."""
    ESTIMATE = Topic("/estimator/odometry", Odometry)
    """The estimator's state at its output rate (IMU rate for the built-in ones): what the attitude and position
    loops, mappers and planners use once an estimator is attached."""
    ESTIMATOR_DIAGNOSTICS = Topic("/estimator/diagnostics", EstimatorDiagnostics)
    """Per-frame diagnostics of a LiDAR odometry."""
    TRAJECTORY_SETPOINT = Topic("/setpoint/trajectory", TrajectorySetpoint)
    TRAJECTORY_UPDATE = Topic("/planner/trajectory", TrajectoryUpdate)
    """Trajectory updates of a replanner, stitched by :class:`cufund.planning.TrajectoryFollower`."""
    ATTITUDE_SETPOINT = Topic("/setpoint/attitude", AttitudeSetpoint)
    """Attitude and thrust from the position controller (or the user in attitude mode)."""
    MANUAL_ATTITUDE_SETPOINT = Topic("/setpoint/attitude_manual", AttitudeSetpoint)
    """Attitude and thrust commanded by a user or planner in attitude mode."""
    RATE_SETPOINT = Topic("/setpoint/rates", RateSetpoint)
    THRUST_TORQUE_SETPOINT = Topic("/setpoint/thrust_torque", ThrustTorqueSetpoint)
    ACTUATOR_COMMAND = Topic("/actuator/command", ActuatorCommand)
    FLIGHT_MODE = Topic("/commander/flight_mode", FlightModeCommand)
    IMU = Topic("/sensors/imu", Imu)
    MAGNETOMETER = Topic("/sensors/magnetometer", MagneticField)
    BAROMETER = Topic("/sensors/barometer", AirPressure)
    GPS = Topic("/sensors/gps", GpsFix)
    POINT_CLOUD = Topic("/sensors/lidar", PointCloud)
    POSE = Topic("/sensors/pose", Pose)
    """A pose source (motion capture, or a slow odometry): position and attitude, no velocity."""
    DEPTH_IMAGE = Topic("/sensors/depth_image", CameraImage)
    RGB_IMAGE = Topic("/sensors/rgb_image", CameraImage)
    ESDF_MAP = Topic("/map/esdf", MapUpdate)
    TUNNEL_ESTIMATE = Topic("/perception/tunnel", TunnelEstimate)
    VEHICLE_STATUS = Topic("/vehicle/status", VehicleStatus)
    MISSION_STATE = Topic("/mission/state", MissionState)
    PLANNER_DIAGNOSTICS = Topic("/planner/diagnostics", PlannerDiagnostics)
    """Per-replan diagnostics of a planner, next to its trajectory updates."""
    DETECTIONS_2D = Topic("/perception/detections_2d", Detections2D)
    """An image detector's boxes (:class:`cufund.perception.OnnxDetector`)."""
    DETECTIONS_3D = Topic("/perception/detections_3d", Detections3D)
    """An image detector's objects in the estimated world frame, from a depth image."""
    BATTERY = Topic("/battery", BatteryStatus)
    """The power module's :class:`BatteryStatus` (only when the scenario's ``vehicle.battery`` is set)."""
