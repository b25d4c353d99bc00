"""ESDF mapper benchmark (issue 14's speed): the tunnel flight's LiDAR frames into the map, before and after.

Replays 276 Mid-360 frames (10 Hz, 27.6 s: the length of `cufund run tunnel`) scanned in the paper's tunnel
course along a flight through it, with body poses at 200 Hz, into the tunnel scenario's map (0.1 m, 12 x 8 x
3.2 m, max range 8 m), three ways, in this process:
  1. before: the previous mapper's work: every frame placed with numpy (per-point pose interpolation) and
     inserted on its own (one beam per point, one distance-field update per frame);
  2. batched: `EsdfMapper` stepped at the scenario's 1 Hz, every ready frame in one `insert_frames` call
     (placement, ray casting and one field update in C++), one beam per point: the same map as 1;
  3. batched + merged beams (the scenario's mapper): one beam per distinct end voxel and frame.
Prints process CPU seconds (all threads) and wall seconds, the ratios to 1, and how the maps compare (the
merged map's extra occupied voxels; its log-odds are >= the per-point map's everywhere).
`--tunnel` also runs `cufund run tunnel` and prints its `component_seconds["esdf_mapper"]` (the target:
<= 0.6 s on a quiet 2-core machine) with the load.

Run: `.venv/bin/python benchmarks/bench_esdf_mapper.py [--tunnel]`
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from cufund import mapping as esdf
from cufund.core.bus import Bus
from cufund.core.messages import Odometry
from cufund.geometry import Transform, interpolate_poses
from cufund.missions.tunnel_course import paper_tunnel_course
from cufund.sensors import Lidar, mid360

T_BL = Transform((0.0, 0.0, 0.08))
MAP = {"resolution": 0.1, "size": (12.0, 8.0, 3.2), "origin_W": (-3.5, -4.0, -0.2), "max_range": 8.0}
DURATION, LIDAR_HZ, POSE_HZ, MAPPER_HZ = 27.6, 10.0, 200.0, 1.0


def pose(t: float) -> tuple[np.ndarray, np.ndarray]:
    """A flight through the course: take-off at x = -2.5, along +x at 0.6 m, a slow yaw wobble, landing at x = 3."""
    s = min(max((t - 3.0) / 20.0, 0.0), 1.0)
    z = 0.6 * min(t / 2.0, 1.0) * (1.0 if t < 25.0 else max(0.0, 1.0 - (t - 25.0) / 2.0)) + 0.08
    p = np.array([-2.5 + 5.5 * s, 0.1 * np.sin(0.4 * t), z])
    yaw = 0.15 * np.sin(0.3 * t)
    return p, np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)])


def make_data() -> tuple[list, list]:
    world = paper_tunnel_course().world  # the paper's layout, as `cufund run tunnel` flies it
    lidar = Lidar(mid360(), T_BL=T_BL)
    frames = []
    for f in range(int(round(DURATION * LIDAR_HZ))):
        cloud, _ = lidar.scan_with_truth(world, pose, t0=f / LIDAR_HZ, frame=f)
        frames.append((cloud.t + float(np.max(cloud.dt, initial=0.0)), cloud))
    poses = []
    for k in range(int(DURATION * POSE_HZ) + 40):
        t = k / POSE_HZ
        p, q = pose(t)
        poses.append((t, Odometry(t=t, p_W=p, v_W=np.zeros(3), q_WB=q, w_B=np.zeros(3))))
    return frames, poses


def before(frames, poses) -> esdf.EsdfMap:
    """The previous mapper's work per frame: numpy placement at each point's time, one insert_scan per frame."""
    m = esdf.EsdfMap(esdf.EsdfMapParams(**MAP))
    t_k = np.array([t for t, _ in poses])
    p_k = np.array([o.p_W for _, o in poses])
    q_k = np.array([o.q_WB for _, o in poses])
    R_BL, t_BL = T_BL.R, np.asarray(T_BL.t)
    for _, cloud in frames:
        t_points = cloud.t + np.asarray(cloud.dt, dtype=float)
        p_WB, R_WB = interpolate_poses(t_k, p_k, q_k, t_points)
        points_W = p_WB + R_WB @ t_BL + np.einsum("nij,nj->ni", R_WB @ R_BL, np.asarray(cloud.points_L, dtype=float))
        mid_p, mid_R = interpolate_poses(
            t_k, p_k, q_k, np.array([cloud.t + 0.5 * float(np.max(cloud.dt, initial=0.0))])
        )
        m.insert_scan(points_W, mid_p[0] + mid_R[0] @ t_BL)
    return m


def mapper(frames, poses, merge: bool) -> esdf.EsdfMap:
    """The scenario's EsdfMapper stepped at 1 Hz on a scripted bus (frames visible at their end)."""
    mp = esdf.EsdfMapper(
        esdf.EsdfMapParams(**MAP, merge_beams=merge), T_BL=T_BL, rate_hz=MAPPER_HZ, cloud_topic="/clouds"
    )
    bus = Bus()  # the stamped messages in flight, each visible at its stamp
    mp.setup(bus)
    for topic, items in ((mp.active_state_topic, poses), (mp.cloud_topic, frames)):
        for t, message in items:
            bus.publish(topic, message, latency_ns=round(t * 1e9))
    for k in range(int(DURATION * MAPPER_HZ) + 2):
        bus.release(round(k / MAPPER_HZ * 1e9))
        mp.integrate(k / MAPPER_HZ, bus)
    assert mp.frames == len(frames), (mp.frames, len(frames))
    return mp.map


def timed(fn, *args):
    gc.collect()
    c, w = time.process_time(), time.perf_counter()
    out = fn(*args)
    return out, time.process_time() - c, time.perf_counter() - w


def load() -> str:
    return f"load {os.getloadavg()[0]:.1f}"


def run_tunnel() -> None:
    with tempfile.TemporaryDirectory() as out:
        cmd = [os.path.join(os.path.dirname(sys.executable), "cufund"), "run", "tunnel", "--out", out]
        l0 = load()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        m = json.load(open(os.path.join(out, "metrics.json")))
    print(
        f"cufund run tunnel ({l0} before, {load()} after): success {m['success']}, sim {m['sim_time_s']:.1f} s in "
        f"{m['wall_time_s']:.1f} s wall = {m['real_time_factor']:.2f}x real time, CPU {m['cpu_time_s']:.1f} s"
    )
    print(f"  esdf_mapper component_seconds: {m['component_seconds']['esdf_mapper']:.3f} s (target <= 0.6 s)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tunnel", action="store_true", help="also run `cufund run tunnel` and print the mapper's seconds")
    args = ap.parse_args()
    frames, poses = make_data()
    n = len(frames)
    print(
        f"{n} Mid-360 frames ({sum(len(c.dt) for _, c in frames)} points) over {DURATION} s, tunnel course, "
        f"map {MAP['size']} m at {MAP['resolution']} m; {load()}"
    )
    ref, c0, w0 = timed(before, frames, poses)
    rows = [("before: numpy placement, insert_scan per frame, every point", c0, w0)]
    exact, c1, w1 = timed(mapper, frames, poses, False)
    rows.append(("EsdfMapper 1 Hz, insert_frames, every point", c1, w1))
    merged, c2, w2 = timed(mapper, frames, poses, True)
    rows.append(("EsdfMapper 1 Hz, insert_frames, merged beams (scenario)", c2, w2))
    for name, c, w in rows:
        print(
            f"  {name:58s} CPU {c:6.3f} s ({1e3 * c / n:5.2f} ms/frame, {c0 / c:4.1f}x)  wall {w:6.3f} s ({w0 / w:4.1f}x)"
        )
    same = np.array_equal(exact.log_odds(), ref.log_odds()) and np.array_equal(exact.distances(), ref.distances())
    occ_ref, occ_m = ref.occupied(), merged.occupied()
    print(f"  per-point batched map == before (log-odds and distances): {same}")
    print(
        f"  merged: log-odds >= before everywhere: {bool(np.all(merged.log_odds() >= ref.log_odds()))}; occupied "
        f"{int(occ_m.sum())} vs {int(occ_ref.sum())} ({int((occ_m & ~occ_ref).sum())} extra, "
        f"{int((occ_ref & ~occ_m).sum())} missing); {load()}"
    )
    if args.tunnel:
        run_tunnel()


if __name__ == "__main__":
    main()
