"""The ``commander`` planner kind: the vehicle state machine driven by commands (a script, a ground station,
MAVLink). With the scenario's controller ``pid`` or ``geometric``, the other one is built too (idle until the
``controller`` command selects it), so the controller can be switched in flight."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError
from cufund.core.registry import Kind, register
from cufund.worlds.builtin import BUILTIN

from .commander import Commander
from .params import CommanderParams
from .tunnel_course import TunnelCourseParams, paper_tunnel_course, tunnel_course, tunnel_course_layout

_SWITCHABLE = ("pid", "geometric")


def _commander(p: CommanderParams, ctx: BuildContext) -> list[Any]:
    cfg = ctx.config
    if p.rate_hz == CommanderParams.rate_hz:  # not set: the scenario's trajectory rate
        p = dataclasses.replace(p, rate_hz=cfg.rates.trajectory_hz)
    spec = cfg.controller
    kind = spec.kind if spec is not None else ""
    components: list[Any] = []
    other = _SWITCHABLE[1 - _SWITCHABLE.index(kind)] if kind in _SWITCHABLE else None
    commander = Commander(p, controller=kind, controllers=(kind,) if other is None else (kind, other))
    ctx.set_commander(commander)  # the controllers built from here on are gated by the commander's status
    if other is not None:
        components += ctx.build("controller", dataclasses.replace(spec, kind=other), "controller")

    def done(t: float, truth: Any) -> bool:  # a scripted run ends once the script is through and it has landed
        run_done = getattr(commander, "run_done", None)  # a mission flying through the commander (e.g. fleet)
        if run_done is not None:
            return bool(run_done(t))
        return (
            bool(p.script)
            and commander.script_done
            and not commander.armed
            and commander.landed
            and t > p.script[-1][0] + 1.0
        )

    ctx.set_done_condition(done)
    ctx.add_metric_hook(
        lambda result: {
            "commander_events": [f"{e['t']:.2f} s {e['message']}" for e in commander.events],
            "commander_denied": len(commander.events.of_kind("denied")),
            "mission_items_reached": len(commander.events.of_kind("mission_item_reached")),
        }
    )
    return [commander, *components]


register(
    Kind(
        "planner",
        "commander",
        CommanderParams,
        _commander,
        None,
        "the vehicle commander: arm, take off, go to, missions, offboard, land, return (script or live)",
    )
)

from . import tunnel_kind  # noqa: E402, F401  (registers itself; imported after the commander kind it builds on)


def _tunnel_course_kind() -> None:
    """The generated tunnel course as a world kind (the course generator is the tunnel mission's)."""

    @dataclass(frozen=True)
    class TunnelCourseWorldParams(TunnelCourseParams):
        """A generated tunnel course: its layout seed and the generator's bounds (:class:`TunnelCourseParams`)."""

        seed: int | None = 0
        """Layout seed (independent of the scenario seed); null: the paper's IMAV 2025 layout."""

        def __post_init__(self) -> None:
            super().__post_init__()
            if self.seed is not None and (
                isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0
            ):
                raise ConfigError(f"world.seed must be an integer >= 0 or null (the paper's layout), got {self.seed!r}")

    def layout(p: TunnelCourseWorldParams) -> object:
        return paper_tunnel_course(p) if p.seed is None else tunnel_course_layout(p.seed, p)

    register(
        Kind(
            "world",
            "tunnel_course",
            TunnelCourseWorldParams,
            lambda p, ctx: layout(p).world,  # type: ignore[attr-defined]
            None,
            "a seeded IMAV-style tunnel course (world.seed picks the layout), checked flyable",
        )
    )


_tunnel_course_kind()
BUILTIN.setdefault("tunnel_course", tunnel_course)  # worlds.load("tunnel_course", seed=...)

from . import fleet_mission  # noqa: E402, F401  (registers the mission kind fleet, which flies through the commander)
from . import formation_follower as _formation_follower  # noqa: E402, F401  (registers the planner kind)
from . import search as _search  # noqa: E402, F401  (registers the mission kind search)
