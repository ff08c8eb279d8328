"""Says when a range sensor that was feeding the scan tracker goes quiet, and when it is back.

A lidar whose driver died leaves the rover blind to every obstacle missing from its map, with nothing else
to show for it: the tracker's tracks just age out. Once scans have come, a gap of more than ``quiet_s``
(or three of the sensor's own periods, for a slow one) is a ``perception_lost`` warning on
``safety/events``; the next scan is ``perception_back``. It warns and does not stop the rover: the map's
obstacles and the other failsafes still hold, and a rover may run without a lidar at all.

Rangefinders are watched one by one (``RangefinderWatch``), by their DISTANCE_SENSOR id: a ring of five
whose front sonar died still hears four, and the rover is blind straight ahead. A reading the link refused
does not count as heard; one that saw nothing within range does (the sensor is alive, the way is clear).
"""

from __future__ import annotations

from collections.abc import Callable

DEFAULT_QUIET_S = 1.0


class ScanWatch:
    """One sensor's silence. ``what`` names its messages in the events (plural), ``one`` a single one."""

    def __init__(
        self,
        event: Callable[[str, str, str], None],
        quiet_s: float = DEFAULT_QUIET_S,
        *,
        what: str = "OBSTACLE_DISTANCE scans",
        one: str = "OBSTACLE_DISTANCE scan",
        blind: str = "obstacles missing from the map are not seen",
    ) -> None:
        self._event = event
        self._quiet_ns = round(quiet_s * 1e9)
        self._what, self._one, self._blind = what, one, blind
        self.last_ns: int | None = None  # the last scan's time (None: no scan yet, nothing to watch)
        self._period_ns = 0
        self.lost = False

    def scan(self, t_ns: int) -> None:
        """A scan came at ``t_ns``."""
        if self.lost:
            gap_s = (t_ns - (self.last_ns or t_ns)) * 1e-9
            self._event("perception_back", "info", f"{self._what} again after {gap_s:.1f} s")
            self.lost = False
        elif self.last_ns is not None:
            self._period_ns = max(0, t_ns - self.last_ns)
        self.last_ns = t_ns

    def check(self, now_ns: int) -> None:
        """Warn once if the scans have stopped by ``now_ns``; call only while ``last_ns`` is set."""
        last = self.last_ns
        if last is None or self.lost:
            return
        quiet_ns = max(self._quiet_ns, 3 * self._period_ns)
        if now_ns - last > quiet_ns:
            self.lost = True
            self._event(
                "perception_lost",
                "warning",
                f"no {self._one} for {(now_ns - last) * 1e-9:.1f} s (they came every "
                f"{self._period_ns * 1e-9:.2f} s): {self._blind}",
            )


class RangefinderWatch:
    """A ``ScanWatch`` per rangefinder id, from its first reading on."""

    def __init__(self, event: Callable[[str, str, str], None], quiet_s: float = DEFAULT_QUIET_S) -> None:
        self._event = event
        self._quiet_s = quiet_s
        self.watches: dict[int, ScanWatch] = {}

    def heard(self, sensor_id: int, t_ns: int) -> None:
        watch = self.watches.get(sensor_id)
        if watch is None:
            watch = self.watches[sensor_id] = ScanWatch(
                self._event,
                self._quiet_s,
                what=f"DISTANCE_SENSOR readings from rangefinder {sensor_id}",
                one=f"usable DISTANCE_SENSOR reading from rangefinder {sensor_id}",
                blind="obstacles missing from the map are not seen where it looks",
            )
        watch.scan(t_ns)

    def check(self, now_ns: int) -> None:
        for watch in self.watches.values():
            watch.check(now_ns)
