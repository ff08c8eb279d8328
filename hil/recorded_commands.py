"""Ground-station commands read back from a recording, as a ``CommandSource`` for a replay (``hil.replay``).

The onboard stack records each command it takes over Zenoh on ``ground/commands`` at the tick that read it
(``logs.commands.command_record``); a replay queues each record here and the stack reads it at the same
tick. ``last_contact_ns`` is the newest command's arrival: the recording does not keep the ground station's
malformed samples, which also count as contact for the ground-link failsafe
(``[safety] ground_link_timeout_s``, off by default).
"""

from __future__ import annotations

import logging
from typing import Any

from logs.commands import RoverCommand, command_from_record

_log = logging.getLogger(__name__)


class RecordedCommands:
    """Commands queued by the replay (``add``) until the stack's next ``poll``."""

    def __init__(self) -> None:
        self._pending: list[RoverCommand] = []
        self.last_contact_ns: int | None = None
        self.rejected = 0  # records that held no command (logged, skipped)

    def add(self, t_ns: int, record: dict[str, Any]) -> None:
        try:
            command = command_from_record(record)
        except ValueError as err:
            self.rejected += 1
            _log.warning("ground/commands record at %d ns skipped: %s", t_ns, err)
            return
        self._pending.append(command)
        if self.last_contact_ns is None or command.received_ns > self.last_contact_ns:
            self.last_contact_ns = command.received_ns

    def poll(self) -> list[RoverCommand]:
        taken, self._pending = self._pending, []
        return taken
