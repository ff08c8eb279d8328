"""A real-time HIL run's two recordings for the report's tests, made by splitting one synthetic trial
the way the two processes record it: the rover's file (``rover run``) without ``truth/*`` and without the
scenario, the peer's (``rover hil peer``) with only ``truth/*`` and the scenario, both on a monotonic
clock far from zero. The peer also records before the rover starts and after it stops (standing, then
pushed aside), which the merge must leave out. Also the same trial in one file, as lockstep records it.
"""

from __future__ import annotations

import copy
from pathlib import Path

from logs.paired_run import TRUTH_TOPICS
from logs.recorder import McapRecorder
from logs.sink import Message
from logs.synthetic import synthetic_metadata, synthetic_trial
from logs.topics import TRUTH_POSE, stamp

DURATION_S = 12.0
BOOT_NS = 5_072_000_000_000  # the monotonic clock's reading when the rover started: ~1.4 h after boot
PEER_EARLY_NS = 3_000_000_000  # the peer starts this long before the rover's first control tick
PUSHED_M = 1.0  # after the rover stopped, its simulated body is moved aside: not part of the drive


def _moved(message: Message, t_ns: int, x: float, y: float) -> Message:
    """A copy of a ``truth/pose`` message at another time and place, standing still."""
    moved = copy.deepcopy(message)
    moved["timestamp"] = stamp(t_ns)
    moved["pose"]["position"].update(x=x, y=y)
    moved["speed_mps"] = 0.0
    return moved


def write_pair(
    folder: Path,
    *,
    clock_offset_ns: int | None = None,
    boot_ns: int = BOOT_NS,
    wobble_m: float = 0.3,
    seed: int = 1,
    peer_run: str | None = None,
    truth_until_s: float | None = None,
) -> tuple[Path, Path, Path]:
    """(one-file reference, rover.mcap, truth.mcap) of the same synthetic trial in ``folder``.

    ``boot_ns``: the clock's reading at the rover's start; ``clock_offset_ns`` the same for the truth
    file (default ``boot_ns``: the same run; another value: a truth recorded at another time);
    ``wobble_m`` and ``seed`` as for ``synthetic_trial`` (two runs that drive differently); ``peer_run``
    the HIL peer run id both files name, as ``rover hil peer`` and ``rover run`` record it (None: none);
    ``truth_until_s``: the peer stopped that long into the trial, before the rover did (None: after it)."""
    folder.mkdir(parents=True, exist_ok=True)
    truth_ns = boot_ns if clock_offset_ns is None else clock_offset_ns
    records = list(synthetic_trial(DURATION_S, wobble_m=wobble_m, seed=seed))
    scenario = synthetic_metadata(DURATION_S) | {"name": "synthetic-rocky", "seed": "3"}
    reference, rover, truth = folder / "lockstep.mcap", folder / "rover.mcap", folder / "truth.mcap"
    with McapRecorder(reference) as recorder:
        recorder.add_metadata("scenario", scenario)
        for topic, t, message in records:
            recorder.publish(topic, boot_ns + t, message)
    with McapRecorder(rover) as recorder:
        run = {} if peer_run is None else {"hil_peer_run": peer_run}
        recorder.add_metadata("trial", {"mode": "rover-run", "config": "peer/rover-hil.toml", **run})
        for topic, t, message in records:
            if topic not in TRUTH_TOPICS:
                recorder.publish(topic, boot_ns + t, message)
    poses = [(t, m) for topic, t, m in records if topic == TRUTH_POSE]
    first, last = poses[0][1], poses[-1][1]
    start, end = first["pose"]["position"], last["pose"]["position"]
    with McapRecorder(truth) as recorder:
        recorder.add_metadata("scenario", scenario)
        recorder.add_metadata("trial", {"mode": "sim-realtime-peer", "config": "<built-in defaults>"})
        recorder.add_metadata(
            "peer", {"mode": "sim-realtime-peer", **({} if peer_run is None else {"run": peer_run})}
        )
        for k in range(30):  # the peer waits for the rover, standing at the start
            t = truth_ns - PEER_EARLY_NS + k * 100_000_000
            recorder.publish(TRUTH_POSE, t, _moved(first, t, start["x"], start["y"]))
        for topic, t, message in records:
            if topic in TRUTH_TOPICS and (truth_until_s is None or t <= truth_until_s * 1e9):
                recorder.publish(topic, truth_ns + t, message)
        if truth_until_s is not None:
            return reference, rover, truth
        end_ns = truth_ns + records[-1][1]
        for k in range(1, 11):  # after the rover stopped: pushed aside, 1 m over a second
            t = end_ns + k * 100_000_000
            recorder.publish(TRUTH_POSE, t, _moved(last, t, end["x"], end["y"] + PUSHED_M * k / 10))
    return reference, rover, truth
