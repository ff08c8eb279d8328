"""The sensor-synchronous loop on a simulated clock: ticks start on pacing samples, a silent sensor falls
back to fixed-rate deadlines, a faster sensor is decimated, and held records keep their order."""

from __future__ import annotations

import dataclasses
import itertools

import pytest

from logs.encoding import EncodedSink
from logs.sink import MemorySink
from navigator.deferred_sink import DeferredSink, deferred_sink
from navigator.paced_loop import DEADLINE_GRACE, SensorPacedScheduler
from tests.runtime.fake_sensor import TICK_COST, SensorLoop
from tests.runtime.rig import Rig, rig_config

MS = 1_000_000
PERIOD = 20 * MS  # 50 Hz


class Loop(SensorLoop):
    def run(self, duration_ns: int) -> SensorPacedScheduler:
        scheduler = SensorPacedScheduler(
            self.clock,
            1e9 / PERIOD,
            self.tick,
            ingest=self.sensor.ingest,
            wait=self.wait,
            latency=self.latency,
            on_tick=self.samples.append,
        )
        scheduler.run(duration_ns)
        return scheduler


def _loop(arrivals: list[int]) -> Loop:
    return Loop.on(arrivals)


def test_each_sample_starts_a_tick_at_once() -> None:
    # A 50 Hz sensor 7.3 ms out of phase with the loop's own start, with +-0.4 ms arrival jitter.
    arrivals = [round(7.3 * MS) + k * PERIOD + (400_000 if k % 3 == 0 else -400_000) for k in range(50)]
    loop = _loop(arrivals)
    stats = loop.run(arrivals[-1] + MS).stats
    sensor_ticks = [(t, trigger) for t, trigger in loop.ticks if trigger is not None]
    assert stats.sensor_ticks == len(sensor_ticks) == 50 and stats.deadline_ticks == 0
    # The tick starts in the instant the sample is read, on the sample's own time: no waiting for a slot.
    assert all(t == trigger for t, trigger in sensor_ticks)
    assert stats.latency_ns.summary_ms()["max_ms"] == pytest.approx(TICK_COST / 1e6)
    # Jitter is the sensor's: |period - 20 ms| is 0 or 0.8 ms here.
    assert stats.jitter_ns.summary_ms()["max_ms"] == pytest.approx(0.8)


def test_a_silent_sensor_falls_back_to_fixed_rate_deadlines_and_back() -> None:
    # Samples for 0.2 s, silence for 0.5 s, then samples again.
    arrivals = [5 * MS + k * PERIOD for k in range(10)] + [705 * MS + k * PERIOD for k in range(10)]
    loop = _loop(arrivals)
    loop.run(900 * MS)
    starts = [t for t, _ in loop.ticks]
    gaps = [b - a for a, b in itertools.pairwise(starts)]
    # Never a gap longer than a period plus the grace: the stall failsafe (0.2 s) is nowhere near.
    assert max(gaps) <= PERIOD + DEADLINE_GRACE * PERIOD + TICK_COST
    silent = [(t, trigger) for t, trigger in loop.ticks if 185 * MS < t < 705 * MS]
    assert silent and all(trigger is None for _, trigger in silent)
    # The first deadline after the last sample is a period plus grace away, then every period exactly.
    deadline_starts = [t for t, _ in silent]
    assert deadline_starts[0] == 185 * MS + PERIOD + round(DEADLINE_GRACE * PERIOD)
    assert {b - a for a, b in itertools.pairwise(deadline_starts)} == {PERIOD}
    # Back on the sensor as soon as it speaks again.
    assert all(trigger == t for t, trigger in loop.ticks if t >= 705 * MS)
    assert sum(1 for _, trigger in loop.ticks if trigger is not None) == 20


def test_a_sensor_back_just_after_each_deadline_tick_paces_the_loop_again() -> None:
    # The sensor comes back (an autopilot reboot) in a new phase: each sample lands 2 ms after one of the
    # fallback's deadline ticks. Decimating those samples against the deadline tick would keep the loop
    # on deadlines for good (seen in `rover bench runtime`: half of a 60 s run on deadline ticks).
    first = [k * PERIOD for k in range(5)]  # ticks at 0..80 ms; deadlines then at 110, 130, 150, ...
    resumed = [152 * MS + k * PERIOD for k in range(20)]
    loop = _loop(first + resumed)
    loop.run(resumed[-1] + MS)
    after = [(t, trigger) for t, trigger in loop.ticks if t >= 152 * MS]
    assert after[0] == (152 * MS, 152 * MS)  # the first sample back starts a tick at once
    assert all(trigger == t for t, trigger in after) and len(after) == 20


def test_a_faster_sensor_is_decimated_to_the_control_rate() -> None:
    arrivals = [k * 5 * MS + MS for k in range(400)]  # 200 Hz
    loop = _loop(arrivals)
    stats = loop.run(2_000 * MS).stats
    assert 95 <= stats.ticks <= 101 and stats.deadline_ticks <= 1
    steady = [s.period_ns for s in loop.samples[20:] if s.period_ns is not None]
    assert set(steady) == {PERIOD}


def test_a_long_tick_counts_overruns_instead_of_bursting() -> None:
    loop = _loop([])  # deadline ticks only

    def slow_tick(trigger_ns: int | None) -> None:
        loop.ticks.append((loop.clock.now_ns(), trigger_ns))
        loop.clock.advance(95 * MS if len(loop.ticks) == 3 else TICK_COST)

    loop.tick = slow_tick  # type: ignore[method-assign]
    stats = loop.run(400 * MS).stats
    assert stats.overruns >= 3
    starts = [t for t, _ in loop.ticks]
    assert min(b - a for a, b in itertools.pairwise(starts)) >= PERIOD // 2


def test_deferred_sink_holds_records_in_order_until_release() -> None:
    inner = MemorySink()
    deferred = DeferredSink(inner)
    deferred.publish("a", 1, {"n": 1})
    deferred.hold()
    deferred.publish("b", 2, {"n": 2})
    deferred.hold()
    deferred.publish("c", 3, {"n": 3})
    assert [t for t, _, _ in inner.records] == ["a"]
    deferred.release()
    deferred.publish("d", 4, {"n": 4})
    assert [(t, log_time) for t, log_time, _ in inner.records] == [("a", 1), ("b", 2), ("c", 3), ("d", 4)]
    assert not deferred.holding


def test_lockstep_ticks_are_paced_by_the_imu_read_inside_them() -> None:
    rig = Rig(rig_config())
    try:
        rig.run_for(1.0)
        # The autopilot's IMU runs at the control rate: every tick read one, on a simulated clock.
        assert rig.stack.last_sensor_to_command_ns == 0
    finally:
        rig.close()
    rig = Rig(dataclasses.replace(rig_config(), pacing_sensor="none"))
    try:
        rig.run_for(0.2)
        assert rig.stack.last_sensor_to_command_ns is None
    finally:
        rig.close()


def _ingest_a_pacing_sample(rig: Rig) -> int:
    """Drive half a second, then step the simulated rover until an ingest finds a pacing sample."""
    rig.run_for(0.5)
    received = None
    while received is None:
        rig.physics_tick()
        received = rig.stack.ingest()
    return received


def test_records_of_the_sensor_to_command_path_wait_until_the_command_is_sent() -> None:
    rig = Rig(rig_config(), deferred=True)
    assert rig.deferred is not None
    try:
        received = _ingest_a_pacing_sample(rig)
        before = len(rig.sink.records)
        assert rig.deferred.holding  # the IMU's own records are held for the tick it starts
        rig.stack.step(received)
        assert not rig.deferred.holding
        new = [(topic, m) for topic, _, m in rig.sink.records[before:]]
        topics_in_order = [topic for topic, _ in new]
        first_tx = next(
            i for i, (topic, m) in enumerate(new) if topic == "can/frames" and m["direction"] == "tx"
        )
        assert "sensors/imu" in topics_in_order[:first_tx]  # recorded in arrival order, after the fact
        assert topics_in_order[-1] == "navigator/state"
        assert rig.stack.last_sensor_to_command_ns == 0
        # Nothing arrived: ingest releases at once and returns None.
        assert rig.stack.ingest() is None and not rig.deferred.holding
    finally:
        rig.close()


def test_close_records_what_was_held_and_the_zero_commands() -> None:
    # A pacing sample was ingested but its tick never ran (the loop stopped): close() must still put the
    # held records and the zero wheel commands it sends into the recording.
    rig = Rig(rig_config(), deferred=True)
    assert rig.deferred is not None
    _ingest_a_pacing_sample(rig)
    before = len(rig.sink.records)
    assert rig.deferred.holding
    rig.close()
    new = rig.sink.records[before:]
    assert not rig.deferred.holding
    assert any(topic == "sensors/imu" for topic, _, _ in new)
    assert any(topic == "can/frames" and m["direction"] == "tx" for topic, _, m in new)


def test_a_tick_that_raises_releases_its_records() -> None:
    rig = Rig(rig_config(), deferred=True)
    assert rig.deferred is not None
    try:
        rig.run_for(0.5)

        def broken(*_: object) -> None:
            raise RuntimeError("guidance failed")

        rig.stack.guidance.tick = broken  # type: ignore[method-assign,assignment]
        with pytest.raises(RuntimeError):
            rig.stack.step()
        assert not rig.deferred.holding
    finally:
        rig.close()


def test_a_deferred_sink_passes_pre_encoded_records_on_as_such() -> None:
    class EncodedMemory(MemorySink):
        def __init__(self) -> None:
            super().__init__()
            self.encoded: list[tuple[str, bytes]] = []

        def publish_encoded(self, topic: str, log_time_ns: int, message: dict, data: bytes) -> None:
            self.encoded.append((topic, data))
            self.publish(topic, log_time_ns, message)

    inner = EncodedMemory()
    deferred = deferred_sink(inner)
    assert isinstance(deferred, EncodedSink) and not isinstance(deferred_sink(MemorySink()), EncodedSink)
    deferred.hold()
    deferred.publish("a", 1, {"n": 1})
    deferred.publish_encoded("b", 2, {"n": 2}, b'{"n":2}')
    assert inner.records == []
    deferred.release()
    assert [topic for topic, _, _ in inner.records] == ["a", "b"]  # in order, nothing dropped
    assert inner.encoded == [("b", b'{"n":2}')]  # the bytes handed over, not encoded again
