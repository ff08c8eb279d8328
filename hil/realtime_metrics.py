"""Trial metrics of a real-time HIL run: the rover's recording and the peer's ground truth, merged.

In lockstep one MCAP holds everything. Across processes the rover (``rover run``) records what it planned
and decided (``navigator/path``, ``navigator/state``, ``wheels/status``) and the peer (``rover hil peer``)
records the ground truth and the scenario metadata. Both stamp messages with the OS monotonic clock,
which all processes on the machine share, so the two streams merge by ``log_time``.

The merge is ``logs.paired_run`` (the same one ``rover logs report ROVER.mcap --truth TRUTH.mcap`` uses):
the truth is cut to the rover's drive, from its first control tick (its first ``navigator/state``) to the
end of its recording; the metrics end the drive at its last arrival, as in lockstep.
"""

from __future__ import annotations

from pathlib import Path

from logs.metrics import TrialMetrics
from logs.paired_run import paired_metrics


def realtime_metrics(rover_mcap: Path, truth_mcap: Path) -> TrialMetrics:
    """The metrics of one real-time HIL run from the rover's MCAP and the peer's truth MCAP."""
    return paired_metrics(rover_mcap, truth_mcap)
