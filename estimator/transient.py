"""Wheel-speed transients: while the wheels speed up or slow down, they lead or lag the ground.

A skid-steer rover launching from standstill spins its wheels up in a fraction of a second; the body
follows a few tenths of a second later (in HIL on rocky ground the wheels read 0.77 m/s while the body
moved at 0.55 m/s, a ratio of 1.4). That ratio is the tyre's transient slip, not the terrain's steady
odometry scale, and the scale state (a slow random walk) must not learn it: one launch taught it +2.5 %,
which a later GPS dropout then integrated as 2.5 % of distance of drift. So for ``settle_s`` after the
mean wheel speed changed faster than ``accel_limit_mps2``, the scale is only *considered*.

(Inflating the odometry speed noise by the size of the change as well was tried: it helped the HIL
launch a little and cost the estimator-level dropout test, whose body follows its wheels at once.)
"""

from __future__ import annotations

from collections import deque
from operator import itemgetter


class WheelTransient:
    """Tracks how recently the mean wheel speed changed quickly.

    The change is judged over a window of ``WINDOW_S`` (the spread of the speeds seen in it), not
    sample to sample, so encoder noise (a few cm/s per sample) never looks like an acceleration.

    Parameters
    ----------
    accel_limit_mps2 : float
        Wheel-speed change rate (m/s^2) above which the wheels are in a transient.
    settle_s : float
        Time (s) after the last such change before the wheels are steady again.
    """

    WINDOW_S = 0.25

    def __init__(self, accel_limit_mps2: float, settle_s: float) -> None:
        self._window_ns = round(self.WINDOW_S * 1e9)
        self._limit_mps = accel_limit_mps2 * self.WINDOW_S
        self._settle_ns = round(settle_s * 1e9)
        self._recent: deque[tuple[int, float]] = deque()  # t_ns, speed m/s, within the window
        self._unsettled_until_ns: int | None = None

    def add(self, t_ns: int, speed_mps: float) -> None:
        """One odometry speed sample (m/s) at ``t_ns``; samples at or before the last one are ignored."""
        recent = self._recent
        if recent and t_ns <= recent[-1][0]:
            return
        recent.append((t_ns, speed_mps))
        while t_ns - recent[0][0] > self._window_ns:
            recent.popleft()
        speed_of = itemgetter(1)  # max and min over the window without a list of its speeds
        if max(map(speed_of, recent)) - min(map(speed_of, recent)) <= self._limit_mps:
            return
        self._unsettled_until_ns = t_ns + self._settle_ns

    def unsettled(self, t_ns: int) -> bool:
        """Whether the wheels changed speed quickly within the last ``settle_s``."""
        return self._unsettled_until_ns is not None and t_ns < self._unsettled_until_ns
