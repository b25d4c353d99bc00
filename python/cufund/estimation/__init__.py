"""State estimation. LiDAR-inertial odometry on GTSAM (issue 12): :class:`LioCore` (pure: samples in, odometry
out) and its parameters :class:`LioParams`; :class:`LioEstimator`, the simulator component (registry kind
``lio``); offline flight records from the standalone sensor models (``flight_data``); error figures and TUM files
(``evaluation``).

Names are imported on first use, so importing this package (as the scenario registry does) does not load GTSAM.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "odometry_errors": "evaluation",
    "read_tum": "evaluation",
    "write_tum": "evaluation",
    "FlatBodyMotion": "flight_data",
    "FlightRecord": "flight_data",
    "LidarFrame": "flight_data",
    "record_flight": "flight_data",
    "replay": "flight_data",
    "LioCore": "lio_core",
    "NavEstimate": "lio_core",
    "ScanDiagnostics": "lio_core",
    "LioEstimator": "lio_estimator",
    "LioParams": "params",
    "run_on_log": "offline",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'cufund.estimation' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
