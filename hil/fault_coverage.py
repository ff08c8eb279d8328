"""Whether a lockstep trial exercised every fault its scenario schedules, and how long it parks for them.

A trial ends when the rover reports ARRIVED at its last goal, rolls over, finds no path, or reaches the
scenario's ``duration_s``. A test engineer who wrote a fault into a scenario expects it to run: so after
the final ARRIVED the trial goes on with the rover parked (a rover standing under a fault is a valid test:
does it drift, creep, stay put?) until every fault has run its course, and any fault the trial still did
not run in full is named as a failed criterion.

A fault without ``duration_s`` lasts "until the trial ends" (``hil.faults`` gives it an end past the
scenario's duration): it has run its course once it started before the end; if it had not started by the
arrival, the trial parks until the scenario's ``duration_s``, so the fault acts for the time the scenario
gave it rather than for no time at all.
"""

from __future__ import annotations

from collections.abc import Sequence

from hil.faults import Fault

_ENDS = {
    "rollover": "a rollover",
    "no_path": "NO_PATH (the planner found no path to the goal)",
}


def lasts_until_the_end(fault: Fault, trial_end_ns: int) -> bool:
    """A fault written without a duration: its end lies past the trial's (``hil.faults``)."""
    return fault.end_ns > trial_end_ns


def park_until_ns(faults: Sequence[Fault], arrived_ns: int, trial_end_ns: int) -> int:
    """When a trial whose rover reported ARRIVED at its last goal at ``arrived_ns`` may stop.

    ``arrived_ns`` itself if no fault is left to run; else the latest end of a fault still to run (or
    still running), and ``trial_end_ns`` (the scenario's ``duration_s``) for a fault without a duration
    that had not yet started. Never later than ``trial_end_ns``.
    """
    until = arrived_ns
    for fault in faults:
        if lasts_until_the_end(fault, trial_end_ns):
            if fault.start_ns >= arrived_ns:
                until = trial_end_ns
        elif fault.end_ns > arrived_ns:
            until = max(until, fault.end_ns)
    return min(until, trial_end_ns)


def unexercised_faults(
    faults: Sequence[Fault],
    ended_ns: int,
    trial_end_ns: int,
    end_reason: str,
    arrived_ns: int | None,
) -> list[str]:
    """Each fault that never started, or was cut short, by a trial that stopped at ``ended_ns``, in words.

    ``trial_end_ns``: the scenario's ``duration_s``; ``end_reason`` as ``TrialResult.end_reason``;
    ``arrived_ns``: when the rover reported ARRIVED at its last goal (None if it did not). An empty list:
    every fault ran its course.
    """
    how = _how_it_ended(ended_ns, trial_end_ns, end_reason, arrived_ns)
    failures = []
    for fault in faults:
        if fault.start_ns >= ended_ns:
            failures.append(f"fault {fault.name} at {_s(fault.start_ns)} s never ran: {how}")
        elif not lasts_until_the_end(fault, trial_end_ns) and fault.end_ns > ended_ns:
            failures.append(
                f"fault {fault.name} from {_s(fault.start_ns)} s to {_s(fault.end_ns)} s was cut short: {how}"
            )
    return failures


def _how_it_ended(ended_ns: int, trial_end_ns: int, end_reason: str, arrived_ns: int | None) -> str:
    at = f"{_s(ended_ns)} s"
    if end_reason == "arrived" and arrived_ns is not None and ended_ns > arrived_ns:
        # Parking runs every fault's course, so only a fault added behind the loader's back gets here.
        return f"the trial ended at {at}, parked since ARRIVED at {_s(arrived_ns)} s"
    if end_reason == "arrived":
        return f"the trial ended at ARRIVED at {at}"
    if end_reason == "timeout" or ended_ns >= trial_end_ns:
        return f"the trial ended at its duration_s, {at}"
    return f"the trial ended at {_ENDS.get(end_reason, end_reason)} at {at}"


def _s(t_ns: int) -> str:
    return f"{t_ns / 1e9:.1f}"
