"""The rover config (``rover.toml``): one file, one section per part, validated on load.

Each section is parsed by the dataclass of the package that owns it; this module only assembles them and
keeps shared quantities single-sourced (the estimator's odometry kinematics take the vehicle's track and
skid factor, so the two cannot disagree).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from estimator.config import EstimatorConfig
from firmware_bridge.can_link import CanConfig
from firmware_bridge.mavlink_link import MavlinkConfig
from firmware_bridge.vesc import VescProfile
from logs.clock import NS_PER_S
from logs.file_kinds import ROVER_CONFIG, refuse_another_kind
from logs.settings import Table, load_toml
from logs.telemetry import ZenohSettings
from navigator.astar import HEURISTICS
from navigator.config_checks import check_cross_fields
from navigator.follower import FollowerConfig
from navigator.map_config import terrain_from_table
from navigator.phase_locked_loop import DEFAULT_LATE_WAIT_NS, DEFAULT_OFFSET_NS
from navigator.planner import COST_MODES, FOOTPRINT_INFLATIONS
from navigator.recovery import RECOVERY_ATTEMPTS, RECOVERY_BACK_M
from navigator.safety_config import SafetyConfig
from navigator.scan_tracker_config import ScanTrackerConfig
from navigator.terrain import TerrainMap
from navigator.terrain_class_settings import (
    PHYSICS_FIELDS,
    PLANNER_FIELDS,
    ClassOverrides,
    overrides_from_table,
    with_overrides,
)
from navigator.terrain_classes import TerrainClass
from navigator.vehicle import VehicleParams
from navigator.yielding import YIELD_MARGIN_M, YIELD_MAX_M, YIELD_MAX_S, YIELD_SPEED_MPS

# [planner] heuristic_weight: 1 is plain A* (optimal); w > 1 finds a path costing at most w times the optimum
# with fewer expansions; below 1 it only slows the search towards Dijkstra, past 10 it is a greedy search
# with no useful bound. `rover plan --weight` refuses what this refuses.
HEURISTIC_WEIGHT_RANGE = (1.0, 10.0)
# The measurement whose arrival starts a control tick in real time (navigator.paced_loop); "none": a
# plain fixed-rate loop.
PACING_SENSORS = ("imu", "gps", "wheels", "none")
# Skid-steer kinematics the estimator shares with the vehicle: single-sourced from [vehicle].
_VEHICLE_KINEMATICS = ("track_m", "skid_factor")
# Busy-poll the pacing link this long before (and at most after) each expected sample (navigator.paced_loop):
# the sample is read as it lands, not after the OS wakes the loop. About this much CPU per sample (1 ms at
# 50 Hz: 5 % of a core); 0 turns it off (a weak companion computer).
DEFAULT_BUSY_POLL_MS = 1.0
# The real-time control loop (docs/runtime.md): "sensor-paced" starts a tick when the pacing sample lands
# (navigator.paced_loop); "phase-locked" ticks on its own steady clock, steered to `phase_offset_ms` after
# the pacing sample is expected (navigator.phase_locked_loop).
CONTROL_LOOPS = ("sensor-paced", "phase-locked")
DEFAULT_CONTROL_LOOP = "phase-locked"
DEFAULT_PHASE_OFFSET_MS = DEFAULT_OFFSET_NS / 1e6
# The phase-locked loop waits this long past a tick's due time for a late sample (bounded jitter).
DEFAULT_PHASE_LATE_WAIT_MS = DEFAULT_LATE_WAIT_NS / 1e6


@dataclass(frozen=True)
class PlannerConfig:
    """A* settings: heuristic name, extra obstacle inflation beyond the footprint (m). ``Planner.from_config``
    builds the planner from them, on the rover and in ``rover plan --config`` alike."""

    heuristic: str = "octile"
    inflation_m: float = 0.1
    # "terrain": class, slope, roughness and direction costs; "classical": obstacles only (the baseline).
    cost_mode: str = "terrain"
    heuristic_weight: float = 1.0  # > 1: weighted A*, cost at most this times the optimum
    # The circle the cost grid inflates obstacles by before the oriented-rectangle check (navigator.planner).
    footprint_inflation: str = "circumscribed"
    sensing_range_m: float = 8.0  # static obstacles seen within this range repair the plan
    moving_horizon_s: float = 3.0  # a moving obstacle predicted on the path this far ahead blocks it
    # A BLOCKED rover drives on only once the way has stayed clear this long (s of the guidance clock): a
    # prediction that clears for a few ticks (a turning cart, a jumpy estimate) does not start it.
    moving_clear_s: float = 0.5
    # A moving obstacle not seen for this long is no longer predicted: out of view, or a lidar track that
    # was forgotten and came back under a new id (navigator.scan_tracker). 0: kept until seen again.
    moving_forget_s: float = 2.0
    # Stopped in a moving obstacle's predicted track, the rover backs off (navigator.yielding): at this
    # speed (0: never, it holds), until the track clears the footprint by inflation_m + yield_margin_m,
    # at most yield_max_m from where it began and for yield_max_s.
    yield_speed_mps: float = YIELD_SPEED_MPS
    yield_margin_m: float = YIELD_MARGIN_M
    yield_max_m: float = YIELD_MAX_M
    yield_max_s: float = YIELD_MAX_S
    # Held for no progress while climbing with its wheels turning, the rover believes the class under it
    # climbs less than that slope and plans again (navigator.climb_learning); false: it holds, as before.
    learn_traction: bool = True
    # Held for no progress while driving and learning does not explain it, the rover backs out straight
    # (at yield_speed_mps, at most recovery_back_m), marks the spot it dug in on as an obstacle and plans
    # round it (navigator.recovery): at most recovery_attempts times a goal or resume. false: it holds.
    recover_when_stuck: bool = True
    recovery_back_m: float = RECOVERY_BACK_M
    recovery_attempts: int = RECOVERY_ATTEMPTS

    @classmethod
    def from_table(cls, table: Table) -> PlannerConfig:
        low, high = HEURISTIC_WEIGHT_RANGE
        config = cls(
            heuristic=table.text("heuristic", cls.heuristic, choices=HEURISTICS),
            inflation_m=table.number("inflation_m", cls.inflation_m, lo=0.0, hi=10.0),
            cost_mode=table.text("cost_mode", cls.cost_mode, choices=COST_MODES),
            heuristic_weight=table.number("heuristic_weight", cls.heuristic_weight, lo=low, hi=high),
            footprint_inflation=table.text(
                "footprint_inflation", cls.footprint_inflation, choices=FOOTPRINT_INFLATIONS
            ),
            sensing_range_m=table.number("sensing_range_m", cls.sensing_range_m, lo=0.0, hi=1000.0),
            moving_horizon_s=table.number("moving_horizon_s", cls.moving_horizon_s, lo=0.0, hi=60.0),
            moving_clear_s=table.number("moving_clear_s", cls.moving_clear_s, lo=0.0, hi=60.0),
            moving_forget_s=table.number("moving_forget_s", cls.moving_forget_s, lo=0.0, hi=3600.0),
            yield_speed_mps=table.number("yield_speed_mps", cls.yield_speed_mps, lo=0.0, hi=5.0),
            yield_margin_m=table.number("yield_margin_m", cls.yield_margin_m, lo=0.0, hi=5.0),
            yield_max_m=table.number("yield_max_m", cls.yield_max_m, lo=0.0, hi=50.0),
            yield_max_s=table.number("yield_max_s", cls.yield_max_s, lo=0.0, hi=120.0),
            learn_traction=table.flag("learn_traction", cls.learn_traction),
            recover_when_stuck=table.flag("recover_when_stuck", cls.recover_when_stuck),
            # At least 0.5 m (less leaves a mark under the rover: not marked), at most a short stretch: it
            # reverses seeing only the believed map and the moving obstacles it tracks.
            recovery_back_m=table.number("recovery_back_m", cls.recovery_back_m, lo=0.5, hi=10.0),
            # 0 would be recover_when_stuck = false under another name: refused.
            recovery_attempts=table.integer("recovery_attempts", cls.recovery_attempts, lo=1, hi=10),
        )
        table.finish()
        return config


@dataclass(frozen=True)
class RoverConfig:
    rover_id: str
    control_rate_hz: float
    vehicle: VehicleParams
    vesc: VescProfile
    can: CanConfig
    mavlink: MavlinkConfig
    zenoh: ZenohSettings
    estimator: EstimatorConfig
    planner: PlannerConfig
    follower: FollowerConfig
    source: str = "<defaults>"
    safety: SafetyConfig = dataclasses.field(default_factory=SafetyConfig)
    perception: ScanTrackerConfig = dataclasses.field(default_factory=ScanTrackerConfig)
    pacing_sensor: str = "imu"
    busy_poll_ms: float = DEFAULT_BUSY_POLL_MS
    control_loop: str = DEFAULT_CONTROL_LOOP
    phase_offset_ms: float = DEFAULT_PHASE_OFFSET_MS
    phase_late_wait_ms: float = DEFAULT_PHASE_LATE_WAIT_MS
    # The real-time HIL peer run this config was written for (``rover hil peer`` writes it into its
    # rover-hil.toml; ``rover run`` records it), so a report pairs each rover recording with its own truth.
    hil_peer_run: str | None = None
    # [map]: the terrain `rover run` plans on (HIL trials use the scenario's instead); None if absent.
    terrain: TerrainMap | None = dataclasses.field(default=None, compare=False, repr=False)
    # [terrain_classes.<name>] as written: where the planner's and guidance's beliefs about the ground leave
    # the built-in table (recorded as config.terrain_classes.<name>.<field>; navigator.config_record).
    terrain_classes: ClassOverrides = dataclasses.field(default_factory=dict)

    @property
    def classes(self) -> dict[int, TerrainClass]:
        """The terrain classes the onboard stack believes in (planner costs, climb limits, speed limits);
        the simulated world's are the scenario's (``Scenario.classes``)."""
        return with_overrides(self.terrain_classes)


def load_rover_config(path: str | Path) -> RoverConfig:
    """Read and validate a rover config file; raises ``logs.settings.ConfigError`` naming file and key."""
    root = load_toml(path)
    # Here, not in rover_config_from_table: a campaign variant's overrides merged over no base config are
    # no file, and a stray [sensors] there is named by its key, not as "a scenario".
    refuse_another_kind(root, ROVER_CONFIG)
    return rover_config_from_table(root)


def rover_config_from_table(root: Table, base_dir: Path | None = None) -> RoverConfig:
    """The config a root table describes; files it names (``[map]`` layers, ``[vesc] dbc``) are read
    relative to ``base_dir``, by default the folder of ``root.source`` (the file the table came from)."""
    base_dir = Path(root.source).parent if base_dir is None else base_dir
    rover_id = root.text("rover_id", "rover1")
    if not rover_id or not all(c.isalnum() or c in "-_" for c in rover_id):
        raise root.error(
            "rover_id", f"use letters, digits, '-' and '_' only (it becomes a Zenoh key), got {rover_id!r}"
        )
    control_rate_hz = root.number("control_rate_hz", 50.0, lo=1.0, hi=1000.0)
    hil_peer_run = root.text("hil_peer_run", "") or None
    if hil_peer_run is not None and not all(c.isalnum() or c in "-_" for c in hil_peer_run):
        raise root.error("hil_peer_run", f"use letters, digits, '-' and '_' only, got {hil_peer_run!r}")
    pacing_sensor = root.text("pacing_sensor", "imu", choices=PACING_SENSORS)
    busy_poll_ms = root.number("busy_poll_ms", DEFAULT_BUSY_POLL_MS, lo=0.0, hi=10.0)
    # Wheel status cannot lock a phase (navigator.config_checks): it paces the sensor-paced loop instead.
    default_loop = "sensor-paced" if pacing_sensor == "wheels" else DEFAULT_CONTROL_LOOP
    control_loop = root.text("control_loop", default_loop, choices=CONTROL_LOOPS)
    # At most half a period: a sample is answered before the next one is due. The default is held to that
    # too (above 625 Hz it would not fit, and a config that never mentions the key must still load).
    half_period_ms = (round(NS_PER_S / control_rate_hz) // 2) / 1e6  # as the scheduler counts it, in ns
    phase_offset_ms = root.number(
        "phase_offset_ms", min(DEFAULT_PHASE_OFFSET_MS, half_period_ms), lo=0.0, hi=half_period_ms
    )
    phase_late_wait_ms = root.number(
        "phase_late_wait_ms", min(DEFAULT_PHASE_LATE_WAIT_MS, half_period_ms), lo=0.0, hi=half_period_ms
    )
    vehicle = VehicleParams.from_table(root.table("vehicle", optional=True))
    vesc = VescProfile.from_table(
        root.table("vesc", optional=True), wheel_radius_m=vehicle.wheel_radius_m, base_dir=base_dir
    )
    estimator_table = root.table("estimator", optional=True)
    for key in _VEHICLE_KINEMATICS:
        # Read here, these would be silently replaced by the vehicle's values below: refuse them instead.
        if estimator_table.has(key):
            raise estimator_table.error(
                key, f"the estimator's odometry uses [vehicle] {key}; set it there, not in [estimator]"
            )
    estimator = EstimatorConfig.from_table(estimator_table)
    estimator = dataclasses.replace(estimator, track_m=vehicle.track_m, skid_factor=vehicle.skid_factor)
    config = RoverConfig(
        rover_id=rover_id,
        control_rate_hz=control_rate_hz,
        vehicle=vehicle,
        vesc=vesc,
        can=CanConfig.from_table(root.table("can", optional=True)),
        mavlink=MavlinkConfig.from_table(root.table("mavlink", optional=True)),
        zenoh=ZenohSettings.from_table(root.table("zenoh", optional=True)),
        estimator=estimator,
        planner=PlannerConfig.from_table(root.table("planner", optional=True)),
        follower=FollowerConfig.from_table(root.table("follower", optional=True)),
        safety=SafetyConfig.from_table(root.table("safety", optional=True)),
        perception=ScanTrackerConfig.from_table(root.table("perception", optional=True)),
        pacing_sensor=pacing_sensor,
        busy_poll_ms=busy_poll_ms,
        control_loop=control_loop,
        phase_offset_ms=phase_offset_ms,
        phase_late_wait_ms=phase_late_wait_ms,
        terrain=(terrain_from_table(root.table("map"), base_dir)[0] if root.has("map") else None),
        hil_peer_run=hil_peer_run,
        terrain_classes=overrides_from_table(root, (*PHYSICS_FIELDS, *PLANNER_FIELDS), {}),
        source=root.source,
    )
    root.finish()
    check_cross_fields(config)
    return config
