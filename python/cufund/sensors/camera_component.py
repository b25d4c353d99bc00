"""Depth and RGB cameras as simulator components."""

from __future__ import annotations

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
    or /sensors/rgb_image), visible ``latency_s`` later. The shutter is global: the whole image is taken at the
    tick's pose."""

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
        if isinstance(self.camera, DepthCamera):
            self.camera.reset()

    def step(self, t: float, bus: BusView) -> None:
        truth: Odometry = bus.latest(Topics.TRUTH_ODOMETRY)
        bus.publish(self.topic, CameraImage(t, self.camera.render(self.world, truth.p_W, truth.q_WB)))
