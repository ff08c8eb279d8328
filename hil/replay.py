"""Replay a recording through the onboard stack: what the rover received, fed to it again under a config.

The analyst's loop for tuning: a trial or a run on the rover is recorded once; the estimator, planner,
follower or safety settings are changed; the same inputs go through the same ``OnboardStack`` code again,
faster than real time, and the new recording says what the rover would have estimated and decided. This is
what a team does with rosbag2 and robot_localization, but deterministic: replayed under the config it ran
with, a lockstep trial gives its recording back byte for byte (tests/hil/test_replay.py).

Inputs, as the recording holds them: the MAVLink frames the rover received (``mavlink/raw``, "rx"), the CAN
frames it received (``can/frames``, "rx", with the error frames its controller delivered: bus-off and
restarted, ``hil.replay_bus_off``), the ground station's commands (``ground/commands``, recorded by
the stack as it takes them), and in a lockstep trial with "objects" perception the observations the
simulator handed over (``perception/obstacles``); a lockstep trial's goals come from its scenario, as
``rover hil trial`` gives them (``hil.replay_setup``). Each onboard tick of the recording (a
``navigator/state`` message) is one tick of the replay at the same clock reading, after everything received
up to then has been written to the stack's links; inputs read between ticks (``rover run``'s
``OnboardStack.ingest``) are read there again. What the stack sends goes nowhere: the replay is open loop,
the recorded motion does not answer a different command (``ReplayResult.wheel_commands_differing`` counts
the ticks whose wheel commands differ from the recording's).

The new recording holds the replayed stack's topics; what the rest of the run wrote, copied as it was: the
truth (``truth/*``: so ``rover logs report`` gives the estimator's error against it) and the simulator's
and trial runner's ``log`` lines; the original's metadata and attachments; the replay's own config
(``config`` metadata, ``config.effective.json``); and a ``replay`` metadata record naming the original.

Not replayed: MAVLink bytes that did not parse as frames, the ground station's malformed Zenoh samples
(contact for the ground-link failsafe), and what a recording made before they were recorded lacks: the
commands before ``ground/commands``, the CAN error frames (and so a lockstep bus-off's refused sends)
before ``can/frames`` marked them "error".
"""

from __future__ import annotations

import base64
import binascii
import itertools
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can

from firmware_bridge.can_export import record_to_message
from firmware_bridge.errors import FrameError
from firmware_bridge.mavlink_transport import memory_pipe_pair
from hil.lockstep import onboard_links
from hil.lockstep_bus import lockstep_bus_pair
from hil.recorded_commands import RecordedCommands
from hil.recorded_obstacles import RecordedObstacles
from hil.replay_bus_off import RecordedBusOffEnd
from hil.replay_planning import NextTickPlanning
from hil.replay_setup import ReplayError, ReplaySetup, config_changes, read_header, replay_setup
from hil.scenario import Scenario
from logs.clock import SimClock, seconds
from logs.commands import RoverCommand, command_from_record
from logs.json_text import loads_json
from logs.log_topic import ONBOARD_LOGGERS, recording_logs
from logs.paired_run import TRUTH_TOPICS
from logs.reader import ReadStats, RecordedMessage, RecordedRaw, read_entries
from logs.recorder import McapRecorder
from logs.topics import (
    CAN_FRAMES,
    GROUND_COMMANDS,
    LOG,
    MAVLINK_RAW,
    NAVIGATOR_STATE,
    PERCEPTION_OBSTACLES,
    WHEELS_COMMAND,
)
from navigator.config import RoverConfig
from navigator.config_record import record_config
from navigator.onboard import OnboardStack

__all__ = ["ReplayError", "ReplayResult", "replay_recording"]

_log = logging.getLogger(__name__)

REPLAY_METADATA = "replay"
# The replay's own config goes in as the recording's config; every other metadata record and attachment
# of the original is copied as it was.
_REPLACED_METADATA = frozenset({"config", REPLAY_METADATA})
_REPLACED_ATTACHMENTS = frozenset({"config.effective.json", "config.toml"})
_INPUT_TOPICS = (MAVLINK_RAW, CAN_FRAMES, PERCEPTION_OBSTACLES, GROUND_COMMANDS)
# Read undecoded: the tick times, the recorded wheel commands, and what is copied as it was.
_RAW_TOPICS = (*TRUTH_TOPICS, NAVIGATOR_STATE, WHEELS_COMMAND, LOG)


@dataclass(frozen=True)
class ReplayResult:
    out_path: Path
    source_mode: str  # the original's trial.mode
    ticks: int  # onboard ticks replayed
    mavlink_frames: int  # received MAVLink frames fed to the link
    can_frames: int  # received CAN frames fed to the link, error frames included
    obstacle_records: int  # perception/obstacles records handed to the stack as its perception
    ground_commands: int  # ground/commands records handed to the stack as the ground station's commands
    # Input records, or obstacles within one, that could not be read or fed (each logged, skipped).
    rejected_inputs: int
    ticks_skipped: int  # navigator/state records earlier than the one before them (a rewritten file)
    copied_messages: int  # truth/* and the simulator's log lines, copied as they were
    wheel_commands_compared: int  # ticks with a wheels/command in both recordings
    wheel_commands_differing: int  # of those, ticks whose wheels/command differs byte for byte
    first_difference_s: float | None  # the first such tick, seconds from the replay's start (a trial's: 0)
    wheel_speed_difference_max_mps: float  # the largest difference of one wheel's commanded speed
    truncated: bool  # the original was cut short or damaged: replayed up to there
    ingests: int = 0  # times the links were read between ticks (as `rover run`'s loop reads them)
    can_error_frames: int = 0  # of can_frames, the controller's error frames (bus-off, restarted...)
    can_sends_refused: int = 0  # frames the replay's CAN end refused during a lockstep trial's bus-off
    # (key, as recorded, as replayed) for each config value that differs, flattened ("estimator.gps_noise_m")
    config_changes: tuple[tuple[str, str, str], ...] = ()

    @property
    def partial(self) -> bool:
        """Not all of the recording went in: cut short, damaged, or some input or tick skipped."""
        return self.truncated or self.rejected_inputs > 0 or self.ticks_skipped > 0


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
    Raises ``LogReadError`` for a file that is missing or not MCAP, ``ReplayError`` for one that cannot be
    replayed (an attached scenario that does not load among them); then nothing is left at ``out``. A file
    cut short or damaged is replayed up to there (``ReplayResult.truncated``).
    """
    header = read_header(recording)
    setup = replay_setup(recording, header, config, scenario)
    replayer = _Replayer(setup, on_progress)
    try:
        with McapRecorder(out, exclusive=True) as recorder:
            for name, data in header.metadata.items():
                if name not in _REPLACED_METADATA:
                    recorder.add_metadata(name, data)
            record_config(recorder, setup.config)
            for attachment in header.attachments.values():
                if attachment.name not in _REPLACED_ATTACHMENTS:
                    recorder.add_attachment(
                        attachment.name, attachment.media_type, attachment.data, attachment.log_time_ns
                    )
            replayer.run(recording, recorder)
            recorder.add_metadata(
                REPLAY_METADATA,
                {
                    "of": str(recording),
                    "of_mode": setup.mode,
                    "config": setup.config.source,
                    "ticks": str(replayer.ticks),
                    "truncated": "true" if replayer.truncated else "false",
                },
            )
    except ReplayError:
        out.unlink(missing_ok=True)  # ours (created exclusively), and it replays nothing
        raise
    wheels = _compare_wheel_commands(replayer.recorded_wheel_commands, out)
    return ReplayResult(
        out_path=out,
        source_mode=setup.mode,
        ticks=replayer.ticks,
        mavlink_frames=replayer.mavlink_frames,
        can_frames=replayer.can_frames,
        obstacle_records=replayer.obstacle_records,
        ground_commands=replayer.ground_commands,
        rejected_inputs=replayer.rejected_inputs,
        ticks_skipped=replayer.ticks_skipped,
        copied_messages=replayer.copied_messages,
        wheel_commands_compared=wheels.compared,
        wheel_commands_differing=wheels.differing,
        first_difference_s=None if wheels.first_ns is None else seconds(wheels.first_ns - replayer.start_ns),
        wheel_speed_difference_max_mps=wheels.largest_mps,
        truncated=replayer.truncated,
        ingests=replayer.ingests,
        can_error_frames=replayer.can_error_frames,
        can_sends_refused=0 if replayer.bus_off is None else replayer.bus_off.refused,
        config_changes=config_changes(header.metadata.get("config", {}), setup.config),
    )


@dataclass(frozen=True)
class _Input:
    """One thing the stack took in, at its log time: a received frame, or a command given from outside."""

    t_ns: int
    mavlink: bytes | None = None
    can: can.Message | None = None
    command: RoverCommand | None = None


class _Replayer:
    """Feeds one recording's inputs to one onboard stack, tick by recorded tick.

    What the stack received is written to its links at the log time it was recorded with, which is when
    the stack read it: inside a tick (lockstep trials: every input) or between ticks, where ``rover run``'s
    loop reads the links as samples arrive (``OnboardStack.ingest``) and the replay does the same.
    """

    def __init__(self, setup: ReplaySetup, on_progress: Callable[[float], None] | None) -> None:
        self._setup = setup
        self._on_progress = on_progress
        self._stats = ReadStats()
        self.obstacles = RecordedObstacles()
        self.ground_station = RecordedCommands()
        self.recorded_wheel_commands: dict[int, bytes] = {}  # the original's wheels/command by log time
        self.ticks = self.mavlink_frames = self.can_frames = self.obstacle_records = self.ground_commands = 0
        self.copied_messages = self.ticks_skipped = self.ingests = self._rejected = 0
        self.can_error_frames = 0
        self.bus_off: RecordedBusOffEnd | None = None  # the rover's CAN end in a lockstep trial's replay
        # What the stack took in since the last tick, in file order, until the next tick's navigator/state
        # says which of it came before the tick (read between ticks) and which inside it.
        self._since_tick: list[_Input] = []
        self._next_progress_ns = 0
        self._last_ns = 0  # the latest log time read
        self.start_ns = 0  # the replay clock's first reading (run sets it)
        self._planning = NextTickPlanning() if setup.plans_a_tick_late else None

    @property
    def truncated(self) -> bool:
        return self._stats.truncated or self._stats.stop is not None

    @property
    def rejected_inputs(self) -> int:
        # The reader's skipped messages (a payload that is not a JSON object) are inputs lost too.
        return self._rejected + self._stats.skipped + self.obstacles.rejected + self.ground_station.rejected

    def run(self, recording: Path, recorder: McapRecorder) -> None:
        self._recording, self._recorder = recording, recorder
        start_ns = self._setup.start_ns
        entries = read_entries(
            recording, topics=_INPUT_TOPICS, raw_topics=_RAW_TOPICS, stats=self._stats, stop_at_damage=True
        )
        messages = (e for e in entries if isinstance(e, RecordedMessage | RecordedRaw))
        first = next(messages, None)  # a `rover run` clock starts where its recording does
        if first is None:
            raise ReplayError(f"{recording} holds no messages to replay")
        self.start_ns = first.log_time_ns if start_ns is None else start_ns
        self._clock = clock = SimClock(self.start_ns)
        # The stack's two wires, as a lockstep trial's, with the recording at the far ends.
        self._rover_bus, self._sim_bus = lockstep_bus_pair("replay", clock)
        if self._setup.bus_off_refuses_sends:
            self.bus_off = RecordedBusOffEnd(self._rover_bus)
        self._rover_pipe, self._sim_pipe = memory_pipe_pair()
        with recording_logs(recorder, clock):
            self._stack = stack = self._build_stack()
            try:
                goals = self._setup.goals
                if goals and not stack.start_mission(goals, self._setup.goal_source):
                    _log.warning(
                        "replay: the stack refused the scenario's goals (its mission_rejected event)"
                    )
                self._take(first)
                for entry in messages:
                    self._take(entry)
                self._between_ticks(self._since_tick)  # read after the last tick, before the run ended
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
        can_end = self._rover_bus if self.bus_off is None else self.bus_off
        can_link, mavlink = onboard_links(config, can_end, self._rover_pipe, clock, recorder)
        return OnboardStack(
            config,
            clock,
            can_link,
            mavlink,
            recorder,
            self._setup.terrain,
            obstacles=self.obstacles if self._setup.obstacles_are_input else None,
            commands=self.ground_station,
            planning=self._planning,
        )

    def _take(self, entry: RecordedMessage | RecordedRaw) -> None:
        topic, t_ns = entry.topic, entry.log_time_ns
        self._last_ns = max(self._last_ns, t_ns)
        if isinstance(entry, RecordedRaw):
            self._take_raw(topic, t_ns, entry.data)
            return
        message = entry.message
        if topic == GROUND_COMMANDS:
            self._take_command(t_ns, message)
        elif topic == PERCEPTION_OBSTACLES:
            # Else the stack's own output, from scans; and a record of its own marks alone is no input.
            if self._setup.obstacles_are_input and self.obstacles.add(t_ns, message):
                self.obstacle_records += 1
        else:
            self._take_frame(topic, t_ns, message)

    def _take_command(self, t_ns: int, record: dict[str, Any]) -> None:
        """A ground station's command was read inside a tick: it is handed over at the next one. One from
        ``rover run --goal`` was given at once, before the loop: so it is again, at its time."""
        self.ground_commands += 1
        if record.get("origin") != "command line":
            self.ground_station.add(t_ns, record)
            return
        try:
            command = command_from_record(record)
        except ValueError as err:
            self._reject(GROUND_COMMANDS, t_ns, str(err))
            return
        self._since_tick.append(_Input(t_ns, command=command))

    def _take_raw(self, topic: str, t_ns: int, data: bytes) -> None:
        if topic == NAVIGATOR_STATE:
            self._tick(t_ns)
        elif topic == WHEELS_COMMAND:
            self.recorded_wheel_commands[t_ns] = data
        elif topic != LOG or not _onboard_line(data):
            # The world's truth, the simulator's and the trial runner's lines: not the stack's, so copied.
            self._recorder.publish_bytes(topic, t_ns, data)
            self.copied_messages += 1

    def _take_frame(self, topic: str, t_ns: int, record: dict[str, Any]) -> None:
        """A mavlink/raw or can/frames record: a received frame waits for its read; a sent one is dropped
        (the replayed stack sends its own)."""
        direction = record.get("direction")
        if direction == "tx":
            return
        if direction != "rx":
            self._reject(topic, t_ns, f"direction {direction!r} is neither 'rx' nor 'tx'")
            return
        if topic == MAVLINK_RAW:
            try:
                frame = base64.b64decode(record["data"], validate=True)
            except (KeyError, TypeError, ValueError, binascii.Error) as err:
                self._reject(topic, t_ns, f"its data is not a frame in base64: {err!r}")
                return
            self._since_tick.append(_Input(t_ns, mavlink=frame))
        else:
            try:
                self._since_tick.append(_Input(t_ns, can=record_to_message(record, t_ns, "replay")))
            except FrameError as err:
                self._reject(topic, t_ns, str(err))

    def _tick(self, t_ns: int) -> None:
        """One recorded tick. What was read before the tick's clock reading was read between ticks (an
        ingest: `rover run`'s loop reads its links as samples arrive); what was read at or after it, inside
        the tick (its own link reads take a moment past the tick's start). Then one step at the reading."""
        now = self._clock.now_ns()
        if t_ns < now:
            # A recording of ours never goes back in time; a rewritten one might. What it read waits for
            # the next tick rather than be fed at a time that already passed.
            self.ticks_skipped += 1
            _log.warning(
                "replay: navigator/state at %d ns is before the replay's clock (%d ns): skipped", t_ns, now
            )
            return
        inputs, self._since_tick = self._since_tick, []
        self._between_ticks([i for i in inputs if i.t_ns < t_ns])
        self._advance_to(t_ns)
        self._take_in([i for i in inputs if i.t_ns >= t_ns])
        if self._planning is not None:
            self._planning.release()
        self._stack.step()
        self._drain()
        self.ticks += 1
        if self._on_progress is not None and t_ns >= self._next_progress_ns:
            self._on_progress(seconds(t_ns - self.start_ns))
            self._next_progress_ns = t_ns + 1_000_000_000

    def _between_ticks(self, inputs: list[_Input]) -> None:
        """Inputs read between ticks, each batch of one log time at that time, as ``rover run``'s loop read
        them (``OnboardStack.ingest``)."""
        for t_ns, batch in itertools.groupby(inputs, key=lambda i: i.t_ns):
            items = list(batch)
            self._advance_to(t_ns)
            self._take_in(items)
            if all(item.command is not None for item in items):
                continue  # a command-line goal alone: the rover read no link then
            stack = self._stack
            # An ingest stops at a pacing sample and leaves the other link for the next read: read again
            # while something written at this time still waits there (the original read it now too).
            self.ingests += 1
            while stack.ingest() is not None and (self._rover_bus.pending() or self._rover_pipe.waiting):
                self.ingests += 1
            self._drain()

    def _take_in(self, inputs: list[_Input]) -> None:
        """Frames onto the links (read at the stack's next read), commands given to the stack."""
        for item in inputs:
            if item.mavlink is not None:
                self._sim_pipe.write(item.mavlink)
                self.mavlink_frames += 1
            elif item.can is not None:
                self._sim_bus.send(item.can)
                self.can_frames += 1
                if item.can.is_error_frame:
                    self.can_error_frames += 1
                    if self.bus_off is not None:
                        self.bus_off.heard(item.can)
            elif item.command is not None:
                self._stack.take_command(item.command)

    def _drain(self) -> None:
        """Drop what the stack sent: nobody answers it in a replay."""
        self._sim_bus.recv_all()
        self._sim_pipe.read()

    def _advance_to(self, t_ns: int) -> None:
        now = self._clock.now_ns()
        if t_ns > now:
            self._clock.advance(t_ns - now)

    def _reject(self, topic: str, t_ns: int, why: str) -> None:
        self._rejected += 1
        _log.warning("replay of %s: %s record at %d ns not fed: %s", self._recording, topic, t_ns, why)


def _onboard_line(data: bytes) -> bool:
    """Whether a ``log`` record is the onboard stack's own (the replayed stack writes its own again)."""
    try:
        name = loads_json(data).get("name", "")
    except (ValueError, AttributeError):
        return False  # not a record the stack wrote: copied as it was
    return isinstance(name, str) and name.split(".", 1)[0] in ONBOARD_LOGGERS


@dataclass(frozen=True)
class _WheelCommandComparison:
    compared: int = 0  # ticks with a wheels/command in both recordings
    differing: int = 0  # of those, ticks whose wheels/command differs byte for byte
    first_ns: int | None = None  # the first such tick's log time
    largest_mps: float = 0.0  # the largest difference of one wheel's commanded speed, any tick


def _compare_wheel_commands(recorded: dict[int, bytes], out: Path) -> _WheelCommandComparison:
    compared = differing = 0
    first: int | None = None
    largest = 0.0
    for entry in read_entries(out, topics=(WHEELS_COMMAND,), raw_topics=(WHEELS_COMMAND,)):
        if not isinstance(entry, RecordedRaw):
            continue
        original = recorded.get(entry.log_time_ns)
        if original is None:
            continue
        compared += 1
        if entry.data == original:
            continue
        differing += 1
        if first is None:
            first = entry.log_time_ns
        largest = max(largest, _largest_speed_difference(original, entry.data))
    return _WheelCommandComparison(compared, differing, first, largest)


def _largest_speed_difference(original: bytes, replayed: bytes) -> float:
    """The largest difference of one wheel's ``speed_mps`` between two wheels/command records (inf when
    either is unreadable or they name different numbers of wheels)."""
    try:
        old, new = loads_json(original)["speed_mps"], loads_json(replayed)["speed_mps"]
        if len(old) != len(new):
            return math.inf
        return max((abs(float(a) - float(b)) for a, b in zip(old, new, strict=True)), default=0.0)
    except (ValueError, TypeError, KeyError, OverflowError):
        return math.inf
