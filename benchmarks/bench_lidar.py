"""Rays/s of cufund.sensors.RaycastScene vs Open3D's RaycastingScene (same scene, same rays, 2 threads),
and frames/s of the LiDAR and camera models in the tunnel world.

    .venv/bin/python benchmarks/bench_lidar.py [--rays 1000000] [--repeats 5] [--threads 2]
    .venv/bin/python benchmarks/bench_lidar.py --models-only      # the sensor models' frames/s and CPU ms/frame

Scenes: a UV sphere of radius 3 m tessellated to about 10k, 100k and 1M triangles. Rays: "random"
(origins uniform in the cube [-2, 2]^3 inside the sphere, directions uniform on the sphere) and
"lidar" (a spinning 64-channel scan from the centre, azimuth-major like an OS1-64's stream).
Each figure is the best of ``--repeats`` casts of all rays, ours and Open3D's interleaved; ratio = cufund rays/s ÷ Open3D rays/s.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import open3d as o3d

import cufund


def best_times(fns, repeats: int) -> list[float]:
    """Best wall time of each function, calls interleaved so load changes hit both alike."""
    for fn in fns:
        fn()  # warm-up (builds the BVH)
    best = [np.inf] * len(fns)
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            fn()
            best[i] = min(best[i], time.perf_counter() - t0)
    return best


def sphere_mesh(triangles: int) -> tuple[np.ndarray, np.ndarray]:
    res = int(round(np.sqrt(triangles / 4.0)))  # create_sphere makes about 4 res^2 triangles
    mesh = o3d.geometry.TriangleMesh.create_sphere(radius=3.0, resolution=res)
    return np.asarray(mesh.vertices, np.float32), np.asarray(mesh.triangles, np.uint32)


def make_rays(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    if kind == "random":
        o = rng.uniform(-2.0, 2.0, (n, 3))
        d = rng.normal(size=(n, 3))
    else:
        rings = 64
        cols = n // rings
        az = np.repeat(np.linspace(0, 2 * np.pi, cols, endpoint=False), rings)
        el = np.tile(np.deg2rad(np.linspace(-16.6, 16.6, rings)), cols)
        o = np.zeros((cols * rings, 3))
        d = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return np.ascontiguousarray(np.column_stack([o, d]), dtype=np.float32)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rays", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--models-only", action="store_true", help="only the sensor models in the tunnel world")
    args = ap.parse_args()
    if not args.models_only:
        scenes(args)
    models(args)


def scenes(args: argparse.Namespace) -> None:
    rng = np.random.default_rng(0)
    print(
        f"cufund {cufund.__version__} vs open3d {o3d.__version__}, {args.rays} rays, {args.threads} threads, "
        f"best of {args.repeats}"
    )
    print(f"{'triangles':>10} {'rays':>7} {'cufund Mrays/s':>15} {'open3d Mrays/s':>15} {'ratio':>6}")
    for target in (10_000, 100_000, 1_000_000):
        v, f = sphere_mesh(target)
        ours = cufund.sensors.RaycastScene()
        ours.add_triangles(v, f)
        theirs = o3d.t.geometry.RaycastingScene()
        theirs.add_triangles(o3d.core.Tensor(v), o3d.core.Tensor(f))
        for kind in ("random", "lidar"):
            rays = make_rays(kind, args.rays, rng)
            rays_o3d = o3d.core.Tensor(rays)
            a = ours.cast_rays(rays, nthreads=args.threads)
            b = theirs.cast_rays(rays_o3d, nthreads=args.threads)
            agree = np.array_equal(np.isfinite(a["t_hit"]), np.isfinite(b["t_hit"].numpy()))
            t_ours, t_theirs = best_times(
                [
                    lambda: ours.cast_rays(rays, nthreads=args.threads),
                    lambda: theirs.cast_rays(rays_o3d, nthreads=args.threads),
                ],
                args.repeats,
            )
            n = len(rays)
            print(
                f"{len(f):>10} {kind:>7} {n / t_ours / 1e6:>15.2f} {n / t_theirs / 1e6:>15.2f} "
                f"{t_theirs / t_ours:>6.2f}{'' if agree else '  (hit/miss differ!)'}"
            )


def models(args: argparse.Namespace) -> None:
    world = cufund.worlds.load("imav2025_tunnel")
    pose = lambda t: (np.array([-1.5 + 0.5 * t, 0.0, 0.55]), np.array([1.0, 0.0, 0.0, 0.0]))  # noqa: E731
    print(
        f"\nsensor models in imav2025_tunnel ({args.threads} threads), best of {args.repeats}, load "
        f"{os.getloadavg()[0]:.1f}:"
    )
    for name, pattern in (("Livox Mid-360", cufund.sensors.mid360()), ("Ouster OS1-64", cufund.sensors.os1_64())):
        lidar = cufund.sensors.Lidar(pattern, cufund.sensors.LidarParams(nthreads=args.threads, range_noise_std=0.02))
        (t,) = best_times([lambda: lidar.scan(world, pose, 0.0)], args.repeats)
        frames = 50
        c0 = time.process_time()
        for _ in range(frames):
            lidar.scan(world, pose, 0.0)  # a new frame of the pattern each time
        cpu = (time.process_time() - c0) / frames
        n = len(pattern.frame(0).t)
        print(
            f"  {name}: {1 / t:8.1f} frames/s ({n} rays/frame, {n / t / 1e6:.2f} Mrays/s incl. Python), "
            f"{1e3 * cpu:.2f} ms CPU per frame"
        )
    cam = cufund.sensors.DepthCamera(
        cufund.sensors.CameraIntrinsics.from_fov(640, 480, np.deg2rad(87.0)), nthreads=args.threads
    )
    (t,) = best_times([lambda: cam.render(world, [-1.5, 0.0, 0.55], [1.0, 0.0, 0.0, 0.0])], args.repeats)
    print(f"  depth camera 640x480: {1 / t:8.1f} frames/s")


if __name__ == "__main__":
    main()
