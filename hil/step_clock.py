"""The simulated sensors' clock in real time: the step's due time, as a hardware timer's tick is.

On the real clock a simulated autopilot's 50 Hz IMU schedule and the simulator's 100 Hz steps drift into
any phase (its first due time is anchored on whatever the first read said, and after a late step it
restarts from the late time); a due time a few microseconds after a step's reading then sends the IMU on
this step or the next depending on the wake-up: 10 ms of sensor jitter, and time stamps that carry the
OS's wake-up overshoot. On the step times every schedule is a multiple of the step, and a sample's time
stamp is when it was due. The real-time simulators (``hil.bench_rover``, ``hil.peer``) set ``t`` to each
step's deadline before they step; a step that wakes late still samples at its deadline.
"""

from __future__ import annotations


class StepClock:
    """A clock that reads ``t``, which its owner sets to each step's due time (ns)."""

    def __init__(self, t: int) -> None:
        self.t = t

    def now_ns(self) -> int:
        return self.t
