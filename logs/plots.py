"""Report plots as inline SVG text (matplotlib's Agg-free SVG backend: no display, no files).

Long series are thinned to at most ``MAX_POINTS`` per line before plotting: a 10-minute trial has ~30k
poses, which a page does not need and which would make the SVG megabytes long.
"""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")  # never a window, whatever the environment says

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from logs.analysis import FloatArray, Series, TrialAnalysis, distance_along
from logs.compare import RunComparison

MAX_POINTS = 1500
_SIZE = (7.0, 3.2)


def _thin(t: FloatArray, values: FloatArray) -> tuple[FloatArray, FloatArray]:
    if len(t) <= MAX_POINTS:
        return t, values
    index = np.linspace(0, len(t) - 1, MAX_POINTS).astype(int)
    return t[index], values[index]


def _svg(figure: Figure) -> str:
    buffer = io.StringIO()
    figure.savefig(buffer, format="svg", bbox_inches="tight")
    plt.close(figure)
    text = buffer.getvalue()
    return text[text.index("<svg") :]  # drop the XML prolog and doctype so it inlines into HTML


def _line(axes: plt.Axes, series: Series, label: str, column: int = 0) -> None:
    if series.t:
        t, values = _thin(np.asarray(series.t), series.array()[:, column])
        axes.plot(t, values, label=label, linewidth=1.0)


def trajectory_svg(run: TrialAnalysis) -> str:
    figure, axes = plt.subplots(figsize=(7.0, 5.0))
    if run.grid is not None and run.grid_extent is not None:
        image = axes.imshow(run.grid, origin="lower", extent=run.grid_extent, cmap="terrain", alpha=0.6)
        figure.colorbar(image, ax=axes, label="elevation (m)")
    if len(run.plan):
        axes.plot(run.plan[:, 0], run.plan[:, 1], "k--", linewidth=1.0, label="plan")
    for series, label in ((run.truth, "truth"), (run.estimate, "estimate")):
        if series.t:
            _, xy = _thin(np.asarray(series.t), series.array()[:, :2])
            axes.plot(xy[:, 0], xy[:, 1], linewidth=1.2, label=label)
    axes.set_xlabel("east (m)")
    axes.set_ylabel("north (m)")
    axes.set_aspect("equal", adjustable="datalim")
    axes.legend(loc="best")
    axes.set_title("trajectory")
    return _svg(figure)


def cross_track_svg(run: TrialAnalysis) -> str:
    figure, axes = plt.subplots(figsize=_SIZE)
    source = run.truth if run.truth.t else run.estimate
    if run.xte.t and len(source.t) >= 2:
        s = distance_along(source.array()[:, :2])
        s_at = np.interp(np.asarray(run.xte.t), np.asarray(source.t), s)
        x, y = _thin(s_at, run.xte.array()[:, 0])
        axes.plot(x, y, linewidth=1.0)
    axes.set_xlabel("distance along the trajectory (m)")
    axes.set_ylabel("cross-track error (m)")
    axes.set_title("cross-track error against distance")
    return _svg(figure)


def vehicle_svg(run: TrialAnalysis) -> str:
    figure, (speed, current, margin) = plt.subplots(3, 1, figsize=(7.0, 6.0), sharex=True)
    _line(speed, run.speed, "speed")
    speed.set_ylabel("speed (m/s)")
    _line(current, run.current, "current")
    current.set_ylabel("input current (A)")
    _line(margin, run.stability, "margin")
    margin.set_ylabel("stability margin (rad)")
    margin.set_xlabel("time (s)")
    speed.set_title("speed, current and stability margin")
    return _svg(figure)


def innovations_svg(run: TrialAnalysis) -> str:
    figure, axes = plt.subplots(figsize=_SIZE)
    for sensor, series in sorted(run.innovations.items()):
        _line(axes, series, sensor)
    axes.set_yscale("symlog")
    axes.set_xlabel("time (s)")
    axes.set_ylabel("NIS")
    if run.innovations:
        axes.legend(loc="best")
    axes.set_title("estimator innovations (normalised, squared)")
    return _svg(figure)


def comparison_svg(comparison: RunComparison) -> str:
    figure, (gap, speed) = plt.subplots(2, 1, figsize=(7.0, 4.8), sharex=True)
    s = np.asarray(comparison.s_m, dtype=np.float64)
    gap.plot(s, np.asarray(comparison.position_gap_m, dtype=np.float64), linewidth=1.0)
    gap.set_ylabel("position gap (m)")
    speed.plot(s, np.asarray(comparison.speed_a, dtype=np.float64), linewidth=1.0, label="A")
    speed.plot(s, np.asarray(comparison.speed_b, dtype=np.float64), linewidth=1.0, label="B")
    speed.set_ylabel("speed (m/s)")
    speed.set_xlabel("distance along the trajectory (m)")
    speed.legend(loc="best")
    gap.set_title("A and B aligned by distance")
    return _svg(figure)
