"""The ``tunnel`` mission kind: the detector, the state machine and the trajectory follower, the run's end
condition, its metrics (:mod:`.tunnel_metrics`) and its run-folder files (:mod:`.tunnel_plots`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.core.registry import Kind, register
from cufund.planning.trajectory_follower import TrajectoryFollower

from .tunnel import TunnelMission, TunnelMissionParams

__all__ = ["course_of"]


def course_of(config: Any) -> Any:
    """The true :class:`~cufund.missions.tunnel_course.TunnelCourse` of a scenario on the ``tunnel_course`` world (for metrics,
    plots and the pre-flight check only; never a flight input), or None for another world."""
    from .tunnel_course import paper_tunnel_course, tunnel_course_layout

    spec = config.world
    if spec is None or spec.kind != "tunnel_course":
        return None
    p = spec.params
    return paper_tunnel_course(p) if p.seed is None else tunnel_course_layout(p.seed, p)


def _detector(ctx: BuildContext, p: TunnelMissionParams, start: np.ndarray) -> Any:
    """Engineer D's detector on the scenario's LiDAR, in the estimated frame, keeping at most the expected frames
    and ordering them from the pad."""
    from cufund.perception import TunnelDetector, TunnelDetectorParams

    if ctx.config.perception is not None and ctx.config.perception.kind == "camera":
        return None  # the perception part publishes the frames from the cameras (perception/camera_tunnel*.py)
    _, lidar = ctx.sensor_of_type("lidar", "", "mission")
    return TunnelDetector(
        TunnelDetectorParams(), T_BL=lidar.extrinsic, cloud_topic=lidar.topic, expected=p.frames, origin_W=start
    )


def _tunnel(p: TunnelMissionParams, ctx: BuildContext) -> list[Any]:
    from .tunnel_metrics import tunnel_metrics
    from .tunnel_plots import write_tunnel_outputs

    cfg = ctx.config
    if cfg.estimator is None:
        raise ConfigError("mission (tunnel) flies on an estimate: set estimator (e.g. estimator: {kind: lio})")
    if p.health_wait_s != TunnelMissionParams.health_wait_s:
        raise ConfigError(
            "mission.health_wait_s: the failsafe supervisor lands after an unhealthy estimate now; set "
            "failsafe.COM_POS_FS_DELAY (hold after) and failsafe.COM_FAIL_ACT_T (land after the hold) instead"
        )
    course = course_of(cfg)
    if course is not None:  # pre-flight: the rules' openings must pass the vehicle with the plan's clearance
        for k, f in enumerate(course.frames):
            if min(f.width, f.height) < 2 * p.clearance:
                raise ConfigError(
                    f"world: opening {k + 1} ({f.width:g} x {f.height:g} m) is unflyable: the mission "
                    f"needs {2 * p.clearance:.2f} m (2 x mission.clearance)"
                )
    start = np.array(cfg.start_p_W if cfg.start_p_W is not None else (0.0, 0.0, 0.0), dtype=float)
    commander = getattr(ctx, "commander", None)
    if commander is not None and hasattr(commander, "attach_mission"):
        # with a commander (planner: commander, e.g. the ground station's): it flies the mission's reference once the
        # operator starts it, and arm / take off / hold / land / return before and after; no follower, no end
        mission = TunnelMission(p, start, yaw=0.0, wait_for_start=True)
        commander.attach_mission(mission)
        ctx.add_metric_hook(lambda result: tunnel_metrics(result, mission, course) if mission.t_end is not None else {})
        detector = _detector(ctx, p, start)
        return [c for c in (detector, mission) if c is not None]
    mission = TunnelMission(p, start, yaw=0.0)
    follower = TrajectoryFollower(
        mission.initial, rate_hz=cfg.rates.trajectory_hz, block=32, update_topic=Topics.TRAJECTORY_UPDATE
    )

    def done(t: float, truth: Any) -> bool:  # run end (a harness check): the mission ended and the vehicle rests
        return (
            mission.finished
            and mission.t_end is not None
            and t >= mission.t_end + 0.5
            and truth.p_W[2] < start[2] + 0.03
            and float(np.linalg.norm(truth.v_W)) < 0.05
        )

    ctx.set_done_condition(done)
    ctx.add_metric_hook(lambda result: tunnel_metrics(result, mission, course))
    detector = _detector(ctx, p, start)
    ctx.add_output_hook(lambda run, out, **kw: write_tunnel_outputs(run, out, mission, course, detector, **kw))
    return [c for c in (detector, mission, follower) if c is not None]


register(
    Kind(
        "mission",
        "tunnel",
        TunnelMissionParams,
        _tunnel,
        None,
        "initialise, take off, detect the tunnel's frames, fly through them on the LIO estimate, land beyond",
    )
)
