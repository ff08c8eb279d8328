"""The start-up checks before the rover may drive, judged every tick, and their reporting until they pass.

The checks: the autopilot's heartbeat heard, every wheel controller heard, and the estimate healthy for
``SETTLE_NS`` without a break. Guidance holds its goal until they pass (``navigator.route_guidance``); the
onboard stack (``navigator.onboard``) judges them each tick and, until they first pass, reports them as
``startup_checks`` events (and lines for the console, ``rover run``).
"""

from __future__ import annotations

from collections.abc import Callable

from estimator.pose import PoseEstimate
from logs.clock import NS_PER_S
from navigator.safety import EventSink

# Readiness check before driving: the estimate must stay healthy this long (several GPS fixes averaged),
# so the first plan does not start from one noisy fix.
SETTLE_NS = 2 * NS_PER_S
# The last start-up check, worded once.
_NOT_SETTLED = f"estimate healthy for < {SETTLE_NS / NS_PER_S:g} s"


class StartUpChecks:
    """The start-up checks' verdict (``judge``), what still fails (``not_ready``) and their reports.

    ``event`` publishes a ``safety/events`` message; ``report_line`` (optional): each ``startup_checks``
    event as a line for the console too (the onboard stack's ``start_up_report``).
    """

    def __init__(self, event: EventSink, report_line: Callable[[str], None] | None = None) -> None:
        self._event = event
        self._report_line = report_line
        self._healthy_since_ns: int | None = None
        self.not_ready = "not yet judged"  # the checks failing at the last judge ("" once all pass)
        self._reported: str | None = None  # the pending checks the last startup_checks event named
        self.passed = False  # they have passed once (reported; not reported again)

    def judge(self, now: int, pose: PoseEstimate | None, heartbeat_heard: bool, wheels_heard: bool) -> bool:
        """Start-up checks before driving: autopilot heard, every wheel controller heard, estimate settled."""
        healthy = pose is not None and pose.healthy
        if not healthy:
            self._healthy_since_ns = None
        elif self._healthy_since_ns is None:
            self._healthy_since_ns = now
        settled = self._healthy_since_ns is not None and now - self._healthy_since_ns >= SETTLE_NS
        if settled and heartbeat_heard and wheels_heard:
            # Every tick once driving: all checks pass (settled implies a healthy pose), no list to join.
            self.not_ready = ""
            return True
        missing = []  # in this order
        if not heartbeat_heard:
            missing.append("no autopilot heartbeat")
        if not wheels_heard:
            missing.append("wheel controllers not all heard")
        if pose is None:
            missing.append("no estimate yet")
        elif not healthy:
            missing.append("estimate unhealthy")
        elif not settled:
            missing.append(_NOT_SETTLED)
        self.not_ready = ", ".join(missing)
        return not missing

    def report(self, ready: bool) -> None:
        """Until the start-up checks first pass: a ``startup_checks`` event naming the pending ones on the
        first tick and whenever they change, then one when all have passed. Without it nothing said why a
        rover without a goal waited (the supervisor starts in IDLE: no mode change to report), nor when it
        became ready; after that, a check failing again shows as guidance's WAITING_ESTIMATE cause. The tick
        calls it only until they have passed."""
        if ready:
            self.passed = True
            settle_s = SETTLE_NS / NS_PER_S
            detail = (
                f"passed: autopilot heard, all wheel controllers heard, estimate healthy for {settle_s:g} s"
            )
            self._event("startup_checks", "info", detail)
            self._say(f"start-up checks {detail}; driving allowed")
        elif self.not_ready != self._reported:
            self._reported = self.not_ready
            self._event("startup_checks", "info", f"pending: {self.not_ready}")
            self._say(f"start-up checks pending: {self.not_ready}; not driving until they pass")

    def _say(self, line: str) -> None:
        if self._report_line is not None:
            self._report_line(line)
