"""The phase-locked fixed-rate loop on a simulated clock: steady ticks locked ``offset`` after the pacing
sample, steered by at most the slew a tick, late samples not waited for (and their latency counted), a
silent sensor leaving a free-running fixed-rate loop, overruns skipped."""

from __future__ import annotations

import dataclasses
import itertools
import threading
from types import SimpleNamespace
from typing import cast

import pytest

from logs.clock import NS_PER_S, SimClock
from logs.settings import ConfigError, parse_toml
from logs.sink import MemorySink
from navigator.config import rover_config_from_table
from navigator.onboard import OnboardStack
from navigator.paced_loop import SensorPacedScheduler
from navigator.phase_locked_loop import PhaseLockedScheduler
from navigator.rover_process import control_scheduler
from tests.runtime.fake_sensor import TICK_COST, SensorLoop
from tests.runtime.rig import Rig, rig_config

MS = 1_000_000
PERIOD = 20 * MS  # 50 Hz
OFFSET = 800_000
LATE_WAIT = 700_000
SLEW = 50_000


class Loop(SensorLoop):
    def run(self, duration_ns: int) -> PhaseLockedScheduler:
        scheduler = PhaseLockedScheduler(
            self.clock,
            1e9 / PERIOD,
            self.tick,
            ingest=self.sensor.ingest,
            wait=self.wait,
            latency=self.latency,
            on_tick=self.samples.append,
            offset_ns=OFFSET,
            late_wait_ns=LATE_WAIT,
            slew_ns=SLEW,
            spin_ns=0,  # a simulated clock does not move by itself
        )
        scheduler.run(duration_ns)
        return scheduler


def _loop(arrivals: list[int]) -> Loop:
    return Loop.on(arrivals)


def _periods(loop: Loop, after_ns: int = 0) -> list[int]:
    starts = [t for t, _ in loop.ticks if t >= after_ns]
    return [b - a for a, b in itertools.pairwise(starts)]


def test_ticks_lock_offset_after_the_sample_and_then_keep_the_period() -> None:
    # A 50 Hz sensor 7.3 ms out of phase with the loop's start.
    arrivals = [round(7.3 * MS) + k * PERIOD for k in range(100)]
    loop = _loop(arrivals)
    scheduler = loop.run(arrivals[-1] + 5 * MS)
    assert scheduler.locks == 1
    locked = [(t, trigger) for t, trigger in loop.ticks if t > 3 * PERIOD]
    # Every tick after locking on starts exactly `offset` after its sample, and answers that sample.
    assert locked and all(trigger is not None and t - trigger == OFFSET for t, trigger in locked)
    assert set(_periods(loop, after_ns=3 * PERIOD)) == {PERIOD}
    # Latency: the offset plus the tick's own time to its command (before the lock, up to a period).
    assert {s.latency_ns for s in loop.samples if s.start_ns > 3 * PERIOD} == {OFFSET + TICK_COST}


def test_arrival_jitter_does_not_move_the_ticks() -> None:
    # Samples late by 0..0.5 ms at random-looking steps: the sensor-paced loop's period would follow them.
    late = [0, 500_000, 100_000, 0, 300_000, 0, 450_000, 200_000]
    arrivals = [5 * MS + k * PERIOD + late[k % len(late)] for k in range(150)]
    loop = _loop(arrivals)
    scheduler = loop.run(arrivals[-1] + 5 * MS)
    # The grid follows the earliest arrivals, so ticks stay `offset` after the on-time samples, and a
    # period stays a period give or take the slew.
    periods = _periods(loop, after_ns=20 * PERIOD)
    assert max(abs(p - PERIOD) for p in periods) <= SLEW
    assert scheduler.stats.deadline_ticks <= 2  # every late sample still made its tick


def test_a_small_phase_step_is_steered_to_at_the_slew_rate() -> None:
    # The sensor's phase moves 0.5 ms later halfway (an autopilot's scheduler change, say): inside the
    # late wait, so every sample is still answered at once while the grid steers over.
    first = [5 * MS + k * PERIOD for k in range(50)]
    second = [first[-1] + PERIOD + 500_000 + k * PERIOD for k in range(100)]
    loop = _loop(first + second)
    scheduler = loop.run(second[-1] + 5 * MS)
    assert scheduler.locks == 1 and scheduler.stats.deadline_ticks == 0
    assert max(abs(p - PERIOD) for p in _periods(loop, after_ns=3 * PERIOD)) <= 500_000
    tail = [(t, trigger) for t, trigger in loop.ticks if t > second[60]]
    assert tail and all(trigger is not None and abs(t - trigger - OFFSET) <= 10_000 for t, trigger in tail)


def test_a_large_phase_step_locks_on_afresh() -> None:
    # 5 ms later: beyond the offset and the late wait. Three missed samples, then a new lock.
    first = [5 * MS + k * PERIOD for k in range(50)]
    second = [first[-1] + PERIOD + 5 * MS + k * PERIOD for k in range(100)]
    loop = _loop(first + second)
    scheduler = loop.run(second[-1] + 5 * MS)
    assert scheduler.locks == 2 and scheduler.late_waits_missed == 3
    # Each missed tick is late by the late wait, never more; the new lock is one step.
    off_period = [p for p in _periods(loop, after_ns=3 * PERIOD) if abs(p - PERIOD) > LATE_WAIT + SLEW]
    assert len(off_period) == 1
    tail = [(t, trigger) for t, trigger in loop.ticks if t > second[5]]
    assert tail and all(trigger is not None and t - trigger == OFFSET for t, trigger in tail)


def test_a_late_sample_is_not_waited_for_and_its_latency_is_counted() -> None:
    arrivals = [5 * MS + k * PERIOD for k in range(60)]
    arrivals[40] += 3 * MS  # 3 ms late: after its tick (due 0.8 ms after it was expected) and its late wait
    loop = _loop(arrivals)
    scheduler = loop.run(arrivals[-1] + 5 * MS)
    missed = [s for s in loop.samples if s.trigger == "deadline" and s.start_ns > 3 * PERIOD]
    assert len(missed) == 1 and scheduler.late_waits_missed == 1
    # It waited the late wait for the sample, then ran: late by that, and no more.
    assert missed[0].start_ns - (arrivals[40] - 3 * MS + OFFSET) == LATE_WAIT
    # The late sample is answered by the next tick: its latency is that wait plus the tick, and shows.
    worst = scheduler.stats.latency_ns.summary_ms()["max_ms"]
    expected_wait = PERIOD + OFFSET - 3 * MS + TICK_COST
    assert worst == pytest.approx(expected_wait / 1e6)


def test_a_silent_sensor_leaves_a_fixed_rate_loop_that_locks_again_when_it_is_back() -> None:
    first = [5 * MS + k * PERIOD for k in range(10)]
    resumed = [713 * MS + k * PERIOD for k in range(20)]  # back in another phase
    loop = _loop(first + resumed)
    scheduler = loop.run(resumed[-1] + 5 * MS)
    silent = [t for t, trigger in loop.ticks if first[-1] + PERIOD < t < resumed[0]]
    # Three ticks wait the late wait for the sample, then the loop runs free on the period.
    assert scheduler.late_waits_missed == 3
    assert silent and {b - a for a, b in itertools.pairwise(silent[4:])} == {PERIOD}
    assert scheduler.locks == 2
    after = [(t, trigger) for t, trigger in loop.ticks if t > resumed[1] + PERIOD]
    assert after and all(trigger is not None and t - trigger == OFFSET for t, trigger in after)


def test_without_a_sensor_it_is_a_plain_fixed_rate_loop() -> None:
    loop = _loop([])
    scheduler = loop.run(500 * MS)
    assert scheduler.locks == 0 and scheduler.stats.sensor_ticks == 0
    assert set(_periods(loop)) == {PERIOD}
    assert scheduler.stats.latency_ns.count == 0


def test_a_long_tick_counts_overruns_instead_of_bursting() -> None:
    loop = _loop([])

    def slow_tick(trigger_ns: int | None) -> None:
        loop.ticks.append((loop.clock.now_ns(), trigger_ns))
        loop.clock.advance(95 * MS if len(loop.ticks) == 3 else TICK_COST)

    loop.tick = slow_tick  # type: ignore[method-assign]
    stats = loop.run(400 * MS).stats
    assert stats.overruns >= 3
    assert min(_periods(loop)) >= PERIOD // 2


@pytest.mark.parametrize(
    ("offset_ns", "slew_ns", "spin_ns"),
    [(-1, SLEW, 0), (PERIOD, SLEW, 0), (OFFSET, 0, 0), (OFFSET, PERIOD, 0), (OFFSET, SLEW, -1)],
)
def test_settings_out_of_range_are_refused(offset_ns: int, slew_ns: int, spin_ns: int) -> None:
    clock = SimClock()
    with pytest.raises(ValueError):
        PhaseLockedScheduler(
            clock, 50.0, lambda _: None, ingest=lambda: None, wait=lambda _: None,
            offset_ns=offset_ns, slew_ns=slew_ns, spin_ns=spin_ns,
        )  # fmt: skip


def test_a_slightly_late_sample_is_waited_for_up_to_the_late_wait() -> None:
    arrivals = [5 * MS + k * PERIOD for k in range(60)]
    arrivals[40] += OFFSET + 400_000  # 0.4 ms after its tick was due: inside the late wait
    loop = _loop(arrivals)
    scheduler = loop.run(arrivals[-1] + 5 * MS)
    tick = next((t, trigger) for t, trigger in loop.ticks if trigger == arrivals[40])
    assert tick == (arrivals[40], arrivals[40])  # started the instant it landed
    assert scheduler.stats.deadline_ticks == 0 and scheduler.late_waits_missed == 0
    # The late tick is late by 0.4 ms, and the one after is back on the grid: jitter 0.4 ms, twice.
    late_periods = sorted(abs(p - PERIOD) for p in _periods(loop, after_ns=3 * PERIOD))[-2:]
    assert late_periods == [pytest.approx(400_000, abs=SLEW)] * 2


def test_the_config_names_the_loop_and_the_rover_drives_on_the_phase_locked_one() -> None:
    config = dataclasses.replace(rig_config(), control_loop="phase-locked", phase_offset_ms=1.5)
    rig = Rig(config)
    try:
        stop = threading.Event()
        end = rig.now_ns + 8 * NS_PER_S

        def wait(_seconds: float) -> None:
            # Time moves in the simulated rover's physics steps; its IMU lands on them.
            rig.physics_tick()
            if rig.now_ns >= end or rig.body.speed > 0.3:
                stop.set()

        scheduler = control_scheduler(rig.stack, rig.clock, config, rig.sink, wait, stop)
        assert isinstance(scheduler, PhaseLockedScheduler) and scheduler.offset_ns == 1_500_000
        stats = scheduler.run()
        assert scheduler.locks >= 1 and stats.sensor_ticks > 0
        assert rig.stack.safety_mode.value == "DRIVING" and rig.body.speed > 0.3
        assert any(topic == "runtime/timing" for topic, _, _ in rig.sink.records)
    finally:
        rig.close()
    paced_config = dataclasses.replace(rig_config(), control_loop="sensor-paced")
    paced = control_scheduler(rig.stack, rig.clock, paced_config, rig.sink, lambda _: None)
    assert isinstance(paced, SensorPacedScheduler)


@pytest.mark.parametrize(
    ("text", "key"),
    [('control_loop = "fast"', "control_loop"), ("phase_offset_ms = 10.5", "phase_offset_ms")],
)
def test_the_config_refuses_an_unknown_loop_and_an_offset_past_half_a_period(text: str, key: str) -> None:
    with pytest.raises(ConfigError, match=key):
        rover_config_from_table(parse_toml(text, "<test>"))


def test_a_sensor_slower_than_the_loop_leaves_a_steady_fixed_rate_loop() -> None:
    # `pacing_sensor = "gps"` at 10 Hz on the 50 Hz loop: its gaps (5 periods) are longer than the grid's
    # outage limit, yet they are its rate; it cannot set every tick's phase, so the loop must not lock on
    # (a lock to each fix was followed by three missed late waits and a short period, every fix).
    arrivals = [3 * MS + k * 100 * MS for k in range(30)]
    loop = _loop(arrivals)
    scheduler = loop.run(arrivals[-1] + PERIOD + 5 * MS)
    assert scheduler.locks == 0 and scheduler.late_waits_missed == 0
    assert set(_periods(loop)) == {PERIOD}
    # Each fix is still answered by the next tick, and counted once.
    assert scheduler.stats.latency_ns.count == len(arrivals)


def test_locking_on_does_not_add_a_tick_for_the_sample_just_answered() -> None:
    # The samples land 0.3 ms before the free-running loop's ticks: the tick that locks on has just
    # answered one, so the locked grid starts at the next sample, not 0.5 ms later at the same one.
    arrivals = [round(19.7 * MS) + k * PERIOD for k in range(50)]
    loop = _loop(arrivals)
    scheduler = loop.run(arrivals[-1] + 5 * MS)
    assert scheduler.locks == 1
    assert scheduler.late_waits_missed == 0 and scheduler.stats.deadline_ticks == 0
    assert min(_periods(loop)) >= PERIOD


def test_the_late_wait_does_not_spin_a_simulated_clock() -> None:
    # With spin_ns 0 (a simulated clock, which does not move by itself) a poll must not be spun on: the
    # late wait of a sensor that fell silent spun on it for ever.
    arrivals = [5 * MS + k * PERIOD for k in range(10)]
    loop = _loop(arrivals)
    polls = itertools.count()

    def poll() -> bool:
        assert next(polls) < 100_000, "spun on a clock that does not move"
        unread = loop.sensor.arrivals[loop.sensor.read :]
        return bool(unread) and unread[0] <= loop.clock.now_ns()

    scheduler = PhaseLockedScheduler(
        loop.clock, 1e9 / PERIOD, loop.tick, ingest=loop.sensor.ingest, wait=loop.wait, poll=poll,
        offset_ns=OFFSET, late_wait_ns=LATE_WAIT, spin_ns=0,
    )  # fmt: skip
    scheduler.run(arrivals[-1] + 10 * PERIOD)
    assert scheduler.locks == 1 and scheduler.late_waits_missed == 3


@pytest.mark.parametrize("loop_name", ["sensor-paced", "phase-locked"])
@pytest.mark.parametrize("rate_hz", [700.0, 1000.0])
def test_every_rate_the_config_allows_builds_its_loop(loop_name: str, rate_hz: float) -> None:
    # The config allows up to 1000 Hz: the default phase_offset_ms (0.8) was refused above 625 Hz even
    # for the sensor-paced loop, which never reads it, and the phase-locked loop's default late wait
    # (0.7 ms) was refused by the scheduler above 714 Hz, a ValueError as `rover run` started.
    text = f'control_rate_hz = {rate_hz}\ncontrol_loop = "{loop_name}"'
    config = rover_config_from_table(parse_toml(text, "<test>"))
    assert config.phase_offset_ms <= 500.0 / rate_hz
    stack = cast(OnboardStack, SimpleNamespace(step=lambda _: None, ingest=lambda: None))
    scheduler = control_scheduler(stack, SimClock(), config, MemorySink(), lambda _: None)
    assert scheduler.period_ns == round(NS_PER_S / rate_hz)


def test_a_phase_step_earlier_locks_on_afresh_too() -> None:
    # 3 ms earlier: every sample is in before its tick, so none is missed, but each waited up to 3 ms
    # more for its tick while the grid was steered over at the slew (60 ticks); a step later locks on
    # afresh after three misses, and one earlier should not cost more.
    first = [5 * MS + k * PERIOD for k in range(50)]
    second = [first[-1] + PERIOD - 3 * MS + k * PERIOD for k in range(100)]
    loop = _loop(first + second)
    scheduler = loop.run(second[-1] + 5 * MS)
    assert scheduler.locks == 2 and scheduler.late_waits_missed == 0
    locked = [s for s in loop.samples if s.start_ns > 3 * PERIOD and s.latency_ns is not None]
    slow = [s for s in locked if s.latency_ns is not None and s.latency_ns > OFFSET + TICK_COST + SLEW]
    assert len(slow) == 1  # the tick that saw the step (its sample waited 3 ms more); before: 60
    tail = [(t, trigger) for t, trigger in loop.ticks if t > second[2]]
    assert tail and all(trigger is not None and t - trigger == OFFSET for t, trigger in tail)


@pytest.mark.parametrize("sensor_hz", [40.0, 60.0])
def test_a_sensor_at_another_rate_leaves_a_steady_fixed_rate_loop(sensor_hz: float) -> None:
    # Not the loop's rate nor a whole multiple of it: its samples drift through the ticks' phase. Taken
    # for a 50 Hz one, each lock was followed by misses, a drop and a relock (40 Hz, 5 s: 65 locks).
    arrivals = [5 * MS + round(k * NS_PER_S / sensor_hz) for k in range(round(5 * sensor_hz))]
    loop = _loop(arrivals)
    scheduler = loop.run(arrivals[-1] + 5 * MS)
    assert scheduler.locks == 0 and scheduler.late_waits_missed == 0
    assert set(_periods(loop)) == {PERIOD}


def test_the_config_refuses_the_phase_locked_loop_paced_by_the_wheels() -> None:
    text = 'control_loop = "phase-locked"\npacing_sensor = "wheels"\n'
    with pytest.raises(ConfigError, match="control_loop") as caught:
        rover_config_from_table(parse_toml(text, "<test>"))
    assert "sensor-paced" in caught.value.problem
    # Without control_loop, the wheels pace the sensor-paced loop (the phase-locked one is the default else).
    paced_by_wheels = rover_config_from_table(parse_toml('pacing_sensor = "wheels"\n', "<test>"))
    assert paced_by_wheels.control_loop == "sensor-paced"
    assert rover_config_from_table(parse_toml("", "<test>")).control_loop == "phase-locked"


def test_each_tick_reports_every_sample_it_answered_as_the_statistics_count_them() -> None:
    arrivals = [5 * MS + k * PERIOD for k in range(60)]
    arrivals[40] += 3 * MS  # misses its tick: the next tick answers it and its own sample
    loop = _loop(arrivals)
    scheduler = loop.run(arrivals[-1] + 5 * MS)
    # runtime/timing (TimingPublisher) takes latencies_ns(): the same samples the summary counts.
    assert sum(len(s.latencies_ns()) for s in loop.samples) == scheduler.stats.latency_ns.count
    (both,) = [s for s in loop.samples if len(s.latencies_ns()) == 2]
    assert max(both.latencies_ns()) == both.latency_ns == PERIOD + OFFSET - 3 * MS + TICK_COST
