"""Success criteria of a scenario, judged from a trial's metrics alone."""

from __future__ import annotations

from hil.scenario import SuccessCriteria
from logs.metrics import TrialMetrics


def judge(criteria: SuccessCriteria, metrics: TrialMetrics) -> list[str]:
    """The criteria the trial failed, in words; an empty list means it succeeded.

    A metric the recording could not give (``None``) fails the criterion that needs it: a gate must not
    pass on missing evidence.
    """
    failures = []
    if criteria.goal_reached and not metrics.goal_reached:
        failures.append("goal not reached (the rover never reported ARRIVED at the last goal)")
    if metrics.rollovers is None or metrics.rollovers > criteria.max_rollovers:
        failures.append(f"rollovers {_shown(metrics.rollovers, '{}')} > {criteria.max_rollovers}")
    if criteria.max_collisions is not None and (
        metrics.collisions is None or metrics.collisions > criteria.max_collisions
    ):
        failures.append(f"collisions {_shown(metrics.collisions, '{}')} > {criteria.max_collisions}")
    if criteria.min_path_accuracy_pct is not None and (
        metrics.path_accuracy_pct is None or metrics.path_accuracy_pct < criteria.min_path_accuracy_pct
    ):
        failures.append(
            f"path accuracy (% of driven) {_shown(metrics.path_accuracy_pct, '{:.1f}')} % "
            f"< {criteria.min_path_accuracy_pct:g} %"
        )
    if criteria.max_duration_s is not None and (
        metrics.duration_s is None or metrics.duration_s > criteria.max_duration_s
    ):
        failures.append(f"duration {_shown(metrics.duration_s, '{:.1f}')} s > {criteria.max_duration_s:g} s")
    final_distance = metrics.final_distance_to_goal_m
    if criteria.max_final_distance_m is not None and (
        final_distance is None or final_distance > criteria.max_final_distance_m
    ):
        failures.append(
            f"final distance to goal (ground truth) {_shown(final_distance, '{:.2f}')} m "
            f"> {criteria.max_final_distance_m:g} m"
        )
    return failures


def _shown(value: float | int | None, pattern: str) -> str:
    return "unknown" if value is None else pattern.format(value)
