"""The topic registry: every MCAP channel and Zenoh key the stack uses, with its JSON schema.

Topic names are the contract between the parts (ARCHITECTURE.md, "Topics"). Where a Foxglove well-known
schema fits, its name and fields are used so a trial opens in Foxglove without plugins; our extra fields
ride along beside Foxglove's (Foxglove ignores fields it does not know).

Conventions for every message: ``timestamp`` is ``{"sec", "nsec"}`` from the component's clock; positions
are local ENU metres (x east, y north, z up) in frame ``"enu"``; angles in radians, yaw counter-clockwise
from east; speeds in m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

JsonSchema = dict[str, Any]

CAN_FRAMES = "can/frames"
CAN_STATS = "can/stats"
MAVLINK_RAW = "mavlink/raw"
MAVLINK_STATS = "mavlink/stats"
SENSORS_GPS = "sensors/gps"
SENSORS_IMU = "sensors/imu"
WHEELS_STATUS = "wheels/status"
WHEELS_COMMAND = "wheels/command"
ESTIMATOR_POSE = "estimator/pose"
ESTIMATOR_INNOVATIONS = "estimator/innovations"
NAVIGATOR_MAP = "navigator/map"
NAVIGATOR_PATH = "navigator/path"
NAVIGATOR_STATE = "navigator/state"
NAVIGATOR_LEARNED = "navigator/learned"
PERCEPTION_OBSTACLES = "perception/obstacles"
SAFETY_EVENTS = "safety/events"
GROUND_COMMANDS = "ground/commands"
LOG = "log"
RUNTIME_TIMING = "runtime/timing"
TRUTH_POSE = "truth/pose"
TRUTH_WHEELS = "truth/wheels"
TRUTH_STABILITY = "truth/stability"
TRUTH_CONTACTS = "truth/contacts"

ENU_FRAME = "enu"

# Metadata record of a file the ground station recorded from the live stream (``rover telemetry record``):
# its topics may be thinned ([zenoh.rates]), so nothing may be counted from them as if complete.
LIVE_STREAM_METADATA = "live_stream"


@dataclass(frozen=True)
class TopicSpec:
    name: str
    schema_name: str
    schema: JsonSchema
    description: str


def _obj(properties: dict[str, JsonSchema], required: list[str] | None = None) -> JsonSchema:
    return {"type": "object", "properties": properties, "required": required or list(properties)}


# The CAN link's counters of received frames it refused, by cause (``can/stats`` ``link_counters``): not
# ours, the wrong length, undecodable.
CAN_REJECTION_CAUSES = ("unknown_id", "wrong_dlc", "decode_errors")

_NUM: JsonSchema = {"type": "number"}
_INT: JsonSchema = {"type": "integer"}
_STR: JsonSchema = {"type": "string"}
_BOOL: JsonSchema = {"type": "boolean"}
_TIME = _obj({"sec": _INT, "nsec": _INT})
_VEC3 = _obj({"x": _NUM, "y": _NUM, "z": _NUM})
_QUAT = _obj({"x": _NUM, "y": _NUM, "z": _NUM, "w": _NUM})
_POSE = _obj({"position": _VEC3, "orientation": _QUAT})


def _nums(n: int | None = None) -> JsonSchema:
    schema: JsonSchema = {"type": "array", "items": _NUM}
    if n is not None:
        schema["minItems"] = n
        schema["maxItems"] = n
    return schema


def _array(items: JsonSchema) -> JsonSchema:
    return {"type": "array", "items": items}


_NUM_OR_NULL: JsonSchema = {"type": ["number", "null"]}
_PERCENTILES = _obj({"p50_ms": _NUM_OR_NULL, "p99_ms": _NUM_OR_NULL, "max_ms": _NUM_OR_NULL, "samples": _INT})

_POSE_IN_FRAME_FIELDS: dict[str, JsonSchema] = {"timestamp": _TIME, "frame_id": _STR, "pose": _POSE}

_SPECS = [
    TopicSpec(
        CAN_FRAMES,
        "rover.CanFrame",
        _obj(
            {
                "timestamp": _TIME,
                "direction": {"type": "string", "enum": ["tx", "rx"]},
                "id": _INT,
                "extended": _BOOL,
                "dlc": _INT,
                "data": {"type": "string", "description": "payload as lowercase hex"},
                "error": {
                    "type": "boolean",
                    "description": "present (true) only on an error frame the controller delivered: "
                    "its error class in id (CAN_ERR_BUSOFF 0x40, CAN_ERR_RESTARTED 0x100...), details "
                    "in data (Linux's layout); absent on every data frame, and in recordings made "
                    "before error frames were recorded",
                },
            },
            required=["timestamp", "direction", "id", "extended", "dlc", "data"],
        ),
        "Every CAN frame the companion sent (tx) or received (rx), raw, and the error frames its "
        "controller delivered (rx, marked error).",
    ),
    TopicSpec(
        CAN_STATS,
        "rover.CanStats",
        _obj(
            {
                "timestamp": _TIME,
                "window_s": _NUM,
                "bitrate": _INT,
                "frames": _INT,
                "bits": _INT,
                "load_pct": _NUM,
                "tx_total": _INT,
                "rx_total": _INT,
                "own_echoes_total": _INT,
                "link_counters": {
                    "type": "object",
                    "additionalProperties": _INT,
                    "required": [*CAN_REJECTION_CAUSES, "bus_errors", "withheld"],
                    "description": "running totals of the link: received frames rejected by cause "
                    "(unknown_id, wrong_dlc, decode_errors), bus errors, and what it did in the rover's "
                    "place (resent, stale_zeroed, withheld, bad_commands, dropped_records)",
                },
            }
        ),
        "The link's own count of the bus over the last window (~1 s): frames and bits (both directions, "
        "each frame on the wire once, before bit stuffing), load as % of the bitrate, running totals, "
        "the link's rejections and interventions. "
        "Never thinned on the live stream: the ground station's bus load comes from it.",
    ),
    TopicSpec(
        MAVLINK_RAW,
        "rover.MavlinkFrame",
        _obj(
            {
                "timestamp": _TIME,
                "direction": {"type": "string", "enum": ["tx", "rx"]},
                "msgid": _INT,
                "name": _STR,
                "sysid": _INT,
                "compid": _INT,
                "data": {"type": "string", "description": "the whole MAVLink frame, base64"},
            }
        ),
        "Every MAVLink frame the companion sent or received, raw bytes.",
    ),
    TopicSpec(
        MAVLINK_STATS,
        "rover.MavlinkStats",
        _obj(
            {
                "timestamp": _TIME,
                "link": {"type": "string", "description": "which MAVLink link: autopilot, ground_station"},
                "window_s": _NUM,
                "rx_frames": _INT,
                "unknown_frames": _INT,
                "bad_frames": _INT,
                "bad_bytes": _INT,
                "bad_crc": _INT,
                "bad_header": _INT,
                "noise_bytes": _INT,
                "truncated": _INT,
                "signature_rejected": _INT,
                "dropped_bytes": _INT,
                "scans": _INT,
                "scans_rejected": _INT,
                "rx_frames_total": _INT,
                "bad_frames_total": _INT,
                "bad_bytes_total": _INT,
                "dropped_bytes_total": _INT,
                # Only once a DISTANCE_SENSOR came (firmware_bridge.mavlink_health): not required.
                "beams": _INT,
                "beams_rejected": _INT,
                "beams_unused": _INT,
                # Only once a mission message came (firmware_bridge.mavlink_mission): not required.
                "mission_messages": _INT,
                "missions_accepted": _INT,
                "missions_cleared": _INT,
                "mission_downloads": _INT,
                "mission_refused": _INT,
                "mission_out_of_sequence": _INT,
                "mission_resends": _INT,
                "mission_timeouts": _INT,
            },
            required=[
                "timestamp",
                "link",
                "window_s",
                "rx_frames",
                "unknown_frames",
                "bad_frames",
                "bad_bytes",
                "bad_crc",
                "bad_header",
                "noise_bytes",
                "truncated",
                "signature_rejected",
                "dropped_bytes",
                "scans",
                "scans_rejected",
                "rx_frames_total",
                "bad_frames_total",
                "bad_bytes_total",
                "dropped_bytes_total",
            ],
        ),
        "The MAVLink link's own count over the last window (~1 s): frames decoded (of them, ids this "
        "dialect does not decode), bad frames by reason (bad CRC, bad header, cut short), bytes skipped "
        "(of them, noise between frames), signed-only commands refused, bytes dropped unread over the "
        "receive budget, OBSTACLE_DISTANCE scans read and refused, DISTANCE_SENSOR readings read, refused "
        "and not used (looking up or down; these three once any came); running totals.",
    ),
    TopicSpec(
        SENSORS_GPS,
        "foxglove.LocationFix",
        _obj(
            {
                "timestamp": _TIME,
                "frame_id": _STR,
                "latitude": _NUM,
                "longitude": _NUM,
                "altitude": _NUM,
                "position_covariance": _nums(9),
                "position_covariance_type": _INT,
                "fix_type": _INT,
                "satellites": _INT,
                "eph_m": _NUM,
            }
        ),
        "Decoded GPS_RAW_INT: WGS84 degrees and metres; covariance in m^2 (ENU).",
    ),
    TopicSpec(
        SENSORS_IMU,
        "rover.Imu",
        _obj({"timestamp": _TIME, "frame_id": _STR, "angular_velocity": _VEC3, "linear_acceleration": _VEC3}),
        "Decoded IMU: body-frame rad/s and m/s^2 (x forward, y left, z up).",
    ),
    TopicSpec(
        WHEELS_STATUS,
        "rover.WheelStatus",
        _obj(
            {
                "timestamp": _TIME,
                "wheels": _array(
                    _obj(
                        {
                            "controller_id": _INT,
                            "erpm": _NUM,
                            "speed_mps": _NUM,
                            "motor_current_a": _NUM,
                            "input_current_a": _NUM,
                            "duty": _NUM,
                            "input_voltage_v": _NUM,
                            "tachometer": _NUM,
                        }
                    )
                ),
            }
        ),
        "Latest decoded VESC status of the six wheels, in wheel order (left front/mid/rear, right f/m/r).",
    ),
    TopicSpec(
        WHEELS_COMMAND,
        "rover.WheelCommand",
        _obj(
            {
                "timestamp": _TIME,
                "speed_mps": _nums(6),
                "erpm": _nums(6),
                "body_speed_mps": _NUM,
                "body_yaw_rate_rps": _NUM,
            }
        ),
        "Six wheel commands, in wheel order, and the body motion they were mixed from.",
    ),
    TopicSpec(
        ESTIMATOR_POSE,
        "foxglove.PoseInFrame",
        _obj(
            {
                **_POSE_IN_FRAME_FIELDS,
                "yaw_rad": _NUM,
                "speed_mps": _NUM,
                "yaw_rate_rps": _NUM,
                "state_names": _array(_STR),
                "covariance": _nums(),
                "healthy": _BOOL,
            }
        ),
        "EKF estimate in ENU; covariance is the full state covariance, row-major, order as state_names.",
    ),
    TopicSpec(
        ESTIMATOR_INNOVATIONS,
        "rover.Innovation",
        _obj(
            {
                "timestamp": _TIME,
                "sensor": _STR,
                "innovation": _nums(),
                "nis": _NUM,
                "accepted": _BOOL,
            }
        ),
        "One measurement update: residual, normalised innovation squared, gate decision.",
    ),
    TopicSpec(
        NAVIGATOR_MAP,
        "foxglove.Grid",
        _obj(
            {
                "timestamp": _TIME,
                "frame_id": _STR,
                "pose": _POSE,
                "column_count": _INT,
                "cell_size": _obj({"x": _NUM, "y": _NUM}),
                "row_stride": _INT,
                "cell_stride": _INT,
                "fields": _array(_obj({"name": _STR, "offset": _INT, "type": _INT})),
                "data": {"type": "string", "description": "base64"},
            }
        ),
        "The terrain map the planner believes: float32 elevation, class and obstacle layers.",
    ),
    TopicSpec(
        NAVIGATOR_PATH,
        "foxglove.PosesInFrame",
        _obj(
            {
                "timestamp": _TIME,
                "frame_id": _STR,
                "poses": _array(_POSE),
                "cost": _NUM,
                "length_m": _NUM,
            }
        ),
        "The current planned path in ENU, start to goal.",
    ),
    TopicSpec(
        NAVIGATOR_STATE,
        "rover.NavigatorState",
        _obj(
            {
                "timestamp": _TIME,
                "mode": _STR,
                "goal": _obj({"x": _NUM, "y": _NUM}),
                "cross_track_error_m": _NUM,
                "speed_limit_mps": _NUM,
                "speed_limit_reason": _STR,
                "target_speed_mps": _NUM,
                "target_yaw_rate_rps": _NUM,
                "safety_mode": _STR,
                "failsafes": _array(_STR),
                # Only while the rover has a mission (navigator.mission): its state (ACTIVE, PAUSED,
                # COMPLETE), the current item (numbered from 0) and how many there are.
                "mission": _obj({"state": _STR, "current": _INT, "count": _INT}),
            },
            # Recordings made before the supervisor's mode and failsafes were added still read.
            required=[
                "timestamp",
                "mode",
                "goal",
                "cross_track_error_m",
                "speed_limit_mps",
                "speed_limit_reason",
                "target_speed_mps",
                "target_yaw_rate_rps",
            ],
        ),
        "Guidance's mode (what it is trying to do) and the safety supervisor's (what reaches the wheels: "
        "IDLE, DRIVING, HOLD, ESTOP) with its active failsafes, goal, cross-track error, speed limit and "
        "the reason for it; with a mission, which of its waypoints the goal is.",
    ),
    TopicSpec(
        NAVIGATOR_LEARNED,
        "rover.LearnedTerrain",
        _obj(
            {
                "timestamp": _TIME,
                # The class (its fixed name and id) and the field of it the rover now believes otherwise:
                # what a rover config's [terrain_classes.<class_name>] <field> = <value> sets
                # (`rover logs learned` writes those tables).
                "class_name": _STR,
                "class_id": _INT,
                "field": _STR,
                "value": _NUM,
                "believed": _NUM,  # the field's value before
                # The slope it learned on, its size: the AHRS's pitch it dug in on (navigator.climb_learning)
                # or the window's mean roll it slid sideways on (navigator.slide_learning).
                "slope_rad": _NUM,
                "plans_up_to_rad": _NUM,  # the steepest slope of that class the planner now plans on
                "x": _NUM,  # where it learned (the estimated position, ENU m)
                "y": _NUM,
            }
        ),
        "What the rover learned of its ground (navigator.climb_learning): a terrain class's figure it now "
        "believes otherwise, one message a learning; the planner plans on it from then on.",
    ),
    TopicSpec(
        PERCEPTION_OBSTACLES,
        "rover.ObstacleArray",
        _obj(
            {
                "timestamp": _TIME,
                "obstacles": _array(
                    _obj({"id": _STR, "x": _NUM, "y": _NUM, "radius_m": _NUM, "vx": _NUM, "vy": _NUM})
                ),
            }
        ),
        "Obstacles perceived in this tick (ENU discs with velocity), as the navigator received them; and "
        "the spots the rover dug in on, marked as static obstacles when it recovered (ids dug-in-N).",
    ),
    TopicSpec(
        SAFETY_EVENTS,
        "rover.SafetyEvent",
        _obj({"timestamp": _TIME, "kind": _STR, "severity": _STR, "detail": _STR}),
        "Safety and link events (mode transitions, faults, recoveries) with their cause.",
    ),
    TopicSpec(
        GROUND_COMMANDS,
        "rover.GroundCommand",
        _obj(
            {
                "timestamp": _TIME,
                "kind": _STR,
                "x": _NUM_OR_NULL,
                "y": _NUM_OR_NULL,
                "received": _TIME,
                "origin": _STR,
            }
        ),
        "A command the onboard stack took (goal, estop, resume): from the ground station over Zenoh, at the "
        'tick that read it, or `rover run --goal` (origin "command line"); received: when it arrived. The '
        "stack's input, so a replay can give it again.",
    ),
    TopicSpec(
        LOG,
        "foxglove.Log",
        _obj({"timestamp": _TIME, "level": _INT, "message": _STR, "name": _STR, "file": _STR, "line": _INT}),
        "Log lines. level: 1 debug, 2 info, 3 warning, 4 error, 5 fatal (Foxglove's enum).",
    ),
    TopicSpec(
        RUNTIME_TIMING,
        "rover.RuntimeTiming",
        _obj(
            {
                "timestamp": _TIME,
                "window_s": _NUM,
                "nominal_period_ms": _NUM,
                "ticks": _INT,
                "sensor_ticks": _INT,
                "deadline_ticks": _INT,
                "overruns": _INT,
                "jitter": _PERCENTILES,
                "latency": _PERCENTILES,
                "tick_time": _PERCENTILES,
                "last_tick_ms": _NUM_OR_NULL,
                "ticks_total": _INT,
                "overruns_total": _INT,
            }
        ),
        "Control-loop timing over the last window (~1 s): period jitter, sensor-to-command latency and "
        "tick time (p50/p99/max ms, null without samples), ticks by trigger (sensor, deadline), overruns.",
    ),
    TopicSpec(
        TRUTH_POSE,
        "foxglove.PoseInFrame",
        _obj(
            {
                **_POSE_IN_FRAME_FIELDS,
                "yaw_rad": _NUM,
                "roll_rad": _NUM,
                "pitch_rad": _NUM,
                "speed_mps": _NUM,
                "lateral_speed_mps": _NUM,
                "yaw_rate_rps": _NUM,
                "terrain": _STR,
            },
            # Not lateral_speed_mps: recordings made before the body could slide sideways lack it.
            required=[
                *_POSE_IN_FRAME_FIELDS,
                "yaw_rad",
                "roll_rad",
                "pitch_rad",
                "speed_mps",
                "yaw_rate_rps",
                "terrain",
            ],
        ),
        "Simulation only: the true pose of the rover; speed along its heading and sideways (body y, left: "
        "0 unless it slides; absent in recordings made before sliding was modelled).",
    ),
    TopicSpec(
        TRUTH_WHEELS,
        "rover.TruthWheels",
        _obj(
            {
                "timestamp": _TIME,
                "wheels": _array(
                    _obj(
                        {
                            "surface_speed_mps": _NUM,
                            "slip": _NUM,
                            "normal_force_n": _NUM,
                            "current_a": _NUM,
                        }
                    )
                ),
                "battery_voltage_v": _NUM,
                "energy_wh": _NUM,
            }
        ),
        "Simulation only: per-wheel slip ratio, normal force, current; battery and energy used.",
    ),
    TopicSpec(
        TRUTH_STABILITY,
        "rover.TruthStability",
        _obj(
            {
                "timestamp": _TIME,
                "roll_rad": _NUM,
                "pitch_rad": _NUM,
                "roll_margin_rad": _NUM,
                "pitch_margin_rad": _NUM,
                "rollover": _BOOL,
            }
        ),
        "Simulation only: tilt and the margin left before tip-over (negative = rolled over).",
    ),
    TopicSpec(
        TRUTH_CONTACTS,
        "rover.Contact",
        _obj(
            {
                "timestamp": _TIME,
                "kind": {"type": "string", "enum": ["collision", "rollover"]},
                "obstacle_id": _STR,
                "x": _NUM,
                "y": _NUM,
            }
        ),
        "Simulation only: a collision with an obstacle or a rollover, once per event.",
    ),
]

TOPICS: dict[str, TopicSpec] = {spec.name: spec for spec in _SPECS}


def spec(topic: str) -> TopicSpec:
    try:
        return TOPICS[topic]
    except KeyError:
        raise KeyError(f"unknown topic {topic!r}; known topics: {', '.join(sorted(TOPICS))}") from None


def stamp(t_ns: int) -> dict[str, int]:
    """Foxglove time from integer nanoseconds."""
    # One divmod, not // and %: half the time on the ~50k stamps of a trial (log times pass 2**30 ns).
    sec, nsec = divmod(t_ns, 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


# Foxglove Log levels (the ``log`` topic's ``level``).
LOG_DEBUG, LOG_INFO, LOG_WARNING, LOG_ERROR, LOG_FATAL = 1, 2, 3, 4, 5


def log_message(
    t_ns: int, level: int, name: str, message: str, file: str = "", line: int = 0
) -> dict[str, Any]:
    """A ``log`` topic message (foxglove.Log): ``name`` says who wrote it (a logger, ``hil.faults``...)."""
    return {
        "timestamp": stamp(t_ns),
        "level": level,
        "message": message,
        "name": name,
        "file": file,
        "line": line,
    }


def stamp_ns(timestamp: dict[str, int]) -> int:
    return int(timestamp["sec"]) * 1_000_000_000 + int(timestamp["nsec"])


def planar_pose(x: float, y: float, yaw: float, z: float = 0.0) -> dict[str, Any]:
    """Foxglove pose of a planar position and a yaw about +z."""
    half = 0.5 * yaw
    return {
        "position": {"x": x, "y": y, "z": z},
        "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(half), "w": math.cos(half)},
    }


def yaw_of(pose: dict[str, Any]) -> float:
    q = pose["orientation"]
    return 2.0 * math.atan2(float(q["z"]), float(q["w"]))
