"""VESC status frames from controller ids the config does not name: the mark of wrong ``[vesc]
controller_ids``.

On a first day the usual mistake is ids that do not match the controllers' own (set in VESC Tool). The
link then reports every configured controller silent, which is true but sends a person looking for a
wiring fault while the controllers are talking on the bus under other ids. A frame with a VESC status
command from such an id is named once per id, with the fix.
"""

from __future__ import annotations

from collections.abc import Sequence

from firmware_bridge.vesc_dbc import VESC_MESSAGES

# The command byte (id >> 8) of every message a controller sends on its own.
STATUS_COMMAND_IDS = frozenset(m.command_id for m in VESC_MESSAGES if m.from_controller)


class ForeignControllers:
    """Remembers the controller ids outside ``configured`` heard sending VESC status frames."""

    def __init__(self, configured: Sequence[int]) -> None:
        self._configured = tuple(configured)
        self.heard: set[int] = set()

    def note(self, arbitration_id: int, is_extended_id: bool) -> str | None:
        """A warning line the first time an id outside the config sends a VESC status frame; else None.
        ``arbitration_id`` is a frame the codec refused as not one of the configured controllers'."""
        command, controller_id = arbitration_id >> 8, arbitration_id & 0xFF
        if not is_extended_id or command not in STATUS_COMMAND_IDS:
            return None
        if controller_id in self._configured or controller_id in self.heard:
            return None
        self.heard.add(controller_id)
        return (
            f"CAN: VESC status frames from controller id {controller_id}, which [vesc] controller_ids "
            f"{list(self._configured)} does not name: if it is one of this rover's six, put its id there "
            "(in wheel order: left front, left middle, left rear, right front, right middle, right rear)"
        )
