"""Fuzz: the ray-casting scene (meshes, rays, options), the scan-ray builder and the cameras."""

from __future__ import annotations

import numpy as np
from fuzz_support import Code, arrays, expect_good, fuzz_settings, scalars
from hypothesis import given
from hypothesis import strategies as st

SCENE = """
scene = cufund._core.lidar.RaycastScene()
v, f = cufund.worlds.primitives.box((1.0, 1.0, 1.0))
scene.add_triangles(v.astype(np.float32), f)
"""
HUGE_RAYS = Code("np.broadcast_to(np.float32([0, 0, 0, 1, 0, 0]), (2**33, 6))")
HUGE_TRIS = Code("np.broadcast_to(np.int64([0, 1, 2]), (2**33, 3))")


@fuzz_settings
@given(
    vertices=st.one_of(arrays([(4, 3), (3, 3), (0, 3), (5,)])),
    triangles=st.one_of(
        arrays([(1, 3), (2, 3), (0, 3), (3,)], st.integers(-3, 2**33).map(float)),
        st.just(np.array([[0, 1, 2]], np.uint64) + np.uint64(2**32)),
        st.just(HUGE_TRIS),
    ),
)
def test_add_triangles(server, vertices, triangles):
    outcome, detail = server.run(
        "lidar",
        "scene = cufund._core.lidar.RaycastScene()",
        "scene.add_triangles(vertices, triangles)",
        {"vertices": vertices, "triangles": triangles},
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    rays=st.one_of(arrays([(5, 6), (6,), (2, 3, 6), (0, 6), (4, 5)]), st.just(HUGE_RAYS)),
    nthreads=st.one_of(st.just(0), scalars()),
    coherent=st.one_of(st.none(), st.booleans(), scalars()),
)
def test_cast_rays(server, rays, nthreads, coherent):
    outcome, detail = server.run(
        "lidar",
        SCENE,
        "result = scene.cast_rays(rays, nthreads, coherent)",
        {"rays": rays, "nthreads": nthreads, "coherent": coherent},
        check="not np.isnan(result['t_hit']).any()",
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    which=st.sampled_from(["d_L", "t", "knot_t", "knot_p", "knot_q"]),
    value=arrays([(3, 3), (3,), (2,), (2, 3), (2, 4), (1,)]),
)
def test_scan_rays(server, which, value):
    args = {
        "d_L": np.eye(3),
        "t": np.array([0.0, 0.05, 0.1]),
        "knot_t": np.array([0.0, 0.1]),
        "knot_p": np.zeros((2, 3)),
        "knot_q": np.array([[1.0, 0, 0, 0], [1.0, 0, 0, 0]]),
    }
    args[which] = value
    outcome, detail = server.run(
        "lidar",
        "",
        "result = cufund._core.lidar.scan_rays(d_L, t, knot_t, knot_p, knot_q)",
        args,
        check="np.isfinite(result).all()",
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    field=st.sampled_from(["width", "height", "fx", "fy", "cx", "cy", "distortion"]),
    value=st.one_of(scalars(), arrays([(5,), (4,)]), st.sampled_from([10**6, 2**31, 5e-324, 1e-300])),
)
def test_camera_intrinsics_and_render(server, field, value):
    code = """
import dataclasses
from cufund.sensors.camera import CameraIntrinsics, DepthCamera
K = dataclasses.replace(CameraIntrinsics(width=16, height=12, fx=10.0, fy=10.0, cx=8.0, cy=6.0), **{field: value})
world = cufund.World()
world.add_box((1.0, 1.0, 1.0), (3.0, 0.0, 0.0))
cam = DepthCamera(K)
result = cam.render(world, np.zeros(3), np.array([1.0, 0, 0, 0]))
"""
    outcome, detail = server.run(
        "camera",
        "",
        code,
        {"field": field, "value": value},
        # NaN marks pixels that see nothing (documented); the rest are depths > 0
        check="result.shape == (K.height, K.width) and np.all(np.isnan(result) | ((result > 0) & np.isfinite(result)))",
        timeout=30,
    )
    expect_good(outcome, detail)
