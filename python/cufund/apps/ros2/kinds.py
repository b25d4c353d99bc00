"""The ``ros2`` bridge kind (the scenario key ``ros2: {...}``), registered through the ``cufund.kinds`` entry points
so that scenarios name it without the layers below importing :mod:`cufund.apps`. Cyclone DDS is imported only when
a scenario asks for the bridge (``pip install 'cufund[ros2]'``)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.core.registry import Kind

from .config import Ros2Params
from .external import ExternalParams

__all__ = ["KINDS", "build_bridge", "default_topics"]

IMU_RATE_FALLBACK_HZ = 100.0


def default_topics(ctx: BuildContext) -> dict[str, tuple[str, str]]:
    """cufund topic -> (ROS 2 name, what it is: imu, lidar, camera, truth, estimate) by default: ``/imu`` and
    ``/livox/lidar`` for the only IMU and LiDAR (``/imu/<name>``, ``/<name>/lidar`` for several),
    ``/camera/<name>/image_raw``, ``/truth/odom``, ``/estimator/odom``."""
    sensors = ctx.config.sensors
    out: dict[str, tuple[str, str]] = {}
    by_type: dict[str, list[str]] = {}
    for name, spec in sensors.items():
        by_type.setdefault(spec.sensor_type or "", []).append(name)
    for name, spec in sensors.items():
        st = spec.sensor_type
        single = len(by_type.get(st or "", [])) == 1
        if st == "imu":
            out[str(spec.topic)] = ("/imu" if single else f"/imu/{name}", "imu")
        elif st == "lidar":
            out[str(spec.topic)] = ("/livox/lidar" if single else f"/{name}/lidar", "lidar")
        elif st == "camera":
            out[str(spec.topic)] = (f"/camera/{name}/image_raw", "camera")
        elif st == "stereo_camera":
            out[str(spec.topic)] = ("/stereo" if single else f"/stereo/{name}", "stereo")
    out[str(Topics.TRUTH_ODOMETRY)] = ("/truth/odom", "truth")
    if ctx.config.estimator is not None:
        out[str(Topics.ESTIMATE)] = ("/estimator/odom", "estimate")
    return out


def topic_types(ctx: BuildContext) -> dict[str, type]:
    """The message class of each cufund topic a scenario may carry: cufund's standard topics and its sensors'."""
    from cufund.core.topics import Topic

    known: dict[str, type] = {str(t): t.type for t in vars(Topics).values() if isinstance(t, Topic)}
    for spec in ctx.config.sensors.values():
        if spec.topic is not None:
            known[str(spec.topic)] = spec.topic.type
    return known


def _intrinsics(spec: Any) -> Any:
    """The pinhole intrinsics of a camera sensor spec (its params', or the D435's of the d435 kinds), or None."""
    intr = getattr(spec.params, "intrinsics", None)
    if intr is None and spec.kind in ("d435_depth", "d435_rgb"):
        from cufund.sensors.camera import d435_depth, d435_rgb

        intr = d435_depth() if spec.kind == "d435_depth" else d435_rgb()
    return intr


def _one(encoder: Callable[[Any], bytes]) -> Callable[[Any], list[bytes]]:
    return lambda m: [encoder(m)]


OPTICAL_SUFFIX = "_optical_frame"
"""A camera's optical frame (x right, y down, z forward; its images' ``frame_id``) is its frame's name with this."""


def _stereo_outs(base: str, ctx: BuildContext, spec: Any, static_tf: list[tuple[str, str, Any, Any]]) -> list[Any]:
    """A ``stereo_camera`` rig as ROS 2 stereo drivers publish it: ``<base>/left/image_raw`` and
    ``<base>/left/camera_info``, ``<base>/right/...`` (``<base>`` the rig's ROS 2 name, ``/stereo`` by default; a
    rig of other than two cameras: ``<base>/cam<i>/...`` with unrectified camera_info), the images in each camera's
    optical frame (``cam0_optical_frame``, a child of ``cam0`` in ``static_tf``), camera_info from the rig's
    calibration (:func:`cufund.apps.ros2.encode.stereo_camera_infos`)."""
    from cufund.geometry import quat_from_matrix
    from cufund.logs.codecs import sensor_frame
    from cufund.sensors.camera_models import R_CO

    from . import bridge, encode
    from .dds import QOS

    rig = spec.params.cameras(getattr(ctx.config, "base_dir", None))
    cam_topics = spec.params.camera_topics(len(rig))
    if len(rig) == 2:
        try:
            infos: list[Any] = list(encode.stereo_camera_infos(*rig))
        except ValueError as e:
            raise ConfigError(f"ros2: the {spec.kind} rig {spec.topic}: {e}") from None
        sides = ["left", "right"]
    else:
        infos = [encode.unrectified_camera_info(c.intrinsics) for c in rig]
        sides = [f"cam{i}" for i in range(len(rig))]
    q_CO = tuple(float(x) for x in quat_from_matrix(R_CO))
    outs = []
    for topic, side, info in zip(cam_topics, sides, infos, strict=True):
        frame = sensor_frame(topic)
        optical = frame + OPTICAL_SUFFIX
        static_tf.append((frame, optical, (0.0, 0.0, 0.0), q_CO))
        image = encode.image_encoder(optical)

        def both(m: Any, image: Any = image, optical: str = optical, info: Any = info) -> list[bytes]:
            return [image(m), encode.camera_info_of(m.t, optical, info)]

        writes = [
            (f"{base}/{side}/image_raw", "sensor_msgs/msg/Image", QOS["sensor_data"]),
            (f"{base}/{side}/camera_info", "sensor_msgs/msg/CameraInfo", QOS["sensor_data"]),
        ]
        outs.append(bridge.Out(topic, writes, both))
    return outs


def build_bridge(p: Ros2Params, ctx: BuildContext) -> list[Any]:
    try:
        from . import bridge, encode
        from .dds import QOS
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise ConfigError(f"ros2 needs Cyclone DDS's Python binding: pip install 'cufund[ros2]' ({e})") from None
    from cufund.logs.codecs import sensor_frame
    from cufund.logs.run_context import static_transforms
    from cufund.scenarios.sensor_frames import sensor_frames

    def spec_of(topic: str) -> Any:
        return next(s for s in ctx.config.sensors.values() if str(s.topic) == topic)

    topics = default_topics(ctx)
    types = topic_types(ctx)
    extra: list[tuple[str, str, str, Callable[[Any], bytes]]] = []  # any other cufund topic mapped by the scenario
    for topic, ros_name in p.topics.items():
        if topic in topics or not ros_name:
            continue
        cls = types.get(topic)
        found = encode.encoder_for(cls, sensor_frame(topic)) if cls is not None else None
        if found is None:
            why = (
                f"no standard ROS 2 message for {cls.__name__}"
                if cls is not None
                else f"not a topic of this scenario (its topics: {', '.join(sorted(types))})"
            )
            raise ConfigError(f"ros2.topics: {topic} cannot be published: {why}")
        extra.append((topic, ros_name, found[0], found[1]))
    estimator = ctx.config.estimator is not None
    body = "base_link"
    outs: list[bridge.Out] = []
    # /tf_static as the run's log has it (one source): world -> odom, base_link_truth -> base_link without an
    # estimator, base_link -> each sensor's frame at its stated mounting (each camera of a rig its own)
    static_tf = static_transforms(sensor_frames(ctx.config), estimator)
    imu_rates = []
    for topic, (ros_name, what) in topics.items():
        ros_name = p.topics.get(topic, ros_name)
        if not ros_name:
            continue
        if what in ("imu", "lidar", "camera"):
            name, spec = next((n, s) for n, s in ctx.config.sensors.items() if str(s.topic) == topic)
            frame = sensor_frame(topic)
            if what == "imu":
                rate = getattr(spec.params, "rate_hz", None)
                if rate:
                    imu_rates.append(float(rate))
                enc = encode.imu_encoder(frame)
                outs.append(bridge.Out(topic, [(ros_name, "sensor_msgs/msg/Imu", QOS["sensor_data"])], _one(enc)))
            elif what == "lidar":
                enc = encode.point_cloud_encoder(frame)
                outs.append(bridge.Out(topic, [(ros_name, "sensor_msgs/msg/PointCloud2", QOS["default"])], _one(enc)))
            else:
                enc = encode.image_encoder(frame)
                info_name = ros_name.rsplit("/", 1)[0] + "/camera_info"
                intr = _intrinsics(spec)
                writes = [(ros_name, "sensor_msgs/msg/Image", QOS["sensor_data"])]
                if intr is None:  # a camera kind whose intrinsics the bridge does not know: the image only
                    outs.append(bridge.Out(topic, writes, _one(enc)))
                    continue

                def cam(m: Any, e: Any = enc, frame: str = frame, k: Any = intr) -> list[bytes]:
                    return [e(m), encode.camera_info(m.t, frame, k.width, k.height, k.fx, k.fy, k.cx, k.cy)]

                writes.append((info_name, "sensor_msgs/msg/CameraInfo", QOS["sensor_data"]))
                outs.append(bridge.Out(topic, writes, cam))
        elif what == "stereo":
            outs += _stereo_outs(ros_name, ctx, spec_of(topic), static_tf)
        else:
            parent, child = ("world", "base_link_truth") if what == "truth" else ("odom", body)
            odo = encode.odometry_encoder(parent, child)

            def odometry(m: Any, odo: Any = odo, parent: str = parent, child: str = child) -> list[bytes]:
                return [odo(m), encode.tf(m.t, [(parent, child, m.p_W, m.q_WB)])]

            outs.append(
                bridge.Out(
                    topic,
                    [(ros_name, "nav_msgs/msg/Odometry", QOS["default"]), ("/tf", "tf2_msgs/msg/TFMessage", QOS["tf"])],
                    odometry,
                    latest_only=what == "truth",
                )
            )
    for topic, ros_name, rtype, encoder in extra:
        outs.append(bridge.Out(topic, [(ros_name, rtype, QOS["default"])], _one(encoder)))
    rate = p.rate_hz or (max(imu_rates) if imu_rates else IMU_RATE_FALLBACK_HZ)
    return [bridge.Ros2Bridge(p, outs, static_tf, ctx.commander, rate)]


KINDS: list[Kind] = [
    Kind(
        "bridge",
        "ros2",
        Ros2Params,
        build_bridge,
        doc="the ROS 2 bridge over DDS (scenario key ros2: {...}; docs/guides/ros2.md)",
    )
]


def build_external(p: ExternalParams, ctx: BuildContext) -> list[Any]:
    """A ROS 2 node as the part being built (``ros2_external``): what it reads and writes, by message type."""
    from cufund.logs.codecs import sensor_frame

    from . import external
    from .encode import encoder_for

    known = topic_types(ctx)
    where = ctx.where
    if not p.node:
        raise ConfigError(f"{where}.node must name the node (the frame_id of its answers on /cufund/step_ack)")
    if not p.writes:
        raise ConfigError(f"{where}.writes must name at least one topic the node publishes")
    reads, writes = [], []
    for topic, ros_name in p.reads.items():
        cls = known.get(topic)
        enc = encoder_for(cls, sensor_frame(topic)) if cls is not None else None
        if enc is None:
            raise ConfigError(f"{where}.reads: {topic} ({getattr(cls, '__name__', 'unknown type')}) cannot be sent")
        reads.append((topic, ros_name, enc[0], enc[1]))
    estimate = None
    for topic, ros_name in p.writes.items():
        cls = known.get(topic)
        dec = external.decoder_for(cls) if cls is not None else None
        if dec is None:
            raise ConfigError(
                f"{where}.writes: {topic} ({getattr(cls, '__name__', 'unknown type')}) cannot be received; a node "
                "writes Odometry (nav_msgs/msg/Odometry) or TrajectorySetpoint (quadrotor_msgs/msg/PositionCommand)"
            )
        writes.append((topic, ros_name, dec[0], dec[1]))
        if cls is not None and cls.__name__ == "Odometry":
            estimate = topic
    name = f"{where}:{p.node}"
    if where == "estimator":
        if estimate is None:
            raise ConfigError(f"{where}: a ros2_external estimator writes an Odometry topic")
        c = external.ExternalEstimator(p, reads, writes, name)
        c.topic = estimate
        return [c]
    return [external.ExternalComponent(p, reads, writes, name)]


KINDS += [
    Kind(group, "ros2_external", ExternalParams, build_external, doc="a ROS 2 node over DDS (docs/guides/ros2.md)")
    for group in ("estimator", "mapper", "planner", "controller")
]
