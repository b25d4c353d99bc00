"""The web ground station (``cufund gcs``): a live run served to a browser page on 127.0.0.1 — 3-D view (MeshCat's
three.js), telemetry, live plots, commands, waypoint and LTLf missions, event log — and an HTTP/websocket API for
scripts. See :mod:`cufund.apps.gcs.server` for the routes and messages."""

from .process import GcsProcess
from .server import GcsServer, parse_speed

__all__ = ["GcsProcess", "GcsServer", "parse_speed"]
