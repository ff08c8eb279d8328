"""Which ``safety/events`` a ground station is told over MAVLink, as STATUSTEXT, and at what severity.

An operator watching QGroundControl or Mission Planner sees STATUSTEXT, not our Zenoh topics: ArduPilot
tells its failsafes there ("Failsafe: ..."), and a rover that holds on ``no_progress`` or ``gps_lost``
without a word to the ground station looks merely stopped. The failsafes, their clearing, the mode changes,
the start-up checks, what the rover learned of its ground and its recoveries when dug in go out (once per
change, as they are emitted); planning chatter (a replan, a path) does not.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

# Event kinds told, by prefix; the rest stay on safety/events and in the log.
TOLD_PREFIXES = ("failsafe.", "cleared.", "mode", "startup_checks", "learned.", "recovery.")
_SEVERITIES = {
    "error": mavlink2.MAV_SEVERITY_ERROR,
    "warning": mavlink2.MAV_SEVERITY_WARNING,
    "info": mavlink2.MAV_SEVERITY_INFO,
}


def told(kind: str) -> bool:
    return kind.startswith(TOLD_PREFIXES)


def status_text(kind: str, detail: str) -> str:
    """The STATUSTEXT for an event: its kind and detail (chunked by the link past 50 bytes)."""
    return f"{kind}: {detail}"


def mav_severity(severity: str) -> int:
    """Our event severity as MAV_SEVERITY; one we do not know reads as a warning."""
    return _SEVERITIES.get(severity, mavlink2.MAV_SEVERITY_WARNING)
