"""The safety supervisor: explicit modes, one failsafe per hazard, every transition reported with its cause.

It is pure: each control tick the onboard stack hands it what the links and the estimator say
(``SafetyInputs``) and whether guidance wants to drive; it answers with the mode and how much of the
guidance command may reach the wheels (``SafetyDecision.speed_scale``: 0 stops them). Time comes in the
inputs, so lockstep tests hit every threshold to the tick. Failsafes, thresholds, actions and how each one
clears are listed in docs/safety.md; the names below are the ``kind`` suffixes on ``safety/events``
(``failsafe.<name>`` when one fires, ``cleared.<name>`` when it clears, ``mode`` for mode changes).

A timed failsafe fires when the measured age or duration is strictly greater than its threshold, so with
a 20 ms tick it fires on the first tick past the threshold and not on the one before it.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Callable, Sequence
from typing import NamedTuple, cast

from firmware_bridge.wheel_names import wheel_label, wheel_labels
from logs.clock import NS_PER_S, to_ns
from navigator.fence_shape import inside_polygon
from navigator.progress_check import WHEELS_TURNING_MPS, ProgressCheck, mean_wheel_speed
from navigator.safety_config import SafetyConfig
from navigator.vehicle import VehicleParams, stability_margins

EventSink = Callable[[str, str, str], None]  # (kind, severity, detail)

# Failsafes whose action is HOLD (zero wheel commands until they clear).
LOOP_STALL = "loop_stall"
WHEEL_SILENT = "wheel_silent"
CAN_BUS_OFF = "can_bus_off"
ESTIMATOR_UNHEALTHY = "estimator_unhealthy"
GPS_LOST = "gps_lost"
HEARTBEAT_LOST = "heartbeat_lost"
ATTITUDE_LOST = "attitude_lost"  # no AHRS attitude the tip-over check can use
GROUND_LINK_LOST = "ground_link_lost"
_NO_ATTITUDE = "no AHRS attitude with a finite roll and pitch"
# Never any: most likely the autopilot does not stream ATTITUDE (the stack does not ask for it). Say where
# that is set on the autopilot rovers run most.
_NEVER_ATTITUDE = (
    "no AHRS attitude with a finite roll and pitch since the start (does the autopilot stream ATTITUDE? "
    "ArduPilot: SRn_EXTRA1, in Hz)"
)
STUCK = "stuck"
NO_PROGRESS = "no_progress"  # pushed, but the estimated position goes nowhere (navigator.progress_check)
# Unpushed for longer than this, the progress window starts again; shorter, it only pauses.
PROGRESS_PAUSE_NS = 2_000_000_000
WHEEL_STALLED = "wheel_stalled"
# A wheel that stalls this many times within the window is seized, not snagged: held until an operator acts.
WHEEL_STALL_LATCH_TRIPS = 3
WHEEL_STALL_LATCH_WINDOW_NS = 30_000_000_000
TIP_OVER = "tip_over"
GEOFENCE = "geofence"
BATTERY_CRITICAL = "battery_critical"
# Failsafes with other actions.
BATTERY_LOW = "battery_low"  # speed limited
ESTOP = "estop"  # latched ESTOP mode
# Why a self-clearing failsafe cleared.
_GONE = "condition gone"
# A pack reading below this is "no reading yet" (STATUS_5 not received), not a flat battery.
_NO_VOLTAGE_V = 1.0
# Wheel status times once None (never heard) is known not to be among them.
_Heard = tuple[int, ...]


class SafetyMode(enum.StrEnum):
    IDLE = "IDLE"  # nothing to do (no goal, arrived, or not yet ready): wheels at zero
    DRIVING = "DRIVING"  # guidance commands reach the wheels (possibly speed-limited)
    HOLD = "HOLD"  # a failsafe is active: wheels at zero until it clears
    ESTOP = "ESTOP"  # emergency stop: wheels at zero until an explicit resume


# A NamedTuple, immutable like a frozen dataclass but cheaper to build (once per control tick, twenty
# fields: the dataclass's __init__, an object.__setattr__ per field, was about half of building them).
class SafetyInputs(NamedTuple):
    """What the supervisor judges, all measured at ``now_ns`` (clock ns). ``None`` means never seen.
    ``inputs._replace(field=value)`` gives a copy with fields changed."""

    now_ns: int
    tick_gap_ns: int | None  # since the previous control tick
    wheel_last_status_ns: tuple[int | None, ...]
    can_bus_off: bool  # the CAN link says it cannot transmit
    can_send_failing_since_ns: int | None  # first tick of the current run of failed wheel-command sends
    estimator_healthy: bool
    last_gps_ns: int | None  # last GPS fix with a 3D fix or better
    last_heartbeat_ns: int | None  # last autopilot HEARTBEAT
    last_ground_contact_ns: int | None  # last sign of life from the ground station
    sent_speed_mps: float  # body speed commanded on the previous tick
    sent_at_ns: int  # when that command was sent
    measured_speed_mps: float | None  # estimated body speed
    roll_pitch_rad: tuple[float, float] | None  # from the autopilot's AHRS
    last_attitude_ns: int | None  # when that roll and pitch arrived: the last with both finite
    lateral_accel_mps2: float
    position_xy: tuple[float, float] | None  # estimated, local ENU
    battery_v: float | None  # pack voltage as the motor controllers see it
    # Per wheel, in wheel order (empty: not judged): the speed commanded on the previous tick, and the
    # speed and motor current the controller last reported.
    wheel_commands_mps: tuple[float, ...] = ()
    wheel_speeds_mps: tuple[float, ...] = ()
    wheel_currents_a: tuple[float, ...] = ()


# A NamedTuple, immutable like a frozen dataclass but cheaper to build (once per control tick: the
# dataclass's __init__, an object.__setattr__ per field, was a measurable share of the tick).
class SafetyDecision(NamedTuple):
    mode: SafetyMode
    speed_scale: float  # multiply guidance's speed and yaw rate by this; 0 stops the wheels
    faults: tuple[str, ...]  # active failsafes, sorted


class SafetySupervisor:
    """Turns inputs into a mode; reports every failsafe firing or clearing and every mode change."""

    def __init__(
        self,
        config: SafetyConfig,
        vehicle: VehicleParams,
        start_ns: int,
        emit: EventSink,
        *,
        controller_ids: Sequence[int] = (),
    ) -> None:
        """``controller_ids``: the wheels' CAN ids in wheel order (``[vesc]``), to name a wheel the way the
        CAN link does (``firmware_bridge.wheel_names``); without them a wheel is named by index and place."""
        self._config = config
        self._controller_ids = tuple(controller_ids)
        self._vehicle = vehicle
        self._start_ns = start_ns
        self._emit = emit
        self._active: dict[str, str] = {}  # failsafe -> detail when it fired
        self._since: dict[str, int] = {}  # condition -> first tick it was seen (for sustained conditions)
        self.mode = SafetyMode.IDLE
        c = config
        self._stall_ns = to_ns(c.loop_stall_s)
        self._silent_ns = to_ns(c.wheel_silent_s)
        self._can_fail_ns = to_ns(c.can_fail_s)
        self._unhealthy_ns = to_ns(c.estimator_unhealthy_s)
        self._gps_ns = to_ns(c.gps_budget_s)
        self._heartbeat_ns = to_ns(c.heartbeat_timeout_s)
        self._attitude_ns = to_ns(c.attitude_timeout_s)
        self._ground_ns = to_ns(c.ground_link_timeout_s)
        self._stuck_ns = to_ns(c.stuck_time_s)
        self._progress = ProgressCheck(to_ns(c.progress_time_s)) if c.progress_time_s > 0.0 else None
        self._unpushed_since_ns: int | None = None  # the first tick of the current run of unpushed ones
        # New goals and resumes so far: what is learned per goal (navigator.climb_learning) counts from one.
        self.goals_given = 0
        self._wheel_stall_ns = to_ns(c.wheel_stall_s)
        self._wheel_stall_hold_ns = to_ns(c.wheel_stall_hold_s)
        self._stall_held_since: int | None = None
        self._stall_trips: list[int] = []  # when wheel_stalled tripped, within the latch window
        self._stall_latched = False
        self._stall_key_names: list[str] = []  # grown by _stall_keys
        self._stall_timing = False  # whether a wheel's stall timer may be in _since
        self._battery_ns = to_ns(c.battery_debounce_s)
        self._battery_floor_v = max(c.battery_low_v, c.battery_critical_v)  # below it a battery timer may run
        self._tip_rad = math.radians(c.tip_margin_deg)
        self._tip_clear_rad = math.radians(c.tip_margin_deg + c.tip_clear_deg)

    @property
    def faults(self) -> tuple[str, ...]:
        return tuple(sorted(self._active))

    def start(self, now_ns: int) -> None:
        """Count the silence of links never heard (GPS, heartbeat, AHRS attitude, wheels, ground station)
        from ``now_ns``: the loop's first tick. Time before it (a warm-up compiling kernels for seconds on a
        cold cache, while a peer waits for our first heartbeat) is nobody's silence and must not fail safe."""
        self._start_ns = now_ns

    # --- commands -------------------------------------------------------------------------------
    def estop(self, source: str) -> None:
        """Latch the emergency stop (from Zenoh, MAVLink or the operator)."""
        self._trip(ESTOP, "error", f"emergency stop from {source}")

    def resume(self, source: str) -> None:
        """Clear the e-stop and the latched stuck and stall checks: the operator has looked and says go."""
        for name in (ESTOP, STUCK, NO_PROGRESS, WHEEL_STALLED):
            self._clear(name, f"resume from {source}")
        self._forget_stalls()
        self._forget_progress()
        self.goals_given += 1

    def new_goal(self) -> None:
        """A new goal clears the stuck, progress and stall checks: the operator chose where to go next."""
        self._clear(STUCK, "new goal")
        self._clear(NO_PROGRESS, "new goal")
        self._clear(WHEEL_STALLED, "new goal")
        self._forget_stalls()
        self._forget_progress()
        self.goals_given += 1

    def progress_learned(self, why: str) -> None:
        """Clear ``no_progress`` once the rover has learned why it went nowhere and planned anew
        (``navigator.climb_learning``): the new route is judged from its start, as a new goal's."""
        self._clear(NO_PROGRESS, why)
        self._forget_progress()

    def progress_recovering(self, why: str) -> None:
        """Clear ``no_progress`` for a rover that backs out of where it dug in, to plan round it
        (``navigator.recovery``): the back-out and the new route are judged from their start."""
        self._clear(NO_PROGRESS, why)
        self._forget_progress()

    def fault_detail(self, name: str) -> str | None:
        """What failsafe ``name`` said when it fired, while it is active; else None."""
        return self._active.get(name)

    def _forget_progress(self) -> None:
        """A new goal or a resume judges progress from then on: the window so far was toward the old one."""
        if self._progress is not None:
            self._progress.reset()
        self._unpushed_since_ns = None

    def _forget_stalls(self) -> None:
        self._stall_trips.clear()
        self._stall_latched = False

    # --- the tick -------------------------------------------------------------------------------
    def update(
        self, inputs: SafetyInputs, wants_to_drive: bool, idle_cause: str = "nothing to drive to"
    ) -> SafetyDecision:
        """Judge one tick. ``idle_cause`` says why guidance does not want to drive (its mode and reason,
        e.g. "guidance BLOCKED: moving obstacle cart-a on the path"); it is the cause a change to IDLE
        reports, so ``safety/events`` and ``navigator/state`` tell the same story."""
        self._check_loop(inputs)
        self._check_links(inputs)
        self._check_estimate(inputs, wants_to_drive)
        self._check_motion(inputs)
        self._check_wheels_turn(inputs)
        self._check_battery(inputs)
        return self._decide(wants_to_drive, idle_cause)

    def _check_loop(self, i: SafetyInputs) -> None:
        gap = i.tick_gap_ns
        # Judged per tick: the tick after a stall runs with zero commands, the next on-time tick clears it.
        stalled = gap is not None and gap > self._stall_ns
        # Details are written only when a failsafe holds: formatting them on every tick was a share of it.
        # A self-clearing failsafe is active exactly while its condition holds: tripped with its detail
        # when it does, cleared (if active) when it does not. Written out at each check, not through a
        # shared helper: they run on every tick, nearly always with nothing to do, and the call was a share.
        if stalled:
            self._trip(
                LOOP_STALL,
                "error",
                _over(f"control tick {_ms(gap or 0)} after the previous one", self._stall_ns),
            )
        elif LOOP_STALL in self._active:
            self._clear(LOOP_STALL, _GONE)

    def _check_links(self, i: SafetyInputs) -> None:
        now, start, limit = i.now_ns, self._start_ns, self._silent_ns
        statuses = i.wheel_last_status_ns
        # cast: the min is taken only once None is known not to be among them.
        if not statuses or (None not in statuses and now - min(cast(_Heard, statuses)) <= limit):
            # The common tick: every wheel heard, the oldest within the limit, so none is silent (the
            # oldest status in C, not a comprehension over the wheels).
            silent = []
        else:
            # Each wheel's age; a controller never heard counts from the supervisor's start (``start``).
            silent = [index for index, t in enumerate(statuses) if now - (start if t is None else t) > limit]
        if silent:
            self._trip(
                WHEEL_SILENT,
                "error",
                f"motor controller of {wheel_labels(silent, self._controller_ids)} silent for more than "
                f"{_ms(self._silent_ns)}",
            )
        elif WHEEL_SILENT in self._active:
            self._clear(WHEEL_SILENT, _GONE)
        failing = 0 if i.can_send_failing_since_ns is None else i.now_ns - i.can_send_failing_since_ns
        if i.can_bus_off:
            self._trip(CAN_BUS_OFF, "error", "the CAN link reports bus-off")
        elif failing > self._can_fail_ns:
            self._trip(
                CAN_BUS_OFF, "error", _over(f"CAN sends failing for {_ms(failing)}", self._can_fail_ns)
            )
        elif CAN_BUS_OFF in self._active:
            self._clear(CAN_BUS_OFF, _GONE)
        self._timeout(
            HEARTBEAT_LOST, "no autopilot heartbeat", i.now_ns, i.last_heartbeat_ns, self._heartbeat_ns
        )
        self._timeout(
            GROUND_LINK_LOST,
            "no word from the ground station",
            i.now_ns,
            i.last_ground_contact_ns,
            self._ground_ns,
        )

    def _check_estimate(self, i: SafetyInputs, wants_to_drive: bool) -> None:
        self._timeout(GPS_LOST, "no 3D GPS fix", i.now_ns, i.last_gps_ns, self._gps_ns)
        if i.estimator_healthy:  # (_sustained's case for a condition gone, written out)
            self._since.pop(ESTIMATOR_UNHEALTHY, None)
            if ESTIMATOR_UNHEALTHY in self._active:
                self._clear(ESTIMATOR_UNHEALTHY, _GONE)
            return
        unhealthy = self._sustained(ESTIMATOR_UNHEALTHY, True, i.now_ns)
        # Before driving, an unhealthy estimate is the start-up wait, not a fault.
        if ESTIMATOR_UNHEALTHY not in self._active and not wants_to_drive:
            unhealthy = 0
        if unhealthy > self._unhealthy_ns:
            self._trip(
                ESTIMATOR_UNHEALTHY,
                "error",
                f"estimate unhealthy for {_ms(unhealthy)} (limit {_ms(self._unhealthy_ns)})",
            )

    def _check_motion(self, i: SafetyInputs) -> None:
        c = self._config
        not_moving = i.measured_speed_mps is None or abs(i.measured_speed_mps) < c.stuck_max_speed_mps
        pushing = abs(i.sent_speed_mps) >= c.stuck_min_command_mps and not_moving
        # Counted from when the command went out, not from the tick that first sees it had no effect.
        pushed = self._sustained(STUCK, pushing, i.now_ns, start_ns=i.sent_at_ns)
        if self._stuck_ns > 0 and pushed > self._stuck_ns:
            # Latched (like ArduPilot's crash check): cleared by a new goal or a resume, not by itself.
            self._trip(
                STUCK,
                "error",
                f"commanded {i.sent_speed_mps:.2f} m/s but moving < {c.stuck_max_speed_mps} m/s "
                f"for {_ms(pushed)}",
            )
        self._check_progress(i)
        # The tip-over check's input has an age like any link's: an AHRS gone quiet, or sending only NaN
        # or inf tilts, would leave it judging the last usable tilt forever, blind to a rover tipping now.
        # Never seen counts from the start, as for GPS and heartbeat: an autopilot that never streams
        # ATTITUDE leaves the check blind from the first tick, and the rover must not drive so.
        self._timeout(
            ATTITUDE_LOST,
            _NO_ATTITUDE if i.last_attitude_ns is not None else _NEVER_ATTITUDE,
            i.now_ns,
            i.last_attitude_ns,
            self._attitude_ns,
        )
        if i.roll_pitch_rad is not None:
            roll, pitch = i.roll_pitch_rad
            margin = min(stability_margins(self._vehicle, roll, pitch, i.lateral_accel_mps2))
            if margin < self._tip_rad:
                self._trip(
                    TIP_OVER,
                    "error",
                    f"tip-over margin {math.degrees(margin):.1f} deg < {c.tip_margin_deg} deg "
                    f"(roll {math.degrees(roll):.1f}, pitch {math.degrees(pitch):.1f} deg)",
                )
            elif margin > self._tip_clear_rad and TIP_OVER in self._active:  # (the why formatted only then)
                self._clear(TIP_OVER, f"margin back to {math.degrees(margin):.1f} deg")
        if c.fence and i.position_xy is not None:
            x, y = i.position_xy
            if not inside_polygon(x, y, c.fence):
                self._trip(GEOFENCE, "error", f"position ({x:.2f}, {y:.2f}) is outside the geofence")
            elif GEOFENCE in self._active:
                self._clear(GEOFENCE, f"back inside the geofence at ({x:.2f}, {y:.2f})")

    def _check_wheels_turn(self, i: SafetyInputs) -> None:
        """A wheel commanded to turn that does not, while its motor draws current, is stalled (seized
        gearbox, jammed stone): held at zero so the motor does not burn at its current limit. A wheel
        drawing no current is not being driven (commands lost: ``stuck``; controller silent:
        ``wheel_silent``), so it is not judged here."""
        if self._wheel_stall_ns <= 0:
            return
        c = self._config
        if WHEEL_STALLED in self._active:
            # Zero commands while held, so the condition is gone: the hold lasts its time, then the wheels
            # are tried again (a wheel still seized fires again one stall time later), unless it has
            # stalled WHEEL_STALL_LATCH_TRIPS times in the window: then it is latched like ``stuck`` (the
            # retries' zero commands also keep resetting the stuck timer, so stuck alone never fires).
            held = i.now_ns - (self._stall_held_since or i.now_ns)
            if held > self._wheel_stall_hold_ns and not self._stall_latched:
                self._clear(WHEEL_STALLED, f"held {_ms(held)}: trying the wheels again")
            return
        min_command, max_speed = c.wheel_stall_min_command_mps, c.wheel_stall_max_speed_mps
        min_current = c.wheel_stall_min_current_a
        commands, speeds = i.wheel_commands_mps, i.wheel_speeds_mps
        # The common ticks, judged in C over the wheels: no wheel commanded enough to judge (stopped), or
        # every wheel turning fast enough (driving). Either way no wheel can be stalling; anything else
        # (a NaN first included: min and max then return it and the test fails) is judged wheel by wheel.
        none_commanded = not commands or max(map(abs, commands)) < min_command
        all_turning = not speeds or min(map(abs, speeds)) >= max_speed
        if none_commanded or all_turning:
            stalling = []
        else:
            judged = zip(commands, speeds, i.wheel_currents_a, strict=False)
            stalling = [
                abs(command) >= min_command and abs(speed) < max_speed and abs(current) >= min_current
                for command, speed, current in judged
            ]
        if not any(stalling):
            # The common tick: no wheel stalling. Its timers are dropped (as _sustained drops a condition
            # gone) only when one may be running, not with a dict pop per wheel on every tick.
            if self._stall_timing:
                for key in self._stall_key_names:
                    self._since.pop(key, None)
                self._stall_timing = False
            return
        self._stall_timing = True
        keys = self._stall_keys(len(i.wheel_commands_mps))
        for index, stalled in enumerate(stalling):
            key = keys[index]
            if not stalled:
                self._since.pop(key, None)  # as _sustained does for a condition gone
                continue
            command, speed, current = (
                i.wheel_commands_mps[index], i.wheel_speeds_mps[index], i.wheel_currents_a[index]
            )  # fmt: skip
            # Counted from when the command went out, as for ``stuck``.
            held = self._sustained(key, True, i.now_ns, start_ns=i.sent_at_ns)
            if held > self._wheel_stall_ns:
                window_start = i.now_ns - WHEEL_STALL_LATCH_WINDOW_NS
                self._stall_trips = [t for t in self._stall_trips if t > window_start] + [i.now_ns]
                self._stall_latched = len(self._stall_trips) >= WHEEL_STALL_LATCH_TRIPS
                latched = (
                    f"; stall {len(self._stall_trips)} in {_ms(WHEEL_STALL_LATCH_WINDOW_NS)}: latched "
                    "until a new goal or resume"
                    if self._stall_latched
                    else ""
                )
                self._trip(
                    WHEEL_STALLED,
                    "error",
                    f"{wheel_label(index, self._controller_ids)} commanded {command:.2f} m/s but turning "
                    f"at {speed:.2f} m/s "
                    f"while drawing {current:.1f} A for {_ms(held)} (limit {_ms(self._wheel_stall_ns)})"
                    + latched,
                )
                self._stall_held_since = i.now_ns
                for other in keys:
                    self._since.pop(other, None)
                return

    def _check_battery(self, i: SafetyInputs) -> None:
        c = self._config
        v = i.battery_v if i.battery_v is not None and i.battery_v > _NO_VOLTAGE_V else None
        active = self._active
        if v is None or (
            v >= self._battery_floor_v and BATTERY_LOW not in active and BATTERY_CRITICAL not in active
        ):
            # Nearly every tick: no reading, or a pack above both thresholds with neither failsafe active to
            # clear. All the loop below would do is drop the two low-voltage timers (a condition gone).
            self._since.pop(BATTERY_CRITICAL, None)
            self._since.pop(BATTERY_LOW, None)
            return
        for name, threshold, severity in (
            (BATTERY_CRITICAL, c.battery_critical_v, "error"),
            (BATTERY_LOW, c.battery_low_v, "warning"),
        ):
            low_for = self._sustained(name, v < threshold, i.now_ns)  # v is a reading here (returned above)
            if low_for > self._battery_ns:
                self._trip(name, severity, f"battery {v:.2f} V below {threshold} V for {_ms(low_for)}")
            elif v > threshold + c.battery_clear_v and name in self._active:
                self._clear(name, f"battery back to {v:.2f} V")

    def _decide(self, wants_to_drive: bool, idle_cause: str) -> SafetyDecision:
        active = self._active  # empty on almost every tick: no sorting then
        holds = sorted(name for name in active if name not in (ESTOP, BATTERY_LOW)) if active else []
        if ESTOP in self._active:
            mode, cause = SafetyMode.ESTOP, self._active[ESTOP]
        elif holds:
            mode, cause = SafetyMode.HOLD, ", ".join(holds)
        elif wants_to_drive:
            mode, cause = SafetyMode.DRIVING, "guidance has a path and no failsafe is active"
        else:
            mode, cause = SafetyMode.IDLE, idle_cause
        if mode is not self.mode:
            severity = "info" if mode in (SafetyMode.IDLE, SafetyMode.DRIVING) else "error"
            self._emit("mode", severity, f"{self.mode.value} -> {mode.value}: {cause}")
            self.mode = mode
        scale = 0.0
        if mode is SafetyMode.DRIVING:
            scale = self._config.battery_low_speed_scale if BATTERY_LOW in self._active else 1.0
        return SafetyDecision(mode, scale, self.faults if active else ())

    # --- helpers --------------------------------------------------------------------------------
    def _stall_keys(self, wheels: int) -> list[str]:
        """The keys of ``wheel_stalled``'s per-wheel sustained conditions, named once per wheel."""
        keys = self._stall_key_names
        while len(keys) < wheels:
            keys.append(f"{WHEEL_STALLED}#{len(keys)}")
        return keys[:wheels] if len(keys) > wheels else keys

    def _check_progress(self, i: SafetyInputs) -> None:
        """``no_progress``: pushed for a whole window, the estimated position moved less than the radius.
        Latched like ``stuck`` (HOLD until a new goal or a resume): the rover digging in at the foot of a
        slope it cannot climb, its speed estimate wandering about zero, goes nowhere for minutes."""
        progress = self._progress
        if progress is None:
            return
        c = self._config
        if abs(i.sent_speed_mps) < c.stuck_min_command_mps or i.position_xy is None:
            # A short dip (a tick turning on the spot, a brief BLOCKED, a wheel's retry) pauses the window;
            # only a longer one starts it again: else a rover dug in, with a slow tick every few seconds,
            # would never be judged.
            if self._unpushed_since_ns is None:
                self._unpushed_since_ns = i.now_ns
            elif i.now_ns - self._unpushed_since_ns > PROGRESS_PAUSE_NS:
                progress.reset()
            return
        self._unpushed_since_ns = None
        moved = progress.update(i.now_ns, *i.position_xy)
        if moved is not None and moved < c.progress_radius_m:
            self._trip(
                NO_PROGRESS,
                "error",
                f"commanded {i.sent_speed_mps:.2f} m/s for {c.progress_time_s:g} s but moved {moved:.2f} m "
                f"(limit {c.progress_radius_m:g} m){_wheels_while_stuck(i.wheel_speeds_mps)}",
            )
            progress.reset()

    def _sustained(self, key: str, condition: bool, now_ns: int, start_ns: int | None = None) -> int:
        """How long ``condition`` has held (0 when it does not): from the first tick it was seen."""
        if not condition:
            self._since.pop(key, None)
            return 0
        return now_ns - self._since.setdefault(key, now_ns if start_ns is None else start_ns)

    def _timeout(self, name: str, what: str, now_ns: int, last_ns: int | None, limit_ns: int) -> None:
        if limit_ns <= 0:
            return
        age = now_ns - (self._start_ns if last_ns is None else last_ns)  # never seen: from the start
        # Self-clearing (see _check_loop).
        if age > limit_ns:
            self._trip(name, "error", _over(f"{what} for {_ms(age)}", limit_ns))
        elif name in self._active:
            self._clear(name, _GONE)

    def _trip(self, name: str, severity: str, detail: str) -> None:
        if name not in self._active:
            self._active[name] = detail
            self._emit(f"failsafe.{name}", severity, detail)

    def _clear(self, name: str, why: str) -> None:
        if self._active.pop(name, None) is not None:
            self._emit(f"cleared.{name}", "info", why)


def _wheels_while_stuck(speeds: Sequence[float]) -> str:
    """What the wheels did while the rover went nowhere, for the operator: turning (slipping or dug in:
    the ground does not carry the push) or not (held: an obstacle, a stall); "" with no wheel reports."""
    mean = mean_wheel_speed(speeds)
    if mean is None:
        return ""
    what = "slipping or dug in" if mean >= WHEELS_TURNING_MPS else "not turning"
    return f"; the wheels turn at {mean:.2f} m/s on average: {what}"


def _over(what: str, limit_ns: int) -> str:
    """A timed failsafe's detail: what was measured, and its limit."""
    return f"{what} (limit {_ms(limit_ns)})"


def _ms(t_ns: int) -> str:
    return f"{t_ns / (NS_PER_S / 1000):.0f} ms"
