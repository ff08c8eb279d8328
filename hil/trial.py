"""The lockstep trial runner: the simulated rover and the onboard stack on one simulated clock.

One tick is ``PHYSICS_DT_NS``. Each tick the simulator reads the wheel commands that crossed the CAN bus,
moves the rover body on the true terrain, answers with status frames and autopilot MAVLink, records ground
truth, and every ``CONTROL_DIVIDER``-th tick runs one onboard control step. Nothing reads wall time, so the
same scenario and seed give the same recording, message for message.

The scenario's goals are the onboard stack's mission (``OnboardStack.start_mission``): the stack drives
them in order, as it drives a mission a ground station uploads, and the trial only watches for the end.
After the rover reports ARRIVED with no mission left to drive (the last goal reached, or a goal a ground
station or Zenoh gave in its place) the trial goes on, the rover parked, while a scenario fault has yet
to run its course (``hil.fault_coverage``); a fault the trial did not run in full is a failed criterion,
named in ``TrialResult.failures`` and on the ``log`` topic. A mission the stack refuses (a goal outside
the geofence: a ``mission_rejected`` event) ends the trial at once, failed: ``end_reason``
"mission_rejected", named in ``failures`` and on the ``log`` topic.
"""

from __future__ import annotations

import dataclasses
import gc
import io
import json
import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from firmware_bridge.dbc_attachment import attach_vesc_dbc
from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_transport import Transport
from firmware_bridge.vesc import VescCodec
from hil.campaign_place import CampaignPlace
from hil.fault_coverage import park_until_ns, unexercised_faults
from hil.lockstep import CanBackend, lockstep_wires, onboard_links
from hil.scenario import MAVLINK_PERCEPTION, Scenario
from hil.success import judge
from hil.world import SimWorld
from logs import topics
from logs.clock import NS_PER_S, MonotonicClock, SimClock, seconds, to_ns
from logs.commands import CommandSource
from logs.log_topic import recording_logs
from logs.metrics import TrialMetrics, compute_metrics
from logs.recorder import McapRecorder
from logs.run_modes import LOCKSTEP_MODE
from logs.sink import FanoutSink, MessageSink
from navigator.config import RoverConfig
from navigator.config_record import record_config, software_version
from navigator.mission import MissionState
from navigator.onboard import OnboardStack
from navigator.route_guidance import Mode
from navigator.terrain_class_settings import overrides_flat
from navigator.terrain_classes import TERRAIN_CLASSES
from navigator.warm_up import warm_up

PHYSICS_DT_NS = 10_000_000  # 100 Hz rover body
MISSION_REJECTED = "mission_rejected"  # TrialResult.end_reason: the stack refused the scenario's goals
CONTROL_DIVIDER = 2  # onboard control at 50 Hz
# After the final ARRIVED: the rover counts as stopped below this body speed; the wait for it is bounded.
AT_REST_MPS = 0.02
SETTLE_MAX_NS = 3_000_000_000
# What a trial writes into its folder.
TRIAL_MCAP = "trial.mcap"
METRICS_JSON = "metrics.json"


@dataclass(frozen=True)
class TrialResult:
    mcap_path: Path
    metrics_path: Path
    metrics: TrialMetrics
    simulated_s: float
    end_reason: str
    success: bool = False
    failures: tuple[str, ...] = ()
    # Wall time of the simulation loop alone (kernels loaded before it; header and metrics not in it).
    loop_wall_s: float = 0.0
    # When the rover reported ARRIVED at its last goal (None: it did not); the trial may have run on
    # after it, parked, for the scenario's faults (``simulated_s`` is then later).
    arrived_s: float | None = None
    # Until when the trial kept the arrived rover parked for the scenario's faults (None: it did not; a
    # trial also runs on briefly after ARRIVED until the rover has come to rest, which is not parking).
    parked_until_s: float | None = None


# Called once the components exist (name -> object), before the first tick: ``rover bench hil`` uses it to
# time each component. Nothing in a normal trial needs it.
ComponentHook = Callable[[dict[str, Any]], None]


def run_trial(
    scenario: Scenario,
    config: RoverConfig,
    out_dir: Path,
    *,
    seed: int | None = None,
    telemetry: MessageSink | None = None,
    on_progress: Callable[[float], None] | None = None,
    can_backend: CanBackend = "lockstep",
    on_components: ComponentHook | None = None,
    commands: CommandSource | None = None,
    ground_station: Transport | None = None,
    campaign: CampaignPlace | None = None,
) -> TrialResult:
    """Run one lockstep trial; writes ``trial.mcap`` and ``metrics.json`` into ``out_dir``, over an earlier
    trial's there (a campaign run again into its folder redoes its trials; ``rover hil trial`` refuses such
    a folder first).

    ``campaign`` names the campaign terrain and variant the trial belongs to (recorded in the ``trial``
    metadata).
    """
    seed = scenario.seed if seed is None else seed
    config = _georeferenced(config, scenario)
    out_dir.mkdir(parents=True, exist_ok=True)
    mcap_path = out_dir / TRIAL_MCAP
    clock = SimClock()

    with McapRecorder(mcap_path) as recorder:
        write_header(recorder, scenario, config, seed, campaign=campaign)
        sink: MessageSink = recorder if telemetry is None else FanoutSink([recorder, telemetry])
        # The onboard stack's warnings go on the recording's log topic too (an analyst reads them there).
        with (
            recording_logs(sink, clock),
            lockstep_wires(config.can, clock=clock, can_backend=can_backend) as wires,
        ):
            codec = VescCodec.for_profile(config.vesc)
            with SimWorld(
                scenario, config.vehicle, codec, clock, wires.sim_bus, wires.sim_mavlink, sink, seed
            ) as world:
                world.record_start(recorder)
                # The rover's CAN end as the scenario's faults leave it (a bus-off refuses its sends).
                onboard_bus = world.rover_can_end(wires.onboard_bus)
                can_link, mavlink = onboard_links(config, onboard_bus, wires.onboard_mavlink, clock, sink)
                stack = OnboardStack(
                    config,
                    clock,
                    can_link,
                    mavlink,
                    sink,
                    scenario.believed_terrain,
                    # "scan", "rangefinders": the stack tracks obstacles from the simulated lidar's
                    # scans or the rangefinders' readings, on the MAVLink link.
                    obstacles=None if scenario.sensors.perception in MAVLINK_PERCEPTION else world.perception,
                    commands=commands,
                    ground_station=None
                    if ground_station is None
                    else MavlinkLink(ground_station, clock, sink, link_timeout_s=None, name="ground_station"),
                )
                if on_components is not None:
                    on_components(
                        {
                            "onboard": stack,
                            "can_link": can_link,
                            "mavlink_link": mavlink,
                            "encoding": sink if isinstance(sink, FanoutSink) else None,
                            "recorder": recorder,
                            "telemetry": telemetry,
                            "world": world,
                            "vescs": world.vescs,
                            "autopilot": world.autopilot,
                            "dynamics": world.body,
                            "truth": world.truth,
                        }
                    )
                # Kernels load (or, on a machine's first run, compile) before the loop, not in its first
                # steps.
                world.body.warm_up()
                warm_up(stack.guidance.planner, config, MonotonicClock())
                loop_started = time.perf_counter()
                with start_up_heap_frozen():
                    end_reason, arrived_ns = _run_loop(scenario, clock, stack, world, sink, on_progress)
                loop_wall_s = time.perf_counter() - loop_started
                fault_failures = unexercised_faults(
                    scenario.faults, clock.now_ns(), to_ns(scenario.duration_s), end_reason, arrived_ns
                )
                if end_reason == MISSION_REJECTED:
                    # The rover never drove: whatever the criteria, the trial tested nothing.
                    fault_failures = [
                        "mission rejected: the onboard stack refused the scenario's goals "
                        "(its mission_rejected event says why)",
                        *fault_failures,
                    ]
                for failure in fault_failures:
                    _log_record(sink, clock.now_ns(), topics.LOG_WARNING, failure)
                stack.close()
                world.vescs.poll()  # the zero commands sent on close reach the controllers
        simulated_s = seconds(clock.now_ns())

    metrics = compute_metrics(mcap_path)
    metrics_path = out_dir / METRICS_JSON
    metrics.write_json(metrics_path)
    failures = (*judge(scenario.success, metrics), *fault_failures)
    return TrialResult(
        mcap_path,
        metrics_path,
        metrics,
        simulated_s,
        end_reason,
        success=not failures,
        failures=failures,
        loop_wall_s=loop_wall_s,
        arrived_s=None if arrived_ns is None else seconds(arrived_ns),
        parked_until_s=_parked_until_s(scenario, arrived_ns),
    )


def _parked_until_s(scenario: Scenario, arrived_ns: int | None) -> float | None:
    if arrived_ns is None:
        return None
    until = park_until_ns(scenario.faults, arrived_ns, to_ns(scenario.duration_s))
    return seconds(until) if until > arrived_ns else None


def _georeferenced(config: RoverConfig, scenario: Scenario) -> RoverConfig:
    """The map's ENU origin is the scenario's datum, so the onboard estimator must use that datum too."""
    lat, lon, alt = scenario.datum
    estimator = dataclasses.replace(config.estimator, datum_lat_deg=lat, datum_lon_deg=lon, datum_alt_m=alt)
    return dataclasses.replace(config, estimator=estimator)


@contextmanager
def start_up_heap_frozen() -> Iterator[None]:
    """Keep the collector off everything alive before the loop (modules, the maps, the compiled kernels,
    the links) while the loop runs, then hand it back.

    A full collection scans every tracked object: 56-87 ms each with the default trial's heap (six trials
    in one process, as ``rover bench hil`` and a campaign worker run them: three came due, in the first
    and the sixth trial; none once frozen). Frozen objects (``gc.freeze``) are not
    scanned, so the collections left look only at what the loop allocates. ``gc.unfreeze`` afterwards
    returns them to the collector, so nothing unreachable from one trial outlives it in a campaign
    worker that runs many. Unlike ``rover run``'s ``freeze_start_up_heap`` there is no collection first:
    it would cost a full collection in every trial, and the garbage is collected after the unfreeze.
    """
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def _run_loop(
    scenario: Scenario,
    clock: SimClock,
    stack: OnboardStack,
    world: SimWorld,
    sink: MessageSink,
    on_progress: Callable[[float], None] | None,
) -> tuple[str, int | None]:
    """Step until the trial ends; returns why it ended and when the rover arrived at its last goal."""
    dt_s = seconds(PHYSICS_DT_NS)
    end_ns = stop_ns = to_ns(scenario.duration_s)
    if not stack.start_mission([(goal.x, goal.y) for goal in scenario.goals], f"scenario {scenario.name}"):
        return MISSION_REJECTED, None  # idling to the timeout would only hide it
    mission = stack.mission
    arrived_ns: int | None = None
    tick = 0
    next_progress_ns = 0
    while clock.now_ns() < stop_ns or _still_rolling(clock.now_ns(), arrived_ns, end_ns, world):
        now = clock.advance(PHYSICS_DT_NS)
        tick += 1
        world.tick(dt_s)
        if tick % CONTROL_DIVIDER == 0:
            stack.step()
            if arrived_ns is not None:
                pass  # parked: ARRIVED holds until a new goal, none is given
            elif stack.mode is Mode.ARRIVED and mission.state is not MissionState.ACTIVE:
                # The step has already made the next waypoint the goal, had there been one.
                arrived_ns = now
                stop_ns = park_until_ns(scenario.faults, now, end_ns)
                if stop_ns <= now:
                    continue  # nothing left to run: stop once the rover has come to rest
                _log_record(
                    sink,
                    now,
                    topics.LOG_INFO,
                    f"ARRIVED at {seconds(now):.1f} s; parked until {seconds(stop_ns):.1f} s "
                    "for the scenario's faults still to run",
                )
            elif stack.mode is Mode.NO_PATH:
                return "no_path", None
        if world.rolled_over:
            return "rollover", arrived_ns
        if on_progress is not None and now >= next_progress_ns:
            on_progress(seconds(now) / scenario.duration_s)
            next_progress_ns = now + NS_PER_S
    return ("timeout", None) if arrived_ns is None else ("arrived", arrived_ns)


def _still_rolling(now_ns: int, arrived_ns: int | None, end_ns: int, world: SimWorld) -> bool:
    """After the final ARRIVED the trial runs on until the rover has come to rest (the zero command
    still has to brake it), so the final pose, and the distance to the goal, is where it really stopped;
    at most ``SETTLE_MAX_NS``, never past the scenario's duration."""
    if arrived_ns is None or now_ns >= min(arrived_ns + SETTLE_MAX_NS, end_ns):
        return False
    return abs(world.body.speed) >= AT_REST_MPS


def _log_record(sink: MessageSink, t_ns: int, level: int, message: str) -> None:
    """A ``log`` record from the trial runner itself (name ``hil.trial``)."""
    sink.publish(topics.LOG, t_ns, topics.log_message(t_ns, level, "hil.trial", message))


def write_header(
    recorder: McapRecorder,
    scenario: Scenario,
    config: RoverConfig,
    seed: int,
    *,
    mode: str = LOCKSTEP_MODE,
    campaign: CampaignPlace | None = None,
) -> None:
    """Metadata (scenario, trial, config) and attachments (scenario, map, config, a swapped-in VESC DBC)
    that make a recording self-describing."""
    obstacles = [{"id": o.id, "x": o.x, "y": o.y, "radius": o.radius_m} for o in scenario.obstacles]
    moving = [
        {
            "id": m.id,
            "radius": m.radius_m,
            "waypoints": m.waypoints,
            "speed_mps": m.speed_mps,
            "start_s": m.start_s,
        }
        for m in scenario.moving_obstacles
    ]
    faults = [dataclasses.asdict(f) for f in scenario.faults]
    goal = scenario.goals[-1]
    recorder.add_metadata(
        "scenario",
        {
            "name": scenario.name,
            "source": Path(scenario.source).name,
            "seed": str(seed),
            "duration_s": repr(scenario.duration_s),
            "terrain": scenario.terrain_summary,
            "path_tolerance_m": repr(scenario.path_tolerance_m),
            "encounter_margin_m": repr(scenario.encounter_margin_m),
            "obstacles_json": json.dumps(obstacles, separators=(",", ":")),
            "moving_obstacles_json": json.dumps(moving, separators=(",", ":")),
            "faults_json": json.dumps(faults, separators=(",", ":")),
            "start_json": json.dumps({"x": scenario.start_xy[0], "y": scenario.start_xy[1]}),
            "goal_json": json.dumps({"x": goal.x, "y": goal.y, "tolerance_m": goal.tolerance_m}),
            "terrain_class": _dominant_class(scenario),
            # How the rover perceived obstacles ([sensors] perception): the real-time peer always over
            # MAVLink, whatever the attached scenario file says (hil.peer.seen_through_lidar).
            "perception": scenario.sensors.perception,
            "perception_json": json.dumps(_perception_record(scenario), separators=(",", ":")),
            # The true world's ground where the scenario retuned it (terrain_classes.sandy.friction_mu):
            # the planner's beliefs are the config record's keys of the same names. None: as it always was.
            **overrides_flat(scenario.terrain_classes),
        },
    )
    trial = {
        "mode": mode,
        "rover_id": config.rover_id,
        # The whole source: a campaign variant's is "<base> + overrides of <terrain>/<variant>/seed<N>".
        "config": config.source,
        "software_version": software_version(),
        "can_bitrate": str(config.can.bitrate),
    }
    if campaign is not None:
        trial.update(campaign.metadata())
    recorder.add_metadata("trial", trial)
    record_config(recorder, config)
    recorder.add_attachment("scenario.toml", "application/toml", scenario.text.encode("utf-8"), 0)
    recorder.add_attachment("map.npz", "application/x-npz", _map_archive(scenario), 0)
    attach_vesc_dbc(recorder, config.vesc)


def _map_archive(scenario: Scenario) -> bytes:
    """The true map's layers (what the simulator drove on), loadable with ``numpy.load``."""
    terrain = scenario.terrain
    buffer = io.BytesIO()
    np.savez_compressed(
        buffer,
        elevation_m=terrain.elevation_m,
        terrain_class=terrain.terrain_class,
        obstacles=terrain.obstacles,
        resolution_m=np.float64(terrain.resolution_m),
        origin_xy=np.asarray(terrain.origin_xy, dtype=np.float64),
    )
    return buffer.getvalue()


def _perception_record(scenario: Scenario) -> dict[str, object]:
    """The simulated perception's settings, as the scenario metadata's ``perception_json`` keeps them."""
    sensors = scenario.sensors
    record: dict[str, object] = {
        "range_m": sensors.perception_range_m,
        "rate_hz": sensors.perception_rate_hz,
        "noise_m": sensors.perception_noise_m,
        "fov_deg": sensors.perception_fov_deg,
        # Where the simulated lidar sat; the rover's belief is the config's [perception].
        "mount_forward_m": sensors.perception_mount_forward_m,
        "mount_left_m": sensors.perception_mount_left_m,
        "mount_yaw_deg": sensors.perception_mount_yaw_deg,
    }
    if sensors.perception == "rangefinders":
        # Only then: the record of every other trial stays as it was.
        if sensors.rangefinder_mounts is None:
            record["rangefinder_yaw_deg"] = list(sensors.rangefinder_yaw_deg)
        else:
            record["rangefinders"] = [
                {"yaw_deg": round(math.degrees(m.yaw_rad), 9), "forward_m": m.forward_m, "left_m": m.left_m}
                for m in sensors.rangefinder_mounts
            ]
        record["rangefinder_fov_deg"] = sensors.rangefinder_fov_deg
    return record


def _dominant_class(scenario: Scenario) -> str:
    """The terrain class covering most of the map: the row a trial falls under in per-terrain tables."""
    counts = np.bincount(scenario.terrain.terrain_class.ravel())
    return TERRAIN_CLASSES[int(np.argmax(counts))].name
