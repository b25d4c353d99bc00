"""Live MeshCat streaming: what the viewer sends, and the local-only server."""

import socket
import urllib.parse

import numpy as np

import cufund
from cufund import Simulator
from cufund.viz.live import LiveViewer
from cufund.viz.meshcat_scene import import_meshcat
from cufund.viz.replay import _RecordingWindow


def test_live_viewer_streams_vehicle_poses():
    meshcat = import_meshcat()
    window = _RecordingWindow()
    p = cufund.vehicle.presets.cu_astro()
    quad = cufund.Quadrotor(p)
    quad.hover([0, 0, 2.0])
    viewer = LiveViewer(p, rate_hz=25, speed=None, visualizer=meshcat.Visualizer(window=window))
    n_setup = len(window.commands)
    sim = Simulator(quad)
    sim.add(viewer)
    sim.run(1.0)
    # one vehicle transform per viewer tick (25 in 1 s), plus flown-path updates every 5 ticks
    sent = window.commands[n_setup:]
    vehicle = [c for c in sent if b"/meshcat/vehicle" in c and b"set_transform" in c]
    assert len(vehicle) == 25
    assert sum(1 for c in sent if b"/meshcat/flown" in c) == 5


def test_server_binds_loopback():
    from cufund.viz.meshcat_server import start_server

    vis, proc = start_server()
    try:
        url = urllib.parse.urlparse(vis.url())
        assert url.hostname == "127.0.0.1"
        with socket.create_connection(("127.0.0.1", url.port), timeout=5):
            pass
        # listening sockets of the server process: none on a wildcard address
        listening = []
        for table in ("/proc/net/tcp", "/proc/net/tcp6"):
            with open(table) as f:
                for line in f.readlines()[1:]:
                    local, state = line.split()[1], line.split()[3]
                    if state == "0A" and int(local.split(":")[1], 16) == url.port:
                        listening.append(local.split(":")[0])
        assert listening and all(set(addr) != {"0"} for addr in listening), listening
    finally:
        vis.window.zmq_socket.close()
        proc.terminate()
        proc.wait(timeout=10)
    assert np.isfinite(proc.returncode)
