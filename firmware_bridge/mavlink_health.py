"""The MAVLink link's health as an operator sees it: counters by what went wrong, ``mavlink/stats`` once a
window, and a rate-limited WARNING while garbage arrives.

The link only counts (``MavlinkCounters``); this module turns the counts into the recorded ``mavlink/stats``
message (window counts and running totals, like ``can/stats`` for the CAN bus) and into one log line per
warning window that names how much garbage came and of which kind, so a spewing autopilot link is seen in
``rover run``'s output and in the trial's recording. Pure: the link asks at each poll with its clock's time.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from logs.clock import NS_PER_S
from logs.topics import stamp

STATS_WINDOW_NS = NS_PER_S
WARNING_WINDOW_NS = 5 * NS_PER_S


@dataclass
class MavlinkCounters:
    """Running counts of the link. ``bad_frames`` = ``bad_crc + bad_header + truncated``; ``bad_bytes`` is
    every byte skipped, ``noise_bytes`` (outside any frame) included, each byte once."""

    rx_frames: int = 0  # frames decoded, ``unknown_frames`` included
    unknown_frames: int = 0  # well-formed, of an id this dialect does not decode (recorded, not garbage)
    bad_frames: int = 0
    bad_bytes: int = 0
    bad_crc: int = 0  # a whole frame whose checksum is wrong
    bad_header: int = 0  # a start marker followed by a header no frame has (flags, length)
    noise_bytes: int = 0  # bytes between frames that start no frame at all
    truncated: int = 0  # a frame cut short: a datagram ended inside it, or its rest was dropped
    dropped_bytes: int = 0  # received over the receive budget and never parsed (a flood)
    tx_frames: int = 0
    tx_errors: int = 0
    goals_accepted: int = 0
    stops_accepted: int = 0  # emergency stops (disarm / flight termination) taken and acknowledged
    commands_rejected: int = 0  # addressed to us but not a goal we can take (answered with the reason)
    signature_rejected: int = 0  # unsigned, replayed or wrongly signed commands (signing on)
    scans: int = (
        0  # OBSTACLE_DISTANCE messages read as range scans (a lidar's, firmware_bridge.obstacle_scan)
    )
    scans_rejected: int = 0  # OBSTACLE_DISTANCE messages that could not be read as a scan (counted, logged)
    beams: int = 0  # DISTANCE_SENSOR readings of obstacle rangefinders (firmware_bridge.distance_sensor)
    beams_rejected: int = 0  # DISTANCE_SENSOR messages that could not be read (counted, logged)
    beams_unused: int = 0  # DISTANCE_SENSOR of sensors looking up or down: not obstacle sensors
    # The mission protocol (firmware_bridge.mavlink_mission), on the link the ground station used:
    mission_messages: int = 0  # mission messages addressed to us
    missions_accepted: int = 0  # uploads completed (MISSION_ACK ACCEPTED after the last item)
    missions_cleared: int = 0  # MISSION_CLEAR_ALL and empty uploads taken
    mission_downloads: int = 0  # downloads completed
    mission_refused: int = 0  # refusals answered (MISSION_ACK error or STATUSTEXT), each logged with why
    mission_out_of_sequence: int = 0  # upload items dropped: duplicates, items after a gap (re-asked)
    mission_resends: int = 0  # requests (download: counts or items) sent again, after a timeout or above
    mission_timeouts: int = 0  # transfers abandoned when their retries ran out (the mission unchanged)

    @property
    def missions_heard(self) -> bool:
        """Any mission message addressed to us has come."""
        return self.mission_messages > 0

    @property
    def rangefinders_heard(self) -> bool:
        """Any DISTANCE_SENSOR has come, read or not."""
        return self.beams + self.beams_rejected + self.beams_unused > 0

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


_WINDOWED = (
    "rx_frames",
    "unknown_frames",
    "bad_frames",
    "bad_bytes",
    "bad_crc",
    "bad_header",
    "noise_bytes",
    "truncated",
    "signature_rejected",
    "dropped_bytes",
    "scans",
    "scans_rejected",
)
# Windowed too, but in mavlink/stats only once a DISTANCE_SENSOR has come: a link without rangefinders
# records what it did before they were read.
_RANGEFINDER_WINDOWED = ("beams", "beams_rejected", "beams_unused")
# Likewise once a mission message has come: a link no ground station sent a mission records as before.
_MISSION_WINDOWED = (
    "mission_messages",
    "missions_accepted",
    "missions_cleared",
    "mission_downloads",
    "mission_refused",
    "mission_out_of_sequence",
    "mission_resends",
    "mission_timeouts",
)
_TOTALS = ("rx_frames", "bad_frames", "bad_bytes", "dropped_bytes")
_REASONS = (
    ("bad_crc", "bad CRC"),
    ("bad_header", "bad header"),
    ("truncated", "truncated"),
)


class _Window:
    """The windowed counters' growth since the window began."""

    def __init__(self, start_ns: int, counters: MavlinkCounters) -> None:
        self.start_ns = start_ns
        self._base = _snapshot(counters)

    def close(self, now_ns: int, counters: MavlinkCounters) -> dict[str, int]:
        now = _snapshot(counters)
        growth = {name: now[name] - self._base[name] for name in now}
        self.start_ns = now_ns
        self._base = now
        return growth


def _snapshot(counters: MavlinkCounters) -> dict[str, int]:
    return {
        name: int(getattr(counters, name)) for name in _WINDOWED + _RANGEFINDER_WINDOWED + _MISSION_WINDOWED
    }


def describe_garbage(growth: dict[str, int], window_s: float, link: str = "autopilot") -> str | None:
    """One line naming the garbage and drops in ``growth``; None when there were none.

    Frames of unknown id are named only beside garbage: a real autopilot sends messages of its own dialect
    (ArduPilot's AHRS2, EKF_STATUS_REPORT...) that this link records without decoding, which is no fault.
    """
    bad, skipped = growth["bad_frames"], growth["bad_bytes"]
    dropped, refused = growth["dropped_bytes"], growth["signature_rejected"]
    if skipped == 0 and dropped == 0 and refused == 0:
        return None
    parts: list[str] = []
    if bad:
        reasons = ", ".join(f"{label} {growth[key]}" for key, label in _REASONS if growth[key])
        parts.append(f"{bad} bad frames ({reasons})")
    if skipped:
        parts.append(f"{skipped} bytes skipped ({growth['noise_bytes']} of them noise between frames)")
    if refused:
        parts.append(f"{refused} commands refused by the signing check")
    if dropped:
        parts.append(f"{dropped} bytes dropped unread over the receive budget")
    line = f"MAVLink {link} link: {'; '.join(parts)} in the last {window_s:.1f} s"
    if growth["unknown_frames"]:
        line += f" ({growth['unknown_frames']} frames of unknown id beside them)"
    return line


@dataclass(frozen=True)
class HealthReport:
    """What one poll should publish (``mavlink/stats``) and log (a WARNING); either may be None."""

    stats: dict[str, Any] | None
    warning: str | None


# What almost every poll gets (no window closes): one shared instance, it is frozen.
_NOTHING_DUE = HealthReport(None, None)


class MavlinkHealth:
    """Closes a stats window every ``stats_window_ns`` and a warning window every ``warning_window_ns`` of
    the link's clock, at the first poll at or after each one's end (``window_s`` is the real length).

    ``link`` names the link in both (``autopilot``, ``ground_station``)."""

    def __init__(
        self,
        start_ns: int,
        counters: MavlinkCounters,
        link: str = "autopilot",
        *,
        stats_window_ns: int = STATS_WINDOW_NS,
        warning_window_ns: int = WARNING_WINDOW_NS,
    ) -> None:
        self._link = link
        self._stats_window_ns = stats_window_ns
        self._warning_window_ns = warning_window_ns
        self._stats = _Window(start_ns, counters)
        self._warning = _Window(start_ns, counters)
        # When the next window closes: before it, ``report`` has nothing to say (the link skips the call).
        self.next_close_ns = self._earliest_close_ns()

    def _earliest_close_ns(self) -> int:
        return min(
            self._stats.start_ns + self._stats_window_ns, self._warning.start_ns + self._warning_window_ns
        )

    def report(self, now_ns: int, counters: MavlinkCounters) -> HealthReport:
        if now_ns < self.next_close_ns:
            # The link asks at every poll (100 a second); a window closes at most once a second.
            return _NOTHING_DUE
        stats = None
        if now_ns - self._stats.start_ns >= self._stats_window_ns:
            window_s = (now_ns - self._stats.start_ns) / NS_PER_S
            growth = self._stats.close(now_ns, counters)
            if not counters.rangefinders_heard:
                for name in _RANGEFINDER_WINDOWED:
                    del growth[name]
            if not counters.missions_heard:
                for name in _MISSION_WINDOWED:
                    del growth[name]
            stats = {"timestamp": stamp(now_ns), "link": self._link, "window_s": window_s, **growth}
            stats.update({f"{name}_total": int(getattr(counters, name)) for name in _TOTALS})
        warning = None
        if now_ns - self._warning.start_ns >= self._warning_window_ns:
            window_s = (now_ns - self._warning.start_ns) / NS_PER_S
            warning = describe_garbage(self._warning.close(now_ns, counters), window_s, self._link)
        self.next_close_ns = self._earliest_close_ns()
        return HealthReport(stats, warning)
