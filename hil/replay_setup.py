"""What a replay (``hil.replay``) builds the onboard stack from, besides the recorded inputs.

A lockstep trial ran with its scenario: the map the rover believed, the scenario's datum as the estimator's,
and the scenario's goals as its mission from the start. A ``rover run`` ran with its config alone: the map
is the config's ``[map]``. The recording says which (``trial.mode``) and carries the scenario as an
attachment.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from hil.scenario import MAVLINK_PERCEPTION, Scenario, scenario_from_table
from logs.errors import LogsError
from logs.reader import ReadStats, RecordedAttachment, RecordedMetadata, read_entries
from logs.run_modes import LOCKSTEP_MODE, PEER_MODE, ROVER_RUN_MODE
from logs.scenario_record import SCENARIO_METADATA
from logs.settings import ConfigError, parse_toml
from navigator.config import RoverConfig
from navigator.config_record import effective_config, flattened
from navigator.terrain import TerrainMap

REPLAYABLE_MODES = (LOCKSTEP_MODE, ROVER_RUN_MODE)


class ReplayError(LogsError):
    """A recording cannot be replayed: no onboard ticks in it, a mode the replay does not know, or what the
    replay needs (the scenario, a map) missing."""


@dataclass(frozen=True)
class RecordingHeader:
    """A recording's metadata records by name and its attachments by name, read without its messages."""

    metadata: dict[str, dict[str, str]]
    attachments: dict[str, RecordedAttachment]
    cut: bool  # the file ends before its summary: what follows the cut (an attachment, too) is lost


@dataclass(frozen=True)
class ReplaySetup:
    """The config as the run used it, its map, the goals it was given at the start, whether recorded
    obstacles are its perception, and where the replay's clock starts."""

    mode: str
    config: RoverConfig
    terrain: TerrainMap
    goals: tuple[tuple[float, float], ...]
    goal_source: str
    obstacles_are_input: bool
    start_ns: int | None  # None: the first message's log time (a `rover run` clock starts anywhere)

    @property
    def plans_a_tick_late(self) -> bool:
        """`rover run` planned on a worker thread (hil.replay_planning); a lockstep trial, inline."""
        return self.mode == ROVER_RUN_MODE

    @property
    def bus_off_refuses_sends(self) -> bool:
        """A lockstep trial's rover end refused sends while bus-off (hil.bus_off.BusOffRoverEnd); `rover
        run`'s bus took them, its link withholding its rounds itself (hil.replay_bus_off)."""
        return self.mode == LOCKSTEP_MODE


def read_header(recording: Path) -> RecordingHeader:
    """Metadata and attachments, read without decompressing a chunk."""
    stats = ReadStats()
    metadata: dict[str, dict[str, str]] = {}
    attachments: dict[str, RecordedAttachment] = {}
    for entry in read_entries(recording, messages=False, stats=stats):
        if isinstance(entry, RecordedMetadata):
            metadata[entry.name] = entry.data
        elif isinstance(entry, RecordedAttachment):
            attachments[entry.name] = entry
    return RecordingHeader(metadata, attachments, stats.truncated)


def replay_setup(
    recording: Path, header: RecordingHeader, config: RoverConfig, scenario: Scenario | None
) -> ReplaySetup:
    """``ReplayError`` naming what is missing when the recording cannot be replayed as it is."""
    mode = header.metadata.get("trial", {}).get("mode", "")
    if mode not in REPLAYABLE_MODES:
        raise ReplayError(f"{recording}: {_why_not_replayable(mode, header)}")
    if mode == ROVER_RUN_MODE:
        if config.terrain is None:
            raise ReplayError(
                f"{config.source}: replaying a `rover run` recording needs the config's [map] table "
                "(the terrain the rover planned on), as `rover run` does"
            )
        return ReplaySetup(mode, config, config.terrain, (), "", obstacles_are_input=False, start_ns=None)
    if scenario is None:
        scenario = _attached_scenario(recording, header)
    # As `rover hil trial` ran it: the map's origin is the scenario's datum, the goals are the mission.
    lat, lon, alt = scenario.datum
    estimator = dataclasses.replace(config.estimator, datum_lat_deg=lat, datum_lon_deg=lon, datum_alt_m=alt)
    # The perception the trial ran with (a campaign may have overridden the scenario file's).
    perception = header.metadata.get(SCENARIO_METADATA, {}).get("perception", scenario.sensors.perception)
    return ReplaySetup(
        mode,
        dataclasses.replace(config, estimator=estimator),
        scenario.believed_terrain,
        tuple((goal.x, goal.y) for goal in scenario.goals),
        f"scenario {scenario.name}",
        obstacles_are_input=perception not in MAVLINK_PERCEPTION,
        start_ns=0,
    )


def config_changes(recorded: dict[str, str], config: RoverConfig) -> tuple[tuple[str, str, str], ...]:
    """(key, as recorded, as replayed) for each config value the replay runs with that differs from the
    recording's ``config`` metadata, flattened (``estimator.gps_noise_m``); "-" for a key one side lacks."""
    replayed = flattened(effective_config(config))
    return tuple(
        (key, recorded.get(key, "-"), replayed.get(key, "-"))
        for key in sorted(recorded.keys() | replayed.keys())
        if recorded.get(key) != replayed.get(key)
    )


def _why_not_replayable(mode: str, header: RecordingHeader) -> str:
    wanted = f"a lockstep trial's ({LOCKSTEP_MODE}) or `rover run`'s ({ROVER_RUN_MODE})"
    if mode == PEER_MODE:
        return f"a HIL peer's truth file ({mode}) holds no onboard stack; replay the rover's, {wanted}"
    if mode:
        return f"trial.mode {mode!r} is not a recording of the onboard stack ({wanted})"
    if not header.metadata:
        cut = " (the file is cut short before them)" if header.cut else ""
        return f"holds no metadata at all{cut}; a replay needs {wanted} recording"
    return f"no trial metadata; a replay needs {wanted} recording"


def _attached_scenario(recording: Path, header: RecordingHeader) -> Scenario:
    attachment = header.attachments.get("scenario.toml")
    if attachment is None:
        cut = " (the file is cut short: it may have been lost)" if header.cut else ""
        raise ReplayError(
            f"{recording}: no scenario.toml attached{cut}; give the trial's scenario (--scenario)"
        )
    name = f"{recording} (attached scenario.toml)"
    try:
        text = attachment.data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ReplayError(f"{name} is not UTF-8 text: {err}; give the trial's scenario (--scenario)") from err
    try:
        # Terrain files it names are looked for beside the recording (they are not attached).
        return scenario_from_table(parse_toml(text, name), text, base_dir=recording.parent)
    except ConfigError as err:
        raise ReplayError(f"{err} (give the trial's scenario file with --scenario)") from err
