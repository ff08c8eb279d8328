"""The real-time HIL peer: the simulated world on the monotonic clock, on real wires to ``rover run``.

The same ``SimWorld`` the lockstep trial steps is paced here by ``navigator.runtime.FixedRateScheduler`` at
100 Hz on a ``MonotonicClock``; its six VESCs sit on a python-can bus opened from config (``udp_multicast``
inside a private network namespace, ``socketcan``/``vcan0`` where the kernel has it) and its autopilot
answers on a UDP MAVLink port on 127.0.0.1 that the OS picked (``rover run`` connects with
``udpout:127.0.0.1:PORT``). Each step starts on the precise wait (``navigator.precise_wait``: sleep, then
spin the last ``spin_ns``; about 9 % of a core at 1 ms), and the world's clock is the step's deadline on the
scheduler's grid (``hil.step_clock.StepClock``), not the time the step woke up: a real IMU samples on a
hardware timer, not on the OS's wake-up overshoot, so the simulated one is stamped and sent every 20 ms of
the grid and the rover's sensor-paced loop meets only the send's own lateness.
Everything the world publishes (ground truth, faults) goes to the peer's own
MCAP, so real-time metrics can be computed from it together with the rover's recording
(``rover logs report ROVER.mcap --truth TRUTH.mcap``, ``logs.paired_run``; ``hil.realtime_metrics``).

The world moves from one step's deadline to the next. When steps ran so late that the scheduler skipped
some (it counts them as overruns), the next deadline is several steps on and the world catches up in
sub-steps of ``PHYSICS_DT_NS``, each on its own grid time, so the simulated rover keeps to real time even
when the machine is busy. A gap of more than ``MAX_SUBSTEPS`` steps is a stall: the time beyond them is
dropped, counted (``hil.peer_stalls``) and recorded on ``log``.

The scenario (its faults and moving obstacles) starts with the peer, or, with ``start_on_command``, is
held until the rover's wheel commands reach the simulated controllers (``hil.peer_start``), so
its times count from the rover's start however long ``rover run`` took to come up.
"""

from __future__ import annotations

import json
import logging
import os
import secrets
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import can

from firmware_bridge.can_bus import CanConfig, open_bus
from firmware_bridge.errors import BridgeSetupError
from firmware_bridge.mavlink_transport import Transport, UdpTransport, open_transport
from firmware_bridge.vesc import VescCodec
from hil.peer_files import write_peer_files
from hil.peer_stalls import PeerStalls, stall_message
from hil.peer_start import ON_FIRST_COMMAND, ON_PEER_START, ScenarioStart
from hil.scenario import MAVLINK_PERCEPTION, Scenario, with_perception
from hil.step_clock import StepClock
from hil.world import SimWorld
from logs import topics
from logs.clock import NS_PER_S, Clock, seconds
from logs.recorder import McapRecorder
from logs.run_modes import PEER_MODE
from navigator.config import RoverConfig
from navigator.precise_wait import DEFAULT_SPIN_NS
from navigator.runtime import FixedRateScheduler, TimingStats, freeze_start_up_heap

_log = logging.getLogger(__name__)

PHYSICS_DT_NS = 10_000_000  # 100 Hz rover body, as in lockstep
# A tick later than this many physics steps is not caught up in full (the world would jump); the time
# beyond them is dropped, and counted as a stall (``hil.peer_stalls``).
MAX_SUBSTEPS = 5
STATUS_PERIOD_NS = 50_000_000  # the status file is rewritten at 20 Hz
TRUTH_MCAP = "truth.mcap"  # the ground truth, in the peer's --out


@dataclass(frozen=True)
class PeerResult:
    mcap_path: Path
    timing: TimingStats
    simulated_s: float
    vesc_timeouts: int
    commands_applied: int
    stalls: PeerStalls
    start: ScenarioStart  # how and when the scenario started (never, if the rover did not command)
    bus_off: dict[str, int] | None = None  # the bus-off announcer's counts; None without a can/off fault

    def describe_bus_off(self) -> str:
        if self.bus_off is None:
            return "no bus-off fault"
        counts = self.bus_off
        return (
            f"bus-off error frames sent {counts['error_frames_sent']} ({counts['repeats']} repeats), "
            f"{counts['send_errors']} failed"
        )


class RealtimePeer:
    """One ``SimWorld`` stepped in real time; ``tick(due_ns)`` is the scheduler's callback.

    The world's clock is ``clock``, a ``StepClock`` this peer sets to each physics step's due time on the
    scheduler's grid, never to when the step woke up: the simulated controllers and sensors run on the
    grid as hardware on its own timer does, and each IMU sample is stamped (``time_boot_ms``) and sent on
    its 20 ms. ``status_path`` (optional) is rewritten atomically every ``STATUS_PERIOD_NS`` with the
    body's pose and speed and the wheels' speeds and command timeouts, so a test or an operator can watch
    the simulated rover without opening the MCAP that is still being written.

    ``start`` (default: the scenario started with the peer): if it is held, the peer holds the world
    (``SimWorld.hold``) and starts it once the rover commands (``_start_on_command``); if the wait runs out
    first, it sets ``stop`` (required then: the scheduler's).
    """

    def __init__(
        self,
        world: SimWorld,
        clock: StepClock,
        recorder: McapRecorder,
        status_path: Path | None,
        *,
        start: ScenarioStart | None = None,
        stop: threading.Event | None = None,
    ) -> None:
        self.world = world
        self._clock = clock
        self._recorder = recorder
        self._status_path = status_path
        self.start = start or ScenarioStart(ON_PEER_START, clock.now_ns())
        if self.start.held:
            if stop is None:
                raise ValueError(
                    "a peer holding its scenario needs the scheduler's stop: its wait can run out"
                )
            world.hold()
        self._stop = stop or threading.Event()
        # The wheel commands the controllers had applied at the last step, and the step that first found
        # new ones since the rover began (None: none yet).
        self._commands_seen = 0
        self._first_round_ns: int | None = None
        self._last_ns: int | None = None  # the previous step's due time; None before the first step
        self._next_status_ns = clock.now_ns()
        self._timeouts_seen = 0
        self.simulated_ns = 0
        self.stalls = PeerStalls(MAX_SUBSTEPS * PHYSICS_DT_NS)

    def tick(self, due_ns: int) -> None:
        """Move the world on to ``due_ns`` (the scheduler's deadline for this step, on its grid).

        Normally that is one physics step; after the scheduler skipped late ticks it is several, each
        stamped with its own grid time so the sensors keep their cadence. The first step is one physics
        step: what came before it (start-up) is not a stall.
        """
        gap = PHYSICS_DT_NS if self._last_ns is None else due_ns - self._last_ns
        if gap <= 0:
            return  # the same deadline twice: nothing to integrate (the scheduler never does this)
        elapsed = self.stalls.note(gap)
        if elapsed < gap:
            self._log(due_ns, stall_message(gap, gap - elapsed))
        self._last_ns = due_ns
        steps = max(1, -(-elapsed // PHYSICS_DT_NS))
        dt_s = seconds(elapsed) / steps
        for index in range(steps):
            # The sub-steps end at the deadline; time dropped in a stall is before them.
            self._clock.t = due_ns - (steps - 1 - index) * elapsed // steps
            self.world.tick(dt_s)
        self.simulated_ns += elapsed
        if self.start.held:
            self._start_on_command(due_ns)
        self._note_timeouts(due_ns)
        if self._status_path is not None and due_ns >= self._next_status_ns:
            self._next_status_ns = due_ns + STATUS_PERIOD_NS
            self.write_status()

    def _start_on_command(self, now: int) -> None:
        """Start the held scenario once the rover commands its wheels; give up and stop the peer if the
        wait ran out.

        The rover sends a round of wheel commands every control tick from its first (zeros while it is not
        ready; ``SimVescBank`` counts those applied). The scenario starts on a round that follows another
        within the controllers' command timeout, with its time zero at the first of them: a lone round,
        such as the zeros a link sends as it closes (a ``rover run`` that stopped in its warm-up), starts
        nothing."""
        vescs = self.world.vescs
        applied = vescs.commands_applied
        if applied > self._commands_seen:
            self._commands_seen = applied
            first = self._first_round_ns
            if first is None or now - first > vescs.command_timeout_ns:
                self._first_round_ns = now  # the first round, or one long after a lone round
            else:
                self.world.start_at(first)
                words = self.start.start(first)
                self.world.record_start(self._recorder, **self.start.record())
                self._log(now, words, topics.LOG_INFO)
                _log.info("HIL peer: %s", words)
                return
        gave_up = self.start.expired(now)
        if gave_up is not None:
            self._log(now, gave_up, topics.LOG_ERROR)
            _log.error("HIL peer: %s", gave_up)
            self._stop.set()

    def _note_timeouts(self, now: int) -> None:
        """Record each command timeout: the evidence that the controllers stopped a silent rover's wheels."""
        timeouts = self.world.vescs.timeouts
        if timeouts > self._timeouts_seen:
            self._log(now, f"VESC command timeout: {timeouts - self._timeouts_seen} wheel(s) stopped")
            self._timeouts_seen = timeouts

    def _log(self, now: int, message: str, level: int = topics.LOG_WARNING) -> None:
        self._recorder.publish(topics.LOG, now, topics.log_message(now, level, "hil.peer", message))

    def write_status(self) -> None:
        assert self._status_path is not None
        body = self.world.body
        status = {
            "t_ns": self._clock.now_ns(),
            "x_m": body.x,
            "y_m": body.y,
            "yaw_rad": body.yaw,
            "speed_mps": body.speed,
            "wheel_speeds_mps": self.world.vescs.wheel_speeds_mps(),
            "targets_erpm": self.world.vescs.targets_erpm(),
            "vesc_timeouts": self.world.vescs.timeouts,
            "commands_applied": self.world.vescs.commands_applied,
            "rolled_over": self.world.rolled_over,
            **self.start.status(self._clock.now_ns()),
            **self.stalls.summary(),
        }
        announcer = self.world.bus_off_announcer
        if announcer is not None:
            status["bus_off"] = announcer.summary()
        _write_atomically(self._status_path, json.dumps(status))


def open_peer_wires(can_config: CanConfig, mavlink_connection: str) -> tuple[can.BusABC, UdpTransport]:
    """The peer's ends of the wires: the configured CAN bus and a loopback ``udpin`` MAVLink port.

    The rover dials the peer (``udpout``), so the peer must listen; port 0 lets the OS pick a free one.
    python-can's ``virtual`` bus (the built-in config's) is refused: it reaches only this process, so
    ``rover run`` in another one would hear no motor controller, and nothing would say why.
    """
    if can_config.interface == "virtual":
        raise BridgeSetupError(
            f"HIL peer CAN bus virtual:{can_config.channel}: python-can's virtual bus reaches only this "
            "process, so `rover run` in another one would hear no motor controller; give "
            "--can-interface udp_multicast --can-channel 239.X.Y.Z (run both under scripts/in-private-netns) "
            "or --can-interface socketcan --can-channel vcan0 (scripts/setup-vcan.sh), or a --config whose "
            "[can] names one"
        )
    if not mavlink_connection.startswith("udpin:"):
        raise BridgeSetupError(
            f"HIL peer MAVLink {mavlink_connection!r}: the peer listens, use udpin:127.0.0.1:PORT (0: any)"
        )
    transport = open_transport(mavlink_connection)
    assert isinstance(transport, UdpTransport)
    try:
        bus = open_bus(can_config)
    except BridgeSetupError:
        transport.close()
        raise
    return bus, transport


def run_peer(
    scenario: Scenario,
    config: RoverConfig,
    out_dir: Path,
    *,
    clock: Clock,
    can_bus: can.BusABC,
    mavlink: Transport,
    mavlink_port: int,
    wait: Callable[[float], None],
    stop: threading.Event,
    seed: int | None = None,
    duration_ns: int | None = None,
    status_path: Path | None = None,
    port_file: Path | None = None,
    on_ready: Callable[[Path], None] | None = None,
    spin_ns: int = DEFAULT_SPIN_NS,
    start_on_command: bool = False,
    start_timeout_ns: int | None = None,
    mavlink_host: str = "127.0.0.1",
) -> PeerResult:
    """Run the simulated rover in real time on opened wires until ``stop`` or ``duration_ns``.

    Writes ``truth.mcap`` and the rover-side files (``hil.peer_files``) into ``out_dir``; the port file
    last, so whoever waits on it finds the rest in place. ``on_ready`` gets the generated rover config.
    ``spin_ns``: each step's last stretch is spun, not slept (0: plain sleep; needs a real clock).
    ``start_on_command``: hold the scenario until the rover commands its wheels, time zero at its first
    command (``hil.peer_start``), for at most ``start_timeout_ns`` (None: no limit) from the peer being
    ready (after its warm-up), then stop.
    ``duration_ns`` counts from the peer's start either way.
    ``mavlink_host`` and ``mavlink_port``: where ``mavlink`` listens, written into the rover's config.
    The wires are the caller's; they are not closed here.
    """
    seed = scenario.seed if seed is None else seed
    out_dir.mkdir(parents=True, exist_ok=True)
    mcap_path = out_dir / TRUTH_MCAP
    with McapRecorder(mcap_path, exclusive=True) as recorder:
        # Names this run in truth.mcap and in the rover config it writes, so the rover's recording names it
        # too: a report pairs each rover recording with its own truth even when runs overlap in time.
        peer_run = secrets.token_hex(8)
        start_on = ON_FIRST_COMMAND if start_on_command else ON_PEER_START
        # The rover in the other process perceives only what the wires carry: the simulated lidar's scans
        # (or the scenario's rangefinders' readings).
        scenario = seen_through_lidar(scenario)
        write_peer_header(recorder, scenario, config, seed, peer_run, start_on)
        codec = VescCodec.for_profile(config.vesc)
        step_clock = StepClock(clock.now_ns())
        with SimWorld(scenario, config.vehicle, codec, step_clock, can_bus, mavlink, recorder, seed) as world:
            world.announce_bus_off(can_bus)  # the rover's controller is in another process: tell it
            if not start_on_command:
                world.record_start(recorder)  # its obstacles and faults count from here, not from the boot
            world.body.warm_up()  # before the port file: whoever waits on it meets a peer that runs on time
            # A held scenario's wait counts from here, the peer ready (its warm-up may have taken seconds;
            # the rover cannot start before the port file below anyway). Recorded when it starts.
            start = (
                ScenarioStart(ON_FIRST_COMMAND, clock.now_ns(), start_timeout_ns)
                if start_on_command
                else ScenarioStart(ON_PEER_START, world.epoch_ns)
            )
            peer = RealtimePeer(world, step_clock, recorder, status_path, start=start, stop=stop)
            if status_path is not None:
                peer.write_status()
            rover_config = write_peer_files(out_dir, scenario, config, mavlink_port, peer_run, mavlink_host)
            if port_file is not None:
                _write_atomically(port_file, f"{mavlink_port}\n")
            if on_ready is not None:
                on_ready(rover_config)
            rate_hz = NS_PER_S / PHYSICS_DT_NS
            scheduler = FixedRateScheduler(
                clock, rate_hz, lambda: peer.tick(scheduler.due_ns), wait=wait, stop=stop, spin_ns=spin_ns
            )
            _log.info("HIL peer for %s running in real time at %.0f Hz", scenario.name, rate_hz)
            freeze_start_up_heap()  # a full collection would hold up the IMU's send by tens of ms
            timing = scheduler.run(duration_ns)
            if status_path is not None:
                peer.write_status()
            announcer = world.bus_off_announcer
            bus_off = None if announcer is None else announcer.summary()
            runtime = {
                "timing_json": json.dumps(timing.summary()),
                "stalls_json": json.dumps(peer.stalls.summary()),
                "start_json": json.dumps(start.status(step_clock.now_ns())),
            }
            if bus_off is not None:
                runtime["bus_off_json"] = json.dumps(bus_off)
            recorder.add_metadata("runtime", runtime)
    return PeerResult(
        mcap_path,
        timing,
        seconds(peer.simulated_ns),
        world.vescs.timeouts,
        world.vescs.commands_applied,
        peer.stalls,
        start,
        bus_off,
    )


def seen_through_lidar(scenario: Scenario) -> Scenario:
    """``scenario`` with the rover perceiving through what MAVLink carries: its rangefinders when it asks
    for them (``[sensors] perception = "rangefinders"``, DISTANCE_SENSOR), else the simulated lidar
    (``"scan"``, OBSTACLE_DISTANCE). ``rover run`` gets no obstacle objects, so a hidden or moving obstacle
    is seen as on the rover, through its own scan tracker."""
    if scenario.sensors.perception in MAVLINK_PERCEPTION:
        return scenario
    return with_perception(scenario, "scan")


def write_peer_header(
    recorder: McapRecorder, scenario: Scenario, config: RoverConfig, seed: int, peer_run: str, start_on: str
) -> None:
    """The lockstep trial's scenario metadata (the metrics need it), and this run's mode and what starts
    its scenario (``hil.peer_start``)."""
    # hil.trial writes the same scenario record; it keeps its writer private, so reuse it through the
    # module and then say which kind of run this is (the later "trial" record wins for readers).
    from hil import trial

    trial.write_header(recorder, scenario, config, seed, mode=PEER_MODE)
    recorder.add_metadata(
        "peer",
        {
            "mode": PEER_MODE,
            "physics_dt_ns": str(PHYSICS_DT_NS),
            "run": peer_run,
            "start": start_on,  # what starts the scenario (hil.peer_start)
        },
    )


def _write_atomically(path: Path, text: str) -> None:
    """Write then rename, so a reader polling the file never sees half of it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    temporary.write_text(text, encoding="utf-8")
    os.replace(temporary, path)
