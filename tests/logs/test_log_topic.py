"""``logs.log_topic``: the onboard stack's warnings on the ``log`` topic, floods cut, other threads queued."""

from __future__ import annotations

import logging
import threading

from logs.clock import SimClock
from logs.log_topic import LogTopicHandler, foxglove_level, recording_logs
from logs.sink import MemorySink

S = 1_000_000_000


def _lines(sink: MemorySink) -> list[dict]:
    return sink.on("log")


def test_warnings_of_the_onboard_loggers_are_recorded_with_the_clock_and_infos_are_not() -> None:
    clock, sink = SimClock(), MemorySink()
    clock.advance(3 * S)
    with recording_logs(sink, clock):
        logging.getLogger("estimator.estimator").warning("wheels spinning in place (%.1f m)", 2.0)
        logging.getLogger("navigator.onboard").info("goal: new goal")
        logging.getLogger("hil.world").warning("the simulator's own: not the onboard stack")
    logging.getLogger("estimator.estimator").warning("after the block: not recorded")
    lines = _lines(sink)
    assert [(m["name"], m["message"], m["level"]) for m in lines] == [
        ("estimator.estimator", "wheels spinning in place (2.0 m)", 3)
    ]
    assert lines[0]["timestamp"] == {"sec": 3, "nsec": 0}
    assert lines[0]["file"].endswith("test_log_topic.py") and lines[0]["line"] > 0


def test_a_flood_is_cut_to_a_burst_per_window_and_the_rest_counted() -> None:
    clock, sink = SimClock(), MemorySink()
    logger = logging.getLogger("navigator.test_flood")
    with recording_logs(sink, clock) as handler:
        for i in range(500):  # 10 s at 50 Hz, the same line but for its numbers
            logger.warning("moving obstacle cart-a predicted on the path (tick %d)", i)
            clock.advance(20_000_000)
        logger.warning("moving obstacle cart-a predicted on the path (tick %d)", 500)  # a new window
        logger.error("another kind of line")
    messages = [m["message"] for m in _lines(sink)]
    assert messages[:5] == [f"moving obstacle cart-a predicted on the path (tick {i})" for i in range(5)]
    assert messages[5] == (
        "moving obstacle cart-a predicted on the path (tick 500) (495 similar lines left out before this one)"
    )
    assert messages[6] == "another kind of line"
    assert len(messages) == 7 and handler.suppressed == 495


def test_close_says_how_many_lines_were_left_out() -> None:
    clock, sink = SimClock(), MemorySink()
    with recording_logs(sink, clock):
        for reason in ("gps_gated", "imu_stale"):
            for i in range(8):
                logging.getLogger("estimator.x").warning("rejected (%s, %d so far)", reason, i + 1)
    messages = [m["message"] for m in _lines(sink)]
    assert len(messages) == 12  # five of each kind, then one summary each
    assert "3 more like: rejected (gps_gated, 8 so far)" in messages
    assert "3 more like: rejected (imu_stale, 8 so far)" in messages


def test_lines_from_another_thread_wait_for_the_recording_thread() -> None:
    clock, sink = SimClock(), MemorySink()
    with recording_logs(sink, clock) as handler:
        worker = threading.Thread(
            target=lambda: logging.getLogger("navigator.plan_worker").warning("slow plan")
        )
        worker.start()
        worker.join()
        assert _lines(sink) == []  # the recorder is single-threaded: nothing published from the worker
        handler.publish_pending()
        assert [m["message"] for m in _lines(sink)] == ["slow plan"]


def test_a_sink_that_fails_is_counted_not_raised() -> None:
    class Broken:
        def publish(self, topic: str, log_time_ns: int, message: dict) -> None:
            raise OSError("disk full")

    handler = LogTopicHandler(Broken(), SimClock())
    logger = logging.getLogger("firmware_bridge.test_broken")
    logger.addHandler(handler)
    try:
        logger.warning("CAN bus-off")
    finally:
        logger.removeHandler(handler)
    assert handler.failed == 1 and handler.published == 0


def test_levels_are_foxglove_levels() -> None:
    assert [foxglove_level(level) for level in (10, 20, 30, 40, 50)] == [1, 2, 3, 4, 5]


class _Unprintable:
    def __str__(self) -> str:
        raise AttributeError("no text")


def test_a_bad_log_call_never_raises_into_the_code_that_logged_on_any_thread() -> None:
    clock, sink = SimClock(), MemorySink()
    logger = logging.getLogger("navigator.test_bad_calls")
    # Ours alone: pytest's capturing handler (up the hierarchy) re-raises formatting errors on purpose.
    logger.propagate = False
    with recording_logs(sink, clock, loggers=("navigator.test_bad_calls",)) as handler:
        logger.warning("cost %(cost)s", {"other": 1})  # KeyError when formatted
        logger.warning("value %s", _Unprintable())  # its __str__ raises
        worker = threading.Thread(target=lambda: logger.warning("plan %(cost)s", {"x": 2}))
        worker.start()
        worker.join()
        handler.publish_pending()  # the loop thread: the worker's bad line must not stop it
    messages = [m["message"] for m in _lines(sink)]
    assert len(messages) == 3 and all("unformattable" in m for m in messages), messages
    assert "KeyError" in messages[0] and "AttributeError" in messages[1] and "KeyError" in messages[2]
