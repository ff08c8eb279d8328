"""The ground station is told the failsafes, their clearing and the mode changes as STATUSTEXT: each
such ``safety/events`` message goes out once, in order, whole once its chunks are joined, at its severity."""

from __future__ import annotations

import base64
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink2

from logs.reader import read_messages
from logs.topics import MAVLINK_RAW, SAFETY_EVENTS
from navigator.event_texts import mav_severity, status_text, told


def _texts_sent(mcap: Path) -> list[tuple[str, int]]:
    """The STATUSTEXTs the rover sent, chunks joined (MAVLink 2 ``id`` / ``chunk_seq``), with severity."""
    parser = mavlink2.MAVLink(None)
    texts: list[tuple[str, int]] = []
    open_ids: dict[int, int] = {}  # id -> index in texts
    for entry in read_messages(mcap, topics=[MAVLINK_RAW]):
        raw = entry.message
        if raw["direction"] != "tx" or raw["name"] != "STATUSTEXT":
            continue
        msg = parser.parse_buffer(base64.b64decode(raw["data"]))[0]
        text = msg.text.rstrip("\x00") if isinstance(msg.text, str) else msg.text.decode().rstrip("\x00")
        if msg.id and msg.id in open_ids and msg.chunk_seq > 0:
            joined, severity = texts[open_ids[msg.id]]
            texts[open_ids[msg.id]] = (joined + text, severity)
            continue
        if msg.id:
            open_ids[msg.id] = len(texts)
        texts.append((text, msg.severity))
    return texts


def test_every_told_event_reaches_the_ground_station_once_in_order(trials: dict[str, Path]) -> None:
    mcap = trials["small_rocky_bus_off"]
    events = [entry.message for entry in read_messages(mcap, topics=[SAFETY_EVENTS])]
    expected = [
        (status_text(e["kind"], e["detail"]), mav_severity(e["severity"])) for e in events if told(e["kind"])
    ]
    assert any(e["kind"] == "failsafe.can_bus_off" for e in events)  # a failsafe is among them
    assert any(not told(e["kind"]) for e in events)  # and something that is not told (a replan, a goal)
    assert _texts_sent(mcap) == expected


def test_only_failsafes_clearing_modes_and_start_up_checks_are_told() -> None:
    assert told("failsafe.no_progress") and told("cleared.gps_lost") and told("mode")
    assert told("startup_checks") and told("learned.terrain")
    assert told("recovery.backing_out") and told("recovery.replanned") and told("recovery.gave_up")
    assert not told("guidance.driving") and not told("goal") and not told("mission")
    assert mav_severity("error") == mavlink2.MAV_SEVERITY_ERROR
    assert mav_severity("nonsense") == mavlink2.MAV_SEVERITY_WARNING
