"""A lockstep HIL rig for failsafe tests: the real onboard stack against the simulator, with fault hooks.

Like ``hil.trial`` (100 Hz physics, control every second tick) but driven tick by tick from the test, on a
flat open 20 m x 20 m map. Faults go in where a real one would: in the bytes on the MAVLink link, in the
frames on the CAN bus, in the battery voltage and attitude the simulated hardware reports, or in the
control loop's timing.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable
from typing import Any

import can
import numpy as np

from firmware_bridge.can_link import CanLink, open_bus
from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_transport import PipeEnd, Transport, memory_pipe_pair
from firmware_bridge.vesc import VescCodec
from hil.autopilot_sim import AutopilotTruth, SimAutopilot
from hil.battery import Battery
from hil.dynamics import RoverDynamics
from hil.vesc_sim import SimVescBank
from logs.clock import SimClock, seconds
from logs.commands import CommandSource
from logs.settings import parse_toml
from logs.sink import MemorySink, Message
from navigator.config import RoverConfig, rover_config_from_table
from navigator.deferred_sink import DeferredSink
from navigator.onboard import OnboardStack
from navigator.terrain import TerrainMap, from_maze

PHYSICS_DT_NS = 10_000_000
CONTROL_DIVIDER = 2
TICK_NS = PHYSICS_DT_NS * CONTROL_DIVIDER  # one control tick
DATUM = (47.0, 8.0, 400.0)
MSG_HEARTBEAT, MSG_GPS_RAW_INT, MSG_ATTITUDE = 0, 24, 30
_channels = itertools.count()


class RigTimeout(TimeoutError):
    """A wait on the rig ran out of simulated time."""


class FaultyBus(can.BusABC):
    """The onboard end of the CAN bus with switchable faults.

    ``silent_ids``: frames from these controllers never arrive. ``drop_commands``: our frames vanish on
    the wire (sent as far as we can tell, never received). ``send_fails``: every send raises, as on a
    bus-off controller.
    """

    def __init__(self, inner: can.BusABC) -> None:
        super().__init__(channel=inner.channel_info)
        self._inner = inner
        self.silent_ids: set[int] = set()
        self.drop_commands = False
        self.send_fails = False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self.send_fails:
            raise can.CanOperationError("simulated bus-off: transmit refused")
        if not self.drop_commands:
            self._inner.send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        while True:
            msg = self._inner.recv(timeout=0)
            if msg is None or (msg.arbitration_id & 0xFF) not in self.silent_ids:
                return msg, False

    def shutdown(self) -> None:
        super().shutdown()
        self._inner.shutdown()


class FaultyAutopilotWire:
    """The simulated autopilot's end of the MAVLink pipe; frames with ids in ``dropped`` never leave.

    pymavlink writes one whole frame per ``write``, so the message id is in the MAVLink 2 header.
    """

    def __init__(self, inner: PipeEnd) -> None:
        self._inner = inner
        self.dropped: set[int] = set()

    def write(self, data: bytes) -> None:
        msgid = data[7] | data[8] << 8 | data[9] << 16 if len(data) >= 10 else -1
        if msgid not in self.dropped:
            self._inner.write(data)

    def read(self) -> bytes:
        return self._inner.read()

    def close(self) -> None:
        self._inner.close()


class FakeGroundStation:
    """A ``CommandSource`` the test drives: queued commands, and ``last_contact_ns`` while in contact."""

    def __init__(self) -> None:
        self.queued: list[Any] = []
        self.last_contact_ns: int | None = None

    def poll(self) -> list[Any]:
        commands, self.queued = self.queued, []
        return commands


def rig_config(**safety: Any) -> RoverConfig:
    """The shipped defaults with the datum of the rig's autopilot and the given ``[safety]`` overrides."""
    config = rover_config_from_table(parse_toml("", "<rig>"))
    lat, lon, alt = DATUM
    estimator = dataclasses.replace(config.estimator, datum_lat_deg=lat, datum_lon_deg=lon, datum_alt_m=alt)
    return dataclasses.replace(
        config, estimator=estimator, safety=dataclasses.replace(config.safety, **safety)
    )


class Rig:
    def __init__(
        self,
        config: RoverConfig,
        *,
        start: tuple[float, float] = (3.0, 3.0),
        goal: tuple[float, float] = (17.0, 17.0),
        commands: CommandSource | None = None,
        seed: int = 0,
        deferred: bool = False,
        ground_station: Transport | None = None,
        resolution_m: float | None = None,
        terrain: TerrainMap | None = None,
    ) -> None:
        """``deferred``: the links and the stack record through a ``DeferredSink`` (as ``rover run``).
        ``ground_station``: the transport of a second MAVLink link, straight to a ground station.
        ``resolution_m``: the map's grid (default one 2 m cell per maze cell; finer where obstacles the
        stack places must be resolved, e.g. a mark where it dug in). ``terrain``: the map itself instead (the
        rover's world and the stack's map), e.g. a slope."""
        self.clock = SimClock()
        self.sink = MemorySink()
        self.deferred = DeferredSink(self.sink) if deferred else None
        onboard_sink = self.sink if self.deferred is None else self.deferred
        self.terrain = (
            from_maze(np.full((10, 10), 2), 2.0, resolution_m=resolution_m) if terrain is None else terrain
        )
        bus_config = dataclasses.replace(config.can, interface="virtual", channel=f"rig-{next(_channels)}")
        self.bus = FaultyBus(open_bus(bus_config))
        self._sim_bus = open_bus(bus_config)
        onboard_pipe, sim_pipe = memory_pipe_pair()
        self.wire = FaultyAutopilotWire(sim_pipe)
        codec = VescCodec.for_profile(config.vesc)
        can_link = CanLink(self.bus, codec, self.clock, onboard_sink)
        mavlink = MavlinkLink(onboard_pipe, self.clock, onboard_sink)
        self.stack = OnboardStack(
            config,
            self.clock,
            can_link,
            mavlink,
            onboard_sink,
            self.terrain,
            commands=commands,
            deferred=self.deferred,
            ground_station=None
            if ground_station is None
            else MavlinkLink(
                ground_station, self.clock, onboard_sink, link_timeout_s=None, name="ground_station"
            ),
        )
        self.vescs = SimVescBank(self._sim_bus, codec, self.clock)
        self.autopilot = SimAutopilot(
            self.wire,
            self.clock,
            np.random.default_rng(seed),
            datum_lat_deg=DATUM[0],
            datum_lon_deg=DATUM[1],
            datum_alt_m=DATUM[2],
        )
        self.body = RoverDynamics(self.terrain, config.vehicle, x=start[0], y=start[1], yaw=0.785)
        self.battery = Battery()
        self.voltage_override: float | None = None
        self.roll_override: float | None = None
        self.control_enabled = True
        self.stack.set_goal(*goal)
        self._tick = 0

    # --- time -----------------------------------------------------------------------------------
    @property
    def now_ns(self) -> int:
        return self.clock.now_ns()

    def physics_tick(self) -> None:
        now = self.clock.advance(PHYSICS_DT_NS)
        del now
        self._tick += 1
        dt_s = seconds(PHYSICS_DT_NS)
        self.vescs.poll()
        vescs = self.vescs
        step = self.body.step(
            dt_s, vescs.wheel_speeds_mps(), self.battery.voltage_v, vescs.stalled(), vescs.wheel_controls()
        )
        vescs.set_rolling_speeds(step.wheel_speeds_mps)
        current = float(np.sum(np.abs(step.motor_currents_a) * np.abs(step.duty)))
        voltage = self.battery.draw(current + 0.5, dt_s)
        if self.voltage_override is not None:
            voltage = self.voltage_override
        limits = step.wheel_speed_limits_mps
        self.vescs.set_electrical(step.motor_currents_a, voltage, step.duty, limits, step.held_speeds_mps)
        self.vescs.step(dt_s)
        self.autopilot.step(
            AutopilotTruth(
                x_m=self.body.x,
                y_m=self.body.y,
                z_m=0.0,
                yaw_rad=self.body.yaw,
                speed_mps=self.body.speed,
                yaw_rate_rps=self.body.yaw_rate,
                accel_body_mps2=step.specific_force_body_mps2,
                roll_rad=self.roll_override if self.roll_override is not None else 0.0,
            )
        )
        self.autopilot.poll()

    def control_tick(self) -> int:
        """Advance to the next control tick and run it (unless control is disabled); returns its time."""
        for _ in range(CONTROL_DIVIDER):
            self.physics_tick()
        if self.control_enabled:
            self.stack.step()
        return self.now_ns

    def run_for(self, duration_s: float) -> None:
        end = self.now_ns + round(duration_s * 1e9)
        while self.now_ns < end:
            self.control_tick()

    def run_until(self, done: Callable[[], bool], within_s: float, what: str) -> int:
        end = self.now_ns + round(within_s * 1e9)
        while self.now_ns < end:
            self.control_tick()
            if done():
                return self.now_ns
        raise RigTimeout(f"{what} did not happen within {within_s} s of simulated time")

    def drive(self) -> int:
        """Run until the supervisor lets guidance drive and the rover moves; returns that time."""
        return self.run_until(
            lambda: self.stack.safety_mode.value == "DRIVING" and self.body.speed > 0.3, 10.0, "driving"
        )

    # --- what was recorded ----------------------------------------------------------------------
    def events(self, kind: str) -> list[tuple[int, Message]]:
        return [(t, m) for topic, t, m in self.sink.records if topic == "safety/events" and m["kind"] == kind]

    def first_event_ns(self, kind: str) -> int | None:
        found = self.events(kind)
        return found[0][0] if found else None

    def commands_at(self, t_ns: int) -> Message:
        for topic, t, m in self.sink.records:
            if topic == "wheels/command" and t == t_ns:
                return m
        raise KeyError(f"no wheels/command at {t_ns}")

    def last_rx_ns(self, topic: str, match: Callable[[Message], bool], before_ns: int) -> int:
        times = [t for tp, t, m in self.sink.records if tp == topic and t <= before_ns and match(m)]
        if not times:
            raise KeyError(f"no {topic} record matching before {before_ns}")
        return max(times)

    def close(self) -> None:
        self.stack.close()
        self._sim_bus.shutdown()
