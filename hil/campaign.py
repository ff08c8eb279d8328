"""Campaign files: terrains x variants x seeds, each combination one lockstep trial.

A campaign is TOML::

    name = "terrain-vs-classical"
    config = "../configs/rover.toml"   # optional base rover config (default: built-in defaults)
    seeds = [1, 2, 3]                   # or: seed_count = 5  (seeds 0 .. 4)
    workers = 0                         # 0: one worker process per core (as --workers 0)

    [[terrains]]
    name = "rocky"                      # names are folder names: letters, digits, - _ . only
    scenario = "../scenarios/rocky.toml"

    [[variants]]
    name = "terrain-aware"
    perception = "scan"                 # optional: each scenario's [sensors] perception, for this variant
    [variants.overrides]                # rover-config keys, merged over the base config
    planner.cost_mode = "terrain"

Paths are relative to the campaign file. Everything (each scenario, each variant's config) is loaded and
validated before the first trial starts, with errors naming the campaign file and the key (and, for a
scenario or config that is wrong, that file and its key too).
"""

from __future__ import annotations

import copy
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.campaign_workers import MAX_WORKERS, resolved_workers
from hil.scenario import PERCEPTION_MODELS, Scenario, load_scenario
from hil.start_clearance import check_start_clear
from logs.file_kinds import CAMPAIGN, ROVER_CONFIG, refuse_another_kind
from logs.settings import MAX_SEED, ConfigError, Table, load_toml
from navigator.config import RoverConfig, rover_config_from_table


@dataclass(frozen=True)
class Variant:
    name: str
    overrides: dict[str, Any]
    # How the rover perceives obstacles in this variant's trials (hil.scenario PERCEPTION_MODELS), in place
    # of each scenario's own [sensors] perception; None: as each scenario says.
    perception: str | None = None


@dataclass(frozen=True)
class TrialSpec:
    """One trial of a campaign; plain data so it can cross into a worker process."""

    terrain: str
    variant: str
    seed: int
    scenario_path: Path
    config_path: Path | None
    overrides: dict[str, Any]
    out_dir: Path
    terrain_index: int = 0  # positions in the campaign file, recorded so reports keep its order
    variant_index: int = 0
    perception: str | None = None  # the variant's perception model (None: the scenario's)

    @property
    def label(self) -> str:
        return f"{self.terrain}/{self.variant}/seed{self.seed}"


@dataclass(frozen=True)
class Campaign:
    name: str
    source: str
    terrains: tuple[tuple[str, Path], ...]
    variants: tuple[Variant, ...]
    seeds: tuple[int, ...]
    config_path: Path | None
    workers: int

    def trials(self, out_dir: Path) -> list[TrialSpec]:
        """Every combination, terrain-major, so partial results fill whole terrains first."""
        return [
            TrialSpec(
                terrain,
                variant.name,
                seed,
                scenario,
                self.config_path,
                variant.overrides,
                out_dir / terrain / variant.name / f"seed{seed}",
                terrain_index,
                variant_index,
                variant.perception,
            )
            for terrain_index, (terrain, scenario) in enumerate(self.terrains)
            for variant_index, variant in enumerate(self.variants)
            for seed in self.seeds
        ]

    def worker_count(self, requested: int | None = None) -> int:
        """Worker processes: ``requested`` (the command line's) or the file's; 0 in either: one per core."""
        return resolved_workers(self.workers if requested is None else requested)


def load_campaign(path: str | Path) -> Campaign:
    """Read a campaign file and validate everything it refers to; ``ConfigError`` on any problem."""
    return campaign_from_table(load_toml(path), Path(path).parent)


def campaign_from_table(root: Table, base: Path) -> Campaign:
    """The campaign ``root`` describes; its paths are relative to ``base`` (the campaign file's folder)."""
    refuse_another_kind(root, CAMPAIGN)
    name = _path_safe_name(root, "name")  # part of the default output folder's name
    root.text("description", "")
    config_path = base / root.text("config") if root.has("config") else None
    if config_path is not None:
        try:
            # The base config alone first, so that a variant's error below can only be its overrides'.
            campaign_config(config_path, {}, root.source)
        except ConfigError as err:
            raise root.error("config", str(err)) from err
    if root.has("seeds") and root.has("seed_count"):
        raise root.error("seed_count", "give either seeds or seed_count, not both")
    if root.has("seed_count"):
        seeds = tuple(range(root.integer("seed_count", lo=1, hi=10_000)))
    else:
        seeds = tuple(root.integers("seeds", [0]))
    if not seeds:
        raise root.error("seeds", "at least one seed is needed, got []")
    if len(set(seeds)) != len(seeds) or any(not 0 <= s <= MAX_SEED for s in seeds):
        raise root.error("seeds", f"seeds must be distinct and 0 to {MAX_SEED}, got {list(seeds)}")
    workers = root.integer("workers", 0, lo=0, hi=MAX_WORKERS)

    terrains: list[tuple[str, Path]] = []
    loaded: list[tuple[Table, Scenario]] = []
    for table in root.tables("terrains", optional=False):
        terrain_name = _path_safe_name(table, "name")
        scenario = base / table.text("scenario")
        table.finish()
        if any(terrain_name == t for t, _ in terrains):
            raise table.error("name", f"duplicate terrain name {terrain_name!r}")
        try:
            loaded.append(
                (table, load_scenario(scenario))
            )  # validated now, not in a worker half an hour later
        except ConfigError as err:
            raise table.error("scenario", str(err)) from err
        terrains.append((terrain_name, scenario))
    if not terrains:
        raise root.error("terrains", "at least one [[terrains]] entry is needed")

    variants: list[Variant] = []
    for table in root.tables("variants"):
        variant_name = _path_safe_name(table, "name")
        overrides = table.raw("overrides", {})
        if not isinstance(overrides, dict):
            raise table.error("overrides", f"must be a table of rover-config keys, got {overrides!r}")
        perception = table.text("perception", "", choices=("", *PERCEPTION_MODELS)) or None
        table.finish()
        if any(variant_name == v.name for v in variants):
            raise table.error("name", f"duplicate variant name {variant_name!r}")
        variant = Variant(variant_name, overrides, perception)
        try:
            config = campaign_config(
                config_path, variant.overrides, f"{root.source} variant {variant_name!r}"
            )
        except ConfigError as err:
            raise _override_error(table, overrides, config_path, err) from err
        _check_starts(loaded, config, f"variant {variant_name!r}")
        variants.append(variant)
    if not variants:
        variants.append(Variant("default", {}))
        _check_starts(loaded, campaign_config(config_path, {}, root.source), "the base config")
    root.finish()
    return Campaign(name, root.source, tuple(terrains), tuple(variants), seeds, config_path, workers)


# Terrain and variant names become folders (<out>/<terrain>/<variant>/seed<N>): one plain path component
# each, never a separator or a way up (".."), whatever the platform.
_SAFE_NAME = re.compile(r"[A-Za-z0-9._-]+")


def _path_safe_name(table: Table, key: str) -> str:
    name = table.text(key)
    if not _SAFE_NAME.fullmatch(name) or name in (".", ".."):
        raise table.error(
            key,
            f"{name!r} is used as a folder name: use letters, digits, '-', '_' and '.' only "
            "(not '.' or '..' alone)",
        )
    return name


def _check_starts(terrains: list[tuple[Table, Scenario]], config: RoverConfig, whose: str) -> None:
    """Each terrain's start against this variant's footprint (``hil.start_clearance``), named under the
    terrain's ``scenario`` key."""
    for table, scenario in terrains:
        try:
            check_start_clear(scenario, config.vehicle)
        except ConfigError as err:
            raise table.error("scenario", f"with the footprint of {whose}: {err}") from err


def _override_error(
    variant: Table, overrides: dict[str, Any], config_path: Path | None, err: ConfigError
) -> ConfigError:
    """``err`` from a variant's merged config, named where a person fixes it: in the campaign file, under
    ``variants[i].overrides``, at the override's own key when it is one the variant wrote (an unknown
    key, a value out of range, or one that contradicts the base config); otherwise the base config's key
    that the overrides now contradict, with that file named."""
    written = _dotted_keys(overrides)
    if err.key and any(
        k == err.key or k.startswith(f"{err.key}.") or err.key.startswith((f"{k}.", f"{k}[")) for k in written
    ):
        return ConfigError(variant.source, variant.key_path(f"overrides.{err.key}"), err.problem)
    base = "the built-in defaults" if config_path is None else f"the base config {config_path}"
    where = f"{err.key}: " if err.key else ""
    return variant.error("overrides", f"merged over {base}: {where}{err.problem}")


def _dotted_keys(table: dict[str, Any], prefix: str = "") -> list[str]:
    """Every leaf of a nested table as a dotted key (``planner.cost_mode``)."""
    keys: list[str] = []
    for key, value in table.items():
        dotted = f"{prefix}{key}"
        keys.extend(_dotted_keys(value, f"{dotted}.") if isinstance(value, dict) and value else [dotted])
    return keys


def campaign_config(config_path: Path | None, overrides: dict[str, Any], where: str) -> RoverConfig:
    """The rover config of one variant: the base file (or defaults) with ``overrides`` merged in."""
    if config_path is None:
        data: dict[str, Any] = {}
        source = "<built-in defaults>"
    else:
        data = _read(config_path)
        source = str(config_path)
        refuse_another_kind(Table(data, source, ""), ROVER_CONFIG)  # the file itself, before any overrides
    merged = _merged(copy.deepcopy(data), overrides)
    label = source if not overrides else f"{source} + overrides of {where}"
    # Files the config names are relative to its folder: the label is no path once overrides are in it.
    base_dir = Path() if config_path is None else config_path.parent
    return rover_config_from_table(Table(merged, label, ""), base_dir)


def _merged(base: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    for key, value in overrides.items():
        if isinstance(value, dict) and isinstance(base.get(key), dict):
            _merged(base[key], value)
        else:
            base[key] = copy.deepcopy(value)
    return base


def _read(path: Path) -> dict[str, Any]:
    try:
        with path.open("rb") as handle:
            return tomllib.load(handle)
    except FileNotFoundError:
        raise ConfigError(str(path), "", "file not found") from None
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise ConfigError(str(path), "", f"cannot read: {err}") from err
