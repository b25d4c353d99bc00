"""`cufund replay RUN.mcap`: re-opens a run's log in the MeshCat viewer (served on 127.0.0.1).

Shows the scenario's world (rebuilt from the run folder's ``config.yaml``, drawn as ``replay.html`` draws it:
:func:`cufund.viz.world_scene.draw_world`), the vehicle at its true pose (``/truth/odometry``) with its flown path
(red), the estimate (``/estimator/odometry``, a translucent blue box and path) when the log has one, the
setpoints' path (``/setpoint/trajectory``, green), the camera framed on the flight, and each LiDAR frame
(``/sensors/lidar``) in the world
frame: its points, in the LiDAR frame, moved by the LiDAR's mounting ``T_BL`` and the body pose at the frame's
stamp (the estimate when there is one — what a mapper would use — else the truth; per-point motion within a
frame is not undone). The vehicle's shape and ``T_BL`` come from the run folder's ``config.yaml`` beside the
log when there is one, else from ``--vehicle`` and the identity.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cufund.geometry import quat_to_matrix
from cufund.logs import McapReadError, log_metadata, log_topics, read_mcap
from cufund.vehicle.params import QuadrotorParams
from cufund.viz.meshcat_scene import (
    ESTIMATE_COLOR,
    ESTIMATE_VEHICLE,
    ESTIMATED,
    FLOWN,
    PLANNED,
    PLANNED_COLOR,
    TRUTH_COLOR,
    VEHICLE,
    apply_view,
    draw_estimate_marker,
    draw_path,
    draw_vehicle,
    frame_view,
    import_meshcat,
    pose_matrix,
    vehicle_scale,
)
from cufund.viz.world_scene import draw_world

__all__ = ["ReplayStats", "add_arguments", "replay_log", "run"]

TRUTH, ESTIMATE, LIDAR = "/truth/odometry", "/estimator/odometry", "/sensors/lidar"
SETPOINTS = "/setpoint/trajectory"
CLOUD = "lidar"
"""The MeshCat path of the current LiDAR frame."""


@dataclass(frozen=True)
class ReplayStats:
    """What a replay drew."""

    frames: int
    """Viewer frames (vehicle poses) sent."""
    clouds: int
    """LiDAR frames drawn."""
    duration_s: float
    """Log time covered [s]."""
    legend: tuple[tuple[str, int], ...] = ()
    """What the scene shows: (text, 0xRRGGBB)."""


def replay_log(
    path: str | Path,
    vis: Any,
    params: QuadrotorParams,
    *,
    speed: float = 1.0,
    rate_hz: float = 25.0,
    T_BL: tuple[np.ndarray, np.ndarray] | None = None,
    sleep: Callable[[float], None] = time.sleep,
    clock: Callable[[], float] = time.perf_counter,
    world: Any = None,
) -> ReplayStats:
    """Plays the log at ``path`` into the MeshCat visualizer ``vis`` at ``rate_hz`` viewer frames per second of
    log time, ``speed`` times real time (0: as fast as possible; ``sleep`` and ``clock`` pace it). ``T_BL``: the
    LiDAR's mounting (p_BL, q_BL [w, x, y, z]); identity when None. ``world``: the scenario's world, drawn
    under the flight (None: MeshCat's grid only)."""
    if not (np.isfinite(speed) and speed >= 0):
        raise ValueError(f"speed must be a finite number >= 0 (0: as fast as possible), got {speed!r}")
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be a positive number, got {rate_hz!r}")
    available = log_topics(path)
    topics = [t for t in (TRUTH, ESTIMATE, LIDAR) if t in available]
    if TRUTH not in topics and ESTIMATE not in topics:
        raise ValueError(f"{str(path)!r} has neither {TRUTH} nor {ESTIMATE}; it has {sorted(available)}")
    p_BL, R_BL = (
        (np.zeros(3), np.eye(3))
        if T_BL is None
        else (np.asarray(T_BL[0], float), quat_to_matrix(np.asarray(T_BL[1], float)))
    )
    meshcat = import_meshcat()
    g = meshcat.geometry
    # a first pass over the poses and setpoints (not the clouds) frames the camera on the whole flight
    seen = [t for t in (TRUTH, ESTIMATE, SETPOINTS) if t in available]
    track: dict[str, list[np.ndarray]] = {t: [] for t in seen}
    for record in read_mcap(path, topics=seen):
        p_W = getattr(record.message, "p_W", None)
        if p_W is not None:
            track[record.topic].append(np.asarray(p_W, dtype=float))
    framing = [np.array(track[t]).reshape(-1, 3) for t in (TRUTH, SETPOINTS) if t in track]
    framing = [f for f in framing if len(f)] or [np.array(track.get(ESTIMATE, [])).reshape(-1, 3)]
    view = frame_view(np.vstack(framing))
    vis.delete()
    apply_view(vis, view)
    legend: list[tuple[str, int]] = [("flown (truth)", TRUTH_COLOR)] if TRUTH in topics else []
    if world is not None:
        legend += draw_world(vis, world)
    scale = vehicle_scale(params, view)
    draw_vehicle(vis, params, scale)
    if ESTIMATE in topics:
        draw_estimate_marker(vis, params, scale)
        legend.append(("estimate", ESTIMATE_COLOR))
    if len(track.get(SETPOINTS, [])) >= 2:
        points = np.array(track[SETPOINTS])
        draw_path(vis, PLANNED, points[:: max(1, len(points) // 3000)], PLANNED_COLOR)
        legend.append(("setpoints", PLANNED_COLOR))
    if LIDAR in topics:
        legend.append(("LiDAR frame (grey: intensity)", 0x808080))

    period_ns = int(round(1e9 / rate_hz))
    latest: dict[str, Any] = {}
    paths: dict[str, list[np.ndarray]] = {TRUTH: [], ESTIMATE: []}
    frames = clouds = 0
    next_frame: int | None = None
    first_ns = last_ns = 0
    wall0 = clock()

    def draw_frame(now_ns: int) -> None:
        nonlocal frames
        for topic, node, path_node, color in (
            (TRUTH, VEHICLE, FLOWN, TRUTH_COLOR),
            (ESTIMATE, ESTIMATE_VEHICLE, ESTIMATED, ESTIMATE_COLOR),
        ):
            odometry = latest.get(topic)
            if odometry is None:
                continue
            vis[node].set_transform(pose_matrix(odometry.p_W, odometry.q_WB))
            paths[topic].append(np.asarray(odometry.p_W, dtype=float))
            if len(paths[topic]) >= 2 and frames % 5 == 4:
                draw_path(vis, path_node, np.array(paths[topic]), color)
        frames += 1
        if speed > 0:
            ahead = (now_ns - first_ns) / 1e9 / speed - (clock() - wall0)
            if ahead > 0:
                sleep(ahead)

    for record in read_mcap(path, topics=topics):
        if next_frame is None:
            first_ns = next_frame = record.log_time_ns
        while record.log_time_ns >= next_frame + period_ns and latest:
            draw_frame(next_frame)
            next_frame += period_ns
        last_ns = record.log_time_ns
        if record.topic == LIDAR:
            body = latest.get(ESTIMATE) or latest.get(TRUTH)
            if body is not None and len(record.message.points_L):
                R_WB = quat_to_matrix(np.asarray(body.q_WB, dtype=float))
                points_B = record.message.points_L.astype(np.float64) @ R_BL.T + p_BL
                points_W = points_B @ R_WB.T + body.p_W
                shade = np.clip(0.3 + 0.7 * np.asarray(record.message.intensity, dtype=np.float64), 0.0, 1.0)
                colors = np.repeat(shade[None, :], 3, axis=0).astype(np.float32)
                vis[CLOUD].set_object(g.PointCloud(points_W.T.astype(np.float32), colors, size=0.03))
                clouds += 1
        else:
            latest[record.topic] = record.message
    if latest and next_frame is not None:
        draw_frame(last_ns)
        for topic, path_node, color in ((TRUTH, FLOWN, TRUTH_COLOR), (ESTIMATE, ESTIMATED, ESTIMATE_COLOR)):
            if len(paths[topic]) >= 2:
                draw_path(vis, path_node, np.array(paths[topic]), color)
    return ReplayStats(frames, clouds, (last_ns - first_ns) / 1e9, tuple(legend))


def _speed(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--speed must be a number, got {text!r}") from None
    if not (np.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"--speed must be >= 0 (0: as fast as possible), got {text!r}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The ``cufund replay`` arguments."""
    parser.add_argument("log", help="a run.mcap written by `cufund run`")
    parser.add_argument("--speed", type=_speed, default=1.0, help="times real time; 0: as fast as possible")
    parser.add_argument("--rate", type=float, default=25.0, help="viewer frames per second of log time")
    parser.add_argument(
        "--vehicle", default=None, help="vehicle preset to draw (default: the run folder's config.yaml, else cu_astro)"
    )
    parser.add_argument("--no-wait", action="store_true", help="do not keep the viewer up after the replay")


def run_context(path: Path, vehicle: str | None) -> tuple[QuadrotorParams, tuple[np.ndarray, np.ndarray] | None]:
    """The vehicle to draw and the LiDAR's mounting, from the run folder's ``config.yaml`` when it loads."""
    from cufund.vehicle import presets

    T_BL = None
    params = None
    config_path = path.parent / "config.yaml"
    if config_path.is_file():
        try:
            from cufund.scenarios.schema import load_scenario

            config = load_scenario(config_path)
            params = config.vehicle_params()
            for spec in (getattr(config, "sensors", None) or {}).values():
                if str(getattr(spec, "topic", "")) == LIDAR and getattr(spec, "extrinsic", None) is not None:
                    T_BL = (np.array(spec.extrinsic.t), np.array(spec.extrinsic.q))
        except Exception as exc:
            print(f"cufund replay: not using {config_path} ({exc})", file=sys.stderr)
    if vehicle is not None:
        factory = getattr(presets, vehicle, None)
        if factory is None or not callable(factory) or vehicle.startswith("_"):
            raise ValueError(f"unknown vehicle preset {vehicle!r}; try crazyflie, cu_astro or iris")
        params = factory()
    return params or presets.cu_astro(), T_BL


def run_world(path: Path) -> Any:
    """The scenario's world, built again from the run folder's ``config.yaml`` beside the log (None: no such
    file, no world, or it does not build; the replay then shows MeshCat's grid)."""
    config_path = path.parent / "config.yaml"
    if not config_path.is_file():
        return None
    try:
        from cufund.scenarios.run_folder import world_of
        from cufund.scenarios.schema import load_scenario

        return world_of(load_scenario(config_path))
    except Exception as exc:
        print(f"cufund replay: no world from {config_path} ({exc})", file=sys.stderr)
        return None


def run(args: argparse.Namespace) -> int:
    """``cufund replay``: 0 when the log was replayed, 2 when it cannot be read."""
    path = Path(args.log)
    try:
        metadata = log_metadata(path)
        params, T_BL = run_context(path, args.vehicle)
    except (McapReadError, ValueError) as exc:
        print(f"cufund replay: {exc}", file=sys.stderr)
        return 2
    from cufund.viz.meshcat_server import start_server

    vis, server = start_server()
    print(f"MeshCat: open {vis.window.web_url}", flush=True)
    try:
        world = run_world(path)
        stats = replay_log(path, vis, params, speed=args.speed, rate_hz=args.rate, T_BL=T_BL, world=world)
        print("shown: " + ", ".join(f"{text} (#{color:06x})" for text, color in stats.legend), flush=True)
        print(
            f"replayed {stats.duration_s:.1f} s of {metadata.get('scenario', path.name)}: {stats.frames} frames, "
            f"{stats.clouds} LiDAR frames"
        )
        if not args.no_wait and sys.stdin.isatty():
            try:
                input("The viewer stays up until you press Enter (or Ctrl-C). ")
            except (KeyboardInterrupt, EOFError):
                pass
    except (McapReadError, ValueError) as exc:
        print(f"cufund replay: {exc}", file=sys.stderr)
        return 2
    finally:
        vis.window.zmq_socket.close()
        server.terminate()
        server.wait(timeout=10)
    return 0
