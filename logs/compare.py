"""Two runs of a scenario (simulated and real, or any two) side by side: aligned by distance travelled.

Each run's trajectory (``truth/pose`` if present, else ``estimator/pose``) is parametrised by the distance
driven from its first sample, s. Both are resampled on a common grid ``s_k = k * step`` up to the shorter
run's distance, and at each point the position gap, the speed of each and the cross-track error of each
are compared. Metrics are compared metric by metric (B - A); metadata key by key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from logs.analysis import FloatArray, Series, TrialAnalysis, distance_along

DEFAULT_STEP_M = 0.25


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

    def summary(self) -> dict[str, Any]:
        """Everything but the point-by-point lists (those go to the JSON in full)."""
        return {
            "a": self.a,
            "b": self.b,
            "step_m": self.step_m,
            "points": len(self.s_m),
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


def _track(run: TrialAnalysis) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(t seconds, xy, s) of the run's trajectory."""
    source = run.truth if run.truth.t else run.estimate
    if not source.t:
        return np.zeros(0), np.zeros((0, 2)), np.zeros(0)
    xy = source.array()[:, :2]
    return np.asarray(source.t), xy, distance_along(xy)


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
    t_a, xy_a, s_a = _track(a)
    t_b, xy_b, s_b = _track(b)
    if len(s_a) < 2 or len(s_b) < 2:
        return result
    length = min(s_a[-1], s_b[-1])
    grid = np.arange(0.0, length + 1e-9, step_m)
    points_a = np.column_stack([np.interp(grid, s_a, xy_a[:, 0]), np.interp(grid, s_a, xy_a[:, 1])])
    points_b = np.column_stack([np.interp(grid, s_b, xy_b[:, 0]), np.interp(grid, s_b, xy_b[:, 1])])
    gap = np.hypot(*(points_a - points_b).T)
    result.s_m = _rounded(grid)
    result.position_gap_m = _rounded(gap)
    result.speed_a = _rounded(_at(grid, s_a, t_a, a.speed))
    result.speed_b = _rounded(_at(grid, s_b, t_b, b.speed))
    result.xte_a = _rounded(_at(grid, s_a, t_a, a.xte))
    result.xte_b = _rounded(_at(grid, s_b, t_b, b.xte))
    result.gap_rms_m = float(np.sqrt(np.mean(gap**2)))
    result.gap_max_m = float(gap.max())
    return result


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
