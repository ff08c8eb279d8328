"""Success criteria of a scenario, judged from a trial's metrics alone."""

from __future__ import annotations

from hil.scenario import SuccessCriteria
from logs.metrics import TrialMetrics


def judge(criteria: SuccessCriteria, metrics: TrialMetrics) -> list[str]:
    """The criteria the trial failed, in words; an empty list means it succeeded."""
    failures = []
    if criteria.goal_reached and not metrics.goal_reached:
        failures.append("goal not reached")
    if metrics.rollovers is None or metrics.rollovers > criteria.max_rollovers:
        failures.append(f"rollovers {metrics.rollovers} > {criteria.max_rollovers}")
    if criteria.max_collisions is not None and (
        metrics.collisions is None or metrics.collisions > criteria.max_collisions
    ):
        failures.append(f"collisions {metrics.collisions} > {criteria.max_collisions}")
    if criteria.min_path_accuracy_pct is not None and (
        metrics.path_accuracy_pct is None or metrics.path_accuracy_pct < criteria.min_path_accuracy_pct
    ):
        failures.append(f"path accuracy {metrics.path_accuracy_pct} % < {criteria.min_path_accuracy_pct} %")
    if criteria.max_duration_s is not None and (
        metrics.duration_s is None or metrics.duration_s > criteria.max_duration_s
    ):
        failures.append(f"duration {metrics.duration_s} s > {criteria.max_duration_s} s")
    return failures
