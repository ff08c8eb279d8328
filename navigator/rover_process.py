"""The ``rover run`` process: start-up checks, the real-time loop, and a shutdown that stops the wheels.

Start-up: the config was validated on load; ``check_runnable`` refuses what cannot run (a lockstep-only
``memory`` MAVLink connection, no ``[map]``), then the Zenoh session and the links are opened (a failure
is a setup error that names what to check). Only then is the recording created, so a run that cannot
start leaves nothing in ``--out``; a failure after that is recorded on the ``log`` topic and the MCAP
closed readable. Before the loop, the A* kernels are compiled (or loaded from numba's cache) by a
warm-up plan and the map is published: neither lands in a tick, and however long the warm-up takes the
link budgets count from the first tick (``OnboardStack``).
Driving waits for the start-up checks in ``OnboardStack`` (autopilot heard, all six controllers heard,
estimate healthy and settled). Planning runs on a worker thread (``navigator.plan_worker``), so a long
plan never delays a tick. The loop is sensor-synchronous (``navigator.paced_loop``): a tick starts
when the pacing measurement has arrived, with a fixed-rate deadline as the fallback; it publishes
``runtime/timing`` once a second.
Just before the loop, the start-up heap is frozen out of the garbage collector's sight
(``navigator.runtime.freeze_start_up_heap``: a full collection had stopped every thread for 35-50 ms).
Shutdown (stop flag set by SIGINT/SIGTERM, or the duration over): the stack sends zero wheel commands
and closes the links, then the recording is closed with the loop's timing summary as metadata.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from firmware_bridge.dbc_attachment import attach_vesc_dbc
from logs import topics
from logs.clock import Clock
from logs.commands import RoverCommand, ZenohCommandReceiver
from logs.encoding import EncodedSink
from logs.errors import RecordingError
from logs.log_topic import recording_logs
from logs.pending_sink import PendingSink
from logs.recorder import McapRecorder
from logs.run_modes import ROVER_RUN_MODE
from logs.sink import FanoutSink, MessageSink
from logs.telemetry import ZenohTelemetry, open_session
from logs.telemetry_station import rate_limited
from logs.wall_clock import WALL_CLOCK_METADATA, take_anchor
from navigator.config import RoverConfig
from navigator.config_record import record_config, software_version
from navigator.deferred_sink import DeferredSink, deferred_sink
from navigator.errors import NavigatorError
from navigator.input_wait import input_poller, input_waiter
from navigator.links import RoverLinks, open_links
from navigator.onboard import OnboardStack
from navigator.paced_loop import SensorPacedScheduler, TickSample
from navigator.phase_locked_loop import PhaseLockedScheduler
from navigator.plan_worker import plan_worker
from navigator.precise_wait import DEFAULT_SPIN_NS
from navigator.runtime import TimingStats, freeze_start_up_heap, realtime_switch_interval
from navigator.terrain import TerrainMap
from navigator.timing_topic import TimingPublisher
from navigator.warm_up import warm_up

_log = logging.getLogger(__name__)


class RoverSetupError(NavigatorError):
    """``rover run`` cannot start as configured (no map, links that do not open)."""


@dataclass(frozen=True)
class RunResult:
    mcap_path: Path
    timing: TimingStats


# foxglove.Log level of the record that says why a run ended on an error.


def check_runnable(config: RoverConfig) -> TerrainMap:
    """The start-up checks that need nothing opened; returns the map to plan on. ``RoverSetupError``
    says what is wrong and which config to use instead."""
    if config.mavlink.connection == "memory":
        raise RoverSetupError(
            f'{config.source}: [mavlink] connection = "memory" is the in-process pipe of lockstep trials '
            "(`rover hil trial --config`), not a link to an autopilot. On the rover, start from "
            "configs/rover.example-hardware.toml; for real-time HIL, run `rover hil peer SCENARIO --out DIR` "
            "and pass the DIR/rover-hil.toml it writes"
        )
    if config.terrain is None:
        raise RoverSetupError(
            f"{config.source}: `rover run` needs a [map] table (the terrain to plan on; "
            "configs/rover.example-hardware.toml has one)"
        )
    return config.terrain


def run_rover(
    config: RoverConfig,
    clock: Clock,
    out_dir: Path,
    *,
    stop: threading.Event,
    wait: Callable[[float], None] | None = None,
    goal: tuple[float, float] | None = None,
    duration_ns: int | None = None,
    telemetry: bool = True,
    wall_ns: Callable[[], int] = time.time_ns,
    announce: Callable[[str], None] = _log.info,
) -> RunResult:
    """Run the onboard stack in real time until ``stop`` is set; returns the recording and timing.

    Nothing is created in ``out_dir`` until every start-up check has passed (the config, the Zenoh
    session, both links): a run that cannot start leaves no recording behind, and an ``out_dir`` that
    already holds a ``rover.mcap`` is refused before anything opens. A failure after that is
    recorded on the ``log`` topic, the recording closed as a readable MCAP, and the error raised.

    ``wall_ns`` is read once, as the recording opens, to date it (``logs.wall_clock``); nothing else
    reads the wall clock.

    ``wait`` idles the loop between reads (default: ``select`` on the pacing link, ``navigator.input_wait``).

    ``announce`` gets one line when the links are open and the recording made (``links_line``), one
    when the warm-up is done and the loop starts, and one per ``startup_checks`` event (what driving
    still waits for, then that it may drive): the CLI prints them, so an operator sees them whatever
    the log level.
    """
    terrain = check_runnable(config)
    mcap_path = out_dir / "rover.mcap"
    if mcap_path.exists():
        # The recorder opens its file for writing: an earlier run's recording there would be emptied.
        raise RoverSetupError(
            f"{mcap_path} already exists (an earlier run's recording; it is left as it is): "
            "give --out a new folder, or move that file away"
        )
    session = None
    publisher: ZenohTelemetry | None = None
    commands: ZenohCommandReceiver | None = None
    planning = plan_worker()
    # Everything opened from here on is closed in the finally, whatever fails on the way: a Zenoh
    # session or command receiver left open keeps the process from exiting (SIGTERM included).
    try:
        if telemetry and config.zenoh.enabled:
            session = open_session(config.zenoh)
            publisher = ZenohTelemetry(session, config.rover_id)
            commands = ZenohCommandReceiver(session, config.rover_id, clock)
        # The links record from the moment they open: into a pending sink until the recording exists.
        pending = PendingSink()
        deferred = deferred_sink(pending)
        links = open_links(config, clock, deferred)
        try:
            recorder = _open_recording(mcap_path, config, clock, wall_ns)
        except RoverSetupError:
            links.close()
            raise
        with recorder:
            try:
                sink: EncodedSink = recorder
                if publisher is not None:
                    sink = FanoutSink([recorder, rate_limited(publisher, config.zenoh.rates_hz)])
                pending.connect(sink)
                announce(links_line(config, links, mcap_path, telemetry=publisher is not None))
                # The onboard stack's warnings go on the recording's log topic too, published on the
                # loop's thread (the planning worker's are queued until the next tick).
                with recording_logs(deferred, clock) as log_lines:
                    stack = OnboardStack(
                        config,
                        clock,
                        links.can,
                        links.mavlink,
                        deferred,
                        terrain,
                        commands=commands,
                        deferred=deferred,
                        planning=planning,
                        start_up_report=announce,
                    )
                    try:
                        timing = _warm_up_and_run(
                            stack, config, clock, links, deferred, wait, goal, stop, duration_ns,
                            lambda _tick: log_lines.publish_pending(), announce,
                        )  # fmt: skip
                    finally:
                        stack.close()  # zero wheel commands, links closed
            except Exception as err:
                links.close()  # if the stack was never built; its zero wheel commands are recorded first
                _record_failure(recorder, clock, err)
                raise
            _log.info("stopped: %s", timing.describe())
            recorder.add_metadata("runtime", {"timing_json": json.dumps(timing.summary())})
    finally:
        # A plan still running is not waited for: its outcome would never be read.
        planning.shutdown(wait=False, cancel_futures=True)
        if commands is not None:
            commands.close()
        if publisher is not None:
            publisher.close()
        if session is not None:
            session.close()
    return RunResult(mcap_path, timing)


def _open_recording(
    mcap_path: Path, config: RoverConfig, clock: Clock, wall_ns: Callable[[], int]
) -> McapRecorder:
    """The run's recording, with its trial metadata and the date of its clock's zero (``wall_clock``);
    ``RoverSetupError`` if the file cannot be made."""
    try:
        recorder = McapRecorder(mcap_path, exclusive=True)
    except RecordingError as err:
        raise RoverSetupError(f"{err} (--out)") from err
    # can_bitrate: the report's bus load for frames counted from the recording (as hil.trial writes it)
    trial = {
        "mode": ROVER_RUN_MODE,
        "rover_id": config.rover_id,
        "config": config.source,
        "software_version": software_version(),
        "can_bitrate": str(config.can.bitrate),
    }
    if config.vesc.dbc_path is not None:  # a swapped-in controller DBC: which protocol the frames are in
        trial["vesc_dbc"] = str(config.vesc.dbc_path)
    if config.hil_peer_run is not None:  # the HIL peer run this rover ran against: its truth names it too
        trial["hil_peer_run"] = config.hil_peer_run
    recorder.add_metadata("trial", trial)
    # The effective config, as a lockstep trial records it: a report comparing this run with a simulated
    # one lists the parameters that differed.
    record_config(recorder, config)
    attach_vesc_dbc(recorder, config.vesc)
    # The date of log time 0 is otherwise unknown (the clock is monotonic): .asc/.trc exports need it.
    recorder.add_metadata(WALL_CLOCK_METADATA, take_anchor(clock, wall_ns).as_metadata())
    return recorder


def _warm_up_and_run(
    stack: OnboardStack,
    config: RoverConfig,
    clock: Clock,
    links: RoverLinks,
    deferred: DeferredSink,
    wait: Callable[[float], None] | None,
    goal: tuple[float, float] | None,
    stop: threading.Event,
    duration_ns: int | None,
    observe: Callable[[TickSample], None] | None = None,
    announce: Callable[[str], None] = _log.info,
) -> TimingStats:
    """Load the kernels, publish the map, set the goal, then run the loop until ``stop`` or the duration.
    ``observe`` (optional) is called after every tick, on the loop's thread."""
    warm_up_start_ns = clock.now_ns()
    warm_up(stack.guidance.planner, config, clock)
    stack.publish_map()
    if goal is not None:
        # As a command, so the recording holds it (ground/commands) and a replay gives it again.
        stack.take_command(RoverCommand("goal", clock.now_ns(), goal[0], goal[1], origin="command line"))
    scheduler = control_scheduler(
        stack,
        clock,
        config,
        deferred,
        wait or input_waiter(links.pacing_sources),
        stop,
        # A caller's own wait (a test's) is the whole wait: no busy-poll around it.
        poll=input_poller(links.pacing_sources) if wait is None else None,
        observe=observe,
    )
    warm_up_s = (clock.now_ns() - warm_up_start_ns) / 1e9
    if stop.is_set():  # SIGINT/SIGTERM during the warm-up (a cold numba cache takes tens of seconds)
        announce(f"warm-up done in {warm_up_s:.1f} s; stopping: a stop was asked during the warm-up")
    else:
        announce(
            f"warm-up done in {warm_up_s:.1f} s; rover {config.rover_id} "
            f"running at {config.control_rate_hz:.0f} Hz, {loop_phrase(config)}; driving waits for "
            "the start-up checks (next line; safety/events: startup_checks)"
        )
    freeze_start_up_heap()
    with realtime_switch_interval():
        return scheduler.run(duration_ns)


def loop_phrase(config: RoverConfig) -> str:
    """The control loop as the warm-up line names it: what starts its ticks."""
    if config.pacing_sensor == "none":  # either loop then runs on its own grid (docs/runtime.md)
        return "fixed-rate, no pacing sensor"
    if config.control_loop == "phase-locked":
        return f"phase-locked {config.phase_offset_ms:g} ms after {config.pacing_sensor}"
    return f"paced by {config.pacing_sensor}"


def links_line(config: RoverConfig, links: RoverLinks, mcap_path: Path, *, telemetry: bool) -> str:
    """What ``rover run`` opened, in one line: where it records, and what to point the peers at."""
    if telemetry:
        zenoh = f"Zenoh {config.zenoh.mode} listening on {', '.join(config.zenoh.listen) or 'nothing'}"
        if any(endpoint.endswith(":0") for endpoint in config.zenoh.listen):
            zenoh += " (port 0: the OS picks; set [zenoh] listen to a fixed port for a station to connect)"
        if config.zenoh.connect:
            zenoh += f", connecting to {', '.join(config.zenoh.connect)}"
    else:
        zenoh = "telemetry off"
    return (
        f"links open: recording {mcap_path}; CAN {config.can.interface} {config.can.channel}; "
        f"MAVLink {links.mavlink_endpoint or config.mavlink.connection}; {zenoh}"
    )


def _record_failure(recorder: McapRecorder, clock: Clock, err: Exception) -> None:
    """Put why the run failed on the ``log`` topic (the recording is closed right after)."""
    now = clock.now_ns()
    try:
        message = f"rover run failed: {type(err).__name__}: {err}"
        recorder.publish(topics.LOG, now, topics.log_message(now, topics.LOG_FATAL, __name__, message))
    except RecordingError as record_err:  # the original error is the one to raise
        _log.error("could not record why the run failed (%s): %s", err, record_err)


def control_scheduler(
    stack: OnboardStack,
    clock: Clock,
    config: RoverConfig,
    sink: MessageSink,
    wait: Callable[[float], None],
    stop: threading.Event | None = None,
    *,
    poll: Callable[[], bool] | None = None,
    observe: Callable[[TickSample], None] | None = None,
) -> SensorPacedScheduler | PhaseLockedScheduler:
    """The real-time loop ``config.control_loop`` names, around ``stack``, publishing ``runtime/timing``
    to ``sink``.

    ``poll`` (``navigator.input_wait.input_poller``) says input waits without blocking: the sensor-paced
    loop busy-polls ``config.busy_poll_ms`` around each expected sample with it, the phase-locked loop
    spins the last stretch before each tick on the clock (``navigator.precise_wait``), fusing what lands
    meanwhile; without it neither spins (a caller's own ``wait``, a test's, is then the whole wait).
    ``observe`` (optional) also gets every tick's ``TickSample`` (a diagnostic's trace).
    """
    period_ns = round(1e9 / config.control_rate_hz)
    timing = TimingPublisher(clock, sink, period_ns)
    on_tick: Callable[[TickSample], None] = timing.observe
    if observe is not None:
        on_tick = _both(timing.observe, observe)
    # What only one loop takes; everything else both take alike.
    loop: type[PhaseLockedScheduler] | type[SensorPacedScheduler]
    if config.control_loop == "phase-locked":
        loop, own = (
            PhaseLockedScheduler,
            {
                "offset_ns": round(config.phase_offset_ms * 1e6),
                "late_wait_ns": round(config.phase_late_wait_ms * 1e6),
                "spin_ns": DEFAULT_SPIN_NS if poll is not None else 0,
            },
        )
    else:
        loop, own = SensorPacedScheduler, {"busy_poll_ns": round(config.busy_poll_ms * 1e6)}
    return loop(
        clock,
        config.control_rate_hz,
        stack.step,
        ingest=stack.ingest,
        wait=wait,
        latency=lambda: stack.last_sensor_to_command_ns,
        on_tick=on_tick,
        stop=stop,
        poll=poll,
        **own,
    )


def _both(
    first: Callable[[TickSample], None], second: Callable[[TickSample], None]
) -> Callable[[TickSample], None]:
    def both(sample: TickSample) -> None:
        first(sample)
        second(sample)

    return both
