"""Campaign files: terrains x variants x seeds, each combination one lockstep trial.

A campaign is TOML::

    name = "terrain-vs-classical"
    config = "../configs/rover.toml"   # optional base rover config (default: built-in defaults)
    seeds = [1, 2, 3]                   # or: seed_count = 5  (seeds 0 .. 4)
    workers = 0                         # 0: one worker process per core

    [[terrains]]
    name = "rocky"
    scenario = "../scenarios/rocky.toml"

    [[variants]]
    name = "terrain-aware"
    [variants.overrides]                # rover-config keys, merged over the base config
    planner.cost_mode = "terrain"

Paths are relative to the campaign file. Everything (each scenario, each variant's config) is loaded and
validated before the first trial starts, with errors naming the file and the key.
"""

from __future__ import annotations

import copy
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hil.scenario import load_scenario
from logs.settings import ConfigError, Table, load_toml
from navigator.config import RoverConfig, rover_config_from_table


@dataclass(frozen=True)
class Variant:
    name: str
    overrides: dict[str, Any]


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
            )
            for terrain_index, (terrain, scenario) in enumerate(self.terrains)
            for variant_index, variant in enumerate(self.variants)
            for seed in self.seeds
        ]

    def worker_count(self) -> int:
        return self.workers if self.workers > 0 else max(1, os.cpu_count() or 1)


def load_campaign(path: str | Path) -> Campaign:
    """Read a campaign file and validate everything it refers to; ``ConfigError`` on any problem."""
    root = load_toml(path)
    base = Path(path).parent
    name = root.text("name")
    root.text("description", "")
    config_path = base / root.text("config") if root.has("config") else None
    if root.has("seeds") and root.has("seed_count"):
        raise root.error("seed_count", "give either seeds or seed_count, not both")
    if root.has("seed_count"):
        seeds = tuple(range(root.integer("seed_count", lo=1, hi=10_000)))
    else:
        seeds = tuple(root.integers("seeds", [0]))
    if not seeds:
        raise root.error("seeds", "at least one seed is needed, got []")
    if len(set(seeds)) != len(seeds) or any(s < 0 for s in seeds):
        raise root.error("seeds", f"seeds must be distinct and >= 0, got {list(seeds)}")
    workers = root.integer("workers", 0, lo=0, hi=256)

    terrains: list[tuple[str, Path]] = []
    for table in root.tables("terrains", optional=False):
        terrain_name = table.text("name")
        scenario = base / table.text("scenario")
        table.finish()
        if any(terrain_name == t for t, _ in terrains):
            raise table.error("name", f"duplicate terrain name {terrain_name!r}")
        load_scenario(scenario)  # validated now, not in a worker half an hour later
        terrains.append((terrain_name, scenario))
    if not terrains:
        raise root.error("terrains", "at least one [[terrains]] entry is needed")

    variants: list[Variant] = []
    for table in root.tables("variants"):
        variant_name = table.text("name")
        overrides = table.raw("overrides", {})
        if not isinstance(overrides, dict):
            raise table.error("overrides", f"must be a table of rover-config keys, got {overrides!r}")
        table.finish()
        if any(variant_name == v.name for v in variants):
            raise table.error("name", f"duplicate variant name {variant_name!r}")
        variant = Variant(variant_name, overrides)
        campaign_config(config_path, variant.overrides, f"{root.source} variant {variant_name!r}")
        variants.append(variant)
    if not variants:
        variants.append(Variant("default", {}))
        campaign_config(config_path, {}, root.source)
    root.finish()
    return Campaign(name, root.source, tuple(terrains), tuple(variants), seeds, config_path, workers)


def campaign_config(config_path: Path | None, overrides: dict[str, Any], where: str) -> RoverConfig:
    """The rover config of one variant: the base file (or defaults) with ``overrides`` merged in."""
    if config_path is None:
        data: dict[str, Any] = {}
        source = "<built-in defaults>"
    else:
        data = _read(config_path)
        source = str(config_path)
    merged = _merged(copy.deepcopy(data), overrides)
    label = source if not overrides else f"{source} + overrides of {where}"
    return rover_config_from_table(Table(merged, label, ""))


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
