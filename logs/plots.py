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
from matplotlib.patches import Circle

from logs.analysis import FloatArray, Series, TrialAnalysis
from logs.compare import RunComparison, track_of

# Text stays text in the SVG (not glyph outlines): a third of the size, and a reader can search and copy
# the legend and axis labels.
matplotlib.rcParams["svg.fonttype"] = "none"

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
    """The map: elevation, obstacles (static as circles, moving ones' tracks), every plan (faint; the last
    bold), truth and estimate, start and goal, and contacts as crosses."""
    figure, axes = plt.subplots(figsize=(7.0, 5.0))
    if run.grid is not None and run.grid_extent is not None:
        image = axes.imshow(run.grid, origin="lower", extent=run.grid_extent, cmap="terrain", alpha=0.6)
        figure.colorbar(image, ax=axes, label="elevation (m)")
    _obstacles(axes, run)
    for index, plan in enumerate(run.plans[:-1]):
        if len(plan):
            axes.plot(
                plan[:, 0], plan[:, 1], "k-", linewidth=0.6, alpha=0.25, label="plans" if index == 0 else None
            )
    if len(run.plan):
        axes.plot(run.plan[:, 0], run.plan[:, 1], "k--", linewidth=1.6, label="last plan")
    for series, label in ((run.truth, "truth"), (run.estimate, "estimate")):
        if series.t:
            _, xy = _thin(np.asarray(series.t), series.array()[:, :2])
            axes.plot(xy[:, 0], xy[:, 1], linewidth=1.2, label=label)
    _start_goal_contacts(axes, run)
    axes.set_xlabel("east (m)")
    axes.set_ylabel("north (m)")
    axes.set_aspect("equal", adjustable="datalim")
    # below the map: inside it the legend hid obstacles and contacts; none for an empty map (matplotlib
    # would warn on the console that it has nothing to list)
    if axes.get_legend_handles_labels()[0]:
        axes.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=4, fontsize="small")
    axes.set_title("trajectory")
    return _svg(figure)


def _obstacles(axes: plt.Axes, run: TrialAnalysis) -> None:
    for index, obstacle in enumerate(run.obstacles):
        circle = Circle(
            (obstacle.x, obstacle.y),
            obstacle.radius_m,
            facecolor="#8b5a2b",
            edgecolor="black",
            alpha=0.5,
            label="obstacle" if index == 0 else None,
        )
        axes.add_patch(circle)
    for index, mover in enumerate(run.moving_obstacles):
        track = np.asarray(mover.waypoints, dtype=np.float64)
        axes.plot(
            track[:, 0],
            track[:, 1],
            color="#c0392b",
            linewidth=2.0,
            alpha=0.5,
            linestyle=":",
            label="moving obstacle track" if index == 0 else None,
        )
        axes.add_patch(Circle(tuple(track[0]), mover.radius_m, fill=False, edgecolor="#c0392b"))


def _start_goal_contacts(axes: plt.Axes, run: TrialAnalysis) -> None:
    start = run.start_xy
    if start is None:
        source = run.truth if run.truth.t else run.estimate
        start = (source.values[0][0], source.values[0][1]) if source.t else None
    if start is not None:
        axes.plot(*start, marker="o", color="green", markersize=8, linestyle="none", label="start")
    if run.goal_xy is not None:
        axes.plot(
            *run.goal_xy,
            marker="*",
            color="gold",
            markeredgecolor="black",
            markersize=13,
            linestyle="none",
            label="goal",
        )
    if run.contacts:
        xy = np.array([(c.x, c.y) for c in run.contacts], dtype=np.float64)
        axes.plot(xy[:, 0], xy[:, 1], "x", color="red", markersize=9, markeredgewidth=2.0, label="contacts")


def cross_track_svg(run: TrialAnalysis) -> str:
    figure, axes = plt.subplots(figsize=_SIZE)
    t, _, s = track_of(run)  # distance driven, robust to an estimate's jitter
    if run.xte.t and len(t) >= 2:
        s_at = np.interp(np.asarray(run.xte.t), t, s)
        x, y = _thin(s_at, run.xte.array()[:, 0])
        axes.plot(x, y, linewidth=1.0)
    axes.set_xlabel("distance along the trajectory (m)")
    axes.set_ylabel("cross-track error (m)")
    axes.set_title("cross-track error (rover's estimate) against distance")
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


def comparison_svg(comparison: RunComparison, label_a: str = "A", label_b: str = "B") -> str:
    """The position gap and both speeds along the distance; the labels say which run (and whether its
    track is truth or estimate)."""
    figure, (gap, speed) = plt.subplots(2, 1, figsize=(7.0, 4.8), sharex=True)
    s = np.asarray(comparison.s_m, dtype=np.float64)
    gap.plot(s, np.asarray(comparison.position_gap_m, dtype=np.float64), linewidth=1.0)
    gap.set_ylabel("position gap (m)")
    speed.plot(s, np.asarray(comparison.speed_a, dtype=np.float64), linewidth=1.0, label=label_a)
    speed.plot(s, np.asarray(comparison.speed_b, dtype=np.float64), linewidth=1.0, label=label_b)
    speed.set_ylabel("speed (m/s)")
    speed.set_xlabel("distance along the trajectory (m)")
    speed.legend(loc="best")
    gap.set_title(f"{label_a} and {label_b} aligned by distance")
    return _svg(figure)
