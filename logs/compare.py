"""Two runs of a scenario (simulated and real, or any two) side by side: aligned by distance travelled.

Each run's trajectory (``truth/pose`` if present, else ``estimator/pose``) is parametrised by the distance
driven from its first sample, s (``logs.travel``: position steps for the truth, the estimator's integrated
speed for an estimate, whose jitter would otherwise count as travel). Both are sampled on a common grid
``s_k = k * step`` up to the shorter run's distance. The position gap at ``s_k`` is the distance from A's
point to the nearest point of B's track within an along-track window round ``s_k``: two runs' distances
drift apart by a few tenths of a metre over a trial (and an estimate's by its speed error), so a strict
point-by-point gap would report that drift as a lateral gap. Speed and cross-track error are read where
each run reached ``s_k``. Metrics are compared metric by metric (B - A); metadata key by key.

Runs of different scenarios (name, start or goal) are not compared point by point: a gap between two
different routes says nothing. The comparison then says why, and keeps the metric and metadata tables.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from logs.analysis import FloatArray, Series, TrialAnalysis
from logs.travel import cumulative, step_lengths, travel_steps

DEFAULT_STEP_M = 0.25
# Along-track window of the position gap: 1 m plus 2 % of the distance (the speed-integrated distance of
# an estimate drifts ~1 % from the truth's; two simulated runs of a scenario drift about as much).
WINDOW_M = 1.0
WINDOW_SHARE = 0.02
_WINDOW_SAMPLES = 101  # points of B looked at per window (2 cm apart in the 1 m window)
# Starts or goals further apart than this are different scenarios (an estimated start is off by up to a
# GPS error, ~0.7 m in the simulated trials).
SAME_PLACE_M = 1.5


@dataclass
class RunComparison:
    a: str
    b: str
    step_m: float
    s_m: list[float | None] = field(default_factory=list)
    position_gap_m: list[float | None] = field(default_factory=list)
    speed_a: list[float | None] = field(default_factory=list)
    speed_b: list[float | None] = field(default_factory=list)
    xte_a: list[float | None] = field(default_factory=list)
    xte_b: list[float | None] = field(default_factory=list)
    gap_rms_m: float | None = None
    gap_max_m: float | None = None
    metrics: dict[str, dict[str, Any]] = field(default_factory=dict)  # name -> {a, b, difference}
    metadata_differences: list[dict[str, str | None]] = field(default_factory=list)
    # Why the runs are not compared point by point (different scenarios); empty when they are.
    not_comparable: list[str] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        """Everything but the point-by-point lists (those go to the JSON in full)."""
        return {
            "a": self.a,
            "b": self.b,
            "step_m": self.step_m,
            "points": len(self.s_m),
            "comparable": not self.not_comparable,
            "not_comparable": self.not_comparable,
            "position_gap_rms_m": self.gap_rms_m,
            "position_gap_max_m": self.gap_max_m,
            "metrics": self.metrics,
            "metadata_differences": self.metadata_differences,
        }

    def to_dict(self) -> dict[str, Any]:
        out = self.summary()
        out["points_by_distance"] = {
            "s_m": self.s_m,
            "position_gap_m": self.position_gap_m,
            "speed_a_mps": self.speed_a,
            "speed_b_mps": self.speed_b,
            "cross_track_error_a_m": self.xte_a,
            "cross_track_error_b_m": self.xte_b,
        }
        return out


def track_of(run: TrialAnalysis) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(t seconds, xy, s) of the run's trajectory; s from ``logs.travel`` (robust to estimate jitter)."""
    if run.truth.t:
        xy = run.truth.array()[:, :2]
        return np.asarray(run.truth.t), xy, cumulative(step_lengths(xy))
    if not run.estimate.t:
        return np.zeros(0), np.zeros((0, 2)), np.zeros(0)
    t = np.asarray(run.estimate.t)
    xy = run.estimate.array()[:, :2]
    speed = None
    if len(run.speed.t) >= 2:  # the estimate's speed (no truth in this run), read at the pose times
        speed = np.interp(t, np.asarray(run.speed.t), run.speed.array()[:, 0])
    return t, xy, cumulative(travel_steps(t, xy, speed))


def windowed_gap(grid: FloatArray, points_a: FloatArray, s_b: FloatArray, xy_b: FloatArray) -> FloatArray:
    """For each ``points_a[k]`` (at distance ``grid[k]``), the distance (m) to the nearest point of track B
    (positions ``xy_b`` at distances ``s_b``) within ``WINDOW_M + WINDOW_SHARE * grid[k]`` of ``grid[k]``."""
    half = WINDOW_M + WINDOW_SHARE * grid
    offsets = np.linspace(-1.0, 1.0, _WINDOW_SAMPLES)
    s_query = np.clip(grid[:, None] + half[:, None] * offsets[None, :], 0.0, s_b[-1])  # (K, W)
    x = np.interp(s_query, s_b, xy_b[:, 0])
    y = np.interp(s_query, s_b, xy_b[:, 1])
    return np.asarray(np.hypot(x - points_a[:, 0:1], y - points_a[:, 1:2]).min(axis=1), dtype=np.float64)


def _at(s_grid: FloatArray, s: FloatArray, t: FloatArray, series: Series) -> FloatArray:
    """``series`` (a function of time) sampled where the run had driven ``s_grid`` metres."""
    if not series.t or len(s) < 2:
        return np.full(len(s_grid), np.nan)
    # s is non-decreasing; where the rover stood still, interp picks the first time at that distance.
    t_at = np.interp(s_grid, s, t)
    return np.interp(t_at, np.asarray(series.t), series.array()[:, 0])


def _rounded(values: FloatArray) -> list[float | None]:
    return [round(float(v), 6) if math.isfinite(v) else None for v in values]  # JSON has no NaN


def compare_runs(a: TrialAnalysis, b: TrialAnalysis, step_m: float = DEFAULT_STEP_M) -> RunComparison:
    result = RunComparison(a.path, b.path, step_m)
    result.metrics = _metric_differences(a.metrics.to_dict(), b.metrics.to_dict())
    result.metadata_differences = _metadata_differences(a.metadata, b.metadata)
    t_a, xy_a, s_a = track_of(a)
    t_b, xy_b, s_b = track_of(b)
    result.not_comparable = scenario_differences(a, b, xy_a, xy_b)
    if len(s_a) < 2 or len(s_b) < 2 or result.not_comparable:
        return result
    length = min(s_a[-1], s_b[-1])
    grid = np.arange(0.0, length + 1e-9, step_m)
    points_a = np.column_stack([np.interp(grid, s_a, xy_a[:, 0]), np.interp(grid, s_a, xy_a[:, 1])])
    gap = windowed_gap(grid, points_a, s_b, xy_b)
    result.s_m = _rounded(grid)
    result.position_gap_m = _rounded(gap)
    result.speed_a = _rounded(_at(grid, s_a, t_a, a.speed))
    result.speed_b = _rounded(_at(grid, s_b, t_b, b.speed))
    result.xte_a = _rounded(_at(grid, s_a, t_a, a.xte))
    result.xte_b = _rounded(_at(grid, s_b, t_b, b.xte))
    result.gap_rms_m = float(np.sqrt(np.mean(gap**2)))
    result.gap_max_m = float(gap.max())
    return result


def scenario_differences(a: TrialAnalysis, b: TrialAnalysis, xy_a: FloatArray, xy_b: FloatArray) -> list[str]:
    """Why two runs are of different scenarios (empty: the same, as far as the recordings say).

    Names are compared when both recordings carry one (a real run's may not); starts and goals when both
    are known: the scenario's ``start_json`` / ``goal_json``, else the first trajectory sample and the
    navigator's last goal."""
    reasons = []
    name_a, name_b = (run.metadata.get("scenario", {}).get("name") for run in (a, b))
    if name_a and name_b and name_a != name_b:
        reasons.append(f"scenario name {name_a!r} vs {name_b!r}")
    for what, place_a, place_b in (
        ("start", a.start_xy or _first(xy_a), b.start_xy or _first(xy_b)),
        ("goal", a.goal_xy, b.goal_xy),
    ):
        if place_a is not None and place_b is not None and math.dist(place_a, place_b) > SAME_PLACE_M:
            reasons.append(
                f"{what} ({place_a[0]:.1f}, {place_a[1]:.1f}) vs ({place_b[0]:.1f}, {place_b[1]:.1f}) m, "
                f"more than {SAME_PLACE_M} m apart"
            )
    return reasons


def _first(xy: FloatArray) -> tuple[float, float] | None:
    return (float(xy[0, 0]), float(xy[0, 1])) if len(xy) else None


def _metric_differences(a: dict[str, Any], b: dict[str, Any]) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    for name in sorted(set(a) | set(b)):
        va, vb = a.get(name), b.get(name)
        if isinstance(va, list | tuple) or isinstance(vb, list | tuple):
            continue
        numeric = all(isinstance(v, int | float) and not isinstance(v, bool) for v in (va, vb))
        difference = round(float(vb) - float(va), 6) if numeric else None  # type: ignore[arg-type]
        out[name] = {"a": va, "b": vb, "difference": difference, "same": va == vb}
    return out


def _metadata_differences(
    a: dict[str, dict[str, str]], b: dict[str, dict[str, str]]
) -> list[dict[str, str | None]]:
    out: list[dict[str, str | None]] = []
    for record in sorted(set(a) | set(b)):
        ra, rb = a.get(record, {}), b.get(record, {})
        if (record in a) != (record in b):
            # One row, not one per key: a real run has no simulator records, an older one no ``config``.
            out.append({"key": f"{record}.*", "a": _keys(a.get(record)), "b": _keys(b.get(record))})
            continue
        for key in sorted(set(ra) | set(rb)):
            if ra.get(key) != rb.get(key):
                out.append({"key": f"{record}.{key}", "a": ra.get(key), "b": rb.get(key)})
    return out


def _keys(record: dict[str, str] | None) -> str | None:
    return None if record is None else f"{len(record)} keys"
