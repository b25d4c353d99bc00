"""The build context a kind's ``build(params, ctx)`` receives has declared fields only: a part adds to the run
through its declared calls (end condition, metrics, run-folder files, commander), and writing an undeclared
attribute fails instead of creating a field someone else reads with ``getattr``."""

from __future__ import annotations

import dataclasses
import json

import pytest

from cufund import ConfigError, ScenarioConfig
from cufund.core.build_context import BuildContext
from cufund.core.components import Component
from cufund.core.registry import Kind, register, unregister
from cufund.scenarios.build import ScenarioBuildContext, build_simulation, run_built
from cufund.scenarios.run_folder import run_into_folder


@dataclasses.dataclass(frozen=True)
class EndAt:
    t_end: float = 0.5


def _ends(p: EndAt, ctx: BuildContext) -> list[Component]:
    where = ctx.where
    ctx.set_done_condition(lambda t, truth: t >= p.t_end)
    ctx.add_metric_hook(lambda result: {"test_end_s": p.t_end, "test_part": where})
    ctx.add_output_hook(lambda run, out, **kw: (out / "test_hook.txt").write_text(f"{run.result.sim_time_s:.3f}\n"))
    return []


def _writes_attribute(p: EndAt, ctx: BuildContext) -> list[Component]:
    ctx.done = lambda t, truth: True  # type: ignore[misc]  # the old undeclared field
    return []


@pytest.fixture
def kinds():
    made = [
        Kind("mission", "test_end_at", EndAt, _ends),
        Kind("planner", "test_end_at", EndAt, _ends),
        Kind("mission", "test_writes_attribute", EndAt, _writes_attribute),
    ]
    for k in made:
        register(k)
    try:
        yield
    finally:
        for k in made:
            unregister(k.group, k.name)


def test_a_part_ends_the_run_and_adds_metrics_and_files(kinds, tmp_path):
    cfg = ScenarioConfig.from_dict(
        {"planner": None, "controller": None, "mission": {"kind": "test_end_at", "t_end": 0.25}, "duration": 5}
    )
    run = run_into_folder(cfg, tmp_path, log=False, plots=False, replay=False)
    assert run.result.status.value == "completed" and run.result.message == "done condition met"
    assert run.result.sim_time_s == 0.25  # the first record at or after t_end (every physics node, 1 kHz)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["test_end_s"] == 0.25 and metrics["test_part"] == "mission"
    assert (tmp_path / "test_hook.txt").read_text() == "0.250\n"


def test_writing_an_undeclared_attribute_fails(kinds):
    cfg = ScenarioConfig.from_dict({"planner": None, "controller": None, "mission": "test_writes_attribute"})
    with pytest.raises(AttributeError, match="'done'"):
        build_simulation(cfg)


def test_one_part_ends_the_run(kinds):
    cfg = ScenarioConfig.from_dict({"planner": "test_end_at", "controller": None, "mission": "test_end_at"})
    with pytest.raises(ConfigError, match="mission: the run's end condition is declared already by planner"):
        build_simulation(cfg)


def test_a_nested_build_gives_the_part_back(kinds):
    seen = []

    def outer(p: EndAt, ctx: BuildContext) -> list[Component]:
        inner = ctx.build("controller", dataclasses.replace(ctx.config.controller, kind="geometric"), "controller")
        seen.append((ctx.where, ctx.seed, ctx.part.kind, type(inner[0]).__name__))
        return inner

    register(Kind("mission", "test_outer", EndAt, outer))
    try:
        cfg = ScenarioConfig.from_dict({"mission": "test_outer", "duration": 0.1})
        built = build_simulation(cfg)
        ctx = built.context
        assert seen == [("mission", ctx.seed_for("mission"), "test_outer", "GeometricController")]
        with pytest.raises(RuntimeError, match="no part is being built"):
            ctx.part  # noqa: B018 - outside a build
        run_built(built)
    finally:
        unregister("mission", "test_outer")


def test_the_commander_gates_the_controllers_built_after_it():
    built = build_simulation(ScenarioConfig.from_dict({"planner": "commander", "controller": "pid"}))
    ctx = built.context
    assert type(ctx.commander).__name__ == "Commander" and ctx.commander in built.simulator.components
    # both controllers (pid and the geometric one to switch to) read the commander's vehicle status
    gated = {
        type(c).__name__
        for c in built.simulator.components
        if getattr(c, "armable", False) and "/vehicle/status" in {str(t) for t in c.optional_inputs}
    }
    assert gated == {"PositionController", "AttitudeController", "RateController", "GeometricController"}, gated
    # no commander and no failsafe supervisor (whose flight termination disarms): gated only by the land detector
    # (whose touchdown disarms) of the trajectory follower's landing, and never without a follower
    plain = build_simulation(ScenarioConfig.from_dict({"controller": "pid", "failsafe": "off"}))
    assert plain.context.commander is None
    names = [type(c).__name__ for c in plain.simulator.components]
    assert names.count("LandDetectorComponent") == 1 and names.count("TrajectoryFollower") == 1, names
    bare = build_simulation(ScenarioConfig.from_dict({"controller": "pid", "failsafe": "off", "planner": None}))
    assert not any(getattr(c, "armable", False) for c in bare.simulator.components)
    assert isinstance(ctx, ScenarioBuildContext) and not hasattr(ctx, "__dict__")
