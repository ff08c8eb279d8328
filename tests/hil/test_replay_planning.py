"""``NextTickPlanning``: a plan asked for in one tick is taken in by the next, as `rover run`'s worker's."""

from __future__ import annotations

import pytest

from hil.replay_planning import NextTickPlanning


def test_a_job_runs_at_once_and_is_done_from_the_next_release() -> None:
    planning = NextTickPlanning()
    ran: list[int] = []

    def double(x: int) -> int:
        ran.append(x)
        return x * 2

    future = planning.submit(double, 21)
    assert ran == [21] and not future.done()  # computed now, deterministic; handed over later
    planning.release()
    assert future.done() and future.result() == 42
    planning.release()  # nothing waiting: nothing happens
    assert future.result() == 42


def test_a_failed_job_fails_at_the_next_release() -> None:
    planning = NextTickPlanning()

    def fails() -> None:
        raise ValueError("no path")

    future = planning.submit(fails)
    assert not future.done()
    planning.release()
    with pytest.raises(ValueError, match="no path"):
        future.result()
