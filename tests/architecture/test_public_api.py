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


# Each old path imported for the first time (so the import really runs the alias) in one fresh interpreter for all
# of them (an interpreter's start-up and cufund's import cost ~1.5 s each): {old path: None, or why it failed}.
OLD_IMPORTS_CHECK = """\
import importlib, json, sys, warnings
results = {}
for old, new in json.loads(sys.argv[1]):
    try:
        assert old not in sys.modules, f"{old} was imported before its own check (by an earlier one's import)"
        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            old_module = importlib.import_module(old)
        new_module = importlib.import_module(new)
        assert old_module is new_module, (old_module, new_module)
        assert new_module.__spec__.name == new, new_module.__spec__.name
        msgs = [str(x.message) for x in w if issubclass(x.category, DeprecationWarning)]
        assert any(old in m and new in m for m in msgs), msgs
        results[old] = None
    except Exception as e:
        results[old] = repr(e)
print(json.dumps(results))
"""


@pytest.fixture(scope="module")
def old_imports() -> dict[str, str | None]:
    import json

    pairs = json.dumps([[old, _moved.new_path(old)] for old in OLD_PATHS])
    r = subprocess.run([sys.executable, "-c", OLD_IMPORTS_CHECK, pairs], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("old", OLD_PATHS)
def test_old_module_paths_import_with_a_deprecation_warning(old, old_imports):
    """In a fresh interpreter, imported for the first time there: the old path gives the new module, warned."""
    assert old in old_imports and old_imports[old] is None, old_imports.get(old)


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
