"""One pass over a recording for the post-trial report: the paper's metrics plus the series to plot and the
engineering figures (estimator error, control-loop timing, CAN bus load, error counts).

Definitions and tolerances: docs/metrics.md ("Report figures"). Absent topics never raise: the figure is
``None`` and the topic is listed in ``missing``. The messages-per-topic table comes from the MCAP summary's
statistics (every channel, without reading the messages the report skips).
"""

from __future__ import annotations

import base64
import gc
import logging
import math
import re
import struct
from collections import Counter
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from mcap.exceptions import McapError
from mcap.reader import make_reader
from numpy.typing import NDArray

from logs.can_load import WINDOW_NS, BusLoad, frame_bits, load_from_frame_windows, load_from_stats
from logs.errors import LogReadError
from logs.metrics import METRIC_TOPICS, TrialMetrics, metrics_from_entries
from logs.obstacle_motion import MovingObstacle
from logs.paired_run import (
    TRUTH_TOPICS,
    PairedRead,
    merged_metrics,
    part_sources,
    read_paired,
    with_problems,
)
from logs.reader import (
    Entry,
    ReadStats,
    RecordedAttachment,
    RecordedMessage,
    RecordedMetadata,
    RecordedRaw,
    read_entries,
)
from logs.scenario_record import SCENARIO_METADATA, StaticObstacle, moving_obstacles, point, static_obstacles
from logs.topics import (
    CAN_FRAMES,
    CAN_REJECTION_CAUSES,
    CAN_STATS,
    ESTIMATOR_INNOVATIONS,
    ESTIMATOR_POSE,
    LIVE_STREAM_METADATA,
    LOG,
    MAVLINK_STATS,
    NAVIGATOR_MAP,
    NAVIGATOR_PATH,
    NAVIGATOR_STATE,
    SAFETY_EVENTS,
    TRUTH_CONTACTS,
    TRUTH_POSE,
    TRUTH_STABILITY,
    WHEELS_STATUS,
    yaw_of,
)

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
DEFAULT_CAN_BITRATE = 500_000
# can/frames are complete when they hold this share of the frames the link counted (can/stats): the
# recorder keeps everything, so only a thinned live stream falls short; a little slack for the frames of a
# poll that straddles a window's end.
_COMPLETE_SHARE = 0.99
# CAN frames are most of a recording; the bus load needs only dlc and the id kind, found without a JSON
# decode in the compact payload the recorder writes (``"extended":true,"dlc":8``).
_DLC = re.compile(rb'"dlc":(\d+)')
_EXTENDED = b'"extended":true'
# An error frame's record (the controller's report, not a frame on the wire): no bits on the bus.
_ERROR_FRAME = b'"error":true'
RAW_TOPICS = frozenset({CAN_FRAMES})
REPORT_TOPICS = frozenset(METRIC_TOPICS) | {
    CAN_STATS,
    ESTIMATOR_INNOVATIONS,
    LOG,
    MAVLINK_STATS,
    NAVIGATOR_MAP,
    SAFETY_EVENTS,
    TRUTH_STABILITY,
}
# mavlink/stats window counters -> report figures: the link's garbage, its receive-budget drops, the
# commands its signing check refused, the OBSTACLE_DISTANCE scans and the DISTANCE_SENSOR readings it could
# not read (firmware_bridge.mavlink_health).
MAVLINK_FIGURES = {
    "bad_frames": "mavlink_bad_frames",
    "dropped_bytes": "mavlink_dropped_bytes",
    "signature_rejected": "mavlink_commands_refused",
    "scans_rejected": "mavlink_scans_refused",
    "beams_rejected": "mavlink_beams_refused",
    "mission_refused": "mavlink_mission_refused",
    "mission_timeouts": "mavlink_mission_timeouts",
}
EXPECTED_TOPICS = (ESTIMATOR_POSE, NAVIGATOR_PATH, NAVIGATOR_STATE, WHEELS_STATUS, CAN_FRAMES)
# A report lists a run's safety/events up to this many of each kind, warnings and errors, and the rest (a
# soak's hour can hold thousands of mode changes): a late failsafe is never pushed out by early chatter. The
# rest are counted; `rover logs csv FILE --topics safety/events` has them all.
EVENTS_LISTED = 200


@dataclass(frozen=True)
class Event:
    """One ``safety/events`` message as a report lists it: seconds from the recording's first message."""

    t_s: float
    severity: str
    kind: str
    detail: str


@dataclass
class Series:
    """Time series for plots: ``t`` seconds from the first message, values aligned."""

    t: list[float] = field(default_factory=list)
    values: list[list[float]] = field(default_factory=list)

    def add(self, t_s: float, *values: float) -> None:
        row = [float(v) for v in values]  # first: a value that is no float leaves the series as it was
        self.t.append(t_s)
        self.values.append(row)

    def array(self) -> FloatArray:
        return np.asarray(self.values, dtype=np.float64).reshape(len(self.t), -1)


@dataclass(frozen=True)
class Contact:
    """A contact from ``truth/contacts``: where the rover was (m), its kind and what it touched."""

    x: float
    y: float
    kind: str
    obstacle_id: str


@dataclass
class TrialAnalysis:
    path: str
    metrics: TrialMetrics
    metadata: dict[str, dict[str, str]]
    attachments: list[str]
    truth: Series  # x, y
    estimate: Series  # x, y, yaw
    truth_yaw: Series  # yaw
    plan: FloatArray  # (M, 2) last planned path
    xte: Series  # cross-track error (m)
    speed: Series  # speed (m/s) from the trajectory topic
    current: Series  # total input current (A)
    stability: Series  # min(roll, pitch) margin (rad)
    innovations: dict[str, Series]  # sensor -> NIS
    figures: dict[str, float | int | None]
    counts: dict[str, int]
    missing: list[str]
    terrain_class: str = "unknown"
    can_load_source: str = "none: no CAN data"  # where the bus-load figures come from, said in the report
    counts_source: str = "MCAP summary"
    grid: FloatArray | None = None  # elevation layer of navigator/map, rows north, for the background
    grid_extent: tuple[float, float, float, float] | None = None
    plans: list[FloatArray] = field(default_factory=list)  # every planned path, in log order
    start_xy: tuple[float, float] | None = None  # the scenario's start (metadata start_json), if recorded
    goal_xy: tuple[float, float] | None = None  # the scenario's goal, else the navigator's last goal
    contacts: list[Contact] = field(default_factory=list)  # truth/contacts (simulation)
    obstacles: list[StaticObstacle] = field(default_factory=list)  # scenario metadata
    moving_obstacles: list[MovingObstacle] = field(default_factory=list)
    # A real-time HIL run: the peer's truth file merged with the rover's ``path`` (logs.paired_run), and
    # (part of the report, file it came from) for each part.
    truth_path: str | None = None
    truth_merged: bool = False  # False: the truth file was given but nothing of it merged (problems say why)
    sources: list[tuple[str, str]] = field(default_factory=list)
    # safety/events in log order (the first EVENTS_LISTED; how many more there were).
    events: list[Event] = field(default_factory=list)
    events_unlisted: int = 0

    def _truth_dict(self) -> dict[str, Any]:
        sources = dict(self.sources)
        return {"truth_path": self.truth_path, "truth_merged": self.truth_merged, "sources": sources}

    def to_dict(self) -> dict[str, Any]:
        return {
            "path": self.path,
            **(self._truth_dict() if self.truth_path else {}),
            "terrain_class": self.terrain_class,
            "metrics": self.metrics.to_dict(),
            "figures": {key: _round(value) for key, value in self.figures.items()},
            "counts": self.counts,
            "counts_source": self.counts_source,
            "can_load_source": self.can_load_source,
            "missing": self.missing,
            "metadata": self.metadata,
            "attachments": self.attachments,
            "events": [
                {"t_s": round(e.t_s, 3), "severity": e.severity, "kind": e.kind, "detail": e.detail}
                for e in self.events
            ],
            "events_unlisted": self.events_unlisted,
        }


def _round(value: float | int | None) -> float | int | None:
    if isinstance(value, float):
        return round(value, 6) if math.isfinite(value) else None
    return value


@dataclass
class _Collector:
    t0: int | None = None
    truth: Series = field(default_factory=Series)
    truth_yaw: Series = field(default_factory=Series)
    estimate: Series = field(default_factory=Series)
    plans: list[FloatArray] = field(default_factory=list)
    goal: tuple[float, float] | None = None
    contacts: list[Contact] = field(default_factory=list)
    xte: Series = field(default_factory=Series)
    speed_truth: Series = field(default_factory=Series)
    speed_estimate: Series = field(default_factory=Series)
    current: Series = field(default_factory=Series)
    stability: Series = field(default_factory=Series)
    innovations: dict[str, Series] = field(default_factory=dict)
    rejected_innovations: int = 0
    state_times: list[int] = field(default_factory=list)
    can_bits: Counter[int] = field(default_factory=Counter)  # window since the first frame -> bits
    can_frames: int = 0
    can_first_ns: int | None = None
    can_last_ns: int = 0
    # can/stats: (window_s, bits, bitrate) per message; frames on the bus (tx + rx totals) and frames
    # recorded so far, at the first and the latest message, for the completeness of can/frames.
    can_stats: list[tuple[float, int, int]] = field(default_factory=list)
    can_stats_first: tuple[int, int] | None = None
    can_stats_last: tuple[int, int] = (0, 0)
    can_link_counters: dict[str, Any] | None = None  # the last can/stats' running totals of the link
    # mavlink/stats: each window's growth of these counters, summed over windows and links.
    mavlink: Counter[str] | None = None
    safety: Counter[str] = field(default_factory=Counter)
    # The first EVENTS_LISTED warnings and errors, and the first EVENTS_LISTED of the rest, in file order.
    alarms: list[Event] = field(default_factory=list)
    notices: list[Event] = field(default_factory=list)
    events_unlisted: int = 0
    log_levels: Counter[int] = field(default_factory=Counter)
    unusable: Counter[str] = field(default_factory=Counter)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    attachments: list[str] = field(default_factory=list)
    counts: Counter[str] = field(default_factory=Counter)
    terrain: Counter[str] = field(default_factory=Counter)
    grid: FloatArray | None = None
    grid_extent: tuple[float, float, float, float] | None = None

    def seconds(self, t_ns: int) -> float:
        if self.t0 is None:
            self.t0 = t_ns
        return (t_ns - self.t0) / 1e9

    def take(self, entry: Entry) -> None:
        if isinstance(entry, RecordedMetadata):
            self.metadata[entry.name] = entry.data
        elif isinstance(entry, RecordedAttachment):
            self.attachments.append(entry.name)
        elif isinstance(entry, RecordedMessage):
            self.counts[entry.topic] += 1
            try:
                self._message(entry)
            # OverflowError: a number of hundreds of digits (JSON has them), too large for a float.
            except (KeyError, TypeError, ValueError, IndexError, OverflowError):
                self.unusable[entry.topic] += 1
        elif isinstance(entry, RecordedRaw):
            self.counts[entry.topic] += 1
            self._can_frame(entry)

    def _can_frame(self, entry: RecordedRaw) -> None:
        found = _DLC.search(entry.data)
        if found is None:
            self.unusable[entry.topic] += 1
            return
        if _ERROR_FRAME in entry.data:
            return  # not on the wire: neither a frame nor bits of the bus load
        t_ns = entry.log_time_ns
        if self.t0 is None:
            self.t0 = t_ns  # plots count time from the first message of any topic
        if self.can_first_ns is None:
            self.can_first_ns = t_ns
        self.can_bits[(t_ns - self.can_first_ns) // WINDOW_NS] += frame_bits(
            _EXTENDED in entry.data, int(found.group(1))
        )
        self.can_frames += 1
        self.can_last_ns = t_ns

    def _can_stats(self, message: dict[str, Any]) -> None:
        window = (float(message["window_s"]), int(message["bits"]), int(message["bitrate"]))
        counters = message.get("link_counters")  # absent in recordings made before it was recorded
        if isinstance(counters, dict):
            self.can_link_counters = counters
        on_bus = int(message["tx_total"]) + int(message["rx_total"])
        self.can_stats.append(window)
        if self.can_stats_first is None:
            self.can_stats_first = (on_bus, self.can_frames)
        self.can_stats_last = (on_bus, self.can_frames)

    def _message(self, entry: RecordedMessage) -> None:
        topic, message, t = entry.topic, entry.message, self.seconds(entry.log_time_ns)
        if topic == TRUTH_POSE:
            p = message["pose"]["position"]
            # Read whole before any series takes it: truth and truth_yaw must stay the same length.
            x, y, yaw = float(p["x"]), float(p["y"]), yaw_of(message["pose"])
            self.truth.add(t, x, y)
            self.truth_yaw.add(t, yaw)
            self.speed_truth.add(t, message["speed_mps"])
            self.terrain[str(message.get("terrain", ""))] += 1
        elif topic == ESTIMATOR_POSE:
            p = message["pose"]["position"]
            self.estimate.add(t, p["x"], p["y"], yaw_of(message["pose"]))
            self.speed_estimate.add(t, message["speed_mps"])
        elif topic == NAVIGATOR_PATH:
            plan = [(float(q["position"]["x"]), float(q["position"]["y"])) for q in message["poses"]]
            self.plans.append(np.asarray(plan, dtype=np.float64).reshape(-1, 2))
        elif topic == NAVIGATOR_STATE:
            self.state_times.append(entry.log_time_ns)
            goal = message.get("goal")
            if isinstance(goal, dict) and goal.get("x") is not None and goal.get("y") is not None:
                self.goal = (float(goal["x"]), float(goal["y"]))
            value = message.get("cross_track_error_m")
            if value is not None:
                self.xte.add(t, value)
        elif topic == WHEELS_STATUS:
            self.current.add(t, sum(float(w["input_current_a"]) for w in message["wheels"]))
        elif topic == TRUTH_STABILITY:
            self.stability.add(t, min(float(message["roll_margin_rad"]), float(message["pitch_margin_rad"])))
        elif topic == ESTIMATOR_INNOVATIONS:
            self.innovations.setdefault(str(message["sensor"]), Series()).add(t, message["nis"])
            self.rejected_innovations += not message["accepted"]
        elif topic == SAFETY_EVENTS:
            severity = str(message["severity"])
            self.safety[severity] += 1  # counted whatever else the message lacks
            listed = self.notices if severity == "info" else self.alarms
            if len(listed) < EVENTS_LISTED:
                listed.append(
                    Event(t, severity, str(message.get("kind", "")), str(message.get("detail", "")))
                )
            else:
                self.events_unlisted += 1
        elif topic == LOG:
            self.log_levels[int(message["level"])] += 1
        elif topic == NAVIGATOR_MAP:
            self._grid(message)
        elif topic == CAN_STATS:
            self._can_stats(message)
        elif topic == MAVLINK_STATS:
            # .get: recordings from before a counter existed (scans_rejected), and links that never had a
            # rangefinder (beams_rejected is reported only after one), lack it; none happened then.
            grown = Counter({key: int(message.get(key, 0)) for key in MAVLINK_FIGURES})
            self.mavlink = grown if self.mavlink is None else self.mavlink + grown
        elif topic == TRUTH_CONTACTS:
            contact = Contact(
                float(message["x"]), float(message["y"]), str(message["kind"]), str(message["obstacle_id"])
            )
            self.contacts.append(contact)

    def _grid(self, message: dict[str, Any]) -> None:
        columns = int(message["column_count"])
        stride = int(message["cell_stride"])
        field_offsets = {f["name"]: int(f["offset"]) for f in message["fields"]}
        offset = field_offsets.get("elevation", 0)
        raw = np.frombuffer(base64.b64decode(message["data"]), dtype=np.uint8)
        rows = len(raw) // int(message["row_stride"])
        cells = raw.reshape(rows * columns, stride)[:, offset : offset + 4].copy()
        self.grid = cells.view("<f4").reshape(rows, columns).astype(np.float64)
        origin = message["pose"]["position"]
        size = message["cell_size"]
        x0, y0 = float(origin["x"]), float(origin["y"])
        self.grid_extent = (x0, x0 + columns * float(size["x"]), y0, y0 + rows * float(size["y"]))


@contextmanager
def _cyclic_gc_paused() -> Iterator[None]:
    """Pause the cyclic garbage collector: the hundreds of thousands of decoded JSON dicts trigger many
    full collections that find nothing (JSON data has no cycles; reference counting frees it), ~30 % of
    a long report's time."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def analyse(
    path: str | Path, *, truth: str | Path | None = None, can_bitrate: int | None = None
) -> TrialAnalysis:
    """Read ``path`` once and compute everything the report shows. ``LogReadError`` for non-MCAP files.

    ``truth``: the ground truth of a real-time HIL run (``rover hil peer``'s ``truth.mcap``), ``path``
    being the rover's recording of it (``rover run``): the two are merged by log time (``logs.paired_run``)
    and analysed in the same single pass as one lockstep recording.
    """
    stats = ReadStats()
    collector = _Collector()
    paired: PairedRead | None = None
    with _cyclic_gc_paused():
        if truth is None:
            entries: Iterable[Entry] = read_entries(
                path, topics=REPORT_TOPICS, stats=stats, raw_topics=RAW_TOPICS
            )
        else:
            paired = read_paired(path, truth, topics=REPORT_TOPICS, raw_topics=RAW_TOPICS)
            entries, stats = paired.entries, paired.stats

        def tee() -> Iterator[Entry]:
            for entry in entries:
                collector.take(entry)
                yield entry

        metrics = metrics_from_entries(tee(), stats)
    if not collector.counts and not collector.metadata and not stats.truncated:
        raise LogReadError(f"{path} holds no messages or metadata at all")
    if paired is None or paired.refused:
        summary_counts = _summary_counts(path) if stats.complete and not stats.truncated else None
        run = _finish(str(path), metrics, collector, stats, can_bitrate, summary_counts)
        if paired is not None:  # given, refused: the rover's file alone, and the problem says why
            run.metrics = with_problems(metrics, paired.problems)
            run.truth_path, run.sources = str(paired.truth), part_sources(paired)
        return run
    rover_counts = (
        _summary_counts(path) if paired.rover_stats.complete and not paired.rover_stats.truncated else None
    )
    run = _finish(str(path), merged_metrics(metrics, paired), collector, stats, can_bitrate, None)
    run.truth_path = str(paired.truth)
    run.truth_merged = paired.truth_kept > 0
    run.sources = part_sources(paired)
    if rover_counts is not None:
        truth_counts = {topic: n for topic, n in collector.counts.items() if topic in TRUTH_TOPICS}
        rover_only = {topic: n for topic, n in rover_counts.items() if topic not in TRUTH_TOPICS}
        run.counts = dict(sorted((rover_only | truth_counts).items()))
        run.counts_source = "rover file's MCAP summary; truth/* read from the truth file, inside the drive"
    else:
        run.counts_source = "topics read (rover file without a summary); truth/* inside the drive"
    return run


def _summary_counts(path: str | Path) -> dict[str, int] | None:
    """Messages per topic from the MCAP summary's statistics record (every channel), or ``None`` when the
    file has no usable summary: the table then lists only the topics the report read."""
    try:
        with Path(path).open("rb") as stream:
            summary = make_reader(stream).get_summary()
    except (McapError, OSError, ValueError, struct.error, EOFError, KeyError) as err:
        logger.debug("%s: no usable summary (%s); counting the topics read", path, err)
        return None
    if summary is None or summary.statistics is None:
        return None
    counts: Counter[str] = Counter()
    for channel_id, count in summary.statistics.channel_message_counts.items():
        channel = summary.channels.get(channel_id)
        if channel is not None:
            counts[channel.topic] += count
    return dict(sorted(counts.items()))


def _finish(
    path: str,
    metrics: TrialMetrics,
    c: _Collector,
    stats: ReadStats,
    can_bitrate: int | None,
    summary_counts: dict[str, int] | None,
) -> TrialAnalysis:
    missing = [topic for topic in EXPECTED_TOPICS if c.counts[topic] == 0]
    missing += [item for item in metrics.missing if item not in missing]
    figures: dict[str, float | int | None] = {}
    figures.update(_estimator_error(c))
    figures.update(_loop_timing(c.state_times))
    bitrate = can_bitrate or _bitrate(c.metadata)
    can_figures, can_load_source = _bus_load(c, bitrate)
    figures.update(can_figures)
    for key, figure in MAVLINK_FIGURES.items():  # None: the recording has no mavlink/stats (older files)
        figures[figure] = None if c.mavlink is None else c.mavlink[key]
    figures["innovations_rejected"] = c.rejected_innovations
    figures["safety_warnings"] = c.safety["warning"]
    figures["safety_errors"] = c.safety["error"] + c.safety["fatal"]
    figures["log_errors"] = sum(n for level, n in c.log_levels.items() if level >= 4)
    figures["unusable_messages"] = sum(c.unusable.values()) + stats.skipped
    speed = c.speed_truth if c.speed_truth.t else c.speed_estimate
    scenario = c.metadata.get(SCENARIO_METADATA, {})
    obstacles, _ = static_obstacles(scenario.get("obstacles_json", "[]"))  # problems: in the metrics
    movers, _ = moving_obstacles(scenario.get("moving_obstacles_json"))
    return TrialAnalysis(
        path=path,
        metrics=metrics,
        metadata=c.metadata,
        attachments=c.attachments,
        truth=c.truth,
        estimate=c.estimate,
        truth_yaw=c.truth_yaw,
        plan=c.plans[-1] if c.plans else np.zeros((0, 2)),
        plans=c.plans,
        start_xy=point(scenario.get("start_json")),
        goal_xy=point(scenario.get("goal_json")) or c.goal,
        contacts=c.contacts,
        obstacles=obstacles,
        moving_obstacles=movers,
        xte=c.xte,
        speed=speed,
        current=c.current,
        stability=c.stability,
        innovations=c.innovations,
        figures=figures,
        counts=summary_counts if summary_counts is not None else dict(sorted(c.counts.items())),
        counts_source="MCAP summary" if summary_counts is not None else "topics read (no MCAP summary)",
        missing=missing,
        can_load_source=can_load_source,
        terrain_class=_terrain_class(c),
        grid=c.grid,
        grid_extent=c.grid_extent,
        # By time: in a `rover run` recording an event of the CAN link's thread is recorded at the next
        # poll, a little after events of the control tick it happened before (a stable sort keeps ties).
        events=sorted(c.alarms + c.notices, key=lambda event: event.t_s),
        events_unlisted=c.events_unlisted,
    )


def _terrain_class(c: _Collector) -> str:
    """The scenario's ``terrain_class`` metadata, else the class the true pose was on most often."""
    declared = c.metadata.get("scenario", {}).get("terrain_class")
    if declared:
        return declared
    c.terrain.pop("", None)
    return c.terrain.most_common(1)[0][0] if c.terrain else "unknown"


def _bitrate(metadata: dict[str, dict[str, str]]) -> int:
    try:
        return int(metadata.get("trial", {}).get("can_bitrate", DEFAULT_CAN_BITRATE))
    except ValueError:
        return DEFAULT_CAN_BITRATE


def _estimator_error(c: _Collector) -> dict[str, float | None]:
    names = (
        "estimator_position_error_rms_m",
        "estimator_position_error_max_m",
        "estimator_yaw_error_rms_rad",
    )
    if len(c.truth.t) < 2 or not c.estimate.t:
        return dict.fromkeys(names)
    truth = c.truth.array()
    estimate = c.estimate.array()
    t_truth = np.asarray(c.truth.t)
    t_est = np.asarray(c.estimate.t)
    inside = (t_est >= t_truth[0]) & (t_est <= t_truth[-1])  # no extrapolation of the truth
    if not inside.any():
        return dict.fromkeys(names)
    t_est = t_est[inside]
    estimate = estimate[inside]
    x = np.interp(t_est, t_truth, truth[:, 0])
    y = np.interp(t_est, t_truth, truth[:, 1])
    error = np.hypot(estimate[:, 0] - x, estimate[:, 1] - y)
    truth_yaw = np.unwrap(c.truth_yaw.array()[:, 0])
    yaw = np.interp(t_est, t_truth, truth_yaw)
    yaw_error = np.angle(np.exp(1j * (estimate[:, 2] - yaw)))  # wrapped to (-pi, pi]
    return {
        names[0]: float(np.sqrt(np.mean(error**2))),
        names[1]: float(error.max()),
        names[2]: float(np.sqrt(np.mean(yaw_error**2))),
    }


def _loop_timing(times_ns: list[int]) -> dict[str, float | None]:
    names = ("control_period_mean_ms", "control_period_p99_ms", "control_period_max_ms")
    if len(times_ns) < 2:
        return dict.fromkeys(names)
    periods = np.diff(np.asarray(times_ns, dtype=np.int64)) / 1e6
    return {
        names[0]: float(periods.mean()),
        names[1]: float(np.percentile(periods, 99)),
        names[2]: float(periods.max()),
    }


def _bus_load(c: _Collector, bitrate: int) -> tuple[dict[str, float | int | None], str]:
    """Bus-load figures and where they come from: the link's own count (``can/stats``) when recorded;
    else the recorded frames, but only when they are known to be every frame (never a live-stream file,
    whose can/frames may be thinned)."""
    recorded_pct = _frames_recorded_pct(c)
    counters = c.can_link_counters
    figures: dict[str, float | int | None] = {
        "can_frames": c.can_frames,
        "can_frames_recorded_pct": recorded_pct,
        "can_frames_rejected": None if counters is None else _rejected(counters),
        "can_rounds_withheld": None if counters is None else int(counters.get("withheld", 0)),
    }
    if c.can_stats:
        load = load_from_stats(c.can_stats)
        source = "can/stats (the link's own count)"
        if recorded_pct is not None and recorded_pct < 100.0 * _COMPLETE_SHARE:
            source += f"; can/frames holds only {recorded_pct:.1f} % of the frames (thinned)"
        return _load_figures(figures, load, c.can_stats[-1][2]), source
    if c.can_first_ns is None:
        return _load_figures(figures, BusLoad(None, None, 0), bitrate), "none: no CAN data"
    if LIVE_STREAM_METADATA in c.metadata:
        source = "none: a live-stream recording without can/stats; its can/frames may be thinned"
        return _load_figures(figures, BusLoad(None, None, 0), bitrate), source
    load = load_from_frame_windows(c.can_bits, c.can_first_ns, c.can_last_ns, bitrate)
    return _load_figures(figures, load, bitrate), "can/frames (every frame recorded)"


def _rejected(counters: dict[str, Any]) -> int:
    """Received frames the link refused, all causes (``can_link.CanCounters.rejected``)."""
    return sum(int(counters.get(cause, 0)) for cause in CAN_REJECTION_CAUSES)


def _frames_recorded_pct(c: _Collector) -> float | None:
    """Share of the frames the link counted between its first and last can/stats that were recorded."""
    if c.can_stats_first is None:
        return None
    on_bus = c.can_stats_last[0] - c.can_stats_first[0]
    recorded = c.can_stats_last[1] - c.can_stats_first[1]
    return 100.0 * recorded / on_bus if on_bus > 0 else None


def _load_figures(
    figures: dict[str, float | int | None], load: BusLoad, bitrate: int
) -> dict[str, float | int | None]:
    figures["can_bitrate"] = bitrate
    figures["can_bus_load_mean_pct"] = load.mean_pct
    figures["can_bus_load_peak_pct"] = load.peak_pct
    return figures
