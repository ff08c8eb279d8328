"""Real-time HIL metrics time moving obstacles from the peer's world start, recorded in its truth.mcap.

The rover's and the peer's recordings are stamped with the monotonic clock (seconds since the machine
booted); the peer's world, and its carts, started at some reading of it.
"""

from __future__ import annotations

import json
from pathlib import Path

from hil.realtime_metrics import realtime_metrics
from logs.clock import to_ns
from logs.recorder import McapRecorder
from logs.topics import NAVIGATOR_STATE, TRUTH_POSE, planar_pose, stamp

# The peer's world started 10^6 s (and a bit) after the boot; the rover drove y = 0 from x = 0 to x = 20
# at 1 m/s, starting 2 s after the world.
WORLD_START_NS = to_ns(1_000_005.0)
DRIVE_START_S = 2.0
# Waits 9 s at (17, 8), then drives down x = 17 at 1 m/s: at y = 0 17 s after the world's start, where the
# rover is then (x = 15: 2 m away, within radius 0.5 + margin 1.5). Timed from the boot, it is elsewhere.
CART = {
    "id": "cart",
    "radius": 0.5,
    "waypoints": [[17.0, 8.0], [17.0, -8.0]],
    "speed_mps": 1.0,
    "start_s": 9.0,
}


def _ns(world_s: float) -> int:
    return WORLD_START_NS + to_ns(world_s)


def _write_truth(path: Path, world: dict[str, str] | None) -> None:
    with McapRecorder(path) as recorder:
        recorder.add_metadata(
            "scenario",
            {
                "encounter_margin_m": "1.5",
                "obstacles_json": "[]",
                "moving_obstacles_json": json.dumps([CART]),
            },
        )
        if world is not None:
            recorder.add_metadata("world", world)
        for index in range(21):
            t = _ns(DRIVE_START_S + index)
            pose = planar_pose(float(index), 0.0, 0.0)
            recorder.publish(TRUTH_POSE, t, {"timestamp": stamp(t), "frame_id": "enu", "pose": pose})


def _write_rover(path: Path) -> None:
    with McapRecorder(path) as recorder:
        for index in range(21):
            t = _ns(DRIVE_START_S + index)
            mode = "ARRIVED" if index == 20 else "DRIVING"
            recorder.publish(NAVIGATOR_STATE, t, {"timestamp": stamp(t), "mode": mode})


def test_the_peers_carts_are_where_its_world_put_them(tmp_path: Path) -> None:
    _write_rover(tmp_path / "rover.mcap")
    _write_truth(tmp_path / "truth.mcap", {"epoch_ns": str(WORLD_START_NS)})
    metrics = realtime_metrics(tmp_path / "rover.mcap", tmp_path / "truth.mcap")
    assert metrics.obstacles_encountered == 1, metrics
    assert not metrics.problems


def test_without_the_world_record_the_carts_are_timed_from_the_boot(tmp_path: Path) -> None:
    # What the metrics did before the peer recorded its start (and right for recordings of that time,
    # whose peer moved its carts on the raw monotonic clock): the cart is elsewhere, not encountered.
    _write_rover(tmp_path / "rover.mcap")
    _write_truth(tmp_path / "truth.mcap", None)
    assert realtime_metrics(tmp_path / "rover.mcap", tmp_path / "truth.mcap").obstacles_encountered == 0
