"""What the real-time peer leaves for ``rover run``: the rover's map as .npy layers and a rover config.

The onboard stack must plan on what the rover *believes* (the scenario's terrain with its known obstacles,
as in lockstep) and georeference GPS on the scenario's datum; ``rover run`` gets both only through its
config. So the peer writes ``map/{elevation,classes,obstacles}.npy`` and ``rover-hil.toml``: the CAN bus
the peer is on, ``udpout:HOST:PORT`` to its autopilot (the loopback address it listens on), the datum,
the map, Zenoh off, the ``[vesc]`` table its simulated controllers speak (ids, drivetrain, and a
swapped-in DBC as an absolute path, so it reads the same from the peer's folder or wherever the file is
copied), and where its simulated lidar sits when that is off the centre (``[perception]`` ``mount_*``,
from the scenario's ``[sensors] perception_mount_*``), or where each simulated rangefinder sits
(``[perception] rangefinders``, by id, for a scenario with ``perception = "rangefinders"``), and the
config's ``[terrain_classes.<name>]`` tables (what the planner believes of the ground: the peer's world is
the scenario's). Every other table is left at the built-in defaults (the ones the peer simulates when it
has no ``--config``); with a custom vehicle, add its tables to the file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hil.scenario import Scenario
from navigator.config import RoverConfig
from navigator.sensor_mount import AT_CENTRE

ROVER_CONFIG_NAME = "rover-hil.toml"
MAP_DIR = "map"


def write_peer_files(
    out_dir: Path,
    scenario: Scenario,
    config: RoverConfig,
    mavlink_port: int,
    peer_run: str | None = None,
    mavlink_host: str = "127.0.0.1",
) -> Path:
    """Write the map layers and ``rover-hil.toml`` into ``out_dir``; returns the config's path.
    ``peer_run``: this peer run's id, which ``rover run`` records beside the peer's own (``hil_peer_run``).
    ``mavlink_host``: the loopback address the peer's autopilot listens on (``rover run`` dials it)."""
    terrain = scenario.believed_terrain
    map_dir = out_dir / MAP_DIR
    map_dir.mkdir(parents=True, exist_ok=True)
    # Saved in their own dtypes: the numba kernels are compiled (and cached) per dtype, and a map of
    # another dtype than lockstep's would cost ``rover run`` a fresh compile inside its first ticks.
    np.save(map_dir / "elevation.npy", terrain.elevation_m)
    np.save(map_dir / "classes.npy", terrain.terrain_class)
    np.save(map_dir / "obstacles.npy", terrain.obstacles)
    lat, lon, alt = scenario.datum
    origin_x, origin_y = terrain.origin_xy
    # json.dumps spells strings and floats the way TOML does (double quotes, repr-exact numbers).
    lines = [
        f"# Written by `rover hil peer` for scenario {scenario.name!r}; connect with",
        f"#   rover run --config {ROVER_CONFIG_NAME} --goal X,Y",
        f"rover_id = {json.dumps(config.rover_id)}",
        f"control_rate_hz = {config.control_rate_hz!r}",
        *([f"hil_peer_run = {json.dumps(peer_run)}"] if peer_run is not None else []),
        "",
        "[can]",
        f"interface = {json.dumps(config.can.interface)}",
        f"channel = {json.dumps(config.can.channel)}",
        "",
        *_vesc_lines(config),
        "[mavlink]",
        f'connection = "udpout:{mavlink_host}:{mavlink_port}"',
        "",
        "[zenoh]",
        "enabled = false",
        "",
        "[estimator]",
        f"datum_lat_deg = {lat!r}",
        f"datum_lon_deg = {lon!r}",
        f"datum_alt_m = {alt!r}",
        "",
        *_perception_lines(scenario),
        "[map]",
        'kind = "npy"',
        f'elevation = "{MAP_DIR}/elevation.npy"',
        f'classes = "{MAP_DIR}/classes.npy"',
        f'obstacles = "{MAP_DIR}/obstacles.npy"',
        f"resolution_m = {terrain.resolution_m!r}",
        f"origin = [{float(origin_x)!r}, {float(origin_y)!r}]",
        "",
        *_class_lines(config),
    ]
    path = out_dir / ROVER_CONFIG_NAME
    path.write_text("\n".join(lines), encoding="utf-8")
    return path


def _class_lines(config: RoverConfig) -> list[str]:
    """The config's ``[terrain_classes.<name>]`` tables as written: the rover plans with the beliefs it was
    given, whatever ground the peer simulates (the scenario's)."""
    lines: list[str] = []
    for name, values in config.terrain_classes.items():
        lines += [f"[terrain_classes.{name}]", *(f"{key} = {value!r}" for key, value in values.items()), ""]
    return lines


def _vesc_lines(config: RoverConfig) -> list[str]:
    """``[vesc]`` as the simulated controllers run it: the rover must address the same ids in the same
    protocol, or it hears none of them."""
    vesc = config.vesc
    lines = [
        "[vesc]",
        f"controller_ids = [{', '.join(map(str, vesc.controller_ids))}]",
        f"pole_pairs = {vesc.pole_pairs}",
        f"gear_ratio = {vesc.gear_ratio!r}",
    ]
    if vesc.dbc_path is not None:
        lines.append(f"dbc = {json.dumps(str(vesc.dbc_path.absolute()))}")
    return [*lines, ""]


def _perception_lines(scenario: Scenario) -> list[str]:
    """``[perception]`` saying where the simulated lidar sits, so ``rover run`` places its returns from
    there; nothing when it sits at the centre facing forward (the default, the file as it always was). For
    rangefinders, where each sits (their messages say their field of view and direction)."""
    sensors = scenario.sensors
    if sensors.perception == "rangefinders":
        # Every id, even at the centre: an id the config does not place is warned about.
        ring = ", ".join(
            f"{{id = {i}, forward_m = {sensor.forward_m!r}, left_m = {sensor.left_m!r}}}"
            for i, sensor in enumerate(sensors.rangefinder_ring)
        )
        return ["[perception]", f"rangefinders = [{ring}]", ""]
    if sensors.lidar_mount == AT_CENTRE:
        return []
    return [
        "[perception]",
        f"mount_forward_m = {sensors.perception_mount_forward_m!r}",
        f"mount_left_m = {sensors.perception_mount_left_m!r}",
        f"mount_yaw_deg = {sensors.perception_mount_yaw_deg!r}",
        "",
    ]
