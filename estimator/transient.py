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
        # The samples within the window, oldest first, as two parallel deques (time ns, speed m/s): the
        # spread is max and min straight over the speeds in C, every sample, with no per-item call.
        self._times: deque[int] = deque()
        self._speeds: deque[float] = deque()
        self._unsettled_until_ns: int | None = None

    def add(self, t_ns: int, speed_mps: float) -> None:
        """One odometry speed sample (m/s) at ``t_ns``; samples at or before the last one are ignored."""
        times, speeds = self._times, self._speeds
        if times and t_ns <= times[-1]:
            return
        times.append(t_ns)
        speeds.append(speed_mps)
        while t_ns - times[0] > self._window_ns:
            times.popleft()
            speeds.popleft()
        if max(speeds) - min(speeds) <= self._limit_mps:
            return
        self._unsettled_until_ns = t_ns + self._settle_ns

    def unsettled(self, t_ns: int) -> bool:
        """Whether the wheels changed speed quickly within the last ``settle_s``."""
        return self._unsettled_until_ns is not None and t_ns < self._unsettled_until_ns
