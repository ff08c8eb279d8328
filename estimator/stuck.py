"""Wheels spinning in place: odometry travel that GPS travel does not confirm.

A rover pushing against a rock or dug into mud turns its wheels at full speed while going nowhere. The
odometry scale state absorbs *partial* slip (sand, mud: a few to tens of percent); it cannot absorb
"wheels at 1 m/s, ground speed 0". Over a sliding window we compare how far GPS moved (the mean of the
window's later fixes minus the mean of its earlier ones, which averages the fix noise down) with how far
the wheels carried the rover, measured the same way on the odometry's dead-reckoned track (each rolled
distance along the heading at the time): so a curve or a U-turn, whose GPS chord is shorter than the
distance rolled, is not taken for spinning. When GPS shows less than half of it, by more than three
GPS-noise sigmas, the wheels are declared spinning and the front end leaves their speed out, so GPS (not
odometry) is believed.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from itertools import accumulate

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
        # Odometry steps, oldest first, as parallel deques: time (ns), |distance| rolled since the previous
        # sample (m), and that step along the heading (east, north m). One deque per field so that the sums
        # over the window (~200 steps, taken on every fix) run over the values in C, with no per-step call.
        self._step_t: deque[int] = deque()
        self._step_rolled: deque[float] = deque()
        self._step_east: deque[float] = deque()
        self._step_north: deque[float] = deque()
        self.spinning = False
        self.shortfall_m = 0.0  # odometry travel GPS did not confirm, at the last judgement (m)

    def add_odometry(self, t_ns: int, distance_m: float, heading_rad: float = 0.0) -> None:
        """Distance (m, signed: negative reversing) the wheels rolled up to ``t_ns`` while heading
        ``heading_rad`` (ENU). A heading off by a constant does not matter: only the track's shape does.
        Steps come in time order (the estimator adds one per wheel sample newer than the last)."""
        self._step_t.append(t_ns)
        self._step_rolled.append(abs(distance_m))
        self._step_east.append(distance_m * math.cos(heading_rad))
        self._step_north.append(distance_m * math.sin(heading_rad))

    def on_fix(self, t_ns: int, x_m: float, y_m: float, std_m: float) -> bool:
        """Offer a raw GPS fix (ENU m); returns whether the wheels are judged to be spinning now."""
        self._fixes.append((t_ns, x_m, y_m, std_m))
        start = t_ns - self._window_ns
        while self._fixes and self._fixes[0][0] < start:
            self._fixes.popleft()
        step_t, first_fix_ns = self._step_t, self._fixes[0][0]
        while step_t and step_t[0] <= first_fix_ns:
            step_t.popleft()
            self._step_rolled.popleft()
            self._step_east.popleft()
            self._step_north.popleft()
        if len(self._fixes) < 4:
            return self.spinning
        rolled = sum(self._step_rolled)  # from 0, in step order: the additions a walk along them makes
        if rolled < self._min_distance_m:
            self.spinning = False
            return False
        fixes = list(self._fixes)
        half = len(fixes) // 2
        early, late = fixes[:half], fixes[half:]
        moved = math.dist(_mean_xy(late), _mean_xy(early))
        # The same measure on the odometry's track, sampled at the fixes' times.
        track = self._track_at([f[0] for f in fixes])
        expected = math.dist(_mean_xy(track[half:]), _mean_xy(track[:half]))
        span_s = (_mean_t(late) - _mean_t(early)) / max(fixes[-1][0] - fixes[0][0], 1)
        std = max([f[3] for f in fixes])
        noise = _NOISE_SIGMAS * std * math.sqrt(1.0 / len(early) + 1.0 / len(late))
        # Scaled back to the whole window: how far the odometry ran ahead of the ground.
        self.shortfall_m = max(expected - moved, 0.0) / max(span_s, 1e-9)
        if self.spinning:
            self.spinning = moved < _RECOVER_SHARE * expected
        else:
            self.spinning = moved < _SPIN_SHARE * expected and expected - moved > noise
        return self.spinning

    def _track_at(self, times: list[int]) -> list[tuple[int, float, float, float]]:
        """The dead-reckoned position (from the window's first odometry step) at each of ``times``,
        shaped like fixes for ``_mean_xy``.

        The running sums come from ``itertools.accumulate`` (0.0, then each step added in order: the
        additions a walk along the steps makes, in C rather than a Python loop over a few hundred steps
        per fix), and each time takes the sums of the steps up to it (steps arrive in time order).
        """
        step_times = list(self._step_t)
        easts = list(accumulate(self._step_east, initial=0.0))
        norths = list(accumulate(self._step_north, initial=0.0))
        positions = []
        for t in times:
            taken = bisect.bisect_right(step_times, t)
            positions.append((t, easts[taken], norths[taken], 0.0))
        return positions


def _mean_xy(fixes: list[tuple[int, float, float, float]]) -> tuple[float, float]:
    return sum([f[1] for f in fixes]) / len(fixes), sum([f[2] for f in fixes]) / len(fixes)


def _mean_t(fixes: list[tuple[int, float, float, float]]) -> float:
    return sum([f[0] for f in fixes]) / len(fixes)
