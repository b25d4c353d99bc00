"""MeshCat's server bound to 127.0.0.1 only (meshcat 0.3.2 binds its web port on all interfaces).

Run as ``python -m cufund.viz.meshcat_server``; :func:`start_server` does that and connects to it.
"""

from __future__ import annotations

import atexit
import re
import subprocess
import sys
from typing import Any

__all__ = ["start_server"]


def start_server() -> tuple[Any, subprocess.Popen]:
    """Starts the local server in a subprocess and returns a connected ``meshcat.Visualizer`` and the process
    (terminated when Python exits)."""
    from .meshcat_scene import import_meshcat

    meshcat = import_meshcat()
    proc = subprocess.Popen(
        [sys.executable, "-u", "-m", "cufund.viz.meshcat_server"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        start_new_session=True,
    )
    atexit.register(proc.terminate)
    urls: dict[str, str] = {}
    assert proc.stdout is not None
    for raw in proc.stdout:
        m = re.search(r"(zmq_url|web_url)=(\S+)", raw.decode())
        if m:
            urls[m.group(1)] = m.group(2)
        if len(urls) == 2:
            break
    if len(urls) != 2:
        raise RuntimeError(f"the MeshCat server exited early: {proc.stderr.read().decode() if proc.stderr else ''}")
    # meshcat's own ViewerWindow(zmq_url) opens a socket, asks for the URL, then opens a second one and leaks the
    # first; we already know both URLs, so connect once
    window = meshcat.visualizer.ViewerWindow.__new__(meshcat.visualizer.ViewerWindow)
    window.server_proc, window.zmq_url, window.web_url = None, urls["zmq_url"], urls["web_url"]
    window.connect_zmq()
    return meshcat.Visualizer(window=window), proc


def _main() -> None:
    import warnings

    import tornado.web

    listen = tornado.web.Application.listen

    def listen_local(self: Any, port: int, address: str = "127.0.0.1", **kwargs: Any) -> Any:
        return listen(self, port, address="127.0.0.1", **kwargs)

    tornado.web.Application.listen = listen_local  # type: ignore[assignment]  # a patch with a narrower signature
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=DeprecationWarning)
        from meshcat.servers.zmqserver import main

        main()


if __name__ == "__main__":
    _main()
