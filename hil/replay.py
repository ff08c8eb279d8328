"""Replay a recording through the onboard stack: what the rover received, fed to it again under a config.

The analyst's loop for tuning: a trial or a run on the rover is recorded once; the estimator, planner,
follower or safety settings are changed; the same inputs go through the same ``OnboardStack`` code again,
faster than real time, and the new recording says what the rover would have estimated and decided. This is
what a team does with rosbag2 and robot_localization, but deterministic: replayed under the config it ran
with, a lockstep trial gives its onboard topics back byte for byte (tests/hil/test_replay.py).

Inputs, as the recording holds them: the MAVLink frames the rover received (``mavlink/raw``, "rx"), the CAN
frames it received (``can/frames``, "rx"), the ground station's commands over Zenoh (``ground/commands``,
recorded by the stack as it takes them), and in a lockstep trial with "objects" perception the
observations the simulator handed over (``perception/obstacles``); a lockstep trial's goals come from its
scenario, as ``rover hil trial`` gives them. Each onboard tick of the recording (a ``navigator/state``
message) is one tick of the replay at the same clock reading, after everything received up to then has been
written to the stack's links; inputs read between ticks (``rover run``'s ``OnboardStack.ingest``) are read
there again. What the stack sends goes nowhere: the replay is open loop, the recorded
motion does not answer a different command (``ReplayResult.commands_differing`` counts the ticks whose
wheel commands differ from the recording's).

The new recording holds the replayed stack's topics, the original's ``truth/*`` copied as they were (so
``rover logs report`` gives the estimator's error against the truth), the original's scenario, trial and
world metadata and attachments, the replay's own config (``config`` metadata, ``config.effective.json``),
and a ``replay`` metadata record naming the original.

Not replayed: MAVLink bytes that did not parse as frames, CAN error frames and bus states (a bus-off
fault's refused sends), the ground station's malformed Zenoh samples (contact for the ground-link
failsafe), and the commands of a recording made before ``ground/commands`` existed.
"""

from __future__ import annotations

import base64
import binascii
import dataclasses
import logging
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import can

from firmware_bridge.can_export import record_to_message
from firmware_bridge.errors import FrameError
from firmware_bridge.mavlink_transport import memory_pipe_pair
from hil.lockstep import onboard_links
from hil.lockstep_bus import lockstep_bus_pair
from hil.recorded_commands import RecordedCommands
from hil.recorded_obstacles import RecordedObstacles
from hil.scenario import MAVLINK_PERCEPTION, Scenario, scenario_from_table
from logs.clock import SimClock, seconds
from logs.errors import LogsError
from logs.log_topic import recording_logs
from logs.paired_run import LOCKSTEP_MODE, TRUTH_TOPICS
from logs.reader import (
    ReadStats,
    RecordedAttachment,
    RecordedMessage,
    RecordedMetadata,
    RecordedRaw,
    read_entries,
)
from logs.recorder import McapRecorder
from logs.scenario_record import SCENARIO_METADATA
from logs.settings import ConfigError, parse_toml
from logs.topics import (
    CAN_FRAMES,
    GROUND_COMMANDS,
    MAVLINK_RAW,
    NAVIGATOR_STATE,
    PERCEPTION_OBSTACLES,
    WHEELS_COMMAND,
)
from navigator.config import RoverConfig
from navigator.config_record import effective_config, flattened, record_config
from navigator.onboard import OnboardStack
from navigator.terrain import TerrainMap

_log = logging.getLogger(__name__)

ROVER_RUN_MODE = "rover-run"
REPLAYABLE_MODES = (LOCKSTEP_MODE, ROVER_RUN_MODE)
REPLAY_METADATA = "replay"
# The replay's own config goes in as the recording's config; every other metadata record and attachment
# of the original is copied as it was.
_REPLACED_METADATA = frozenset({"config", REPLAY_METADATA})
_REPLACED_ATTACHMENTS = frozenset({"config.effective.json", "config.toml"})
_INPUT_TOPICS = (MAVLINK_RAW, CAN_FRAMES, PERCEPTION_OBSTACLES, GROUND_COMMANDS)


class ReplayError(LogsError):
    """A recording cannot be replayed: no onboard ticks in it, a mode the replay does not know, or what the
    replay needs (the scenario, a map) missing."""


@dataclass(frozen=True)
class ReplayResult:
    out_path: Path
    source_mode: str  # the original's trial.mode
    ticks: int  # onboard ticks replayed
    mavlink_frames: int  # received MAVLink frames fed to the link
    can_frames: int  # received CAN frames fed to the link
    obstacle_records: int  # perception/obstacles records handed to the stack as its perception
    ground_commands: int  # ground/commands records handed to the stack as the ground station's commands
    rejected_inputs: int  # input records that could not be fed (malformed: each logged), skipped
    truth_messages: int  # truth/* messages copied
    commands_compared: int  # ticks with a wheels/command in both recordings
    commands_differing: int  # of those, ticks whose wheels/command differs byte for byte
    first_difference_s: float | None  # the first such tick's clock reading
    truncated: bool  # the original was cut short: replayed up to the cut
    ingests: int = 0  # times the links were read between ticks (as `rover run`'s loop reads them)
    # (key, as recorded, as replayed) for each config value that differs, flattened ("estimator.gps_noise_m")
    config_changes: tuple[tuple[str, str, str], ...] = ()


@dataclass(frozen=True)
class _Setup:
    """What the stack is built from, besides the inputs: the config as the run used it, its map, the goals
    it was given at the start, and whether recorded obstacles are its perception."""

    mode: str
    config: RoverConfig
    terrain: TerrainMap
    goals: tuple[tuple[float, float], ...]
    goal_source: str
    obstacles_are_input: bool
    start_ns: int | None  # the replay clock's start; None: the first input's log time


def replay_recording(
    recording: Path,
    config: RoverConfig,
    out: Path,
    *,
    scenario: Scenario | None = None,
    on_progress: Callable[[float], None] | None = None,
) -> ReplayResult:
    """Replay ``recording`` through an ``OnboardStack`` built from ``config``; write the new recording to
    ``out`` (never over an existing file: ``RecordingError``).

    ``scenario``: a lockstep trial's scenario (its goals, datum and map); None: the one the recording has
    attached. ``on_progress`` gets the replayed clock's reading in seconds about once a simulated second.
    Raises ``LogReadError`` for a file that is missing, not MCAP or damaged, ``ReplayError`` for one that
    cannot be replayed (an attached scenario that does not load among them).
    """
    metadata, attachments = _header(recording)
    setup = _setup(recording, metadata, attachments, config, scenario)
    with McapRecorder(out, exclusive=True) as recorder:
        for name, data in metadata.items():
            if name not in _REPLACED_METADATA:
                recorder.add_metadata(name, data)
        record_config(recorder, setup.config)
        for attachment in attachments.values():
            if attachment.name not in _REPLACED_ATTACHMENTS:
                recorder.add_attachment(
                    attachment.name, attachment.media_type, attachment.data, attachment.log_time_ns
                )
        replayer = _Replayer(setup, recorder, on_progress)
        replayer.run(recording)
        recorder.add_metadata(
            REPLAY_METADATA,
            {
                "of": str(recording),
                "of_mode": setup.mode,
                "config": setup.config.source,
                "ticks": str(replayer.ticks),
                "truncated": "true" if replayer.stats.truncated else "false",
            },
        )
    compared, differing, first = _compare_commands(replayer.recorded_commands, out)
    return ReplayResult(
        out_path=out,
        source_mode=setup.mode,
        ticks=replayer.ticks,
        mavlink_frames=replayer.mavlink_frames,
        can_frames=replayer.can_frames,
        obstacle_records=replayer.obstacle_records,
        ground_commands=replayer.ground_commands,
        rejected_inputs=replayer.rejected + replayer.obstacles.rejected + replayer.commands.rejected,
        truth_messages=replayer.truth_messages,
        commands_compared=compared,
        commands_differing=differing,
        first_difference_s=None if first is None else seconds(first),
        truncated=replayer.stats.truncated,
        ingests=replayer.ingests,
        config_changes=_config_changes(metadata.get("config", {}), setup.config),
    )


def _config_changes(recorded: dict[str, str], config: RoverConfig) -> tuple[tuple[str, str, str], ...]:
    """The config values the replay runs with that differ from the recording's ``config`` metadata (a key
    only one of them has shows "-" on the other side)."""
    replayed = flattened(effective_config(config))
    return tuple(
        (key, recorded.get(key, "-"), replayed.get(key, "-"))
        for key in sorted(recorded.keys() | replayed.keys())
        if recorded.get(key) != replayed.get(key)
    )


def _header(recording: Path) -> tuple[dict[str, dict[str, str]], dict[str, RecordedAttachment]]:
    """Metadata and attachments, read without decompressing a chunk."""
    metadata: dict[str, dict[str, str]] = {}
    attachments: dict[str, RecordedAttachment] = {}
    for entry in read_entries(recording, messages=False):
        if isinstance(entry, RecordedMetadata):
            metadata[entry.name] = entry.data
        elif isinstance(entry, RecordedAttachment):
            attachments[entry.name] = entry
    return metadata, attachments


def _setup(
    recording: Path,
    metadata: dict[str, dict[str, str]],
    attachments: dict[str, RecordedAttachment],
    config: RoverConfig,
    scenario: Scenario | None,
) -> _Setup:
    mode = metadata.get("trial", {}).get("mode", "")
    if mode not in REPLAYABLE_MODES:
        what = f"trial.mode {mode!r}" if mode else "no trial metadata"
        raise ReplayError(
            f"{recording}: {what}; a replay needs a recording of the onboard stack, a lockstep trial's "
            f"({LOCKSTEP_MODE}) or `rover run`'s ({ROVER_RUN_MODE}), not a HIL peer's truth file"
        )
    if mode == ROVER_RUN_MODE:
        if config.terrain is None:
            raise ReplayError(
                f"{config.source}: replaying a `rover run` recording needs the config's [map] table "
                "(the terrain the rover planned on), as `rover run` does"
            )
        return _Setup(mode, config, config.terrain, (), "", obstacles_are_input=False, start_ns=None)
    if scenario is None:
        scenario = _attached_scenario(recording, attachments)
    # As `rover hil trial` ran it: the map's origin is the scenario's datum, the goals are the mission.
    lat, lon, alt = scenario.datum
    estimator = dataclasses.replace(config.estimator, datum_lat_deg=lat, datum_lon_deg=lon, datum_alt_m=alt)
    # The perception the trial ran with (a campaign may have overridden the scenario file's).
    perception = metadata.get(SCENARIO_METADATA, {}).get("perception", scenario.sensors.perception)
    return _Setup(
        mode,
        dataclasses.replace(config, estimator=estimator),
        scenario.believed_terrain,
        tuple((goal.x, goal.y) for goal in scenario.goals),
        f"scenario {scenario.name}",
        obstacles_are_input=perception not in MAVLINK_PERCEPTION,
        start_ns=0,
    )


def _attached_scenario(recording: Path, attachments: dict[str, RecordedAttachment]) -> Scenario:
    attachment = attachments.get("scenario.toml")
    if attachment is None:
        raise ReplayError(f"{recording}: no scenario.toml attached; give the trial's scenario (--scenario)")
    name = f"{recording} (attached scenario.toml)"
    try:
        text = attachment.data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ReplayError(f"{name} is not UTF-8 text: {err}; give the trial's scenario (--scenario)") from err
    try:
        # Terrain files named in it are looked for beside the recording.
        return scenario_from_table(parse_toml(text, name), text, base_dir=recording.parent)
    except ConfigError as err:
        raise ReplayError(f"{err} (give the trial's scenario file with --scenario)") from err


class _Replayer:
    """Feeds one recording's inputs to one onboard stack, tick by recorded tick.

    What the stack received is written to its links at the log time it was recorded with, which is when
    the stack read it: inside a tick (lockstep trials: every input) or between ticks, where ``rover run``'s
    loop reads the links as samples arrive (``OnboardStack.ingest``) and the replay does the same.
    """

    def __init__(
        self, setup: _Setup, recorder: McapRecorder, on_progress: Callable[[float], None] | None
    ) -> None:
        self._setup = setup
        self._recorder = recorder
        self._on_progress = on_progress
        self.stats = ReadStats()
        self.obstacles = RecordedObstacles()
        self.commands = RecordedCommands()
        self.recorded_commands: dict[int, bytes] = {}  # the original's wheels/command by log time
        self.ticks = self.mavlink_frames = self.can_frames = self.obstacle_records = self.ground_commands = 0
        self.rejected = self.truth_messages = self.out_of_order_ticks = self.ingests = 0
        # Link inputs not written yet, all of one log time (_pending_ns): a later message moves it on.
        self._mavlink_in: list[bytes] = []
        self._can_in: list[can.Message] = []
        self._pending_ns: int | None = None
        self._next_progress_ns = 0
        self._last_ns = 0  # the latest log time read

    def run(self, recording: Path) -> None:
        entries = read_entries(
            recording,
            topics=_INPUT_TOPICS,
            raw_topics=(*TRUTH_TOPICS, NAVIGATOR_STATE, WHEELS_COMMAND),
            stats=self.stats,
        )
        self._recording = recording
        # Metadata and attachments come in file order too (read already, by _header).
        first = next((e for e in entries if isinstance(e, RecordedMessage | RecordedRaw)), None)
        if first is None:
            raise ReplayError(f"{recording} holds no messages to replay")
        start_ns = self._setup.start_ns
        self._clock = clock = SimClock(first.log_time_ns if start_ns is None else start_ns)
        # The stack's two wires, as a lockstep trial's, with the recording at the far ends.
        self._rover_bus, self._sim_bus = lockstep_bus_pair("replay", clock)
        self._rover_pipe, self._sim_pipe = memory_pipe_pair()
        with recording_logs(self._recorder, clock):
            self._stack = stack = self._build_stack()
            try:
                if self._setup.goals and not stack.start_mission(self._setup.goals, self._setup.goal_source):
                    _log.warning("replay: the stack refused the scenario's goals, as the trial's did or not")
                self._take(first)
                for entry in entries:
                    if isinstance(entry, RecordedMessage | RecordedRaw):
                        self._take(entry)
                if self._pending_ns is not None:
                    self._ingest()
                # The run ended (the stack closed: zero commands sent) at its last recorded message.
                self._advance_to(self._last_ns)
            finally:
                stack.close()
                self._drain()
                self._rover_bus.shutdown()
                self._sim_bus.shutdown()
        if self.ticks == 0:
            raise ReplayError(f"{recording} holds no onboard ticks (navigator/state): nothing was replayed")

    def _build_stack(self) -> OnboardStack:
        config, clock, recorder = self._setup.config, self._clock, self._recorder
        can_link, mavlink = onboard_links(config, self._rover_bus, self._rover_pipe, clock, recorder)
        return OnboardStack(
            config,
            clock,
            can_link,
            mavlink,
            recorder,
            self._setup.terrain,
            obstacles=self.obstacles if self._setup.obstacles_are_input else None,
            commands=self.commands,
        )

    def _take(self, entry: RecordedMessage | RecordedRaw) -> None:
        topic, t_ns = entry.topic, entry.log_time_ns
        self._last_ns = max(self._last_ns, t_ns)
        if self._pending_ns is not None and t_ns > self._pending_ns:
            # Read at a time with no tick: between ticks, as the real-time loop reads its links.
            self._ingest()
        if isinstance(entry, RecordedRaw):
            if topic == NAVIGATOR_STATE:
                self._tick(t_ns)
            elif topic == WHEELS_COMMAND:
                self.recorded_commands[t_ns] = entry.data
            else:  # truth/*: the world's, not the stack's, so copied as it was
                self._recorder.publish_bytes(topic, t_ns, entry.data)
                self.truth_messages += 1
            return
        message = entry.message
        if message.get("direction", "rx") != "rx":
            return  # what the rover sent: the replayed stack sends its own
        if topic == MAVLINK_RAW:
            try:
                self._mavlink_in.append(base64.b64decode(message["data"], validate=True))
            except (KeyError, TypeError, ValueError, binascii.Error) as err:
                self._reject(topic, t_ns, f"its data is not a frame in base64: {err!r}")
                return
            self._pending_ns = t_ns
        elif topic == CAN_FRAMES:
            try:
                self._can_in.append(record_to_message(message, t_ns, "replay"))
            except FrameError as err:
                self._reject(topic, t_ns, str(err))
                return
            self._pending_ns = t_ns
        elif topic == GROUND_COMMANDS:  # read inside a tick: handed over at the next one
            self.commands.add(t_ns, message)
            self.ground_commands += 1
        elif self._setup.obstacles_are_input:  # perception/obstacles, likewise
            self.obstacles.add(t_ns, message)
            self.obstacle_records += 1

    def _tick(self, t_ns: int) -> None:
        """One recorded tick: the clock to its reading, what arrived then into the links, one step."""
        now = self._clock.now_ns()
        if t_ns < now:
            # A recording of ours never goes back in time; a rewritten one might. Its inputs wait for the
            # next tick rather than be fed at a time that already passed.
            self.out_of_order_ticks += 1
            _log.warning(
                "replay: navigator/state at %d ns is before the replay's clock (%d ns): skipped", t_ns, now
            )
            return
        self._advance_to(t_ns)
        self._write_pending()
        self._stack.step()
        self._drain()
        self.ticks += 1
        if self._on_progress is not None and t_ns >= self._next_progress_ns:
            self._on_progress(seconds(t_ns))
            self._next_progress_ns = t_ns + 1_000_000_000

    def _ingest(self) -> None:
        """The pending inputs written at their log time and read there, as ``rover run``'s loop read them."""
        assert self._pending_ns is not None
        self._advance_to(self._pending_ns)
        self._write_pending()
        stack = self._stack
        # An ingest stops at a pacing sample and leaves the other link for the next read: read again when
        # something written at this time is still waiting there (the original read it at this time too).
        while stack.ingest() is not None and (self._rover_bus.pending() or self._rover_pipe.waiting):
            pass
        self._drain()
        self.ingests += 1

    def _write_pending(self) -> None:
        for frame in self._mavlink_in:
            self._sim_pipe.write(frame)
        for message in self._can_in:
            self._sim_bus.send(message)
        self.mavlink_frames += len(self._mavlink_in)
        self.can_frames += len(self._can_in)
        self._mavlink_in, self._can_in = [], []
        self._pending_ns = None

    def _drain(self) -> None:
        """Drop what the stack sent: nobody answers it in a replay."""
        self._sim_bus.recv_all()
        self._sim_pipe.read()

    def _advance_to(self, t_ns: int) -> None:
        now = self._clock.now_ns()
        if t_ns > now:
            self._clock.advance(t_ns - now)

    def _reject(self, topic: str, t_ns: int, why: str) -> None:
        self.rejected += 1
        _log.warning("replay of %s: %s record at %d ns not fed: %s", self._recording, topic, t_ns, why)


def _compare_commands(recorded: dict[int, bytes], out: Path) -> tuple[int, int, int | None]:
    """(ticks compared, ticks whose wheels/command differs, the first such tick's log time)."""
    compared = differing = 0
    first: int | None = None
    for entry in read_entries(out, topics=(WHEELS_COMMAND,), raw_topics=(WHEELS_COMMAND,)):
        if not isinstance(entry, RecordedRaw):
            continue
        original = recorded.get(entry.log_time_ns)
        if original is None:
            continue
        compared += 1
        if entry.data != original:
            differing += 1
            if first is None:
                first = entry.log_time_ns
    return compared, differing, first
