"""Frames/s of the stereo camera rig in the ``vio_room`` (issue 25's target: >= 30 stereo frames/s of 640x480 with
shading and shadows on 2 cores).

    .venv/bin/python benchmarks/bench_render.py [--frames 60] [--threads 2]

Renders the ``stereo_camera`` sensor kind's default rig (two 640x480 cameras, 11 cm baseline, grey, sun shadows)
from poses on a 1.5 m circle at 1.2 m height, turning, as the scenario builds it; one stereo frame = both images,
as the component publishes them (uint8). Prints frames/s, wall ms per stereo frame (median and best), the CPU ms
per stereo frame (this process, all its threads) and the frames/s that CPU time allows on 2 free cores, the same
without shadows and in RGB, and the machine's load average before and after (the 2 cores are shared: on a loaded
machine the wall figures are the load's as much as the renderer's).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from cufund import _core
from cufund.geometry import quat_from_rotvec
from cufund.sensors.camera import RgbCamera
from cufund.sensors.kinds import StereoCameraParams
from cufund.worlds.vio_room import vio_room


def rig(params: StereoCameraParams, threads: int) -> list[RgbCamera]:
    return [
        RgbCamera(
            cal.intrinsics,
            cal.T_BC,
            light_W=params.light_W,
            ambient=params.ambient,
            nthreads=threads,
            shadows=params.shadows,
            grayscale=params.color == "gray",
        )
        for cal in params.cameras()
    ]


def run(cams: list[RgbCamera], frames: int) -> tuple[np.ndarray, float]:
    """Wall seconds of each stereo frame, and CPU seconds per stereo frame (all threads)."""
    world = vio_room(0)
    times = []
    cpu = 0.0
    for k in range(frames + 3):
        a = 2 * np.pi * k / frames
        p = (1.5 * np.cos(a), 1.5 * np.sin(a), 1.2)
        q = quat_from_rotvec((0.0, 0.0, a + np.pi))  # looking at the walls, turning
        t0, c0 = time.perf_counter(), time.process_time()
        for cam in cams:
            cam.render(world, p, q)
        if k >= 3:  # warm-up: the scene's BVH and the material table
            times.append(time.perf_counter() - t0)
            cpu += time.process_time() - c0
    return np.array(times), cpu / frames


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    load0 = os.getloadavg()
    print(f"cores: {os.cpu_count()}, thread pool: {_core.thread_pool_size()}, threads used: {args.threads}")
    print(f"load average before: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    print(
        f"{'configuration':<44} {'stereo fps':>10} {'median ms':>10} {'best ms':>8} {'CPU ms':>7} {'fps/2 free cores':>16}"
    )
    rows = [
        ("640x480 stereo, grey, shading + shadows", StereoCameraParams()),
        ("640x480 stereo, grey, shading, no shadows", StereoCameraParams(shadows=False)),
        ("640x480 stereo, RGB, shading + shadows", StereoCameraParams(color="rgb")),
    ]
    for name, params in rows:
        t, cpu = run(rig(params, args.threads), args.frames)
        print(
            f"{name:<44} {1.0 / np.median(t):>10.1f} {1e3 * np.median(t):>10.1f} {1e3 * t.min():>8.1f} "
            f"{1e3 * cpu:>7.1f} {min(args.threads, 2) / cpu:>16.1f}"
        )
    load1 = os.getloadavg()
    print(f"load average after: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")


if __name__ == "__main__":
    main()
