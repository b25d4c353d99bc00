"""Depth and image cameras, single or in a rig (stereo pair, multi-camera), as simulator components."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from cufund.core.components import BusView, Component
from cufund.core.messages import CameraImage, Odometry, Topics
from cufund.core.topics import Topic
from cufund.worlds.world import World

from .camera import DepthCamera, RgbCamera

DEPTH_TOPIC = Topics.DEPTH_IMAGE
RGB_TOPIC = Topics.RGB_IMAGE


class CameraComponent(Component):
    """Renders ``camera`` (a DepthCamera or RgbCamera) of ``world`` from the true pose at ``rate_hz`` (any rate,
    e.g. 30 Hz) and publishes a :class:`~cufund.core.messages.CameraImage` on ``topic`` (default: /sensors/depth_image
    or /sensors/rgb_image), visible ``latency_s`` later. The frame's stamp is the tick's time, the centre of its
    exposure: an RgbCamera with an exposure time or a rolling shutter is moved over them along the true velocity
    and body rates at the tick."""

    name = "camera"
    reads_truth = True

    def __init__(
        self,
        camera: DepthCamera | RgbCamera,
        world: World,
        topic: str | None = None,
        rate_hz: float = 30.0,
        latency_s: float = 0.0,
    ) -> None:
        if not isinstance(camera, (DepthCamera, RgbCamera)):
            raise ValueError(f"camera must be a DepthCamera or RgbCamera, got {type(camera).__name__}")
        if not isinstance(world, World):
            raise ValueError(f"world must be a cufund.World, got {type(world).__name__}")
        self.camera, self.world, self.rate_hz, self.latency_s = camera, world, float(rate_hz), float(latency_s)
        topic = topic or (DEPTH_TOPIC if isinstance(camera, DepthCamera) else RGB_TOPIC)
        self.topic = topic if isinstance(topic, Topic) else Topic(topic, CameraImage)
        self.inputs = (Topics.TRUTH_ODOMETRY,)
        self.outputs = (self.topic,)

    def reset(self) -> None:
        self.camera.reset()

    def step(self, t: float, bus: BusView) -> None:
        truth: Odometry = bus.latest(Topics.TRUTH_ODOMETRY)
        bus.publish(self.topic, CameraImage(t, _render(self.camera, self.world, truth)))


def _render(camera: DepthCamera | RgbCamera, world: World, truth: Odometry) -> np.ndarray:
    if isinstance(camera, RgbCamera) and (camera.exposure_s > 0 or camera.line_time_s > 0):
        image = camera.render(world, truth.p_W, truth.q_WB, v_W=truth.v_W, w_B=truth.w_B)
    else:
        image = camera.render(world, truth.p_W, truth.q_WB)
    assert isinstance(image, np.ndarray)  # without want_ids
    return image


class CameraRigComponent(Component):
    """A rig of cameras triggered together (a stereo pair, a multi-camera head): at each tick every camera renders
    ``world`` from the true pose and publishes a CameraImage on its own topic, all with the same stamp
    ``t - timeshift_s`` (the tick's time in the rig's clock: Kalibr's t_imu = t_cam + timeshift)."""

    name = "camera_rig"
    reads_truth = True

    def __init__(
        self,
        cameras: Sequence[DepthCamera | RgbCamera],
        world: World,
        topics: Sequence[str | Topic],
        rate_hz: float = 20.0,
        latency_s: float = 0.0,
        phase_s: float = 0.0,
        timeshift_s: float = 0.0,
    ) -> None:
        cams = list(cameras)
        if not cams or not all(isinstance(c, (DepthCamera, RgbCamera)) for c in cams):
            raise ValueError("cameras must be a non-empty list of DepthCamera or RgbCamera")
        if len(topics) != len(cams):
            raise ValueError(f"need one topic per camera: {len(cams)} cameras, {len(topics)} topics")
        if not isinstance(world, World):
            raise ValueError(f"world must be a cufund.World, got {type(world).__name__}")
        self.cameras, self.world = cams, world
        self.rate_hz, self.latency_s, self.phase_s = float(rate_hz), float(latency_s), float(phase_s)
        self.timeshift_s = float(timeshift_s)
        self.topics = tuple(t if isinstance(t, Topic) else Topic(t, CameraImage) for t in topics)
        if len({str(t) for t in self.topics}) != len(self.topics):
            raise ValueError(f"the rig's topics must differ, got {[str(t) for t in self.topics]}")
        self.inputs = (Topics.TRUTH_ODOMETRY,)
        self.outputs = self.topics

    def reset(self) -> None:
        for cam in self.cameras:
            cam.reset()

    def step(self, t: float, bus: BusView) -> None:
        truth: Odometry = bus.latest(Topics.TRUTH_ODOMETRY)
        stamp = t - self.timeshift_s
        for cam, topic in zip(self.cameras, self.topics, strict=True):
            bus.publish(topic, CameraImage(stamp, _render(cam, self.world, truth)))
