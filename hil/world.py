"""The simulated world and its peers, stepped one physics tick at a time.

Everything on the simulator's side of the wires: the rover body on the true terrain (``hil.dynamics``), the
battery, six VESC controllers on the CAN bus, the autopilot on the MAVLink link with its GPS and IMU
models, moving obstacles, simulated perception, the scenario's faults, and the ground-truth recorder. The
lockstep trial (``hil.trial``) and the real-time peer (``hil.peer``) both drive it; only their clocks and
wires differ.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from types import TracebackType

import can
import numpy as np

from firmware_bridge.mavlink_transport import Transport
from firmware_bridge.vesc import WHEEL_COUNT, VescCodec
from hil.autopilot_sim import AutopilotTruth, SimAutopilot
from hil.battery import REGEN_CURRENT_LIMIT_A, Battery
from hil.bus_off import BusOffAnnouncer, BusOffRoverEnd
from hil.dynamics import DynamicsStep, RoverDynamics
from hil.fault_links import FaultyCanBus, FaultyTransport
from hil.faults import FaultSchedule
from hil.lidar_sim import SimLidar
from hil.perception_sim import PerceptionSim
from hil.rangefinder_sim import SimRangefinders
from hil.scenario import Scenario
from hil.sensors import GpsModel, ImuModel
from hil.truth import TruthRecorder
from hil.vesc_sim import SimVescBank
from logs.clock import Clock
from logs.recorder import McapRecorder
from logs.scenario_record import WORLD_METADATA
from logs.sink import MessageSink
from navigator.footprint import Footprint, disc_gap_m
from navigator.vehicle import VehicleParams

ELECTRONICS_CURRENT_A = 0.5  # computer, radios and controllers at idle
TRUTH_DIVIDER = 2  # ground truth recorded every second physics tick
# A held scenario's time zero (SimWorld.hold): later than any clock's reading (int64 nanoseconds: 146
# years), so every fault's start lies ahead and scenario time before it is negative.
_HELD_EPOCH_NS = 2**62


class SimWorld:
    """The world and the simulated peers on the simulator's ends of the CAN bus and MAVLink link."""

    def __init__(
        self,
        scenario: Scenario,
        vehicle: VehicleParams,
        codec: VescCodec,
        clock: Clock,
        can_bus: can.BusABC,
        mavlink: Transport,
        sink: MessageSink,
        seed: int,
    ) -> None:
        self.scenario = scenario
        self._clock = clock
        self._sink = sink
        # The world's start on its clock: time zero of the scenario's faults and moving obstacles (the
        # real-time peer's monotonic clock counts from the boot). Recorded by record_start (metadata "world");
        # hold and start_at move it (the real-time peer's start on the rover's first command).
        self.epoch_ns = clock.now_ns()
        self.faults = FaultSchedule(
            scenario.faults, epoch_ns=self.epoch_ns, controller_ids=codec.profile.controller_ids
        )
        # Separate streams so a fault or an extra obstacle never shifts the sensor noise.
        sensor_rng = np.random.default_rng(seed)
        fault_rng = np.random.default_rng([seed, 1])
        perception_rng = np.random.default_rng([seed, 2])
        has = {f.target for f in scenario.faults}
        # The world's own wrappers, shut in close(); the wires themselves belong to whoever opened them.
        self._faulty_can: FaultyCanBus | None = None
        self._rover_ends: list[BusOffRoverEnd] = []
        self.bus_off_announcer: BusOffAnnouncer | None = None  # real time only: announce_bus_off
        if "can" in has:
            can_bus = self._faulty_can = FaultyCanBus(can_bus, self.faults, clock, fault_rng)
        if "mavlink" in has:
            mavlink = FaultyTransport(mavlink, self.faults, clock, fault_rng)
        self._vesc_faults = "vesc" in has
        self._battery_faults = "battery" in has
        self.can_bus = can_bus
        sensors = scenario.sensors
        # One regeneration floor for the physics (what the pack takes) and the controllers (what they report
        # taking): set apart, the energy metric would differ from the pack's energy.
        regen_current_limit_a = REGEN_CURRENT_LIMIT_A
        self.vescs = SimVescBank(can_bus, codec, clock, regen_current_limit_a=regen_current_limit_a)
        self.autopilot = SimAutopilot(
            mavlink,
            clock,
            sensor_rng,
            datum_lat_deg=scenario.datum[0],
            datum_lon_deg=scenario.datum[1],
            datum_alt_m=scenario.datum[2],
            gps_rate_hz=sensors.gps_rate_hz,
            imu_rate_hz=sensors.imu_rate_hz,
            gps_noise_m=sensors.gps_noise_m,
            gyro_noise_rps=sensors.gyro_noise_rps,
            accel_noise_mps2=sensors.accel_noise_mps2,
            gps=GpsModel(
                sensor_rng,
                self.faults,
                noise_m=sensors.gps_noise_m,
                latency_s=sensors.gps_latency_s,
                dropout_probability=sensors.gps_dropout_probability,
                satellites=sensors.gps_satellites,
            ),
            imu=ImuModel(
                sensor_rng,
                self.faults,
                gyro_noise_rps=sensors.gyro_noise_rps,
                accel_noise_mps2=sensors.accel_noise_mps2,
                gyro_bias_rps=sensors.gyro_bias_rps,
                accel_bias_mps2=sensors.accel_bias_mps2,
            ),
        )
        self.body = RoverDynamics(
            scenario.terrain,
            vehicle,
            scenario.classes,  # the true world's ground; the rover's beliefs are its config's
            x=scenario.start_xy[0],
            y=scenario.start_xy[1],
            yaw=scenario.start_yaw_rad,
            regen_current_limit_a=regen_current_limit_a,
        )
        self._footprint = Footprint.of(vehicle)
        self.battery = Battery()
        self.truth = TruthRecorder(sink, scenario)
        self.perception = PerceptionSim(
            clock,
            self._perception_origin(sensors.perception_mount_forward_m, sensors.perception_mount_left_m),
            scenario.obstacles,
            scenario.moving_obstacles,
            perception_rng,
            range_m=sensors.perception_range_m,
            rate_hz=sensors.perception_rate_hz,
            noise_m=sensors.perception_noise_m,
            epoch_ns=self.epoch_ns,
        )
        # The lidar, when the rover perceives through scans ("scan"), on the autopilot's (fault-wrapped)
        # MAVLink wire; its own noise stream, so turning it on shifts no other.
        self.lidar = (
            SimLidar(
                mavlink,
                clock,
                self.perception.obstacles_at,
                np.random.default_rng([seed, 3]),
                range_m=sensors.perception_range_m,
                rate_hz=sensors.perception_rate_hz,
                noise_m=sensors.perception_noise_m,
                fov_deg=sensors.perception_fov_deg,
                mount=sensors.lidar_mount,
            )
            if sensors.perception == "scan"
            else None
        )
        # The ring of rangefinders ("rangefinders"), read out by the autopilot and sent from it as
        # DISTANCE_SENSOR; its own noise stream too.
        self.rangefinders = (
            SimRangefinders(
                self.autopilot.send_sensor,
                clock,
                self.perception.obstacles_at,
                np.random.default_rng([seed, 4]),
                sensors=sensors.rangefinder_ring,
                fov_deg=sensors.rangefinder_fov_deg,
                range_m=sensors.perception_range_m,
                rate_hz=sensors.perception_rate_hz,
                noise_m=sensors.perception_noise_m,
            )
            if sensors.perception == "rangefinders"
            else None
        )
        self._tick = 0
        self._has_faults = bool(scenario.faults)
        self._next_fault_change_ns: float = self.epoch_ns  # the first tick applies the faults (_apply_faults)
        self._has_moving_obstacles = bool(scenario.moving_obstacles)
        self.last_step: DynamicsStep | None = None

    def close(self) -> None:
        """Shut what the world opened itself (the CAN fault wrapper); the caller's wires stay open.

        Safe to call twice. python-can logs "... was not properly shut down" for a bus collected unshut.
        """
        if self._faulty_can is not None:
            self._faulty_can.shutdown()
        for end in self._rover_ends:
            end.shutdown()

    def __enter__(self) -> SimWorld:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        self.close()

    def record_start(self, recorder: McapRecorder, **how: str) -> None:
        """The world's start on its clock (metadata ``world``): the metrics move the obstacles from it.
        ``how``: further string entries of the record (the real-time peer's, saying what started it)."""
        recorder.add_metadata(WORLD_METADATA, {"epoch_ns": str(self.epoch_ns), **how})

    def hold(self) -> None:
        """Hold the scenario's time at zero until ``start_at``; call before the first tick.

        The world still steps, its sensors and controllers still talk (a rover needs GPS, IMU and wheel
        status to start up), but no fault is active or announced and the moving obstacles wait at their
        first waypoints: the scenario's time zero lies beyond any reading of the clock. The real-time
        peer holds a scenario until the rover's first wheel command (``hil.peer_start``).
        """
        self._move_epoch(_HELD_EPOCH_NS)

    def start_at(self, epoch_ns: int) -> None:
        """Start a held scenario with its time zero at ``epoch_ns`` on the clock (at most now: the next tick
        applies what is due by then)."""
        if epoch_ns > self._clock.now_ns():
            raise ValueError(
                f"a scenario cannot start in the future: {epoch_ns} ns > now {self._clock.now_ns()}"
            )
        self._move_epoch(epoch_ns)

    def _move_epoch(self, epoch_ns: int) -> None:
        # Every part that counts from the world's start, with it: the faults (and so the fault-wrapped
        # wires, the sensor models and the bus-off announcer, which ask them), the moving obstacles and the
        # next fault change, which the next tick then applies.
        self.epoch_ns = epoch_ns
        self.faults.epoch_ns = epoch_ns
        self.perception.epoch_ns = epoch_ns
        self._next_fault_change_ns = epoch_ns

    def rover_can_end(self, bus: can.BusABC) -> can.BusABC:
        """The rover's end of an in-process CAN bus, as the scenario's faults leave it.

        Lockstep only, where one process holds both ends: during a ``can`` ``off`` fault the rover's own
        controller is bus-off too (``hil.bus_off``: its sends fail, it hears nothing but the error
        frames). Without such a fault, ``bus`` itself. A wrapper is the world's, shut in ``close()``. (Real
        time, where the rover is another process: ``announce_bus_off``.)
        """
        if self.faults.scheduled("can", "off"):
            end = BusOffRoverEnd(bus, self.faults, self._clock)
            self._rover_ends.append(end)
            return end
        return bus

    def announce_bus_off(self, bus: can.BusABC) -> None:
        """Tell a rover in another process, on the shared ``bus`` (the raw one this world was given), when
        its controller goes bus-off and restarts (``hil.bus_off.BusOffAnnouncer``): the real-time peer's
        counterpart of ``rover_can_end``. Without a ``can`` ``off`` fault in the scenario, nothing."""
        if self.faults.scheduled("can", "off"):
            self.bus_off_announcer = BusOffAnnouncer(bus, self.faults)

    @property
    def rolled_over(self) -> bool:
        return self.body.rolled_over

    def _perception_origin(self, forward_m: float, left_m: float) -> Callable[[], tuple[float, float]]:
        """Where the obstacle sensor is (ENU): the body's centre, or the mount's point on it. Range is
        measured from there, as the lidar's scans are; a detector's field of view is not modelled (it sees
        all round), so the mount's yaw does not matter here."""
        if forward_m == 0.0 and left_m == 0.0:
            return lambda: (self.body.x, self.body.y)

        def mount_point() -> tuple[float, float]:
            body = self.body
            cos_yaw, sin_yaw = math.cos(body.yaw), math.sin(body.yaw)
            return (
                body.x + forward_m * cos_yaw - left_m * sin_yaw,
                body.y + forward_m * sin_yaw + left_m * cos_yaw,
            )

        return mount_point

    def tick(self, dt_s: float) -> DynamicsStep:
        """One physics tick ending at the clock's now: commands in, body moves, status and sensors out."""
        now = self._clock.now_ns()
        self._tick += 1
        if self._has_faults:
            self._apply_faults(now)
        vescs, body, battery = self.vescs, self.body, self.battery
        vescs.poll()
        # Only a scheduled vesc fault seizes a wheel (_apply_faults): without one, no wheel is stalled, and
        # the dynamics take "nothing given" as six freely turning wheels without asking the bank every tick.
        stalled = vescs.stalled() if self._vesc_faults else ()
        # A controller that has let go of its motor (timed out, rebooting, under-voltage) lets its wheel roll
        # with the ground; the battery cut-off lowers the current limits (hil.vesc_limits).
        step = body.step(dt_s, vescs.wheel_speeds_mps(), battery.voltage_v, stalled, vescs.wheel_controls())
        vescs.set_rolling_speeds(step.wheel_speeds_mps)
        # The motors' draw (each I x duty, nothing back from a braking one) is summed in the physics kernel.
        voltage = battery.draw(step.motor_input_current_a + ELECTRONICS_CURRENT_A, dt_s)
        # The motors' speed limits at this voltage too, and where their current limit holds a wheel: the VESCs
        # report the speed the wheels turn.
        vescs.set_electrical(
            step.motor_currents_a, voltage, step.duty, step.wheel_speed_limits_mps, step.held_speeds_mps
        )
        vescs.step(dt_s)
        autopilot = self.autopilot
        # Every other tick at the default rates the autopilot has nothing to send and its GPS nothing to
        # remember (SimAutopilot.next_truth_ns): its truth is neither built nor given. The world's clocks
        # hold still through a tick (SimClock, the real-time peer's StepClock), so ``now`` is the reading
        # step would take itself.
        if now >= autopilot.next_truth_ns:
            # The pose from the step (the body's state after it, as plain tuple fields: no property calls).
            # Positional, in AutopilotTruth's field order: keywords cost half as much again.
            truth = AutopilotTruth(
                step.x,  # x_m
                step.y,  # y_m
                body.elevation_m,  # z_m
                step.yaw,  # yaw_rad
                step.speed_mps,
                step.yaw_rate_rps,
                step.specific_force_body_mps2,  # accel_body_mps2
                step.roll_rad,
                step.pitch_rad,
                voltage,  # battery_voltage_v
                battery.current_a,
                round(100.0 * battery.state_of_charge),  # battery_remaining_pct
                step.lateral_speed_mps,
            )
            autopilot.step(truth)
        autopilot.poll()
        lidar = self.lidar
        if lidar is not None and now >= lidar.next_ns:
            lidar.step(step.x, step.y, step.yaw)
        rangefinders = self.rangefinders
        if rangefinders is not None and now >= rangefinders.next_ns:
            rangefinders.step(step.x, step.y, step.yaw)
        # Ground truth is recorded every TRUTH_DIVIDER-th tick; between those, the recorder has something
        # to do only while a contact may begin or end (TruthRecorder.on_step), so it is not called at all.
        truth_recorder = self.truth
        record = self._tick % TRUTH_DIVIDER == 0
        if record or step.collided or step.rollover or truth_recorder.in_collision:
            truth_recorder.on_step(now, body, step, battery, record_state=record)
        if self._has_moving_obstacles:
            self._moving_contacts(now, step)
        self.last_step = step
        return step

    def _apply_faults(self, now: int) -> None:
        """The faults' effects on the world's parts at ``now``. Which faults are active changes only at a
        fault's start or end, and the announcements and the parts' settings with it (setting a controller
        or the battery again to what it already is changes nothing): they are redone only on the first
        tick at or past the next such moment. The bus-off announcer keeps its own period, every tick."""
        changed = now >= self._next_fault_change_ns
        if changed:
            self.faults.announce(self._sink, now)
        if self.bus_off_announcer is not None:
            self.bus_off_announcer.poll(now)
        if not changed:
            return
        self._next_fault_change_ns = self.faults.next_change_ns(now)
        if self._vesc_faults:
            active = self.faults.active_all("vesc", now)
            for wheel in range(WHEEL_COUNT):
                kinds = {f.kind for f in active if f.controller == wheel}
                self.vescs.set_rebooting(wheel, "off" in kinds)
                self.vescs.set_stuck(wheel, "stuck" in kinds)
        if self._battery_faults:
            sag = self.faults.active("battery", now)
            if sag is None:
                self.battery.set_sag(0.0, 0.0)
            else:
                self.battery.set_sag(sag.sag_v, sag.extra_resistance_ohm)

    def _moving_contacts(self, now: int, step: DynamicsStep) -> None:
        """A moving obstacle (a disc) touching the footprint rectangle is a collision (reported once per
        contact). Every tick: the pose is the step's (the body's state after it, without property calls),
        and the truth recorder hears all the obstacles' contacts in one call."""
        pose = (step.x, step.y, step.yaw)
        footprint = self._footprint
        touching = [
            obstacle.id
            for obstacle, (x, y, _vx, _vy) in self.perception.moving_states(now)
            if disc_gap_m(pose, footprint, (x, y), obstacle.radius_m) < 0.0
        ]
        self.truth.on_moving_contacts(now, touching, self.body)
