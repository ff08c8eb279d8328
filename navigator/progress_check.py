"""Progress while pushing: how far the rover's estimated position moved over a window of seconds.

The ``stuck`` failsafe watches the estimated speed; a rover spinning its wheels at the foot of a slope it
cannot climb can keep that estimate wandering around zero by more than its threshold (GPS noise and
slipping odometry) for minutes, while it goes nowhere. This check looks at the position instead, as Nav2's
progress checker does (``required_movement_radius`` within ``movement_time_allowance``), but on means over
a couple of seconds at each end of the window, so GPS noise of half a metre neither hides a rover that
goes nowhere nor trips one that creeps on.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

# Positions are averaged per bucket of this length; each end of the window is the mean of END_BUCKETS.
BUCKET_NS = 500_000_000
END_BUCKETS = 4
# Wheels whose reported speeds average at least this (m/s) turn: a rover going nowhere so is slipping or
# dug in; below it, it is held by something, or stalled.
WHEELS_TURNING_MPS = 0.1


def mean_wheel_speed(speeds: Sequence[float]) -> float | None:
    """The mean of the wheels' reported speeds' magnitudes (the finite ones), or None with none."""
    known = [abs(v) for v in speeds if math.isfinite(v)]
    return sum(known) / len(known) if known else None


class ProgressCheck:
    """Feed it the estimated position each tick while the rover is pushed; ``reset`` when it is not."""

    def __init__(self, window_ns: int) -> None:
        # Buckets spanning the window (at least both ends' worth, so the two means never overlap).
        self._buckets_needed = max(2 * END_BUCKETS, math.ceil(window_ns / BUCKET_NS))
        self._means: deque[tuple[float, float]] = deque(maxlen=self._buckets_needed)
        self._bucket_end_ns: int | None = None
        self._sum_x = self._sum_y = 0.0
        self._count = 0

    def reset(self) -> None:
        self._means.clear()
        self._bucket_end_ns = None
        self._sum_x = self._sum_y = 0.0
        self._count = 0

    def update(self, now_ns: int, x: float, y: float) -> float | None:
        """The net movement (m) between the window's first and last seconds, on the tick a bucket closes
        once the rover has been pushed for a whole window; else None. Not finite positions are left out."""
        if not (math.isfinite(x) and math.isfinite(y)):
            return None
        closed = False
        if self._bucket_end_ns is None:
            self._bucket_end_ns = now_ns + BUCKET_NS
        elif now_ns >= self._bucket_end_ns:
            if self._count:
                self._means.append((self._sum_x / self._count, self._sum_y / self._count))
                closed = True
            self._sum_x = self._sum_y = 0.0
            self._count = 0
            self._bucket_end_ns = now_ns + BUCKET_NS
        self._sum_x += x
        self._sum_y += y
        self._count += 1
        if not closed or len(self._means) < self._buckets_needed:
            return None
        first = list(self._means)[:END_BUCKETS]
        last = list(self._means)[-END_BUCKETS:]
        dx = sum(p[0] for p in last) / END_BUCKETS - sum(p[0] for p in first) / END_BUCKETS
        dy = sum(p[1] for p in last) / END_BUCKETS - sum(p[1] for p in first) / END_BUCKETS
        return math.hypot(dx, dy)
