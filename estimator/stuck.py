"""Wheels spinning in place: odometry travel that GPS travel does not confirm.

A rover pushing against a rock or dug into mud turns its wheels at full speed while going nowhere. The
odometry scale state absorbs *partial* slip (sand, mud: a few to tens of percent); it cannot absorb
"wheels at 1 m/s, ground speed 0". Over a sliding window we compare the distance GPS moved (the mean of
the window's later fixes minus the mean of its earlier ones, which averages the fix noise down) with the
distance the wheels rolled. When GPS shows less than half of it, by more than three GPS-noise sigmas, the
wheels are declared spinning and the front end leaves their speed out, so GPS (not odometry) is believed.
"""

from __future__ import annotations

import math
from collections import deque

# Declared spinning below this share of the odometry distance; trusted again above the second share
# (hysteresis, so a rover creeping out of a hole does not flicker between the two).
_SPIN_SHARE = 0.5
_RECOVER_SHARE = 0.7
_NOISE_SIGMAS = 3.0


class StuckDetector:
    """Compares GPS and odometry travel over a sliding window.

    Parameters
    ----------
    window_s : float
        Length of the comparison window, seconds.
    min_distance_m : float
        Odometry travel (m) over the window below which nothing is judged (standing still is not stuck).
    """

    def __init__(self, window_s: float, min_distance_m: float) -> None:
        self._window_ns = round(window_s * 1e9)
        self._min_distance_m = min_distance_m
        self._fixes: deque[tuple[int, float, float, float]] = deque()  # t_ns, x, y, std
        self._odometry: deque[tuple[int, float]] = deque()  # t_ns, |distance| rolled since previous
        self.spinning = False
        self.shortfall_m = 0.0  # odometry travel GPS did not confirm, at the last judgement (m)

    def add_odometry(self, t_ns: int, distance_m: float) -> None:
        """Distance (m, unsigned) the wheels rolled up to ``t_ns``."""
        self._odometry.append((t_ns, abs(distance_m)))

    def on_fix(self, t_ns: int, x_m: float, y_m: float, std_m: float) -> bool:
        """Offer a raw GPS fix (ENU m); returns whether the wheels are judged to be spinning now."""
        self._fixes.append((t_ns, x_m, y_m, std_m))
        start = t_ns - self._window_ns
        while self._fixes and self._fixes[0][0] < start:
            self._fixes.popleft()
        while self._odometry and self._odometry[0][0] <= self._fixes[0][0]:
            self._odometry.popleft()
        if len(self._fixes) < 4:
            return self.spinning
        rolled = sum(d for _, d in self._odometry)
        if rolled < self._min_distance_m:
            self.spinning = False
            return False
        half = len(self._fixes) // 2
        early, late = list(self._fixes)[:half], list(self._fixes)[half:]
        moved = math.dist(_mean_xy(late), _mean_xy(early))
        # Odometry rolled over the whole window, GPS "moved" between the two halves' mean times.
        span_s = (_mean_t(late) - _mean_t(early)) / max(self._fixes[-1][0] - self._fixes[0][0], 1)
        expected = rolled * span_s
        std = max(f[3] for f in self._fixes)
        noise = _NOISE_SIGMAS * std * math.sqrt(1.0 / len(early) + 1.0 / len(late))
        # Scaled back to the whole window: how far the odometry ran ahead of the ground.
        self.shortfall_m = max(expected - moved, 0.0) / max(span_s, 1e-9)
        if self.spinning:
            self.spinning = moved < _RECOVER_SHARE * expected
        else:
            self.spinning = moved < _SPIN_SHARE * expected and expected - moved > noise
        return self.spinning


def _mean_xy(fixes: list[tuple[int, float, float, float]]) -> tuple[float, float]:
    return sum(f[1] for f in fixes) / len(fixes), sum(f[2] for f in fixes) / len(fixes)


def _mean_t(fixes: list[tuple[int, float, float, float]]) -> float:
    return sum(f[0] for f in fixes) / len(fixes)
