"""Trial metrics computed from one MCAP recording alone (the paper's path accuracy, obstacle-avoidance
success and rollovers, plus energy, distance, duration and tracking error).

Exact definitions and tolerances: docs/metrics.md. Absent data never raises: the metric is ``None`` and
the topic or metadata key goes into ``missing``; unusable values are skipped and described in ``problems``.
"""

from __future__ import annotations

import itertools
import json
import math
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from logs.reader import (
    Entry,
    ReadStats,
    RecordedMessage,
    RecordedMetadata,
    RecordedRaw,
    Source,
    decode_json_object,
    read_entries,
)
from logs.scenario_record import (
    SCENARIO_METADATA,
    WORLD_METADATA,
    moving_obstacles,
    static_obstacles,
    world_epoch_ns,
)
from logs.topics import (
    ESTIMATOR_POSE,
    NAVIGATOR_PATH,
    NAVIGATOR_STATE,
    TRUTH_CONTACTS,
    TRUTH_POSE,
    WHEELS_STATUS,
)
from logs.travel import step_lengths, travel_steps

DEFAULT_PATH_TOLERANCE_M = 0.5
DEFAULT_ENCOUNTER_MARGIN_M = 1.5
ARRIVED_MODE = "ARRIVED"
DECIMALS = 6
# Distances compared with a tolerance get this much slack so float noise cannot flip a boundary case.
DISTANCE_EPSILON_M = 1e-9
_J_PER_WH = 3600.0
_POINT_BLOCK = 1024  # points per vectorised distance block: bounds memory at block x path segments

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class TrialMetrics:
    trajectory_topic: str | None
    duration_s: float | None
    distance_m: float | None
    path_tolerance_m: float
    path_accuracy_pct: float | None
    route_length_m: float | None
    route_accuracy_pct: float | None
    encounter_margin_m: float
    obstacles_encountered: int | None
    obstacles_avoided: int | None
    obstacle_avoidance_success_pct: float | None
    collisions: int | None
    rollovers: int | None
    energy_wh: float | None
    energy_wh_per_m: float | None
    goal_reached: bool | None
    final_distance_to_goal_m: float | None
    cross_track_error_rms_m: float | None
    cross_track_error_max_m: float | None
    # The least distance from the trajectory (the rover's centre) to an obstacle's edge, and that obstacle:
    # how near the rover came, where "encountered" only says whether it came within the margin.
    closest_obstacle_m: float | None = None
    closest_obstacle_id: str | None = None
    # What braking gave back to the pack (Wh, >= 0; energy_wh is net of it): energy_wh + this is drawn.
    energy_regenerated_wh: float | None = None
    truncated: bool = False
    skipped_messages: int = 0
    missing: tuple[str, ...] = ()
    problems: tuple[str, ...] = field(default=())

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-able dict; floats rounded to ``DECIMALS`` so the output is stable across runs."""
        return {key: _plain(value) for key, value in asdict(self).items()}

    def write_json(self, path: str | Path) -> None:
        target = Path(path)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps(self.to_dict(), indent=2, sort_keys=True) + "\n", encoding="utf-8")


def _plain(value: Any) -> Any:
    if isinstance(value, float):
        return round(value, DECIMALS) + 0.0 if math.isfinite(value) else None  # + 0.0 turns -0.0 into 0.0
    if isinstance(value, list | tuple):
        return [_plain(item) for item in value]
    return value


# --- what is gathered from the file ------------------------------------------------------------
@dataclass
class _Trial:
    poses: dict[str, list[tuple[int, float, float, float]]] = field(default_factory=dict)  # t, x, y, speed
    paths: list[tuple[int, FloatArray]] = field(default_factory=list)
    states: list[tuple[int, dict[str, Any]]] = field(default_factory=list)
    contacts: list[dict[str, Any]] = field(default_factory=list)
    # t, the six controllers' net power (W), and what the braking ones among them gave back (W, >= 0)
    power: list[tuple[int, float, float]] = field(default_factory=list)
    scenario: dict[str, str] | None = None
    world: dict[str, str] | None = None  # the simulated world's start (hil.world), when recorded
    seen: set[str] = field(default_factory=set)
    rejected: Counter[str] = field(default_factory=Counter)


def _gather(entries: Iterable[Entry]) -> _Trial:
    trial = _Trial()
    # estimator/pose read undecoded (compute_metrics): decoded only when no truth/pose gives the trajectory.
    deferred_estimates: list[RecordedRaw] = []
    seen = trial.seen
    for entry in entries:
        # Messages first: all but a handful of the entries are messages.
        if isinstance(entry, RecordedMessage):
            topic = entry.topic
            take = _TAKERS.get(topic)
            if take is not None:
                seen.add(topic)
                # _take_or_reject, inline: a Python frame fewer on each of ~6,000 messages a trial.
                try:
                    take(trial, topic, entry.log_time_ns, entry.message)
                except _UNUSABLE:
                    trial.rejected[topic] += 1
        elif isinstance(entry, RecordedRaw):
            if entry.topic == ESTIMATOR_POSE:
                trial.seen.add(entry.topic)
                deferred_estimates.append(entry)
        elif isinstance(entry, RecordedMetadata):
            if entry.name == SCENARIO_METADATA:
                trial.scenario = entry.data
            elif entry.name == WORLD_METADATA:
                trial.world = entry.data
    if not trial.poses.get(TRUTH_POSE):
        _take_deferred_estimates(trial, deferred_estimates)
    return trial


# What a taker raises for a message without usable values: it is rejected (counted), not taken.
_UNUSABLE = (KeyError, TypeError, ValueError, IndexError)


def _take_or_reject(trial: _Trial, entry: RecordedMessage, take: _Taker) -> None:
    try:
        take(trial, entry.topic, entry.log_time_ns, entry.message)
    except _UNUSABLE:
        trial.rejected[entry.topic] += 1


def _take_deferred_estimates(trial: _Trial, deferred_estimates: list[RecordedRaw]) -> None:
    """The estimated poses become the trajectory (no usable truth): decode them now. One that is not a
    JSON object is rejected as one without usable values."""
    for raw in deferred_estimates:
        message = decode_json_object(raw.data)
        if message is None:
            trial.rejected[raw.topic] += 1
        else:
            _take_or_reject(trial, RecordedMessage(raw.topic, raw.log_time_ns, message), _take_pose)


def _finite(value: Any) -> float:
    """``value`` as a finite float; ``ValueError`` for anything else (an integer of hundreds of digits,
    which JSON allows, too: float() raises OverflowError for it)."""
    try:
        number = float(value)
    except OverflowError as err:
        raise ValueError(f"{value!r} is too large for a float") from err
    if not math.isfinite(number):
        raise ValueError(f"non-finite value {value!r}")
    return number


# What each metrics topic's message adds to the trial: (trial, topic, log time, message); raises KeyError,
# TypeError, ValueError or IndexError for a message without usable values (_take_or_reject).
_Taker = Callable[[_Trial, str, int, dict[str, Any]], None]


def _take_pose(trial: _Trial, topic: str, t_ns: int, message: dict[str, Any]) -> None:
    position = message["pose"]["position"]
    speed = message.get("speed_mps")
    speed = float(speed) if isinstance(speed, int | float) and not isinstance(speed, bool) else math.nan
    trial.poses.setdefault(topic, []).append((t_ns, _finite(position["x"]), _finite(position["y"]), speed))


def _take_path(trial: _Trial, topic: str, t_ns: int, message: dict[str, Any]) -> None:
    points = [(_finite(p["position"]["x"]), _finite(p["position"]["y"])) for p in message["poses"]]
    trial.paths.append((t_ns, np.asarray(points, dtype=np.float64).reshape(-1, 2)))


def _take_state(trial: _Trial, topic: str, t_ns: int, message: dict[str, Any]) -> None:
    if not isinstance(message.get("mode"), str):
        raise ValueError("navigator/state without a mode")
    trial.states.append((t_ns, message))


def _take_contact(trial: _Trial, topic: str, t_ns: int, message: dict[str, Any]) -> None:
    if message["kind"] not in ("collision", "rollover"):
        raise ValueError(f"unknown contact kind {message['kind']!r}")
    trial.contacts.append(message)


def _take_power(trial: _Trial, topic: str, t_ns: int, message: dict[str, Any]) -> None:
    wheels = message["wheels"]
    if not wheels:
        raise ValueError("wheels/status without wheels")
    # A non-finite voltage or current makes its product, and so the sum, non-finite (inf * 0 is NaN):
    # one check of the sum is the check of every value (the hot loop of the metrics pass). A list, not a
    # generator, for sum: the same additions in the same order, without a generator frame per message.
    each = [float(w["input_voltage_v"]) * float(w["input_current_a"]) for w in wheels]
    watts = _finite(sum(each))
    trial.power.append((t_ns, watts, -sum([p for p in each if p < 0.0])))


# Looked up once per message, instead of comparing its topic with each metrics topic in turn.
_TAKERS: dict[str, _Taker] = {
    TRUTH_POSE: _take_pose,
    ESTIMATOR_POSE: _take_pose,
    NAVIGATOR_PATH: _take_path,
    NAVIGATOR_STATE: _take_state,
    TRUTH_CONTACTS: _take_contact,
    WHEELS_STATUS: _take_power,
}
# The topics the metrics read (the rest of a recording is passed over).
METRIC_TOPICS = tuple(_TAKERS)


# --- geometry ----------------------------------------------------------------------------------
def distances_to_polyline(points: FloatArray, polyline: FloatArray) -> FloatArray:
    """Shortest distance (m) from each of ``points`` (K, 2) to the polyline ``polyline`` (M >= 1, 2)."""
    if len(polyline) == 1:
        return np.asarray(np.hypot(*(points - polyline[0]).T), dtype=np.float64)
    start = polyline[:-1]  # (S, 2)
    along = polyline[1:] - start
    length_sq = np.einsum("ij,ij->i", along, along)
    safe_length_sq = np.where(length_sq > 0.0, length_sq, 1.0)  # zero-length segment: its start point
    result = np.empty(len(points), dtype=np.float64)
    for first in range(0, len(points), _POINT_BLOCK):
        block = points[first : first + _POINT_BLOCK]
        offset = block[:, None, :] - start[None, :, :]  # (B, S, 2)
        fraction = np.clip(np.einsum("bsk,sk->bs", offset, along) / safe_length_sq, 0.0, 1.0)
        fraction = np.where(length_sq > 0.0, fraction, 0.0)
        gap = offset - fraction[:, :, None] * along[None, :, :]
        result[first : first + _POINT_BLOCK] = np.sqrt(np.einsum("bsk,bsk->bs", gap, gap)).min(axis=1)
    return result


def near_polyline(points: FloatArray, polyline: FloatArray, radius: float) -> NDArray[np.bool_]:
    """Whether each of ``points`` (K, 2) lies within ``radius`` (m) of the polyline (M >= 1, 2).

    The same answer as ``distances_to_polyline(...) <= radius``, without its K x M cost on long polylines
    (a 600 s trajectory has 30,000 segments): the nearest *vertex* settles most points, because a point
    within ``radius`` of a vertex is near the polyline, and a point further than ``radius + L / 2`` from
    every vertex (L the longest segment) is near no segment (every point of a segment is within L / 2 of
    one of its ends). Only the points in between are measured against every segment.
    """
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    vertex_gap, _ = cKDTree(polyline).query(points, k=1)
    longest = float(np.hypot(*np.diff(polyline, axis=0).T).max()) if len(polyline) > 1 else 0.0
    near = vertex_gap <= radius
    unsure = ~near & (vertex_gap <= radius + 0.5 * longest)
    if unsure.any():
        near[unsure] = distances_to_polyline(points[unsure], polyline) <= radius
    return np.asarray(near, dtype=bool)


# --- the metrics -------------------------------------------------------------------------------
@dataclass
class _Notes:
    missing: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


def compute_metrics(source: Source) -> TrialMetrics:
    """All trial metrics from one recording (a path or a binary stream); see docs/metrics.md."""
    stats = ReadStats()
    # The estimated poses are the trajectory only when the recording has no truth (a real run): read
    # undecoded, they cost the JSON decoding only then (a simulated trial has both; half its cost is
    # decoding).
    entries = read_entries(source, topics=METRIC_TOPICS, raw_topics=(ESTIMATOR_POSE,), stats=stats)
    return metrics_from_entries(entries, stats)


def metrics_from_entries(entries: Iterable[Entry], stats: ReadStats) -> TrialMetrics:
    """The metrics of entries read elsewhere (one pass feeding several analyses); ``stats`` of that read,
    consulted after ``entries`` is exhausted. Messages on topics the metrics do not use are ignored."""
    trial = _gather(entries)
    notes = _Notes()
    for topic, count in sorted(trial.rejected.items()):
        notes.problems.append(f"{topic}: {count} message(s) without usable values skipped")
    if stats.truncated:
        notes.problems.append("recording is cut short; metrics cover the part before the cut")

    scenario = trial.scenario
    if scenario is None:
        notes.missing.append(f"metadata:{SCENARIO_METADATA}")
        scenario = {}
    tolerance = _scenario_length(scenario, "path_tolerance_m", DEFAULT_PATH_TOLERANCE_M, notes)
    margin = _scenario_length(scenario, "encounter_margin_m", DEFAULT_ENCOUNTER_MARGIN_M, notes)

    trajectory_topic, times, xy, speeds = _trajectory(trial, notes)
    has_trajectory = len(times) > 0
    steps = _travel(trajectory_topic, times, xy, speeds, notes)
    distance = float(steps.sum()) if has_trajectory else None
    drive_end_ns = _drive_end_ns(trial)
    duration = _duration_s(times, drive_end_ns)

    collisions, rollovers = _contact_counts(trial, trajectory_topic, notes)
    avoidance = _obstacle_avoidance(trial, scenario, times, xy, margin, notes)
    encountered, avoided, success = avoidance.encountered, avoidance.avoided, avoidance.success_pct
    energy, regenerated = _energy_wh(trial, notes)
    goal_reached, goal_distance = _goal(trial, xy, notes)
    xte_rms, xte_max = _cross_track(trial, drive_end_ns)
    route_length, route_accuracy = _route_accuracy(trial, xy, tolerance)

    return TrialMetrics(
        trajectory_topic=trajectory_topic,
        duration_s=duration,
        distance_m=distance,
        path_tolerance_m=tolerance,
        path_accuracy_pct=_path_accuracy(trial, times, xy, steps, tolerance, notes),
        route_length_m=route_length,
        route_accuracy_pct=route_accuracy,
        encounter_margin_m=margin,
        obstacles_encountered=encountered,
        obstacles_avoided=avoided,
        obstacle_avoidance_success_pct=success,
        collisions=collisions,
        rollovers=rollovers,
        energy_wh=energy,
        energy_wh_per_m=energy / distance if energy is not None and distance else None,
        goal_reached=goal_reached,
        final_distance_to_goal_m=goal_distance,
        cross_track_error_rms_m=xte_rms,
        cross_track_error_max_m=xte_max,
        closest_obstacle_m=avoidance.closest_m,
        closest_obstacle_id=avoidance.closest_id,
        energy_regenerated_wh=regenerated,
        truncated=stats.truncated,
        skipped_messages=stats.skipped + sum(trial.rejected.values()),
        missing=tuple(notes.missing),
        problems=tuple(notes.problems),
    )


def _scenario_length(scenario: dict[str, str], key: str, default: float, notes: _Notes) -> float:
    text = scenario.get(key)
    if text is None:
        return default
    try:
        value = _finite(text)
    except ValueError:
        value = -1.0
    if value < 0.0:
        notes.problems.append(
            f"metadata {SCENARIO_METADATA}.{key}={text!r} is not a length >= 0; used {default}"
        )
        return default
    return value


def _trajectory(trial: _Trial, notes: _Notes) -> tuple[str | None, NDArray[np.int64], FloatArray, FloatArray]:
    """(topic, log times ns, positions (N, 2) m, speeds (N,) m/s, NaN where not recorded)."""
    for topic in (TRUTH_POSE, ESTIMATOR_POSE):
        samples = trial.poses.get(topic)
        if samples:
            order = sorted(range(len(samples)), key=lambda i: samples[i][0])  # stable: file order on ties
            times = np.array([samples[i][0] for i in order], dtype=np.int64)
            xy = np.array([samples[i][1:3] for i in order], dtype=np.float64)
            speeds = np.array([samples[i][3] for i in order], dtype=np.float64)
            return topic, times, xy, speeds
    notes.missing.append(f"{TRUTH_POSE} or {ESTIMATOR_POSE}")
    return None, np.zeros(0, dtype=np.int64), np.zeros((0, 2), dtype=np.float64), np.zeros(0)


def _travel(
    topic: str | None, times: NDArray[np.int64], xy: FloatArray, speeds: FloatArray, notes: _Notes
) -> FloatArray:
    """Distance driven over each trajectory segment: position steps for the truth, the integrated speed
    for the estimate, whose position jitter would otherwise count as travel (logs.travel)."""
    if topic != ESTIMATOR_POSE:
        return step_lengths(xy)
    if len(speeds) and not bool(np.all(np.isfinite(speeds))):
        notes.problems.append(
            f"{ESTIMATOR_POSE}: speed_mps missing or not finite; distance summed from position steps, "
            "which counts the estimate's jitter as travel"
        )
        return step_lengths(xy)
    return travel_steps((times - times[0]) / 1e9 if len(times) else np.zeros(0), xy, speeds)


def _path_accuracy(
    trial: _Trial,
    times: NDArray[np.int64],
    xy: FloatArray,
    steps: FloatArray,
    tolerance: float,
    notes: _Notes,
) -> float | None:
    if not trial.paths:
        notes.missing.append(NAVIGATOR_PATH)
        return None
    if len(xy) < 2:
        return None
    paths = sorted(trial.paths, key=lambda item: item[0])
    path_times = np.array([t for t, _ in paths], dtype=np.int64)
    # The path in force for a segment is the latest path logged at or before the segment's end sample.
    in_force = np.searchsorted(path_times, times[1:], side="right") - 1
    midpoints = 0.5 * (xy[:-1] + xy[1:])
    counted = 0.0
    within = 0.0
    for index in np.unique(in_force):
        if index < 0 or len(paths[int(index)][1]) == 0:
            continue  # no path in force yet (or an empty one): not counted either way
        mask = in_force == index
        counted += float(steps[mask].sum())
        near = near_polyline(midpoints[mask], paths[int(index)][1], tolerance + DISTANCE_EPSILON_M)
        within += float(steps[mask][near].sum())
    if counted <= 0.0:
        return None
    return 100.0 * within / counted


def planned_route(paths: list[FloatArray]) -> list[FloatArray]:
    """The route the rover was asked to drive: each plan up to where the next one took over, then the last.

    ``paths`` in log-time order (empty ones are left out). A plan is cut at the point of it closest to
    the next plan's first pose (the rover's position when it replanned: a detour round a new obstacle,
    or a return after straying), so a part that was planned but superseded before the rover got there is
    not asked of it, while the last plan counts to its end (the goal).
    """
    plans = [path for path in paths if len(path) > 0]
    route = []
    for plan, successor in itertools.pairwise(plans):
        route.append(_cut_at_closest(plan, successor[0]))
    if plans:
        route.append(plans[-1])
    return route


def _cut_at_closest(polyline: FloatArray, point: FloatArray) -> FloatArray:
    """``polyline`` from its start to its point closest to ``point`` (the first such point on ties)."""
    if len(polyline) == 1:
        return polyline
    start = polyline[:-1]
    along = polyline[1:] - start
    length_sq = np.einsum("ij,ij->i", along, along)
    fraction = np.einsum("ij,ij->i", point - start, along) / np.where(length_sq > 0.0, length_sq, 1.0)
    fraction = np.clip(np.where(length_sq > 0.0, fraction, 0.0), 0.0, 1.0)
    closest = start + fraction[:, None] * along
    segment = int(np.argmin(np.hypot(*(closest - point).T)))
    return np.vstack([polyline[: segment + 1], closest[segment][None, :]])


def _route_pieces(route: list[FloatArray], spacing: float) -> tuple[FloatArray, FloatArray]:
    """Midpoints and lengths of the route cut into pieces no longer than ``spacing`` (m)."""
    midpoints: list[FloatArray] = []
    lengths: list[FloatArray] = []
    for polyline in route:
        for a, b in itertools.pairwise(polyline):
            length = float(np.hypot(*(b - a)))
            if length <= 0.0:
                continue
            count = max(1, math.ceil(length / spacing))
            centres = (np.arange(count, dtype=np.float64) + 0.5) / count
            midpoints.append(a + centres[:, None] * (b - a))
            lengths.append(np.full(count, length / count))
    if not midpoints:
        return np.zeros((0, 2)), np.zeros(0)
    return np.vstack(midpoints), np.concatenate(lengths)


def _route_accuracy(trial: _Trial, xy: FloatArray, tolerance: float) -> tuple[float | None, float | None]:
    """(route length m, % of it the trajectory passed within ``tolerance``); see docs/metrics.md."""
    paths = [path for _, path in sorted(trial.paths, key=lambda item: item[0])]
    route = planned_route(paths)
    if not route:
        return None, None
    # Pieces a fifth of the tolerance long: a piece counts whole or not at all, so this bounds the error.
    midpoints, lengths = _route_pieces(route, max(tolerance, 0.05) / 5.0)
    total = float(lengths.sum())
    if total <= 0.0:
        return 0.0, None
    if len(xy) == 0:
        return total, None
    followed = near_polyline(midpoints, xy, tolerance + DISTANCE_EPSILON_M)
    return total, 100.0 * float(lengths[followed].sum()) / total


def _contact_counts(
    trial: _Trial, trajectory_topic: str | None, notes: _Notes
) -> tuple[int | None, int | None]:
    # No contact message at all is normal in simulation (the channel only appears with the first event);
    # a real run has no truth, so there the counts are unknown.
    if TRUTH_CONTACTS not in trial.seen and trajectory_topic != TRUTH_POSE:
        notes.missing.append(TRUTH_CONTACTS)
        return None, None
    kinds = Counter(str(contact["kind"]) for contact in trial.contacts)
    return kinds["collision"], kinds["rollover"]


class _Avoidance(NamedTuple):
    encountered: int | None = None
    avoided: int | None = None
    success_pct: float | None = None
    closest_m: float | None = None  # centre of the rover to the nearest obstacle's edge (< 0: inside it)
    closest_id: str | None = None


def _obstacle_avoidance(
    trial: _Trial,
    scenario: dict[str, str],
    times: NDArray[np.int64],
    xy: FloatArray,
    margin: float,
    notes: _Notes,
) -> _Avoidance:
    text = scenario.get("obstacles_json")
    if text is None:
        notes.missing.append(f"metadata:{SCENARIO_METADATA}.obstacles_json")
        return _Avoidance()
    obstacles, static_problems = static_obstacles(text)
    movers, moving_problems = moving_obstacles(scenario.get("moving_obstacles_json"))
    epoch_ns, epoch_problems = world_epoch_ns(trial.world) if movers else (0, [])
    notes.problems += static_problems + moving_problems + epoch_problems
    if len(xy) == 0:
        return _Avoidance()
    hit = {str(c.get("obstacle_id")) for c in trial.contacts if c["kind"] == "collision"}
    # obstacle id -> least distance from the trajectory to its edge
    clearance: dict[str, float] = {}
    for obstacle in obstacles:
        centre = np.array([[obstacle.x, obstacle.y]], dtype=np.float64)
        clearance[obstacle.id] = float(distances_to_polyline(centre, xy)[0]) - obstacle.radius_m
    # The simulator moves them on the world's time: the clock that stamps the log, from the world's start.
    t_s = (times - epoch_ns) / 1e9
    for mover in movers:
        centres = np.array([mover.state_at(float(t))[:2] for t in t_s], dtype=np.float64)
        clearance[mover.id] = float(np.hypot(*(xy - centres).T).min()) - mover.radius_m
    # A collision means the obstacle was in the way and not avoided, whatever the sampled geometry says
    # (a cart that drives into the rover between two samples, a wall a footprint corner touched).
    encountered = [
        obstacle_id
        for obstacle_id, edge_m in clearance.items()
        if edge_m <= margin + DISTANCE_EPSILON_M or obstacle_id in hit
    ]
    avoided = sum(obstacle_id not in hit for obstacle_id in encountered)
    # The first of the nearest, in the scenario's order (static, then moving): a stable pick on a tie. A
    # distance that is not a number (an obstacle whose entries overflow) is left out: min() with a NaN
    # key would answer by the order instead.
    measured = {key: edge_m for key, edge_m in clearance.items() if not math.isnan(edge_m)}
    closest_id = min(measured, key=measured.__getitem__) if measured else None
    closest_m = None if closest_id is None else measured[closest_id]
    if TRUTH_CONTACTS in notes.missing:
        return _Avoidance(len(encountered), None, None, closest_m, closest_id)
    success = 100.0 * avoided / len(encountered) if encountered else None
    return _Avoidance(len(encountered), avoided, success, closest_m, closest_id)


def _energy_wh(trial: _Trial, notes: _Notes) -> tuple[float | None, float | None]:
    """Net energy the six controllers drew (Wh), and what the braking ones gave back (Wh, >= 0): to the
    pack, or to the motors pulling at the same time (a skid-steer turn's inner side brakes)."""
    if WHEELS_STATUS not in trial.seen:
        notes.missing.append(WHEELS_STATUS)
        return None, None
    samples = sorted(trial.power, key=lambda item: item[0])
    if len(samples) < 2:
        notes.problems.append(f"{WHEELS_STATUS}: energy needs at least two usable samples")
        return None, None
    times_s = np.array([t for t, _, _ in samples], dtype=np.float64) / 1e9
    watts = np.array([p for _, p, _ in samples], dtype=np.float64)
    returned_w = np.array([r for _, _, r in samples], dtype=np.float64)
    # The trapezoid rule is linear, and each sample's net is what the pulling motors drew less what the
    # braking ones gave back: drawn = net + returned, exactly.
    return _trapezoid_j(times_s, watts) / _J_PER_WH, _trapezoid_j(times_s, returned_w) / _J_PER_WH


def _trapezoid_j(times_s: FloatArray, watts: FloatArray) -> float:
    return float(np.sum(0.5 * (watts[1:] + watts[:-1]) * np.diff(times_s)))


def _goal(trial: _Trial, xy: FloatArray, notes: _Notes) -> tuple[bool | None, float | None]:
    if not trial.states:
        notes.missing.append(NAVIGATOR_STATE)
        return None, None
    reached = trial.states[-1][1]["mode"] == ARRIVED_MODE
    if len(xy) == 0:
        return reached, None
    for _, state in reversed(trial.states):
        goal = state.get("goal")
        try:
            gx, gy = _finite(goal["x"]), _finite(goal["y"])
        except (KeyError, TypeError, ValueError):
            continue
        return reached, math.hypot(float(xy[-1, 0]) - gx, float(xy[-1, 1]) - gy)
    return reached, None


def _drive_end_ns(trial: _Trial) -> int | None:
    """When the drive ended: the rover's last arrival (the state that began the final run of ARRIVED
    states) if the recording ends ARRIVED, else None (the drive lasts to the end of the recording).

    A recording may go on after the arrival (``rover run`` until it is stopped; a lockstep trial parked
    for its scenario's faults): the time spent standing at the goal is not part of the drive."""
    states = sorted(trial.states, key=lambda item: item[0])  # stable: file order on ties
    if not states or states[-1][1]["mode"] != ARRIVED_MODE:
        return None
    index = len(states) - 1
    while index > 0 and states[index - 1][1]["mode"] == ARRIVED_MODE:
        index -= 1
    return states[index][0]


def _duration_s(times: NDArray[np.int64], drive_end_ns: int | None) -> float | None:
    """From the first trajectory sample to the last one of the drive (at or before its end)."""
    if len(times) == 0:
        return None
    driven = times if drive_end_ns is None else times[times <= drive_end_ns]
    if len(driven) == 0:
        return 0.0  # it reported ARRIVED before the first sample: it never had to move
    return (int(driven[-1]) - int(times[0])) / 1e9


def _cross_track(trial: _Trial, drive_end_ns: int | None) -> tuple[float | None, float | None]:
    errors = []
    for t_ns, state in trial.states:
        if drive_end_ns is not None and t_ns > drive_end_ns:
            continue  # standing at the goal after the drive: no tracking to judge
        try:
            errors.append(_finite(state["cross_track_error_m"]))
        except (KeyError, TypeError, ValueError):
            continue
    if not errors:
        return None, None
    values = np.array(errors, dtype=np.float64)
    return float(np.sqrt(np.mean(values**2))), float(np.max(np.abs(values)))
