"""The ``commander`` planner kind: the vehicle state machine driven by commands (a script, a ground station,
MAVLink). With the scenario's controller ``pid`` or ``geometric``, the other one is built too (idle until the
``controller`` command selects it), so the controller can be switched in flight."""

from __future__ import annotations

import dataclasses
from typing import Any

from ..registry import Kind, register
from .commander import Commander
from .params import CommanderParams

_SWITCHABLE = ("pid", "geometric")


def _commander(p: CommanderParams, ctx: Any) -> list[Any]:
    cfg = ctx.config
    if p.rate_hz == CommanderParams.rate_hz:  # not set: the scenario's trajectory rate
        p = dataclasses.replace(p, rate_hz=cfg.rates.trajectory_hz)
    spec = cfg.controller
    kind = spec.kind if spec is not None else ""
    components: list[Any] = []
    kinds: tuple[str, ...] = (kind,)
    ctx.commander = True  # the controllers built from here on are gated by the commander's status
    if kind in _SWITCHABLE:
        other = _SWITCHABLE[1 - _SWITCHABLE.index(kind)]
        part, where, seed = ctx.part, ctx.where, ctx.seed
        components += ctx.build("controller", dataclasses.replace(spec, kind=other), "controller")
        ctx.part, ctx.where, ctx.seed = part, where, seed
        kinds = (kind, other)
    commander = Commander(p, controller=kind, controllers=kinds)

    def done(t: float, truth: Any) -> bool:  # a scripted run ends once the script is through and it has landed
        return bool(p.script) and commander.script_done and not commander.armed and commander.landed \
            and t > p.script[-1][0] + 1.0

    ctx.done = done
    ctx.commander = commander
    ctx.metric_hooks.append(lambda result: {
        "commander_events": [f"{e['t']:.2f} s {e['message']}" for e in commander.events],
        "commander_denied": len(commander.events.of_kind("denied")),
        "mission_items_reached": len(commander.events.of_kind("mission_item_reached"))})
    return [commander, *components]


register(Kind("planner", "commander", CommanderParams, _commander, None,
              "the vehicle commander: arm, take off, go to, missions, offboard, land, return (script or live)"))

from . import tunnel_kind  # noqa: F401  (the tunnel mission kind registers itself)
