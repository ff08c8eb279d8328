"""Issue 5: a ground station process sends a goal over UDP; the rover acknowledges it and drives there."""

from __future__ import annotations

import math
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

import pymap3d
import pytest

from firmware_bridge.mavlink_transport import UdpTransport
from hil.trial import run_trial
from logs import topics
from logs.reader import read_messages

pytestmark = pytest.mark.realtime  # a ground station process and the rover answer each other in time

SCRIPT = Path(__file__).resolve().parent / "gcs_goal_script.py"
GCS_GOAL = (3.0, 8.0)  # ENU metres: far from the scenario's own goal (11.5, 7.5)
WAIT_S = 20.0


def test_ground_station_goal_is_acknowledged_and_driven_to(small_scenario, default_config, tmp_path):
    lat, lon, _ = pymap3d.enu2geodetic(GCS_GOAL[0], GCS_GOAL[1], 0.0, *small_scenario.datum)
    transport = UdpTransport("udpin", "127.0.0.1", 0)
    port = transport.local_address[1]
    gcs = subprocess.Popen(
        [sys.executable, str(SCRIPT), str(port), repr(float(lat)), repr(float(lon))],
        stdout=subprocess.PIPE,
        text=True,
    )
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(
        target=lambda: [lines.put(line.strip()) for line in gcs.stdout or []], daemon=True
    ).start()
    seen: list[str] = []

    def wait_for(word: str) -> None:
        while word not in seen:
            seen.append(lines.get(timeout=WAIT_S))

    def on_progress(share: float) -> None:
        # Lockstep runs far faster than a process starts, so the simulated clock is held (wall-clock waits
        # only) until the ground station is up and its heartbeats are in the rover's socket. The next
        # simulated second the rover reads them and answers with its own heartbeat; the ground station then
        # sends the goal, and the clock is held once more until the command is on the wire.
        if "ready" not in seen:
            wait_for("ready")
            time.sleep(0.5)
        elif "sent" not in seen:
            wait_for("sent")

    try:
        result = run_trial(
            small_scenario,
            default_config,
            tmp_path / "trial",
            ground_station=transport,
            on_progress=on_progress,
        )
        gcs.wait(timeout=WAIT_S)
        while not lines.empty():
            seen.append(lines.get())
    finally:
        if gcs.poll() is None:
            gcs.kill()
        transport.close()

    assert "ack 0" in seen, seen  # MAV_RESULT_ACCEPTED
    goals = [
        m.message["detail"]
        for m in read_messages(result.mcap_path, topics=[topics.SAFETY_EVENTS])
        if m.message["kind"] == "goal"
    ]
    x, y = (float(v) for v in goals[-1].removeprefix("new goal (").removesuffix(")").split(","))
    # Through WGS84 and back: centimetres apart at most.
    assert math.hypot(x - GCS_GOAL[0], y - GCS_GOAL[1]) < 0.05
    assert result.end_reason == "arrived"
    final = [
        m.message["pose"]["position"] for m in read_messages(result.mcap_path, topics=[topics.TRUTH_POSE])
    ][-1]
    assert math.hypot(final["x"] - GCS_GOAL[0], final["y"] - GCS_GOAL[1]) < 1.0
