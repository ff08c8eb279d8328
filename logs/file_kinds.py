"""Which kind of settings file a TOML table is: a scenario, a campaign or a rover config.

Each kind has top-level keys no other kind has (a scenario's ``[terrain]``, a campaign's ``[[terrains]]``, a
rover config's ``[can]``). Each loader asks ``refuse_another_kind`` first, so a file of another kind is
named as that mix-up ("this is a campaign, not a scenario") rather than by the first key it lacks
("terrain: required key is missing"), which names nothing the user got wrong. A table with keys of two
kinds, or of none, is left to the loader: its own errors then say which key is wrong. A table both a scenario
and a rover config take (``[terrain_classes.<name>]``: the world's ground, the planner's beliefs) is in
neither kind's keys, so it tells no kind.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from logs.settings import ConfigError, Table, near_miss


@dataclass(frozen=True)
class FileKind:
    noun: str  # "rover config"
    # Top-level keys only this kind has; the ones every such file has first (they are named first).
    keys: tuple[str, ...]
    example: str  # where to find one, said where one was expected: "a scenario (<example>) goes here"
    goes: str  # where one of these goes instead, said when one is found in the wrong place


SCENARIO = FileKind(
    "scenario",
    (
        "terrain",
        "start",
        "goals",
        "obstacles",
        "moving_obstacles",
        "sensors",
        "faults",
        "success",
        "duration_s",
        "seed",
        "path_tolerance_m",
        "encounter_margin_m",
        "datum",
        "tags",
    ),
    "scenarios/default.toml, docs/hil.md",
    "a scenario goes first in `rover hil trial SCENARIO` or `rover hil peer SCENARIO`, or in a campaign's "
    "[[terrains]] scenario",
)
CAMPAIGN = FileKind(
    "campaign",
    ("terrains", "variants", "seeds", "seed_count", "workers", "config"),
    "campaigns/paper.toml, docs/hil.md",
    "a campaign runs with `rover hil campaign CAMPAIGN`",
)
# The tables of a rover config, none of which a scenario or a campaign has.
ROVER_CONFIG_TABLES = (
    "vehicle",
    "vesc",
    "can",
    "mavlink",
    "zenoh",
    "estimator",
    "planner",
    "follower",
    "safety",
    "perception",
    "map",
)
ROVER_CONFIG = FileKind(
    "rover config",
    (
        *ROVER_CONFIG_TABLES,
        "rover_id",
        "control_rate_hz",
        "pacing_sensor",
        "busy_poll_ms",
        "control_loop",
        "phase_offset_ms",
        "phase_late_wait_ms",
        "hil_peer_run",
    ),
    # Two, because the commands that take one want different links (docs/runtime.md): the lockstep one's
    # MAVLink is the in-process pipe, which `rover run` refuses.
    "configs/rover.toml lists every key, for lockstep trials; `rover run` on the rover starts from "
    "configs/rover.example-hardware.toml",
    "a rover config goes after --config, or in a campaign's config",
)
KINDS = (SCENARIO, CAMPAIGN, ROVER_CONFIG)


def kind_of(root: Table) -> FileKind | None:
    """The one kind whose keys ``root`` has; None when it has keys of no kind or of more than one."""
    present = set(root.keys())
    matches = [kind for kind in KINDS if present.intersection(kind.keys)]
    return matches[0] if len(matches) == 1 else None


def refuse_another_kind(root: Table, expected: FileKind) -> None:
    """Raise ``ConfigError`` naming the mix-up when ``root`` is a file of another kind than ``expected``."""
    found = kind_of(root)
    if found is None or found is expected:
        return
    present = set(root.keys())  # not root.has(): that marks a key asked, and a typo's key must stay unasked
    shown = [key for key in found.keys if key in present]
    if all(any(near_miss(key, meant) for meant in expected.keys) for key in shown):
        # Every key that looks like the other kind is a typo of one of the expected kind's ([[terrain]] and
        # seed in a campaign, for [[terrains]] and seeds): the loader names the typo, the likelier mistake.
        return
    raise ConfigError(
        root.source,
        "",
        f"this is a {found.noun} (it has {evidence(root, found)}), not a {expected.noun}: a {expected.noun} "
        f"({expected.example}) goes here; {found.goes}",
    )


def evidence(root: Table, kind: FileKind, most: int = 3) -> str:
    """The first ``most`` of ``kind``'s keys ``root`` has, as TOML writes them: what shows it is one."""
    return _listed([_as_written(key, root.raw(key)) for key in kind.keys if root.has(key)][:most])


def _as_written(key: str, value: Any) -> str:
    """A key as TOML writes it: ``[table]``, ``[[array]]`` of tables, or the plain key."""
    if isinstance(value, dict):
        return f"[{key}]"
    if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        return f"[[{key}]]"
    return key


def _listed(items: list[str]) -> str:
    return items[0] if len(items) == 1 else f"{', '.join(items[:-1])} and {items[-1]}"
