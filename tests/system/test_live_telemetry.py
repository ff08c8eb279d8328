"""A lockstep trial publishes on Zenoh what it records: same topics, log times and payloads."""

from __future__ import annotations

import threading
import time

import pytest

from hil.trial import run_trial
from logs import topics
from logs.reader import read_messages
from logs.telemetry import TelemetrySample, ZenohTelemetry, subscribe
from tests.system.zenoh_pair import open_pair

pytestmark = pytest.mark.realtime  # the live stream must keep up with the trial

CHECKED = (topics.SENSORS_GPS, topics.NAVIGATOR_PATH, topics.SAFETY_EVENTS)


def test_live_stream_matches_recording(small_scenario, default_config, tmp_path):
    ground, rover = open_pair()
    received: list[TelemetrySample] = []
    lock = threading.Lock()

    def on_sample(sample: TelemetrySample) -> None:
        if sample.topic in CHECKED:
            with lock:
                received.append(sample)

    subscription = subscribe(ground, default_config.rover_id, on_sample)
    try:
        # Lossless for the comparison: at many times real time the trial can outpace the link, and by
        # default a put that finds the queue full is dropped (it was, for sensors/gps, on a fast run).
        telemetry = ZenohTelemetry(rover, default_config.rover_id, block_when_congested=True)
        # Zenoh routes declared subscribers asynchronously; wait until a probe gets through.
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline and subscription.received == 0:
            telemetry.publish(
                topics.LOG,
                0,
                {
                    "timestamp": topics.stamp(0),
                    "level": 2,
                    "message": "probe",
                    "name": "test",
                    "file": "",
                    "line": 0,
                },
            )
            time.sleep(0.05)
        assert subscription.received > 0, "the subscriber never saw the probe"
        result = run_trial(small_scenario, default_config, tmp_path / "trial", telemetry=telemetry)
        recorded = [
            (m.topic, m.log_time_ns, m.message) for m in read_messages(result.mcap_path, topics=list(CHECKED))
        ]
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            with lock:
                if len(received) >= len(recorded):
                    break
            time.sleep(0.05)
        telemetry.close()
    finally:
        subscription.close()
        rover.close()
        ground.close()
    with lock:
        live = [(s.topic, s.log_time_ns, s.message) for s in received]
    assert len(recorded) > 50
    key = lambda item: (item[0], item[1])  # noqa: E731
    assert sorted(live, key=key) == sorted(recorded, key=key)
