"""One real-time HIL run from two recordings: the rover's (``rover run``) and the peer's ground truth
(``rover hil peer``), merged into one stream of entries by log time.

In lockstep one MCAP holds everything. Across processes the rover records what it sensed, planned and
decided, and the peer records the ground truth (``truth/*``) and the scenario metadata. Both stamp their
messages with the OS monotonic clock, which every process on the machine shares, so the two streams merge
by ``log_time`` and the merged stream is analysed like one lockstep recording (``logs.analysis`` and
``logs.metrics`` take it in their single pass).

What comes from where: ``truth/*`` messages from the truth file only, cut to the rover's drive (its first
control tick, the first ``navigator/state``, to its last one: the peer runs before the rover
starts and after it stops, with the rover standing still); every other message from the rover's file,
whole. Metadata: the rover's records as they are; the truth file's ``scenario`` record (the metrics need
its obstacles, tolerances and goal) when the rover has none, and its ``world`` record (when the peer's
world started: its moving obstacles are timed from it); the truth file's other records and its
attachments under ``truth:NAME``, so the peer's own ``trial`` and ``config`` are never taken for the
rover's.
"""

from __future__ import annotations

import heapq
from collections.abc import Collection, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from logs.errors import LogReadError, LogsError
from logs.metrics import METRIC_TOPICS, TrialMetrics, metrics_from_entries
from logs.reader import (
    Entry,
    ReadStats,
    RecordedAttachment,
    RecordedMessage,
    RecordedMetadata,
    RecordedRaw,
    RecordingOutline,
    read_entries,
    read_outline,
)
from logs.run_modes import LOCKSTEP_MODE
from logs.scenario_record import SCENARIO_METADATA, WORLD_METADATA
from logs.topics import NAVIGATOR_STATE, TRUTH_CONTACTS, TRUTH_POSE, TRUTH_STABILITY, TRUTH_WHEELS

# What the peer knows and the rover does not; everything else comes from the rover's file.
TRUTH_TOPICS = frozenset({TRUTH_POSE, TRUTH_WHEELS, TRUTH_STABILITY, TRUTH_CONTACTS})
TRUTH_PREFIX = "truth:"  # the truth file's own metadata and attachments, kept apart from the rover's
# A lockstep trial's log times (``LOCKSTEP_MODE``) are a simulated clock counted from 0, so they overlap any
# other lockstep trial's whichever run that was, and say nothing about pairing.
TRIAL_METADATA = "trial"
PEER_METADATA = "peer"  # the truth file's record of its HIL peer run (``run``: its id)


@dataclass
class PairedRead:
    """The merged entries of a rover file and a truth file, and what the merge found."""

    rover: Path
    truth: Path
    entries: Iterator[Entry]  # one pass; read lazily, so a long run is never all in memory at once
    stats: ReadStats  # both reads together (cut, skipped): complete once ``entries`` is exhausted
    rover_stats: ReadStats
    truth_stats: ReadStats
    window_ns: tuple[int, int]  # the rover's drive in log time; empty (start > end) if it has no tick
    truth_kept: int = 0  # truth messages inside the window
    truth_dropped: int = 0  # truth messages outside it (the peer before the rover started or after it ended)
    problems: list[str] = field(default_factory=list)
    # Not merged at all (a lockstep trial on either side, or a truth file that cannot be read): the
    # rover's file alone.
    refused: bool = False
    # The truth merged covers only part of the drive (the peer stopped first, or its file is cut): the
    # figures from the truth and those from the rover's file are of different spans.
    truth_partial: bool = False


def read_paired(
    rover: str | Path,
    truth: str | Path,
    *,
    topics: Collection[str],
    raw_topics: Collection[str] = (),
) -> PairedRead:
    """Read both files and merge them: ``LogReadError`` for a rover file that is missing, not MCAP or
    damaged; such a truth file is a problem named in ``problems``, and the entries are the rover's alone.

    ``topics``: the topics wanted; those in ``TRUTH_TOPICS`` are read from ``truth`` only, the others
    (and ``raw_topics``) from ``rover`` only. A truth file that has no truth message inside the rover's
    drive (another run's, or a lockstep trial's, whose clock is simulated) is a problem named in
    ``problems``: the entries are then the rover's run alone, without the truth file's metadata either.

    The rover's file is read twice: first its control ticks and metadata (the window needs them before
    the truth is cut), then everything, streamed into the merge; the truth inside the window is held in
    memory (a fraction of the rover's messages: no CAN frames, no innovations).
    """
    rover, truth = Path(rover), Path(truth)
    rover_stats, truth_stats = ReadStats(), ReadStats()
    wanted_truth = [topic for topic in topics if topic in TRUTH_TOPICS]
    wanted_rover = [topic for topic in topics if topic not in TRUTH_TOPICS]
    # quiet at a cut: the second read below says where the rover's file is cut, once
    ticks = list(read_entries(rover, topics=[NAVIGATOR_STATE], warn_cut=False))
    window = drive_window(ticks)
    rover_records = _records_by_name(ticks)
    rover_has_scenario = SCENARIO_METADATA in rover_records
    truth_records: dict[str, dict[str, str]] = {}
    result = PairedRead(rover, truth, iter(()), ReadStats(), rover_stats, truth_stats, window)
    kept: list[Entry] = []
    truth_metadata: list[Entry] = []
    first_truth_ns: int | None = None
    last_truth_ns = 0
    unreadable: str | None = None
    try:
        # refuse_empty: a truth file with no recording in it is not readable, not a recording cut short
        # (that would read as this run's being cut).
        for entry in read_entries(truth, topics=wanted_truth, stats=truth_stats, refuse_empty=True):
            if isinstance(entry, RecordedMessage):
                first_truth_ns = entry.log_time_ns if first_truth_ns is None else first_truth_ns
                last_truth_ns = entry.log_time_ns
                if window[0] <= entry.log_time_ns <= window[1]:
                    kept.append(entry)
                else:
                    result.truth_dropped += 1
            elif isinstance(entry, RecordedMetadata):
                truth_records[entry.name] = entry.data  # a later record of a name replaces an earlier one
                keep_name = entry.name == WORLD_METADATA or (
                    entry.name == SCENARIO_METADATA and not rover_has_scenario
                )
                truth_metadata.append(
                    entry if keep_name else RecordedMetadata(TRUTH_PREFIX + entry.name, entry.data)
                )
            elif isinstance(entry, RecordedAttachment):
                truth_metadata.append(
                    RecordedAttachment(
                        TRUTH_PREFIX + entry.name, entry.media_type, entry.log_time_ns, entry.data
                    )
                )
    except LogReadError as err:
        # The truth is the second input of this run, not the run: the rover's readable file is still
        # reported, alone, with the truth file's problem named (as a truth of another run is).
        unreadable = f"{truth}: not merged: not readable ({err}); the run is the rover's file alone"
    kept.sort(key=_log_time)  # stable
    refused = (
        unreadable
        or _lockstep_refusal(rover, _trial_mode(rover_records), truth, _trial_mode(truth_records))
        or _other_run_refusal(rover, _peer_run(rover_records), truth, _peer_run(truth_records))
    )
    if refused is not None:
        result.problems.append(refused)
        result.refused = True
        # The rover's file alone, as without --truth: a lockstep trial keeps its own truth/*, and the
        # truth file's reading (a cut, skipped messages) is no part of this run's.
        result.truth_stats = ReadStats()
        rover_entries = read_entries(rover, topics=topics, stats=rover_stats, raw_topics=raw_topics)
        result.entries = _merged([], rover_entries, [], result)
        return result
    result.truth_kept = len(kept)
    partial = _partial_cover(truth, kept, window)
    if partial is not None:
        result.problems.append(partial)
        result.truth_partial = True
    if wanted_truth and not kept:
        span = None if first_truth_ns is None else (first_truth_ns, last_truth_ns)
        result.problems.append(_no_overlap(truth, span, window))
        truth_metadata = []  # another run's scenario would be taken for this one's
    rover_entries = read_entries(rover, topics=wanted_rover, stats=rover_stats, raw_topics=raw_topics)
    result.entries = _merged(truth_metadata, rover_entries, kept, result)
    return result


def _records_by_name(entries: Iterable[Entry]) -> dict[str, dict[str, str]]:
    """``entries``' metadata by record name, a later record of a name replacing an earlier one: what
    ``read_outline`` gives as ``metadata``, so a pair is judged the same from either."""
    return {entry.name: entry.data for entry in entries if isinstance(entry, RecordedMetadata)}


def _trial_mode(records: Mapping[str, Mapping[str, str]]) -> str | None:
    """``trial.mode`` (``rover-run``, ``sim-lockstep`` ...), if recorded."""
    return records.get(TRIAL_METADATA, {}).get("mode")


def _peer_run(records: Mapping[str, Mapping[str, str]]) -> str:
    """The HIL peer run a recording belongs to, from its metadata by record name: a truth's own (``peer``
    ``run``), a rover recording's (``trial`` ``hil_peer_run``, from the rover-hil.toml the peer wrote); ""
    for older recordings. Whichever of the two files a recording is given as: a rover recording given as
    the truth, or a truth as the rover's, still names its run."""
    own = records.get(PEER_METADATA, {}).get("run")
    return own or records.get(TRIAL_METADATA, {}).get("hil_peer_run", "")


def _different_runs(run: str, other_run: str) -> bool:
    """Whether two recordings' peer runs (``_peer_run``) say they are of different runs: both recorded and
    not the same. Two runs at the same time overlap in log time: only the ids tell them apart."""
    return bool(run) and bool(other_run) and run != other_run


def _other_run_refusal(rover: Path, rover_run: str, truth: Path, truth_run: str) -> str | None:
    """Why a truth recorded by another HIL peer run than the one the rover ran against must not be merged
    (two runs at the same time overlap in log time); None when the ids agree or either is not recorded."""
    if not _different_runs(rover_run, truth_run):
        return None
    return (
        f"{truth}: not merged: recorded by HIL peer run {truth_run}, and {rover} ran against peer run "
        f"{rover_run}: another run's truth; the run is the rover's file alone"
    )


def _lockstep_refusal(rover: Path, rover_mode: str | None, truth: Path, truth_mode: str | None) -> str | None:
    """Why the two files must not be merged by log time, when either is a lockstep trial; else None."""
    lockstep = [path for path, mode in ((rover, rover_mode), (truth, truth_mode)) if mode == LOCKSTEP_MODE]
    if not lockstep:
        return None
    return (
        f"{truth}: not merged: {' and '.join(map(str, lockstep))} "
        f"{'is a lockstep trial' if len(lockstep) == 1 else 'are lockstep trials'} (trial.mode "
        f"{LOCKSTEP_MODE}), recorded on a simulated clock that starts at 0 in every trial, so log times "
        "cannot tell whether the two are one run; --truth pairs a `rover run` recording with its "
        "`rover hil peer` truth.mcap (compare two trials by giving both files instead); "
        "the run is the rover's file alone"
    )


def _log_time(entry: Entry) -> int:
    """Merge key: a message's log time; metadata and attachments (no place in time) go through at once."""
    return entry.log_time_ns if isinstance(entry, RecordedMessage | RecordedRaw) else -1


def _merged(
    truth_metadata: list[Entry], rover_entries: Iterator[Entry], truth: list[Entry], result: PairedRead
) -> Iterator[Entry]:
    yield from truth_metadata
    # The rover first: a rover and a truth message of the same log time keep that order, every time.
    # heapq.merge takes the two streams as they come: a message the rover recorded a little out of order
    # stays where it was (the metrics sort what they need by log time).
    yield from heapq.merge(rover_entries, truth, key=_log_time)
    _combine_into(result.stats, result.rover_stats, result.truth_stats)


def drive_window(rover_entries: Iterable[Entry]) -> tuple[int, int]:
    """(first control tick, last control tick): the span of the rover's ``navigator/state`` in log time;
    ``(0, -1)`` (empty) when it has none (it never ran its control loop: no drive to measure).

    The end is the last tick, not the first arrival: the rover may be sent on (a patrol), and a lockstep
    trial also goes on until the rover comes to rest; the metrics end the drive at the last arrival."""
    ticks = [
        e.log_time_ns for e in rover_entries if isinstance(e, RecordedMessage) and e.topic == NAVIGATOR_STATE
    ]
    return (min(ticks), max(ticks)) if ticks else (0, -1)


def _no_overlap(truth: str | Path, span: tuple[int, int] | None, window: tuple[int, int]) -> str:
    if window[0] > window[1]:
        return f"{truth}: not merged: the rover recorded no control tick (navigator/state), so no drive"
    if span is None:
        return f"{truth}: no truth message (truth/pose, truth/contacts ...): the run is the rover's alone"
    return (
        f"{truth}: no truth message inside the rover's drive "
        f"(truth {span[0] / 1e9:.3f}-{span[1] / 1e9:.3f} s, "
        f"rover {window[0] / 1e9:.3f}-{window[1] / 1e9:.3f} s of the monotonic clock): not the same run, or "
        "not recorded on the same machine; the run is the rover's alone"
    )


# How far inside the rover's drive the truth may start or end and still count as covering it: the peer
# records its truth every physics step, so a whole run's ends are one step (10-20 ms) from the drive's.
COVER_SLACK_NS = 500_000_000


def _partial_cover(truth: Path, kept: Sequence[Entry], window: tuple[int, int]) -> str | None:
    """Why the truth ``kept`` inside the drive ``window`` does not cover all of it; None when it does (or
    has nothing in it: ``_no_overlap`` says that)."""
    times = [entry.log_time_ns for entry in kept if isinstance(entry, RecordedMessage)]
    if not times or (times[0] - window[0] <= COVER_SLACK_NS and window[1] - times[-1] <= COVER_SLACK_NS):
        return None
    end = "ends" if window[1] - times[-1] > COVER_SLACK_NS else "starts"
    return (
        f"{truth}: the truth {end} inside the rover's drive (truth {times[0] / 1e9:.3f}-"
        f"{times[-1] / 1e9:.3f} s, drive {window[0] / 1e9:.3f}-{window[1] / 1e9:.3f} s of the monotonic "
        "clock: the peer stopped first, or its file is cut): trajectory, distance, duration, accuracy, "
        f"obstacle and goal-distance figures are of the {(times[-1] - times[0]) / 1e9:.1f} s it covers, "
        f"energy and the rover's other figures of the whole {(window[1] - window[0]) / 1e9:.1f} s drive; "
        "energy per metre, which would divide one by the other, is left out"
    )


def misplaced_truths(pairs: Sequence[tuple[Path, Path]]) -> list[str]:
    """What is wrong with (rover, truth) pairs given in order (``--truth`` once per rover recording) when
    a truth belongs to another run than its rover's: the truth files given in another order than the
    rover files. Empty when nothing is.

    Only what the recordings' outlines tell (``read_outline``: no message decoded, so cheap before the
    report's pass). First the HIL peer run both name (the truth's ``peer`` ``run``, the rover's ``trial``
    ``hil_peer_run`` from the rover-hil.toml that peer wrote): two different runs never pair, even runs
    recorded at the same time. Recordings made before the run ids, by the log-time spans: a truth recorded
    while another pair's rover ran and not while its own did. A pair with a file that cannot be read is left
    to the report, which says why, and a lockstep trial's span (a simulated clock from 0, overlapping every
    other lockstep trial's) counts as no span; ``read_paired`` still checks each pair against the rover's
    drive."""
    outlines = _outlines({path for pair in pairs for path in pair})
    spans = {path: _real_time_span(outline) for path, outline in outlines.items()}
    runs = {path: _peer_run(outline.metadata) for path, outline in outlines.items()}
    problems = []
    for number, (rover, truth) in enumerate(pairs, start=1):
        if _different_runs(runs.get(rover, ""), runs.get(truth, "")):
            problems.append(_other_peer_run(number, rover, truth, runs, pairs))
            continue
        if rover not in spans or truth not in spans or _overlap(spans[truth], spans[rover]):
            continue
        owners = [
            f"rover recording {other_number} ({other})"
            for other_number, (other, _) in enumerate(pairs, start=1)
            if other_number != number and _overlap(spans[truth], spans.get(other))
        ]
        if owners:
            problems.append(
                f"--truth {truth} (truth {number}) pairs with rover recording {number} ({rover}) but was "
                f"recorded while {' and '.join(owners)} ran, not while {rover} did"
            )
    return problems


def _outlines(paths: Iterable[Path]) -> dict[Path, RecordingOutline]:
    """Each readable file's outline; an unreadable one is left to the report, which says why in its place."""
    outlines = {}
    for path in paths:
        try:
            outlines[path] = read_outline(path, warn_cut=False)  # the report's read warns of a cut
        except LogsError:
            continue
    return outlines


def _real_time_span(outline: RecordingOutline) -> tuple[int, int] | None:
    """The file's log-time span; ``None`` for a lockstep trial or a file without messages."""
    lockstep = _trial_mode(outline.metadata) == LOCKSTEP_MODE
    return None if lockstep else outline.span_ns


def _other_peer_run(
    number: int, rover: Path, truth: Path, runs: dict[Path, str], pairs: Sequence[tuple[Path, Path]]
) -> str:
    """A truth of another peer run than its rover's, and whose run it is when that rover is among the pairs:
    decided by the run ids, so it holds for runs recorded at the same time too."""
    owners = [
        f"rover recording {other_number} ({other})"
        for other_number, (other, _) in enumerate(pairs, start=1)
        if other_number != number and runs.get(other) == runs[truth]
    ]
    whose = f"; it is the truth of {' and '.join(owners)}" if owners else ""
    return (
        f"--truth {truth} (truth {number}) pairs with rover recording {number} ({rover}) but was recorded by "
        f"HIL peer run {runs[truth]}, and {rover} ran against peer run {runs[rover]}{whose}"
    )


def _overlap(a: tuple[int, int] | None, b: tuple[int, int] | None) -> bool:
    return a is not None and b is not None and a[0] <= b[1] and b[0] <= a[1]


def _combine_into(stats: ReadStats, a: ReadStats, b: ReadStats) -> None:
    stats.messages = a.messages + b.messages
    stats.malformed = a.malformed + b.malformed
    stats.unknown_channel = a.unknown_channel + b.unknown_channel
    stats.not_json = a.not_json + b.not_json
    stats.truncated = a.truncated or b.truncated
    stats.complete = a.complete and b.complete


def paired_metrics(rover: str | Path, truth: str | Path) -> TrialMetrics:
    """The paper's metrics of one real-time run (``logs.metrics``) on the merged stream; a pairing problem
    (no truth inside the rover's drive) is among ``problems``."""
    paired = read_paired(rover, truth, topics=METRIC_TOPICS)
    return merged_metrics(metrics_from_entries(paired.entries, paired.stats), paired)


def merged_metrics(metrics: TrialMetrics, paired: PairedRead) -> TrialMetrics:
    """The metrics of the merged stream as the run's: the pairing's problems added, and no energy per
    metre when the truth covers only part of the drive (the rover's energy of the whole drive over the
    truth's distance of a part of it)."""
    if paired.truth_partial:
        metrics = replace(metrics, energy_wh_per_m=None)
    return with_problems(metrics, paired.problems)


def with_problems(metrics: TrialMetrics, problems: Sequence[str]) -> TrialMetrics:
    return replace(metrics, problems=(*metrics.problems, *problems)) if problems else metrics


def part_sources(paired: PairedRead) -> list[tuple[str, str]]:
    """(part of the report, where it came from), for the report to say which file each figure is from."""
    rover, truth = paired.rover, paired.truth
    if paired.refused:
        return [("everything (the truth file was not merged)", f"rover: {rover}")]
    if paired.truth_kept == 0:
        return [("everything (no truth inside the rover's drive)", f"rover: {rover}")]
    start_ns, end_ns = paired.window_ns
    cut = (
        f"truth: {truth} (truth/*, cut to the rover's drive {start_ns / 1e9:.3f}-{end_ns / 1e9:.3f} s of "
        f"the monotonic clock: {paired.truth_kept} messages kept, {paired.truth_dropped} outside dropped)"
    )
    return [
        ("trajectory, distance, duration, path and route accuracy, obstacle avoidance, goal distance", cut),
        ("collisions and rollovers (truth/contacts), stability margin (truth/stability)", cut),
        ("scenario: name, seed, start, goal, obstacles, tolerances", f"truth: {truth} (metadata)"),
        ("estimator error", f"rover: {rover} (estimator/pose) vs truth/pose interpolated by log time"),
        (
            "everything else: plans, cross-track error, goal reached, energy, control loop, CAN, MAVLink, "
            "innovations, safety events, log",
            f"rover: {rover}",
        ),
    ]
