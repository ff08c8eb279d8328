"""A swapped-in controller DBC (``[vesc] dbc``) attached to a recording, so the frames can be read later.

Every recording made with a team's own DBC carries the file as read (``vesc.dbc``): the lockstep trial's,
the real-time peer's and ``rover run``'s. Its metadata names the path; this keeps what the file said,
which a path on another machine, or a file edited since, no longer does. The shipped DBC is not attached:
it is the code's.
"""

from __future__ import annotations

import logging

from firmware_bridge.vesc import VescProfile
from logs.recorder import McapRecorder

ATTACHMENT_NAME = "vesc.dbc"
_log = logging.getLogger(__name__)


def attach_vesc_dbc(recorder: McapRecorder, profile: VescProfile) -> None:
    dbc_path = profile.dbc_path
    if dbc_path is None:
        return
    try:
        data = dbc_path.read_bytes()
    except OSError as err:  # it loaded when the config did; gone since: the metadata still names it
        _log.warning("cannot attach the VESC DBC %s to the recording: %s", dbc_path, err)
        return
    recorder.add_attachment(ATTACHMENT_NAME, "text/plain", data, 0)
