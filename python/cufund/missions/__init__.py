"""The vehicle command layer: commands as data, the commander state machine, its event log (shared by the MAVLink
vehicle endpoint, the web ground station and scripted scenarios)."""

from .commander import Commander
from .commands import (
    ACK_RESULTS,
    COMMANDS,
    Command,
    CommandAck,
    MissionItem,
    parse_command,
)
from .events import EventLog
from .mission_request import MissionRequestError, parse_mission
from .params import PX4_NAMES, CommanderParams

__all__ = [
    "ACK_RESULTS",
    "COMMANDS",
    "PX4_NAMES",
    "Command",
    "CommandAck",
    "Commander",
    "CommanderParams",
    "EventLog",
    "MissionItem",
    "MissionRequestError",
    "parse_command",
    "parse_mission",
]
