"""A log written by cufund before the ROS 2 messages (commit 8d09c8b: clouds as JSON ``foxglove.PointCloud``,
images as ``foxglove.RawImage``, GPS fixes as ``foxglove.LocationFix``, odometry with the Foxglove views) is read
back exactly by today's :func:`cufund.logs.read_mcap`.

``data/log_8d09c8b.mcap`` was written by that commit's own ``cufund.logs`` (not by today's code made to write the
old form), from the messages of :func:`_messages`, by running this file as a script on that commit's tree::

    git archive 8d09c8b python/cufund | tar -x -C /tmp/old
    cp .venv/lib/python3.11/site-packages/cufund/_core*.so /tmp/old/python/cufund/
    .venv/bin/python tests/logs/test_old_logs.py /tmp/old/python tests/logs/data/log_8d09c8b.mcap
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

FIXTURE = Path(__file__).parent / "data" / "log_8d09c8b.mcap"


def _messages() -> list[tuple[str, int, object]]:
    """(topic, log time [ns], message): three LiDAR frames, truth clouds, depth and colour images, GPS fixes and
    truth odometry, random but seeded."""
    from cufund import messages as M

    rng = np.random.default_rng(7)
    out: list[tuple[str, int, object]] = []
    for k in range(3):
        n = 20 + k
        t = 0.1 * (k + 1) + 1e-10 * k
        ns = int(t * 1e9)
        out += [
            (
                "/sensors/lidar",
                ns,
                M.PointCloud(
                    t=t,
                    dt=np.linspace(0, 0.09, n),
                    points_L=rng.normal(size=(n, 3)).astype(np.float32),
                    ranges=rng.random(n) * 10,
                    intensity=rng.random(n),
                    channel=np.arange(n, dtype=np.int32) % 4,
                    frame=k,
                ),
            ),
            (
                "/truth/point_cloud",
                ns,
                M.LidarTruth(t=t, points_W=rng.normal(size=(n, 3)), object_ids=np.arange(n, dtype=np.int64)),
            ),
            ("/sensors/depth", ns, M.CameraImage(t=t, image=rng.random((4, 5)).astype(np.float32))),
            ("/sensors/rgb_image", ns, M.CameraImage(t=t, image=(rng.random((4, 5, 3)) * 255).astype(np.uint8))),
            (
                "/sensors/gps",
                ns,
                M.GpsFix(t, 47.0 + 1e-6 * k, 8.0, 400.0 + k, np.array([0.1, 0.2, 0.0]), 3, 10, 1.5, 3.0),
            ),
            (
                "/truth/odometry",
                ns,
                M.Odometry(
                    t,
                    rng.normal(size=3),
                    rng.normal(size=3),
                    np.array([1.0, 0.0, 0.0, 0.0]),
                    rng.normal(size=3),
                    np.zeros(3),
                    np.zeros(3),
                ),
            ),
        ]
    return out


def _same(a: object, b: object) -> bool:
    import dataclasses

    if type(a) is not type(b):
        return False
    for f in dataclasses.fields(a):  # type: ignore[arg-type]
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if not (x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y)):
                return False
        elif x != y:
            return False
    return True


def test_a_log_written_by_cufund_before_the_ros2_messages_is_read_back_exactly():
    from mcap.reader import make_reader

    from cufund.logs import read_mcap

    with open(FIXTURE, "rb") as f:
        summary = make_reader(f).get_summary()
    schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert schemas["/sensors/lidar"] == "foxglove.PointCloud" and schemas["/sensors/depth"] == "foxglove.RawImage"
    assert schemas["/sensors/gps"] == "foxglove.LocationFix" and "/truth/odometry/tf" in schemas  # the old form
    written = _messages()
    back = list(read_mcap(FIXTURE))
    assert [(r.topic, r.log_time_ns) for r in back] == [(topic, ns) for topic, ns, _ in written]
    for record, (topic, _, message) in zip(back, written, strict=True):
        assert _same(record.message, message), topic


if __name__ == "__main__":  # writes the fixture with the cufund of the tree given (see the module's docstring)
    sys.meta_path[:] = [f for f in sys.meta_path if "ScikitBuild" not in type(f).__name__]
    sys.path.insert(0, sys.argv[1])
    from cufund.logs import McapLogger

    with McapLogger(sys.argv[2], {"scenario": "a log of cufund 8d09c8b (JSON clouds, images, fixes)"}) as log:
        for topic, ns, message in _messages():
            log.write(topic, message, ns, ns)
