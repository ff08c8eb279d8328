"""``rover plan MAP [--start X,Y] [--goal X,Y] [--config rover.toml]``: plan once, print cost, length, nodes
expanded and time (with ``--json`` also the path, as ``[x, y]`` points in metres from the start to the
goal). A scenario's own ``[start]`` and first ``[[goals]]`` are the defaults. The vehicle, the planner
settings and the terrain classes it believes in are a rover config's (``--config``, read as ``rover hil
trial --config`` reads it: ``[vehicle]``, ``[planner]``, ``[terrain_classes.*]``) or the built-in defaults;
``--heuristic``, ``--weight``, ``--cost-mode`` and ``--footprint-inflation`` override them."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

from logs.settings import ConfigError, parse_toml, read_settings_text
from navigator.astar import HEURISTICS
from navigator.config import HEURISTIC_WEIGHT_RANGE, PlannerConfig, load_rover_config, rover_config_from_table
from navigator.errors import NavigatorError
from navigator.plan_tools import PlanMap, Point, draw_png, export_costs, load_map, map_from_table, plan_once
from navigator.planner import COST_MODES, FOOTPRINT_INFLATIONS, Planner
from navigator.terrain_classes import TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import VehicleParams
from rover_cli.arg_types import bounded_float

# option -> the PlannerConfig field it overrides (an option not given leaves the config's value)
_PLANNER_OPTIONS = {
    "heuristic": "heuristic",
    "weight": "heuristic_weight",
    "cost_mode": "cost_mode",
    "footprint_inflation": "footprint_inflation",
}


def _point(text: str) -> tuple[float, float]:
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"expected X,Y in metres, got {text!r}") from err
    return x, y


def register(families: Any) -> None:
    plan = families.add_parser("plan", help="plan a path on a map and print (or draw) it")
    plan.add_argument(
        "map",
        type=Path,
        help="TOML with a [terrain] table (e.g. a scenario), an .npy elevation or a .png obstacle image",
    )
    # argparse reads "-5,3" as an option, so a negative X is given as --start=-5,3.
    plan.add_argument(
        "--start",
        type=_point,
        default=None,
        help="start X,Y (ENU metres; default: the scenario's [start] xy; negative X: --start=-5,3)",
    )
    plan.add_argument(
        "--goal",
        type=_point,
        default=None,
        help="goal X,Y (ENU metres; default: the scenario's first [[goals]] xy)",
    )
    plan.add_argument(
        "--config",
        type=Path,
        default=None,
        help="rover config TOML: plan with its [vehicle] and [planner] (the options below override them)",
    )
    defaults = PlannerConfig()
    plan.add_argument(
        "--heuristic",
        choices=HEURISTICS,
        default=None,
        help=f"default: the config's, else {defaults.heuristic}",
    )
    low, high = HEURISTIC_WEIGHT_RANGE
    plan.add_argument(
        "--weight",
        type=bounded_float(low, high, "the range of [planner] heuristic_weight"),
        default=None,
        help=f"heuristic weight, {low:g} to {high:g} (> 1: bounded suboptimal; default: the config's, "
        f"else {defaults.heuristic_weight:g})",
    )
    plan.add_argument(
        "--cost-mode",
        choices=COST_MODES,
        default=None,
        help=f"default: the config's, else {defaults.cost_mode}",
    )
    plan.add_argument(
        "--footprint-inflation",
        choices=FOOTPRINT_INFLATIONS,
        default=None,
        help="circle obstacles are inflated by before the oriented-rectangle check (docs/planning.md; "
        f"default: the config's, else {defaults.footprint_inflation})",
    )
    plan.add_argument(
        "--resolution-m",
        type=float,
        default=None,
        help="cell size of an .npy / .png map (a TOML sets its own)",
    )
    plan.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    plan.add_argument("--png", type=Path, default=None, help="draw the path over the cost map")
    plan.add_argument(
        "--export-costs", type=Path, default=None, help="write the exact edge-cost model (.npz)"
    )
    plan.set_defaults(handler=run_plan)


def _endpoints(args: argparse.Namespace, plan_map: PlanMap) -> tuple[Point, Point]:
    """``--start`` / ``--goal`` as given, else the map file's; a ``ConfigError`` when neither says."""
    return (
        _given_or_named(args.map, "--start", args.start, plan_map.start, "[start] xy"),
        _given_or_named(args.map, "--goal", args.goal, plan_map.goal, "[[goals]] xy"),
    )


def _given_or_named(map_path: Path, option: str, given: Point | None, named: Point | None, key: str) -> Point:
    if given is not None:
        return given
    if named is None:
        raise ConfigError(
            str(map_path), "", f"no {option} given and the map names no {key}; give {option} X,Y"
        )
    return named


def _settings(args: argparse.Namespace) -> tuple[VehicleParams, PlannerConfig, dict[int, TerrainClass]]:
    """The vehicle, planner settings and terrain classes: the config's (or the defaults), with the options
    given on top."""
    if args.config is None:
        vehicle, planner, classes = VehicleParams(), PlannerConfig(), dict(TERRAIN_CLASSES)
    else:
        config = load_rover_config(args.config)  # ConfigError names the file and the key
        vehicle, planner, classes = config.vehicle, config.planner, config.classes
    given = {field: getattr(args, option) for option, field in _PLANNER_OPTIONS.items()}
    return vehicle, dataclasses.replace(planner, **{k: v for k, v in given.items() if v is not None}), classes


def _rovers_map(args: argparse.Namespace) -> PlanMap:
    """The map to plan on, from one read of the file: for a scenario with ``[[obstacles]]``, the rover's map
    of it as a trial's rover plans on it (the terrain with the obstacles it knows, ``known = true``, the
    default); for a rover config with a ``[map]``, that map, as ``rover run`` plans on it; else the map file.
    A rover config without a ``[map]`` is named as a config."""
    if args.map.suffix.lower() != ".toml" or args.resolution_m is not None:
        return load_map(args.map, args.resolution_m)  # an image or a layer, or the --resolution-m refusal
    from hil.scenario import scenario_from_table
    from logs.file_kinds import SCENARIO, refuse_another_kind

    text = read_settings_text(args.map)
    root = parse_toml(text, str(args.map))
    if root.has("map") and not root.has("terrain"):
        terrain = rover_config_from_table(root).terrain
        assert terrain is not None  # a config with [map] has its map
        return PlanMap(terrain)  # a rover config names no start nor goal
    refuse_another_kind(root, SCENARIO)
    if root.has("obstacles"):
        scenario = scenario_from_table(root, text, base_dir=args.map.parent)
        goal = scenario.goals[0]
        return PlanMap(scenario.believed_terrain, scenario.start_xy, (goal.x, goal.y))
    return map_from_table(root, args.map.parent)


def run_plan(args: argparse.Namespace) -> int:
    try:
        vehicle, settings, classes = _settings(args)
        plan_map = _rovers_map(args)
        start, goal = _endpoints(args, plan_map)
        # As guidance builds it, but without the goal's cost-to-go field: that pays off over replans, and
        # one plan built on it would report a full Dijkstra's expansions and time.
        planner = Planner.from_config(plan_map.terrain, vehicle, settings, classes=classes)
        report = plan_once(planner, start, goal)
    except (NavigatorError, ConfigError) as err:
        print(f"rover plan: {err}", file=sys.stderr)  # stdout stays the figures (or JSON) only
        return 2
    figures = {
        "cost": report.cost,
        "length_m": report.length_m,
        "expanded": report.expanded,
        "time_ms": report.time_ms,
        "heuristic": settings.heuristic,
        "heuristic_weight": settings.heuristic_weight,
        "cost_mode": settings.cost_mode,
        "footprint_inflation": settings.footprint_inflation,
        "points": len(report.points),
    }
    try:
        if args.export_costs is not None:
            export_costs(planner, report, args.export_costs)
            figures["export"] = str(args.export_costs)
        if args.png is not None:
            draw_png(planner, report, args.png)
            figures["png"] = str(args.png)
    except OSError as err:
        print(
            f"rover plan: cannot write {err.filename or 'the output'}: {err.strerror or err}", file=sys.stderr
        )
        return 2
    if args.json:
        # The path itself only in JSON (a script's input); the text form stays a short summary.
        print(json.dumps({**figures, "path": [[float(x), float(y)] for x, y in report.points]}))
    else:
        width = max(map(len, figures))
        for key, value in figures.items():
            print(f"{key:>{width}}: {value:.3f}" if isinstance(value, float) else f"{key:>{width}}: {value}")
    return 0
