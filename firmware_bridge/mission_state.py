"""What the rover does with its mission: ``navigator.mission.Mission`` keeps it, the MAVLink mission server
(``firmware_bridge.mavlink_mission``) reports it as MISSION_CURRENT's ``mission_state``.

Defined here, below both (``navigator`` imports ``firmware_bridge``, never the other way round:
docs/ARCHITECTURE.md); ``navigator.mission`` exports it as its own.
"""

from __future__ import annotations

import enum


class MissionState(enum.StrEnum):
    NONE = "NONE"  # no mission
    NOT_STARTED = "NOT_STARTED"  # uploaded, not driven yet: MISSION_START or MISSION_SET_CURRENT starts it
    ACTIVE = "ACTIVE"  # driving to the current waypoint
    PAUSED = "PAUSED"  # a single goal replaced it; setting a current item drives it again
    COMPLETE = "COMPLETE"  # the last waypoint was reached
