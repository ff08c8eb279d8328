"""The effective rover config of a run, as a recording keeps it (a lockstep trial's and ``rover run``'s).

A campaign variant is the base config with overrides merged in, so the config *file* alone does not say
what ran. The recording gets the effective values twice: as a JSON attachment (the whole config, nested,
for people and tools) and flattened into the ``config`` metadata record (``planner.cost_mode`` ->
``classical``), which ``rover logs report`` compares key by key between two runs: a simulated trial
against a real run shows which parameters differed.
"""

from __future__ import annotations

import dataclasses
import enum
import json
from importlib import metadata as package_metadata
from pathlib import Path
from typing import Any

from logs.recorder import McapRecorder
from navigator.config import RoverConfig

REDACTED = "<redacted>"
# Secrets stay out of recordings that get shared; the record still says whether one was set.
_SECRET_FIELDS = frozenset({"signing_key"})
# Not configuration: where it came from is in the trial metadata; the map is attached on its own; the HIL
# peer run a rover ran against is an id, different every run (the trial record has it as hil_peer_run).
_LEFT_OUT = frozenset({"source", "terrain", "hil_peer_run"})


def software_version() -> str:
    try:
        return package_metadata.version("rover-stack")
    except package_metadata.PackageNotFoundError:
        return "unknown"


def record_config(recorder: McapRecorder, config: RoverConfig) -> None:
    """The ``config`` metadata record (flattened), ``config.effective.json``, and the config file as
    written (``config.toml``) unless it holds the MAVLink signing key: recordings get shared, the key must
    not travel with them (the JSON has every other value, the key redacted)."""
    effective = effective_config(config)
    recorder.add_metadata("config", flattened(effective))
    recorder.add_attachment(
        "config.effective.json",
        "application/json",
        json.dumps(effective, indent=2, sort_keys=True).encode("utf-8"),
        0,
    )
    config_path = Path(config.source)
    if config_path.is_file() and not config.mavlink.signing_key:
        recorder.add_attachment("config.toml", "application/toml", config_path.read_bytes(), 0)


def effective_config(config: RoverConfig) -> dict[str, Any]:
    """Every config value as plain JSON data, nested by table, secrets redacted."""
    return {
        f.name: _plain(f.name, getattr(config, f.name))
        for f in dataclasses.fields(config)
        if f.name not in _LEFT_OUT
    }


def flattened(table: dict[str, Any], prefix: str = "") -> dict[str, str]:
    """``{"planner": {"cost_mode": "x"}}`` -> ``{"planner.cost_mode": "x"}``; non-strings as JSON text."""
    out: dict[str, str] = {}
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flattened(value, f"{name}."))
        else:
            out[name] = value if isinstance(value, str) else json.dumps(value, sort_keys=True)
    return out


def _plain(name: str, value: Any) -> Any:
    if name in _SECRET_FIELDS:
        return REDACTED if value else ""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(f.name, getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): _plain(str(k), v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain("", v) for v in value]
    if value is None or isinstance(value, bool | int | float | str):
        return value
    if isinstance(value, enum.Enum):
        return _plain(name, value.value)
    return str(value)  # a path or another value type: its spelling is what a reader compares
