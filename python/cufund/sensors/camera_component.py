"""Depth and RGB cameras as simulator components."""

from __future__ import annotations

from ..components import Bus, Component
from ..messages import Odometry, Topics
from ..worlds.world import World
from .camera import CameraImage, DepthCamera, RgbCamera

DEPTH_TOPIC = "/sensors/depth_image"
RGB_TOPIC = "/sensors/rgb_image"


class CameraComponent(Component):
    """Renders ``camera`` (a DepthCamera or RgbCamera) of ``world`` from the ground-truth pose at ``rate_hz``
    and publishes a :class:`cufund.sensors.CameraImage` on ``topic`` (default: /sensors/depth_image or
    /sensors/rgb_image). The shutter is global: the whole image is taken at the tick's pose."""

    name = "camera"

    def __init__(self, camera: DepthCamera | RgbCamera, world: World, topic: str | None = None,
                 rate_hz: float = 30.0) -> None:
        if not isinstance(camera, (DepthCamera, RgbCamera)):
            raise ValueError(f"camera must be a DepthCamera or RgbCamera, got {type(camera).__name__}")
        if not isinstance(world, World):
            raise ValueError(f"world must be a cufund.World, got {type(world).__name__}")
        self.camera, self.world, self.rate_hz = camera, world, float(rate_hz)
        self.topic = topic or (DEPTH_TOPIC if isinstance(camera, DepthCamera) else RGB_TOPIC)

    def reset(self) -> None:
        if isinstance(self.camera, DepthCamera):
            self.camera.reset()

    def step(self, t: float, bus: Bus) -> None:
        truth: Odometry = bus.get(Topics.GROUND_TRUTH)
        image = self.camera.render(self.world, truth.p_W, truth.q_WB)
        bus.publish(self.topic, CameraImage(t, image, truth.p_W.copy(), truth.q_WB.copy()))
