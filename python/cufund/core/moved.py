"""Module paths of cufund 0.1 that moved when the package was regrouped into layers (0.2). Importing an old path
gives the module at its new home with a :class:`DeprecationWarning` (``cufund`` installs the finder on import);
the old paths go in the next release. :func:`new_class_path` maps a class name a 0.1 log recorded
(``cufund.messages:Imu``) to its name now, as a string, without importing anything."""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import ModuleType

__all__ = ["MOVED", "MOVED_PACKAGES", "install", "new_class_path", "new_path"]

MOVED: dict[str, str] = {
    "cufund.bus": "cufund.core.bus",
    "cufund.components": "cufund.core.components",
    "cufund.config": "cufund.core.config",
    "cufund.limits": "cufund.core.limits",
    "cufund.messages": "cufund.core.messages",
    "cufund.registry": "cufund.core.registry",
    "cufund.scheduler": "cufund.core.scheduler",
    "cufund.topics": "cufund.core.topics",
    "cufund.params": "cufund.vehicle.params",
    "cufund.presets": "cufund.vehicle.presets",
    "cufund.quadrotor": "cufund.vehicle.quadrotor",
    "cufund.faults": "cufund.sensors.faults",
    "cufund.esdf": "cufund.mapping",
    "cufund.lidar": "cufund.sensors",
    "cufund.scenario": "cufund.scenarios",
    "cufund.scenario_build": "cufund.scenarios.build",
    "cufund.run_folder": "cufund.scenarios.run_folder",
    "cufund.cli": "cufund.apps.cli",
    "cufund.demo": "cufund.apps.demo",
    "cufund.live": "cufund.apps.live",
    "cufund.viz.log_replay": "cufund.apps.log_replay",
    "cufund.worlds.tunnel_course": "cufund.missions.tunnel_course",
    "cufund.sensors.pose": "cufund.geometry",
    "cufund.control.rotations": "cufund.geometry",
    "cufund.estimation.frames": "cufund.estimation.boundary",
}
"""Old module path -> new module path."""

MOVED_PACKAGES: dict[str, str] = {
    "cufund.gcs": "cufund.apps.gcs",
    "cufund.mavlink": "cufund.apps.mavlink",
    "cufund.sweep": "cufund.apps.sweep",
}
"""Old package -> new package (their submodules move with them)."""


def new_path(old: str) -> str | None:
    """Where the module ``old`` lives now, or None if it did not move."""
    if old in MOVED:
        return MOVED[old]
    for a, b in MOVED_PACKAGES.items():
        if old == a or old.startswith(a + "."):
            return b + old[len(a) :]
    return None


MOVED_CLASSES: dict[str, str] = {
    "cufund.planning.diagnostics:PlannerDiagnostics": "cufund.core.messages:PlannerDiagnostics",
}
"""Classes that moved on their own (not with their module)."""


def new_class_path(path: str) -> str:
    """The ``module:QualName`` a class recorded as ``path`` (by cufund 0.1 or earlier in 0.2) has now; ``path``
    itself when it did not move. Pure string work: nothing is imported."""
    if path in MOVED_CLASSES:
        return MOVED_CLASSES[path]
    module, sep, qualname = path.partition(":")
    new = new_path(module) if sep else None
    return f"{new}:{qualname}" if new is not None else path


class _Alias(importlib.abc.Loader):
    def __init__(self, old: str, new: str) -> None:
        self.old, self.new = old, new
        self.spec: importlib.machinery.ModuleSpec | None = None

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        warnings.warn(
            f"{self.old} moved to {self.new}; the old path goes in the next release", DeprecationWarning, stacklevel=2
        )
        module = importlib.import_module(self.new)
        self.spec = module.__spec__
        return module

    def exec_module(self, module: ModuleType) -> None:
        module.__spec__ = self.spec  # the import system set the alias's spec on the real module: undo that


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(
        self, fullname: str, path: object = None, target: object = None
    ) -> importlib.machinery.ModuleSpec | None:
        new = new_path(fullname) if fullname.startswith("cufund.") else None
        if new is None:
            return None
        return importlib.machinery.ModuleSpec(fullname, _Alias(fullname, new))


def install() -> None:
    """Makes the old paths importable (once)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())  # before the path finder, which would load a second copy of a
        # moved package's submodule through the old package's __path__
