"""The precise wait (sleep, then spin) never returns before its deadline, on a fake and on the real clock;
the fixed-rate scheduler with it starts every tick at or after its deadline; the input poller sees a
datagram without blocking."""

from __future__ import annotations

import socket
import time

import pytest

from logs.clock import MonotonicClock
from navigator.input_wait import input_poller
from navigator.precise_wait import sleep_until, spin_until
from navigator.runtime import FixedRateScheduler

MS = 1_000_000


class SteppingClock:
    """Moves 7 us per reading (a spin makes progress) and by whatever ``sleep`` is asked, plus an
    overshoot, as a woken thread does."""

    def __init__(self, overshoot_ns: int = 0) -> None:
        self.t = 1_000 * MS
        self.overshoot_ns = overshoot_ns
        self.sleeps: list[int] = []

    def now_ns(self) -> int:
        self.t += 7_000
        return self.t

    def sleep(self, seconds: float) -> None:
        asked = round(seconds * 1e9)
        self.sleeps.append(asked)
        self.t += asked + self.overshoot_ns


@pytest.mark.parametrize("overshoot_ns", [0, 300_000, 900_000])
def test_sleep_until_sleeps_short_of_the_deadline_and_spins_onto_it(overshoot_ns: int) -> None:
    clock = SteppingClock(overshoot_ns)
    deadline = clock.t + 10 * MS
    returned = sleep_until(clock, deadline, spin_ns=MS, sleep=clock.sleep)
    # One sleep, ending a spin's length before the deadline; the spin absorbs the overshoot.
    assert len(clock.sleeps) == 1 and clock.sleeps[0] <= 9 * MS
    assert deadline <= returned < deadline + 7_000


def test_an_early_wakeup_sleeps_again_and_never_returns_early() -> None:
    clock = SteppingClock()
    woken_early = [True, True, False]

    def interrupted_sleep(seconds: float) -> None:
        clock.sleep(seconds / 4 if woken_early.pop(0) else seconds)

    deadline = clock.t + 10 * MS
    assert sleep_until(clock, deadline, spin_ns=MS, sleep=interrupted_sleep) >= deadline
    assert len(clock.sleeps) == 3


def test_a_deadline_already_past_returns_at_once_and_a_negative_spin_is_refused() -> None:
    clock = SteppingClock()
    assert sleep_until(clock, clock.t - MS, spin_ns=MS, sleep=clock.sleep) > clock.t - MS - 1
    assert clock.sleeps == []
    with pytest.raises(ValueError):
        sleep_until(clock, clock.t, spin_ns=-1)


def test_on_the_real_clock_it_never_returns_before_the_deadline() -> None:
    clock = MonotonicClock()
    for spin_ns in (0, MS):
        late = []
        for _ in range(20):
            deadline = clock.now_ns() + 2 * MS
            late.append(sleep_until(clock, deadline, spin_ns) - deadline)
        assert min(late) >= 0
    deadline = clock.now_ns() + 200_000
    assert spin_until(clock, deadline) >= deadline


@pytest.mark.realtime
def test_fixed_rate_ticks_with_the_precise_wait_start_at_or_after_their_deadlines() -> None:
    clock = MonotonicClock()
    starts: list[int] = []
    waits: list[float] = []

    def wait(seconds: float) -> None:
        waits.append(seconds)
        time.sleep(seconds)

    scheduler = FixedRateScheduler(clock, 100.0, lambda: starts.append(clock.now_ns()), wait=wait, spin_ns=MS)
    begin = clock.now_ns()
    stats = scheduler.run(205 * MS)
    assert stats.ticks == len(starts) >= 15
    # Tick k is due at begin + k * 10 ms (measured from just before run() read its start).
    assert all(start >= begin + k * 10 * MS for k, start in enumerate(starts))
    # The wait is never asked to sleep into the spun stretch before a deadline.
    assert max(waits) <= 0.001 + 1e-9
    with pytest.raises(ValueError):
        FixedRateScheduler(clock, 50.0, lambda: None, wait=time.sleep, spin_ns=-1)


@pytest.mark.realtime
def test_input_poller_sees_a_datagram_without_blocking() -> None:
    with (
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as rx,
        socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as tx,
    ):
        rx.bind(("127.0.0.1", 0))
        poll = input_poller([rx])
        assert poll is not None
        started = time.monotonic()
        assert poll() is False
        assert time.monotonic() - started < 0.05
        tx.sendto(b"imu", rx.getsockname())
        deadline = time.monotonic() + 2.0
        while not poll() and time.monotonic() < deadline:
            pass
        assert poll() is True
    # Nothing with a descriptor (python-can's virtual bus, the in-memory pipe): nothing to poll.
    assert input_poller([object()]) is None
