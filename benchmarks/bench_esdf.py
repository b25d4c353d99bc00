"""ESDF benchmark (issue 6): cufund.mapping against the `edt` package (parallel=2) and scipy, same run.

Prints times and ratios for
  1. the full exact EDT of a 400 x 400 x 60 occupancy grid,
  2. the incremental map update after one Mid-360-like frame versus a full recompute of the map,
  3. batched distance + gradient query throughput.
Run: `.venv/bin/python benchmarks/bench_esdf.py` (or `make bench`).
"""

from __future__ import annotations

import time

import edt as edt_pkg
import numpy as np
from scipy import ndimage

from cufund import mapping as esdf

SHAPE = (400, 400, 60)
RES = 0.1
ORIGIN = np.array([-20.0, -20.0, -0.5])
THREADS = 2


def best_of(fn, repeat=5):
    fn()  # warm-up
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def make_world(rng, n_boxes=150):
    """Axis-aligned boxes (lo, hi) standing on the ground z = 0, inside the 40 x 40 x 6 m map."""
    centre = rng.uniform([-19, -19, 0], [19, 19, 0], size=(n_boxes, 3))
    half = rng.uniform([0.15, 0.15, 0.5], [1.5, 1.5, 2.7], size=(n_boxes, 3))
    lo = centre - half * [1, 1, 0]
    hi = centre + half * [1, 1, 2]
    return lo, hi


def world_occupancy(lo, hi):
    occ = np.zeros(SHAPE, dtype=bool)
    occ[:, :, : int(round(0.5 / RES))] = True  # ground below z = 0
    for a, b in zip(lo, hi, strict=True):
        i0 = np.clip(np.floor((a - ORIGIN) / RES).astype(int), 0, SHAPE)
        i1 = np.clip(np.ceil((b - ORIGIN) / RES).astype(int), 0, SHAPE)
        occ[i0[0] : i1[0], i0[1] : i1[1], i0[2] : i1[2]] = True
    return occ


def mid360_frame(rng, origin, lo, hi, n=20000, max_range=40.0):
    """One 0.1 s Mid-360 frame (200 k points/s; 360 deg x [-7, 52] deg; non-repetitive pattern as
    random directions), ray-cast exactly against the boxes and the ground; misses are dropped."""
    az = rng.uniform(0, 2 * np.pi, n)
    el = np.radians(rng.uniform(-7.0, 52.0, n))
    d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_best = np.where(d[:, 2] < 0, -origin[2] / d[:, 2], np.inf)
        inv = 1.0 / d
        for a, b in zip(lo, hi, strict=True):
            t1 = (a - origin) * inv
            t2 = (b - origin) * inv
            tn = np.max(np.minimum(t1, t2), axis=1)
            tf = np.min(np.maximum(t1, t2), axis=1)
            hit = (tn <= tf) & (tn > 0) & (tn < t_best)
            t_best[hit] = tn[hit]
    keep = t_best <= max_range
    return origin + t_best[keep, None] * d[keep]


def full_edt(name, occ):
    free = ~occ  # the `edt` package and scipy measure the distance to the nearest zero
    print(f"1) full EDT of a {SHAPE[0]}x{SHAPE[1]}x{SHAPE[2]} grid, {name} ({occ.mean():.1%} occupied), voxel {RES} m")
    t_edt = best_of(lambda: edt_pkg.edt(free, anisotropy=(RES,) * 3, parallel=THREADS))
    t_scipy = best_of(lambda: ndimage.distance_transform_edt(free, sampling=RES), repeat=2)
    t32 = best_of(lambda: esdf.edt(occ, voxel_size=RES, nthreads=THREADS, dtype=np.float32))
    t64 = best_of(lambda: esdf.edt(occ, voxel_size=RES, nthreads=THREADS))
    ref = ndimage.distance_transform_edt(free, sampling=RES)
    err = np.max(np.abs(esdf.edt(occ, voxel_size=RES) - ref))
    print(f"   edt package (parallel={THREADS}, float32):    {t_edt * 1e3:8.1f} ms")
    print(f"   scipy distance_transform_edt (float64):  {t_scipy * 1e3:8.1f} ms")
    print(
        f"   cufund.mapping.edt (nthreads={THREADS}, float32): {t32 * 1e3:8.1f} ms   "
        f"speed vs edt: {t_edt / t32:.2f}x   vs scipy: {t_scipy / t32:.1f}x"
    )
    print(
        f"   cufund.mapping.edt (nthreads={THREADS}, float64): {t64 * 1e3:8.1f} ms   "
        f"speed vs edt: {t_edt / t64:.2f}x   vs scipy: {t_scipy / t64:.1f}x   max |diff| vs scipy: {err:.1e} m"
    )


def main():
    rng = np.random.default_rng(0)
    lo, hi = make_world(rng)
    grids = (("box world", world_occupancy(lo, hi)), ("uniform random 1%", rng.random(SHAPE) < 0.01))
    for name, occ in grids:
        full_edt(name, occ)

    print("2) incremental update after one Mid-360 frame (~20000 beams, max range 40 m) vs full recompute")
    print("   (map built over 40 frames, then 10 more frames timed one by one: median; full recompute: best of 5)")
    params = esdf.EsdfMapParams(
        resolution=RES, size=(40.0, 40.0, 6.0), origin_W=tuple(ORIGIN), max_range=40.0, nthreads=THREADS
    )
    for scenario, step in (("moving 0.3 m/frame", 0.3), ("hovering", 0.0)):
        m = esdf.EsdfMap(params)
        path = [np.array([-15.0 + step * i, 0.5 * np.sin(0.2 * i) if step else 0.0, 1.2]) for i in range(50)]
        frames = [mid360_frame(rng, p, lo, hi) for p in path]
        for p, f in zip(path[:40], frames[:40], strict=True):  # build the map along the path
            m.insert_scan(f, p)
        total, field, stats = [], [], []
        for p, f in zip(path[40:], frames[40:], strict=True):
            t = time.perf_counter()
            s = m.insert_scan(f, p)
            total.append(time.perf_counter() - t)
            field.append(s.field_seconds)
            stats.append(s)
        t_total, t_field = float(np.median(total)), float(np.median(field))
        t_full = best_of(m.recompute, repeat=5)
        flipped = int(np.median([s.flipped_voxels for s in stats]))
        changed = int(np.median([s.changed_distances for s in stats]))
        print(
            f"   [{scenario}] {len(frames[-1])} returns/frame, median {flipped} voxels flipped, {changed} distances changed"
        )
        print(f"   [{scenario}] full recompute of the signed field:        {t_full * 1e3:7.1f} ms")
        print(
            f"   [{scenario}] incremental field update:                  {t_field * 1e3:7.1f} ms"
            f"   incremental / full: {t_field / t_full:.1%}"
        )
        print(
            f"   [{scenario}] whole insert_scan (ray casting + field):   {t_total * 1e3:7.1f} ms"
            f"   (ray casting + incremental) / full: {t_total / t_full:.1%}"
        )

    print("3) queries: distance + gradient (trilinear), 1e6 random points")
    q = rng.uniform(ORIGIN, ORIGIN + [40, 40, 6], size=(1_000_000, 3))
    t_q = best_of(lambda: m.distance_and_gradient(q), repeat=3)
    print(f"   {1e6 / t_q / 1e6:.1f} M points/s ({THREADS} threads)")


if __name__ == "__main__":
    main()
