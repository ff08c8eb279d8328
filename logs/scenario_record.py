"""The scenario as a recording keeps it: the ``scenario`` metadata record's JSON values, parsed.

The trial runner (``hil.trial.write_header``) writes them; the metrics judge obstacle avoidance with them
and the report draws them. Every value is checked: a bad entry is skipped and described, never raised.
Beside it the ``world`` record holds the simulated world's start on the clock that stamps the log
(``epoch_ns``), time zero of the moving obstacles' motion.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from logs.obstacle_motion import MovingObstacle

SCENARIO_METADATA = "scenario"
WORLD_METADATA = "world"


@dataclass(frozen=True)
class StaticObstacle:
    id: str
    x: float
    y: float
    radius_m: float


def _finite(value: Any) -> float:
    if isinstance(value, bool):
        raise TypeError(f"expected a number, got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"non-finite value {value!r}")
    return number


def _items(text: str, key: str, problems: list[str]) -> list[Any]:
    try:
        items = json.loads(text)
        if not isinstance(items, list):
            raise ValueError("not a JSON list")
    except ValueError as err:
        problems.append(f"metadata {SCENARIO_METADATA}.{key} is unusable: {err}")
        return []
    return items


def static_obstacles(text: str) -> tuple[list[StaticObstacle], list[str]]:
    """``obstacles_json`` (a list of ``{"id", "x", "y", "radius"}``): the obstacles and the problems."""
    problems: list[str] = []
    obstacles = []
    for position, item in enumerate(_items(text, "obstacles_json", problems)):
        try:
            obstacles.append(
                StaticObstacle(
                    str(item["id"]), _finite(item["x"]), _finite(item["y"]), _finite(item["radius"])
                )
            )
        except (KeyError, TypeError, ValueError) as err:
            problems.append(f"obstacles_json[{position}] skipped: {err!r}")
    return obstacles, problems


def moving_obstacles(text: str | None) -> tuple[list[MovingObstacle], list[str]]:
    """``moving_obstacles_json`` (``{"id", "radius", "waypoints", "speed_mps", "start_s"}``; ``start_s``
    is 0 when absent, as in recordings older than it). None (no such key) gives no obstacles."""
    problems: list[str] = []
    if text is None:
        return [], problems
    movers = []
    for position, item in enumerate(_items(text, "moving_obstacles_json", problems)):
        try:
            waypoints = tuple((_finite(x), _finite(y)) for x, y in item["waypoints"])
            if len(waypoints) < 2:
                raise ValueError(f"{len(waypoints)} waypoint(s), at least two are needed")
            radius, speed = _finite(item["radius"]), _finite(item["speed_mps"])
            start = _finite(item.get("start_s", 0.0))
            if radius <= 0.0 or speed < 0.0:
                raise ValueError(f"radius {radius} must be > 0 and speed_mps {speed} >= 0")
            movers.append(MovingObstacle(str(item["id"]), radius, waypoints, speed, start))
        except (KeyError, TypeError, ValueError) as err:
            problems.append(f"moving_obstacles_json[{position}] skipped: {err!r}")
    return movers, problems


def point(text: str | None) -> tuple[float, float] | None:
    """``start_json`` / ``goal_json`` (``{"x", "y", ...}``), or None when absent or unusable."""
    if text is None:
        return None
    try:
        item = json.loads(text)
        return _finite(item["x"]), _finite(item["y"])
    except (ValueError, KeyError, TypeError):
        return None


def world_epoch_ns(record: dict[str, str] | None) -> tuple[int, list[str]]:
    """The ``world`` record's ``epoch_ns`` (an integer >= 0), and the problems; 0 when there is no record.

    0 is right for every recording without one: lockstep clocks start at 0, and the real-time peer moved
    its obstacles on the raw monotonic clock until it started recording the world's start."""
    if record is None or "epoch_ns" not in record:
        return 0, []
    text = record["epoch_ns"]
    try:
        epoch = int(text)
        if not 0 <= epoch < 2**63:  # log times are int64
            raise ValueError("out of range")
    except ValueError:
        return 0, [f"metadata {WORLD_METADATA}.epoch_ns={text!r} is not an int64 >= 0; used 0"]
    return epoch, []
