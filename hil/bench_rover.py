"""The simulated rover of ``rover bench runtime``: six VESCs and the autopilot, 100 Hz on the monotonic clock.

A lighter peer than ``rover hil peer`` (flat ground, no faults, no recording): the bench measures the
onboard loop, not the world. It runs as a process's target (the bench spawns it inside the private
network namespace, CAN on ``udp_multicast``) or in a thread (a ``virtual`` bus); it opens its own bus.

Each step waits for its deadline with ``navigator.precise_wait.sleep_until`` (sleep, then spin the last
``spin_ns``), and the autopilot reads the step's due time as its clock (``hil.step_clock.StepClock``): a
real IMU samples on a hardware timer, and the sensor-paced loop takes whatever jitter the IMU's send has
as its own.
``spin_ns`` 0 is the plain sleep (with the OS's wake-up overshoot).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from firmware_bridge.can_link import CanConfig, open_bus
from firmware_bridge.mavlink_transport import Transport, UdpTransport
from firmware_bridge.vesc import VescCodec
from hil.autopilot_sim import AutopilotTruth, SimAutopilot
from hil.dynamics import RoverDynamics
from hil.jitter_trace import ImuSendLog
from hil.step_clock import StepClock
from hil.vesc_sim import SimVescBank
from logs.clock import MonotonicClock, seconds
from navigator.config import RoverConfig
from navigator.precise_wait import sleep_until
from navigator.runtime import freeze_start_up_heap
from navigator.terrain import TerrainMap

DATUM = (47.0, 8.0, 400.0)
SIM_DT_NS = 10_000_000


def run_sim_rover(
    stop: Any,
    bus_config: CanConfig,
    mavlink_port: int,
    config: RoverConfig,
    terrain: TerrainMap,
    spin_ns: int,
    trace_path: Path | None = None,
) -> None:
    """Step the simulated rover until ``stop`` (a threading or multiprocessing event) is set.

    ``trace_path``: write the IMU frames' due and send times there at the end (``hil.jitter_trace``).
    """
    clock = MonotonicClock()
    sample_clock = StepClock(clock.now_ns())
    bus = open_bus(bus_config)
    codec = VescCodec.for_profile(config.vesc)
    vescs = SimVescBank(bus, codec, clock)
    udp = UdpTransport("udpout", "127.0.0.1", mavlink_port)
    send_log = ImuSendLog(udp) if trace_path is not None else None
    transport: Transport = send_log if send_log is not None else udp
    autopilot = SimAutopilot(
        transport,
        sample_clock,
        np.random.default_rng(1),
        datum_lat_deg=DATUM[0],
        datum_lon_deg=DATUM[1],
        datum_alt_m=DATUM[2],
    )
    body = RoverDynamics(terrain, config.vehicle, x=5.0, y=5.0, yaw=0.785)
    body.warm_up()  # before the first IMU frame: the bench times the rover from that frame on
    freeze_start_up_heap()  # a full collection would hold up the IMU's send by tens of ms
    due = sample_clock.t = clock.now_ns()
    dt_s = seconds(SIM_DT_NS)
    truth: AutopilotTruth | None = None
    try:
        while not stop.is_set():
            # The autopilot sends first, on the wake-up, with the state the last step ended in: a real IMU
            # samples on its own timer. Sending after the physics step would stamp the step's varying
            # compute time onto the IMU's timing, and the sensor-synchronous loop would inherit it.
            sample_clock.t = due
            if send_log is not None:
                send_log.due_ns = due
            if truth is not None:
                autopilot.step(truth)
            autopilot.poll()
            vescs.poll()
            step = body.step(dt_s, vescs.wheel_speeds_mps(), 24.0, (), vescs.wheel_controls())
            vescs.set_rolling_speeds(step.wheel_speeds_mps)
            vescs.set_electrical(step.motor_currents_a, 24.0, step.duty)
            vescs.step(dt_s)
            truth = AutopilotTruth(
                x_m=body.x,
                y_m=body.y,
                z_m=0.0,
                yaw_rad=body.yaw,
                speed_mps=body.speed,
                yaw_rate_rps=body.yaw_rate,
                accel_body_mps2=step.specific_force_body_mps2,
            )
            due += SIM_DT_NS
            sleep_until(clock, due, spin_ns)
        if send_log is not None and trace_path is not None:
            send_log.save(trace_path)
    finally:
        udp.close()
        bus.shutdown()
