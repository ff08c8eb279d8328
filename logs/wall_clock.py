"""When a real-time recording happened: one reading of the wall clock against the recording's own clock.

Recordings stamp every message with the run's clock (the OS monotonic clock on the rover, simulated time in
lockstep), which has no date. ``rover run`` reads the wall clock once, when its recording opens, and keeps
the pair in the ``wall_clock`` metadata record; a tool that needs dates (``rover can export``'s .asc / .trc
headers) maps a log time to UTC with it. Lockstep trials have no such record: simulated time has no date.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from datetime import UTC, datetime

from logs.clock import NS_PER_S, Clock

logger = logging.getLogger(__name__)

WALL_CLOCK_METADATA = "wall_clock"


@dataclass(frozen=True)
class WallClockAnchor:
    """The wall clock (Unix ns, UTC) and the recording's clock (ns) read at the same moment."""

    unix_ns: int
    clock_ns: int

    def unix_ns_at(self, log_time_ns: int) -> int:
        """The wall-clock time (Unix ns) of a log time, assuming both clocks ran at the same rate since."""
        return self.unix_ns + (log_time_ns - self.clock_ns)

    def as_metadata(self) -> dict[str, str]:
        utc = datetime.fromtimestamp(self.unix_ns / NS_PER_S, UTC).isoformat(timespec="microseconds")
        return {"unix_ns": str(self.unix_ns), "clock_ns": str(self.clock_ns), "utc": utc}

    @classmethod
    def from_metadata(cls, data: Mapping[str, str]) -> WallClockAnchor | None:
        """The anchor a ``wall_clock`` record holds; None (logged) when it is malformed."""
        try:
            return cls(int(data["unix_ns"]), int(data["clock_ns"]))
        except (KeyError, TypeError, ValueError) as err:
            logger.warning("the recording's %s metadata is unusable (%r): no dates", WALL_CLOCK_METADATA, err)
            return None


def take_anchor(clock: Clock, wall_ns: Callable[[], int]) -> WallClockAnchor:
    """Read ``wall_ns`` (e.g. ``time.time_ns``) between two readings of ``clock``; their midpoint is its
    match, so the pair is off by at most half the few microseconds the three reads take."""
    before = clock.now_ns()
    unix_ns = wall_ns()
    after = clock.now_ns()
    return WallClockAnchor(unix_ns, before + (after - before) // 2)
