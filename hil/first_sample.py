"""When a simulated peer's first sample is too late to send: the one rule of the autopilot and the VESCs.

``SimWorld`` makes its peers at the world's epoch and first steps them one physics tick (10 ms) later. A
stream whose cadence counts from the epoch would send its first sample at that step, late, and its second
on the cadence right after: at 50 Hz both 10 ms apart, and the rover's 50 Hz loop takes the two in one
read (two first GPS fixes at the same time, two first motor statuses). So a first sample half a period late
or more, but less than a whole period, is taken (its noise drawn, its state read) and not sent; the next, on
the cadence, is the first sent. A first step a whole period late or more (the real-time peer's, after its
warm-up) sends there and resumes from it.
"""

from __future__ import annotations


def first_sample_withheld(due_ns: int, period_ns: int, now_ns: int) -> bool:
    """Whether a stream's first sample, due at ``due_ns`` and taken at ``now_ns``, goes unsent."""
    return due_ns + period_ns > now_ns and 2 * (now_ns - due_ns) >= period_ns
