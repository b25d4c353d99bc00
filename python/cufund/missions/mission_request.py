"""Plain-language mission requests: :func:`parse_mission` turns a sentence into a typed, validated fleet mission
(docs/guides/fleet-missions.md).

The offline grammar (:mod:`cufund.missions.mission_request_grammar`) reads the built-in phrases; any other sentence
goes to the chat endpoint the environment configures (:mod:`cufund.missions.mission_request_llm`), if any. Both give
the same plain data, which :func:`~cufund.missions.mission_request_schema.mission_from_data` validates into a
:class:`~cufund.missions.mission_request_schema.Mission` checked against the fleet.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from .fleet_context import FleetContext, MissionRequestError
from .mission_request_grammar import GrammarMiss, request_to_data
from .mission_request_llm import LlmEndpoint, propose_mission
from .mission_request_schema import Formation, GoHome, Mission, Orbit, Survey, Waypoints, Zigzag, mission_from_data

__all__ = [
    "FleetContext",
    "Formation",
    "GoHome",
    "Mission",
    "MissionRequestError",
    "Orbit",
    "Survey",
    "Waypoints",
    "Zigzag",
    "parse_mission",
]


def parse_mission(
    text: str,
    fleet: Any = None,
    *,
    area: Any = None,
    vehicles: Sequence[str] | None = None,
    endpoint: LlmEndpoint | None = None,
) -> Mission:
    """The mission ``text`` asks for, checked against ``fleet`` (a built fleet, a :class:`FleetContext`, a mapping
    of its fields, or None: one vehicle ``uav1`` at the origin, no geofence).

    ``area``: the polygon ``[[x, y], ...]`` [m] the operator selected ("survey this polygon"); ``vehicles``: the
    selected vehicles, for a sentence that names none (default: all); ``endpoint``: the chat endpoint for free text
    (default: the environment's, :meth:`LlmEndpoint.from_env`).

    Raises :class:`MissionRequestError` with the reason: a malformed request, an unsafe one (outside the geofence,
    below ground or the minimum altitude, too many waypoints), an unknown vehicle, or free text with no chat
    endpoint configured.
    """
    ctx = FleetContext.of(fleet)
    try:
        data = request_to_data(text, ctx, selection=vehicles)
    except GrammarMiss:
        data = propose_mission(text, ctx, endpoint)
    return mission_from_data(data, ctx, area=area, vehicles=vehicles)
