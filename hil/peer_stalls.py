"""Stalls of the real-time peer: steps so late that the simulated world dropped time.

``hil.peer.RealtimePeer`` integrates the time from its previous step's deadline to this one's (the
scheduler's grid, which skips the ticks a late step overran, so it keeps to real time), but at most
``cap_ns`` of it in one step (a longer jump would move the rover through walls); whatever is beyond the
cap is simulated time that never happened. A stall means the simulated world stood still while the
rover's clock ran on: no status frames, no IMU, no GPS, and the simulated controllers' command timeout
measured on a frozen world.
Each stall is counted here and recorded on the peer's ``log`` topic (name ``hil.peer``) in the words of
``stall_message``, which ``parse_stall_message`` reads back (``hil.soak_report``), so a soak can say when
the peer stalled even if the peer was killed before writing its summary.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

_NS_PER_MS = 1_000_000
_STALL = re.compile(
    r"peer stalled: (\d+(?:\.\d+)?) ms between steps, (\d+(?:\.\d+)?) ms of simulated time dropped"
)


@dataclass
class PeerStalls:
    """The peer's step gaps: how many stalled, the simulated time dropped, the longest gap (ns)."""

    cap_ns: int  # the most simulated time one step integrates
    stalls: int = 0
    dropped_ns: int = 0
    longest_gap_ns: int = 0

    def note(self, gap_ns: int) -> int:
        """Take the time since the previous step's deadline; returns the simulated time to integrate now."""
        self.longest_gap_ns = max(self.longest_gap_ns, gap_ns)
        if gap_ns <= self.cap_ns:
            return gap_ns
        self.stalls += 1
        self.dropped_ns += gap_ns - self.cap_ns
        return self.cap_ns

    def summary(self) -> dict[str, float]:
        return {
            "stalls": self.stalls,
            "dropped_sim_ms": self.dropped_ns / _NS_PER_MS,
            "longest_step_gap_ms": self.longest_gap_ns / _NS_PER_MS,
        }

    def describe(self) -> str:
        return (
            f"{self.stalls} stall(s) (steps more than {self.cap_ns / _NS_PER_MS:g} ms apart), "
            f"{self.dropped_ns / _NS_PER_MS:.0f} ms of simulated time dropped, "
            f"longest gap between steps {self.longest_gap_ns / _NS_PER_MS:.0f} ms"
        )


def stall_message(gap_ns: int, dropped_ns: int) -> str:
    return (
        f"peer stalled: {gap_ns / _NS_PER_MS:.1f} ms between steps, "
        f"{dropped_ns / _NS_PER_MS:.1f} ms of simulated time dropped"
    )


def parse_stall_message(text: str) -> tuple[float, float] | None:
    """(gap ms, dropped ms) of a ``stall_message``, or None for any other text."""
    match = _STALL.fullmatch(text)
    return None if match is None else (float(match.group(1)), float(match.group(2)))
