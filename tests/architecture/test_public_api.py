"""The public API: every name in each public package's ``__all__`` imports, and every module path of cufund 0.1
that moved still imports, to the same module object, with a DeprecationWarning that names the new path."""

from __future__ import annotations

import importlib
import subprocess
import sys
import warnings

import pytest

import cufund
from cufund.core import moved as _moved

PUBLIC_PACKAGES = [
    "cufund",
    "cufund.core",
    "cufund.vehicle",
    "cufund.worlds",
    "cufund.logs",
    "cufund.simulator",
    "cufund.sensors",
    "cufund.estimation",
    "cufund.mapping",
    "cufund.perception",
    "cufund.planning",
    "cufund.control",
    "cufund.missions",
    "cufund.scenarios",
]


@pytest.mark.parametrize("package", PUBLIC_PACKAGES)
def test_every_public_name_imports(package):
    module = importlib.import_module(package)
    names = getattr(module, "__all__", None)
    assert names, f"{package} has no __all__"
    assert len(names) == len(set(names)), f"{package}.__all__ repeats a name"
    for name in names:
        assert getattr(module, name, None) is not None, f"{package}.{name} is in __all__ but does not import"


def test_the_top_level_api_is_what_0_1_offered():
    for name in [
        "Bus",
        "BusView",
        "Component",
        "ConfigError",
        "Controller",
        "Estimator",
        "FlightMode",
        "Mapper",
        "Planner",
        "Quadrotor",
        "QuadrotorBatch",
        "QuadrotorParams",
        "QuadrotorState",
        "Recorder",
        "RunStatus",
        "ScenarioConfig",
        "ScenarioRun",
        "Sensor",
        "SimulationResult",
        "Simulator",
        "Subscription",
        "Topic",
        "Topics",
        "World",
        "__version__",
        "available_scenarios",
        "control",
        "load_scenario",
        "messages",
        "planning",
        "presets",
        "run_scenario",
        "sensors",
        "worlds",
    ]:
        assert hasattr(cufund, name), name
    assert cufund.QuadrotorParams is cufund.vehicle.QuadrotorParams
    assert cufund.Topics is cufund.core.messages.Topics


OLD_PATHS = sorted(_moved.MOVED) + sorted(_moved.MOVED_PACKAGES)


@pytest.mark.parametrize("old", OLD_PATHS)
def test_old_module_paths_import_with_a_deprecation_warning(old):
    """In a fresh interpreter (so the import really runs the alias): the old path gives the new module, warned."""
    new = _moved.new_path(old)
    code = (
        "import importlib, warnings, sys\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        f"    old = importlib.import_module({old!r})\n"
        f"new = importlib.import_module({new!r})\n"
        "assert old is new, (old, new)\n"
        f"assert new.__spec__.name == {new!r}, new.__spec__.name\n"
        "msgs = [str(x.message) for x in w if issubclass(x.category, DeprecationWarning)]\n"
        f"assert any({old!r} in m and {new!r} in m for m in msgs), msgs\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]


def test_old_submodule_of_a_moved_package_imports():
    """One module object, not a second copy loaded through the old package's path."""
    code = (
        "import importlib, warnings\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    old = importlib.import_module('cufund.mavlink.frames')\n"
        "assert old is importlib.import_module('cufund.apps.mavlink.frames')\n"
        "assert any('cufund.apps.mavlink.frames' in str(x.message) for x in w), [str(x.message) for x in w]\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]


def test_old_names_from_the_package():
    """``from cufund import presets`` worked in 0.1 and still does without a warning (presets is public);
    ``cufund.lidar`` and ``cufund.esdf`` are 0.1's names for the sensors and mapping packages, warned."""
    from cufund import presets

    assert presets is cufund.vehicle.presets
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        assert cufund.lidar.RaycastScene is cufund.sensors.RaycastScene
        assert cufund.esdf.EsdfMap is cufund.mapping.EsdfMap


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'nonexistent'"):
        cufund.nonexistent  # noqa: B018
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("cufund.nonexistent_module")
