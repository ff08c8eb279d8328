"""Trial metrics of a real-time HIL run: the rover's recording and the peer's ground truth, merged.

In lockstep one MCAP holds everything. Across processes the rover (``rover run``) records what it planned
and decided (``navigator/path``, ``navigator/state``, ``wheels/status``) and the peer (``rover hil peer``)
records the ground truth and the scenario metadata. Both stamp messages with the OS monotonic clock,
which all processes on the machine share, so the two streams merge by ``log_time``.

The peer runs before the rover starts and after it arrives; to measure the same trial as lockstep, the
truth is cut to the rover's drive: from its first control tick (its first ``navigator/state``) to its
first ARRIVED state, or the end of its recording if it never arrived.
"""

from __future__ import annotations

from pathlib import Path

from logs.metrics import ARRIVED_MODE, METRIC_TOPICS, TrialMetrics, metrics_from_entries
from logs.reader import Entry, ReadStats, RecordedMessage, read_entries
from logs.topics import NAVIGATOR_STATE, TRUTH_CONTACTS, TRUTH_POSE

# What the peer knows and the rover does not; everything else the metrics read comes from the rover.
TRUTH_TOPICS = (TRUTH_POSE, TRUTH_CONTACTS)


def realtime_metrics(rover_mcap: Path, truth_mcap: Path) -> TrialMetrics:
    """The metrics of one real-time HIL run from the rover's MCAP and the peer's truth MCAP."""
    rover_stats, truth_stats = ReadStats(), ReadStats()
    rover_topics = [t for t in METRIC_TOPICS if t not in TRUTH_TOPICS]
    rover_entries = list(read_entries(rover_mcap, topics=rover_topics, stats=rover_stats))
    truth_entries = list(read_entries(truth_mcap, topics=TRUTH_TOPICS, stats=truth_stats))
    start_ns, end_ns = drive_window(rover_entries)
    metadata = [e for e in truth_entries if not isinstance(e, RecordedMessage)]
    messages = [
        e
        for e in rover_entries + truth_entries
        if isinstance(e, RecordedMessage) and start_ns <= e.log_time_ns <= end_ns
    ]
    messages.sort(key=lambda e: e.log_time_ns)  # stable: same-time messages keep their file order
    merged: list[Entry] = [*metadata, *messages]
    stats = ReadStats(
        messages=rover_stats.messages + truth_stats.messages,
        malformed=rover_stats.malformed + truth_stats.malformed,
        unknown_channel=rover_stats.unknown_channel + truth_stats.unknown_channel,
        not_json=rover_stats.not_json + truth_stats.not_json,
        truncated=rover_stats.truncated or truth_stats.truncated,
        complete=rover_stats.complete and truth_stats.complete,
    )
    return metrics_from_entries(merged, stats)


def drive_window(rover_entries: list[Entry]) -> tuple[int, int]:
    """(first control tick, first ARRIVED) in the rover's log time; the whole recording if no state."""
    states = [e for e in rover_entries if isinstance(e, RecordedMessage) and e.topic == NAVIGATOR_STATE]
    times = [e.log_time_ns for e in rover_entries if isinstance(e, RecordedMessage)]
    if not times:
        return 0, -1  # nothing recorded: an empty window, the metrics report what is missing
    if not states:
        return min(times), max(times)
    arrived = [e.log_time_ns for e in states if e.message.get("mode") == ARRIVED_MODE]
    return states[0].log_time_ns, arrived[0] if arrived else max(times)
