"""Six simulated VESC motor controllers: the far end of the rover's CAN bus in HIL.

Each controller obeys only frames carrying its own id, follows SET_RPM with a first-order motor response
no faster than the physics says its motor can turn at the pack's voltage, nor further than its
current-limited torque turns it against the ground (``set_electrical``), so STATUS reports the speed the
wheel turns, stops when commands stop arriving (the firmware's command timeout), and
sends STATUS / STATUS_4 / STATUS_5 on a schedule read from the clock, in wheel order, so a lockstep run is
deterministic.
"""

from __future__ import annotations

import logging
import math
import operator
from collections.abc import Sequence

import can

from firmware_bridge.can_bus import BatchBus
from firmware_bridge.errors import BridgeError, FrameError
from firmware_bridge.vesc import WHEEL_COUNT, FieldEncoder, VescCodec, VescFrame
from firmware_bridge.wheel_names import wheel_label
from hil.battery import REGEN_CURRENT_LIMIT_A
from hil.first_sample import first_sample_withheld
from hil.vesc_limits import (
    ALL_DRIVEN,
    DEFAULT_TIMEOUT_BRAKE_CURRENT_A,
    DRIVEN,
    SupplyLimits,
    WheelControls,
    check_brake_current,
)
from logs.clock import Clock, to_ns

logger = logging.getLogger(__name__)

_NONE_STALLED = (0.0,) * WHEEL_COUNT  # SimVescBank.stalled with no wheel seized
_IDLE_TEMPERATURE_C = 25.0
# STATUS_4's fields this model holds constant (FieldEncoder: converted once): an idle temperature, no
# position control.
_IDLE_STATUS_4 = {"temp_fet": _IDLE_TEMPERATURE_C, "temp_motor": _IDLE_TEMPERATURE_C, "pid_pos": 0.0}
_STATUS_CURRENT_LIMIT_A = 3000.0  # the int16 / 10 field holds +-3276.7 A
_INT32_MAX = (1 << 31) - 1
_VOLTAGE_FIELD_MAX_V = 3000.0  # int16 / 10
# What a status frame that cannot be encoded or sent raises: counted (send_errors), the rest still go.
_SEND_ERRORS = (can.CanError, BridgeError, ValueError, KeyError)
# No command for this long: the firmware releases the motor (what SimVescBank does by default).
DEFAULT_COMMAND_TIMEOUT_S = 0.5


class SimVescBank:
    """Six VESCs on ``bus``, in the wheel order of ``codec.profile.controller_ids``."""

    def __init__(
        self,
        bus: can.BusABC,
        codec: VescCodec,
        clock: Clock,
        *,
        status_rate_hz: float = 50.0,
        slow_status_rate_hz: float = 10.0,
        command_timeout_s: float = DEFAULT_COMMAND_TIMEOUT_S,
        motor_time_constant_s: float = 0.05,
        max_erpm: float = 30_000.0,
        input_voltage_v: float = 24.0,
        regen_current_limit_a: float = REGEN_CURRENT_LIMIT_A,
        timeout_brake_current_a: float = DEFAULT_TIMEOUT_BRAKE_CURRENT_A,
        supply: SupplyLimits | None = None,
    ) -> None:
        if not (math.isfinite(regen_current_limit_a) and regen_current_limit_a >= 0.0):
            raise ValueError(f"SimVescBank regen_current_limit_a must be >= 0, got {regen_current_limit_a}")
        for name, value in (
            ("status_rate_hz", status_rate_hz),
            ("slow_status_rate_hz", slow_status_rate_hz),
            ("command_timeout_s", command_timeout_s),
            ("motor_time_constant_s", motor_time_constant_s),
            ("max_erpm", max_erpm),
        ):
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"SimVescBank {name} must be a positive number, got {value}")
        self._bus = bus
        self._codec = codec
        self._clock = clock
        self.profile = codec.profile
        self._ids = codec.profile.controller_ids
        self._wheel_of = {cid: i for i, cid in enumerate(self._ids)}
        self._status_period_ns = to_ns(1.0 / status_rate_hz)
        self._slow_period_ns = to_ns(1.0 / slow_status_rate_hz)
        self._timeout_ns = to_ns(command_timeout_s)
        # What a timed-out controller brakes its released motor with (hil.vesc_limits), and its supply limits.
        self._timeout_brake_a = check_brake_current(timeout_brake_current_a)
        self._supply = supply or SupplyLimits()
        self._supply_voltage_v = input_voltage_v  # the latest from the physics (set_electrical), unclamped
        self._timed_out = [False] * WHEEL_COUNT  # past the command timeout: released until the next command
        self.under_voltage = False  # every controller in its under-voltage fault (one pack feeds them all)
        self.under_voltage_faults = 0
        # Per wheel, the speed the physics turned the wheel at (m/s): a released motor's encoder reads it.
        self._rolling_mps: Sequence[float] = (0.0,) * WHEEL_COUNT
        self._tau_s = motor_time_constant_s
        self._blend_dt_s = math.nan  # the step length _blend is for (step): none yet
        self._blend = 0.0
        self._max_erpm = max_erpm
        now = clock.now_ns()
        self._next_status_ns = now
        self._next_slow_ns = now
        self._status_sent = False  # before the first status: hil.first_sample decides what it sends
        self._targets = [0.0] * WHEEL_COUNT
        self._erpm = [0.0] * WHEEL_COUNT  # the speed each motor's speed loop drives it to
        # The speed each motor turns at, which STATUS and the tachometer measure: its loop's, unless its
        # current limit holds it (the physics' held speeds: set_electrical).
        self._measured_erpm = [0.0] * WHEEL_COUNT
        self._tacho_erev = [0.0] * WHEEL_COUNT
        self._last_command_ns: list[int | None] = [None] * WHEEL_COUNT
        self._motor_current_a = [0.0] * WHEEL_COUNT
        self._duty_cycle = [0.0] * WHEEL_COUNT  # the motors' duty from the physics (set_electrical)
        # Per wheel, the most surface speed (m/s) its motor can turn at the pack's voltage (the physics':
        # set_electrical), as given; ERPM in step.
        self._speed_limits_mps: Sequence[float] = (math.inf,) * WHEEL_COUNT
        # Per wheel, the slowest and fastest (m/s, signed) its motor's current-limited torque turns it at
        # (the physics': set_electrical), as given; none until told.
        self._held_floors_mps: Sequence[float] = (-math.inf,) * WHEEL_COUNT
        self._held_ceilings_mps: Sequence[float] = (math.inf,) * WHEEL_COUNT
        self._input_voltage_v = input_voltage_v
        self._regen_floor_a = -regen_current_limit_a  # the input current's floor while braking
        # The latest set_electrical's loads, not yet clamped into the fields above (_take_loads); None: none.
        self._loads: tuple[tuple[float, ...], float, tuple[float, ...]] | None = None
        self.commands_applied = 0
        self.timeouts = 0
        self.ignored_frames = 0  # valid traffic not for us (other ids, other kinds)
        self.bad_frames = 0  # frames we could not decode
        self.send_errors = 0
        self.reboots = 0
        self._rebooting = [False] * WHEEL_COUNT  # fault: controller silent while it restarts
        self._stuck = [False] * WHEEL_COUNT  # fault: the wheel is seized
        # Frame id -> (the reader of each controller's SET_RPM, its wheel): the commands of every control
        # tick, _take's usual case, in one lookup and without decode's dict and VescFrame per frame.
        self._set_rpm_readers = {
            frame_id: (decoder.values, self._wheel_of[decoder.controller_id])
            for frame_id, decoder in codec.field_decoders("SET_RPM", ("erpm",)).items()
        }
        # The lockstep bus takes a status period's frames, and gives everything waiting, in one call.
        self._batch_bus = bus if isinstance(bus, BatchBus) else None
        # Per wheel: the encoders of its status frames, looked up once (eighteen frames per 20 ms).
        self._status_encoders = [
            (
                codec.encoder("STATUS", cid).fields(("erpm", "current", "duty")),
                codec.encoder("STATUS_4", cid).fields(("current_in",), _IDLE_STATUS_4),
                codec.encoder("STATUS_5", cid).fields(("tacho", "voltage_in")),
            )
            for cid in self._ids
        ]
        self._status_of_wheel = [status for status, _, _ in self._status_encoders]  # STATUS, every 20 ms
        # Frame id -> message name of each status frame we send, for a send failure's log line.
        self._status_names = {
            encoder.message.frame_id: encoder.message.name
            for encoders in self._status_encoders
            for encoder in encoders
        }

    # --- commands in ---------------------------------------------------------------------------
    def poll(self) -> int:
        """Drain the bus and apply the commands addressed to our controllers; returns frames read."""
        now = self._clock.now_ns()
        if self._batch_bus is not None:  # the lockstep bus: everything waiting in one call (BatchBus)
            try:
                frames = self._batch_bus.recv_all()
            except can.CanError as err:
                logger.debug("simulated VESC bank: receive failed: %s", err)
                return 0
            readers = self._set_rpm_readers
            for msg in frames:  # _take's usual frame, a SET_RPM of ours, without the call (every tick)
                set_rpm = readers.get(msg.arbitration_id)
                if set_rpm is None or msg.is_error_frame or (values := set_rpm[0](msg)) is None:
                    self._take(msg, now)
                else:
                    self._command_erpm(set_rpm[1], values[0], now)
            return len(frames)
        return self._poll_each(now)

    def _poll_each(self, now: int) -> int:
        """``poll`` on a bus without ``recv_all``: frame by frame until none is waiting or receiving fails."""
        count = 0
        while True:
            try:
                msg = self._bus.recv(timeout=0)
            except can.CanError as err:
                logger.debug("simulated VESC bank: receive failed: %s", err)
                break
            if msg is None:
                break
            count += 1
            self._take(msg, now)
        return count

    def _take(self, msg: can.Message, now: int) -> None:
        """One received frame: a command for one of our controllers is applied, anything else counted."""
        if msg.is_error_frame:
            return
        set_rpm = self._set_rpm_readers.get(msg.arbitration_id)
        if set_rpm is not None and (values := set_rpm[0](msg)) is not None:
            self._command_erpm(set_rpm[1], values[0], now)
            return
        try:
            frame = self._codec.decode(msg)
        except FrameError as err:
            if err.reason == "unknown_id":
                self.ignored_frames += 1
            else:
                self.bad_frames += 1
                logger.debug("simulated VESC bank: rejected frame: %s", err)
            return
        self._apply(frame, now)

    def _command_erpm(self, wheel: int, erpm: float, now_ns: int) -> None:
        """A SET_RPM of ``erpm`` for ``wheel``: poll's usual frame, read without the codec's VescFrame."""
        if self._rebooting[wheel]:
            return  # a controller restarting hears nothing
        # Six per control tick: max(min())'s clamp by comparisons (a decoded ERPM is finite).
        top = self._max_erpm
        self._targets[wheel] = erpm if -top <= erpm <= top else (top if erpm > top else -top)
        self._last_command_ns[wheel] = now_ns
        self._timed_out[wheel] = False
        self.commands_applied += 1

    def _apply(self, frame: VescFrame, now_ns: int) -> None:
        wheel = self._wheel_of[frame.controller_id]
        values = frame.values
        if frame.kind == "SET_RPM":
            self._command_erpm(wheel, values["erpm"], now_ns)
            return
        if self._rebooting[wheel]:
            return  # a controller restarting hears nothing
        if frame.kind == "SET_DUTY":
            target = max(-1.0, min(1.0, values["duty"])) * self._max_erpm
        elif frame.kind == "SET_CURRENT_BRAKE" or (frame.kind == "SET_CURRENT" and values["current"] == 0.0):
            target = 0.0
        else:
            # Our own status echoed back, or current control, which this speed-only model does not have.
            self.ignored_frames += 1
            return
        self._targets[wheel] = target
        self._last_command_ns[wheel] = now_ns
        self._timed_out[wheel] = False
        self.commands_applied += 1

    # --- faults --------------------------------------------------------------------------------
    def set_rebooting(self, wheel: int, rebooting: bool) -> None:
        """While rebooting a controller is silent and its motor is released (the wheel rolls free); it comes
        back with fresh state."""
        if rebooting and not self._rebooting[wheel]:
            self.reboots += 1
            logger.info("simulated VESC of %s: rebooting", wheel_label(wheel, self._ids))
        elif not rebooting and self._rebooting[wheel]:
            # Fresh firmware state: no target, tachometer from zero, waiting for its first command; its
            # encoder reads the speed the wheel rolls at.
            self._targets[wheel] = 0.0
            self._tacho_erev[wheel] = 0.0
            self._last_command_ns[wheel] = None
            self._timed_out[wheel] = False
        self._rebooting[wheel] = rebooting
        if rebooting:
            self._targets[wheel] = 0.0

    def set_stuck(self, wheel: int, stuck: bool) -> None:
        """A seized wheel does not turn, whatever it is commanded (its motor stalls: ``stalled``)."""
        self._stuck[wheel] = stuck

    def stalled(self) -> tuple[float, ...]:
        """Per wheel: the sign of the command a seized wheel's motor is stalled against (0: turning freely,
        or nothing commanded). The physics (``RoverDynamics.step``) turns it into the stall current."""
        if not any(self._stuck):
            return _NONE_STALLED  # every physics step asks; a seized wheel is a rare fault
        return tuple(
            math.copysign(1.0, target) if stuck and target != 0.0 else 0.0
            for stuck, target in zip(self._stuck, self._targets, strict=True)
        )

    def released(self, wheel: int) -> bool:
        """Whether ``wheel``'s controller has let go of its motor: rebooting, past its command timeout, or
        in its under-voltage fault (``hil.vesc_limits``). A seized wheel is never released: its lock holds
        it whatever its controller does."""
        if self._stuck[wheel]:
            return False
        return self._rebooting[wheel] or self._timed_out[wheel] or self.under_voltage

    def wheel_controls(self) -> WheelControls:
        """What each controller does with its motor, for the physics (``RoverDynamics.step``'s
        ``controls``): per wheel the brake current of a released motor (A: the timeout brake current past
        the command timeout, 0 rebooting or under-voltage) or ``DRIVEN``; then per wheel the fraction of
        its motor current limit the battery cut-off leaves (``SupplyLimits.current_limit_fraction``)."""
        voltage = self._supply_voltage_v
        supply = self._supply
        # Every physics step: the usual case (nothing released, a pack above the cut-off) by comparisons.
        if (
            voltage >= supply.battery_cut_start_v
            and True not in self._timed_out
            and True not in self._rebooting
        ):
            return ALL_DRIVEN
        brakes = tuple(
            DRIVEN
            if not self.released(i)
            else (self._timeout_brake_a if self._timed_out[i] and not self._faulted(i) else 0.0)
            for i in range(WHEEL_COUNT)
        )
        return brakes + (supply.current_limit_fraction(voltage),) * WHEEL_COUNT

    def _faulted(self, wheel: int) -> bool:
        """Rebooting or under-voltage: nothing drives or brakes the motor (a timeout's brake needs firmware
        that runs and a supply above its minimum)."""
        return self._rebooting[wheel] or self.under_voltage

    def set_rolling_speeds(self, wheel_speeds_mps: Sequence[float]) -> None:
        """The surface speeds (m/s, wheel order) the physics turned the wheels at this step
        (``DynamicsStep.wheel_speeds_mps``): a released motor's encoder reads its wheel's, from the next
        ``step`` on. Kept as given (every physics step)."""
        self._rolling_mps = wheel_speeds_mps

    # --- physics -------------------------------------------------------------------------------
    def step(self, dt_s: float) -> None:
        """Advance the motors by ``dt_s`` seconds, then send whatever status is due at the clock's now."""
        if not (math.isfinite(dt_s) and dt_s >= 0):
            raise ValueError(f"SimVescBank.step needs a finite dt_s >= 0, got {dt_s}")
        now = self._clock.now_ns()
        if dt_s != self._blend_dt_s:
            # The motor's first-order blend for this step length, kept: every physics step has the same one.
            self._blend_dt_s, self._blend = dt_s, 1.0 - math.exp(-dt_s / self._tau_s)
        blend = self._blend
        # Every physics step, six wheels: the per-wheel lists held in locals (they are mutated in place).
        erpm, targets, stuck, tacho = self._erpm, self._targets, self._stuck, self._tacho_erev
        measured = self._measured_erpm
        limits, erpm_per_mps = self._speed_limits_mps, self.profile.erpm_per_mps
        floors, ceilings = self._held_floors_mps, self._held_ceilings_mps
        last_command_ns, timeout_ns = self._last_command_ns, self._timeout_ns
        timed_out, rebooting, under_voltage = self._timed_out, self._rebooting, self.under_voltage
        for i in range(WHEEL_COUNT):
            last = last_command_ns[i]
            if last is not None and now - last > timeout_ns:
                # Firmware behaviour: no command within the timeout => release the motor, braked with the
                # timeout brake current (hil.vesc_limits), until the next command.
                targets[i] = 0.0
                last_command_ns[i] = None
                self._timed_out[i] = True
                self.timeouts += 1
                logger.debug("simulated VESC of %s: command timeout, releasing", wheel_label(i, self._ids))
            before = erpm[i]
            if stuck[i]:
                after = 0.0
            elif timed_out[i] or rebooting[i] or under_voltage:  # released(i), inline: every step, six wheels
                # Nothing drives it: its encoder reads the speed the physics rolled the wheel at.
                erpm[i] = after = self._rolling_mps[i] * erpm_per_mps
                tacho[i] += 0.5 * (measured[i] + after) * dt_s / 60.0
                measured[i] = after
                continue
            else:
                after = before + (targets[i] - before) * blend
            # The motor turns no faster than the pack's voltage lets it (back-EMF at the top duty), whatever
            # the speed loop asks: the speed a real VESC measures, and the one the physics applies next.
            top = limits[i] * erpm_per_mps
            if after > top:
                after = top
            elif after < -top:
                after = -top
            erpm[i] = after
            # It turns no further than its current-limited torque turns it against the ground: the speed a
            # real VESC measures while its loop asks for more than the limit gives (+-inf while the limit
            # does not bind). The loop still asks (erpm), so the physics' next pull is again the limit's.
            ceiling, floor = ceilings[i] * erpm_per_mps, floors[i] * erpm_per_mps
            if after > ceiling:
                after = ceiling
            elif after < floor:
                after = floor
            # Trapezoid over the step; erev = ERPM x minutes.
            tacho[i] += 0.5 * (measured[i] + after) * dt_s / 60.0
            measured[i] = after
        self._send_due_status(now)

    def set_electrical(
        self,
        motor_currents_a: Sequence[float],
        input_voltage_v: float,
        duties: Sequence[float],
        speed_limits_mps: Sequence[float] | None = None,
        held_speeds_mps: tuple[Sequence[float], Sequence[float]] | None = None,
    ) -> None:
        """Loads from the physics engine, reported in the next status frames: motor currents, the supply
        voltage and the motors' duty cycles (signed, as ``DynamicsStep.duty``); and, when given, the most
        surface speed each wheel's motor can turn at (m/s, >= 0: ``DynamicsStep.wheel_speed_limits_mps``),
        which the motors keep to from the next ``step`` on (None: no limit, or the last one given); and the
        slowest and fastest each wheel's current-limited torque turns it at, (floors, ceilings) (m/s,
        signed, +-inf where the limit does not bind: ``DynamicsStep.held_speeds_mps``): what the motors
        turn at, measure and report from the next ``step`` on while their speed loops ask for more (None:
        the last ones given)."""
        if len(motor_currents_a) != WHEEL_COUNT:
            raise ValueError(f"need {WHEEL_COUNT} motor currents in wheel order, got {len(motor_currents_a)}")
        if len(duties) != WHEEL_COUNT:
            raise ValueError(f"need {WHEEL_COUNT} duty cycles in wheel order, got {len(duties)}")
        if speed_limits_mps is not None:
            self._set_speed_limits(speed_limits_mps)
        if held_speeds_mps is not None:
            self._set_held_speeds(*held_speeds_mps)
        self._take_supply(input_voltage_v)
        # Kept as given (tuple() of the physics' tuples is the tuple itself) and clamped only when a status
        # frame is next due (_take_loads): the physics gives them every step, while STATUS goes every other
        # step at the default rates and STATUS_4 / STATUS_5 every tenth, so half of the clamping was for
        # loads the next step replaced unread.
        self._loads = (tuple(motor_currents_a), input_voltage_v, tuple(duties))

    def _take_supply(self, input_voltage_v: float) -> None:
        """The pack's voltage for the next step's controls; entering or leaving the under-voltage fault
        (below ``l_min_vin``: every controller, as one pack feeds them all) is logged and counted."""
        self._supply_voltage_v = input_voltage_v
        under = self._supply.under_voltage(input_voltage_v)
        if under != self.under_voltage:
            self.under_voltage = under
            if under:
                self.under_voltage_faults += 1
                logger.info(
                    "simulated VESCs: under-voltage fault at %.2f V, motors released", input_voltage_v
                )
            else:
                logger.info(
                    "simulated VESCs: supply back at %.2f V, under-voltage fault cleared", input_voltage_v
                )

    def _set_speed_limits(self, speed_limits_mps: Sequence[float]) -> None:
        """Keep the physics' speed limits as given. Every physics step: six non-negative numbers, checked
        with builtins only (their least >= 0; a NaN makes the sum unequal to itself: min() can pass one
        over); anything else is a ValueError naming it."""
        if (
            len(speed_limits_mps) != WHEEL_COUNT
            or not min(speed_limits_mps) >= 0.0
            or sum(speed_limits_mps) != sum(speed_limits_mps)
        ):
            raise ValueError(
                f"need {WHEEL_COUNT} wheel speed limits >= 0 m/s in wheel order, got {list(speed_limits_mps)}"
            )
        self._speed_limits_mps = speed_limits_mps

    def _set_held_speeds(self, floors_mps: Sequence[float], ceilings_mps: Sequence[float]) -> None:
        """Keep the physics' held-speed floors and ceilings as given. Every physics step: six of each,
        each floor at most its ceiling (a NaN is neither, so fails), checked with builtins only; anything
        else is a ValueError naming it."""
        if (
            len(floors_mps) != WHEEL_COUNT
            or len(ceilings_mps) != WHEEL_COUNT
            or not all(map(operator.le, floors_mps, ceilings_mps))
        ):
            raise ValueError(
                f"need {WHEEL_COUNT} held-speed floors each at most its ceiling (m/s, wheel order), got "
                f"{list(floors_mps)} and {list(ceilings_mps)}"
            )
        self._held_floors_mps, self._held_ceilings_mps = floors_mps, ceilings_mps

    def _take_loads(self) -> None:
        """Clamp the latest loads (``set_electrical``) into the fields the status frames carry."""
        if self._loads is None:
            return
        motor_currents_a, input_voltage_v, duties = self._loads
        self._loads = None
        # Every status period: the clamps are comparisons (a third of max(min()) calls' cost), each with
        # max(min())'s results: a value in range is kept as it is; a current beyond the field's limit
        # is the limit, and a non-finite one reads 0; a duty beyond +-1 is +-1, and NaN reads 1.0 (as
        # max(-1.0, min(1.0, nan)) gave).
        limit = _STATUS_CURRENT_LIMIT_A
        self._motor_current_a = [
            c if -limit <= c <= limit else (0.0 if not math.isfinite(c) else limit if c > limit else -limit)
            for c in motor_currents_a
        ]
        self._duty_cycle = [d if -1.0 <= d <= 1.0 else (-1.0 if d < -1.0 else 1.0) for d in duties]
        voltage = input_voltage_v if math.isfinite(input_voltage_v) else 0.0
        self._input_voltage_v = max(0.0, min(_VOLTAGE_FIELD_MAX_V, voltage))

    # --- status out ----------------------------------------------------------------------------
    def _send_due_status(self, now: int) -> None:
        fast_due = now >= self._next_status_ns
        slow_due = now >= self._next_slow_ns
        send_fast = fast_due
        if not self._status_sent and (fast_due or slow_due):
            # The first status round, a step after the epoch: a fast status that late is not sent, or the
            # rover's first poll would take it and the next, 10 ms apart (hil.first_sample).
            self._status_sent = True
            send_fast = fast_due and not first_sample_withheld(
                self._next_status_ns, self._status_period_ns, now
            )
        if fast_due:
            self._next_status_ns = _next_due(self._next_status_ns, self._status_period_ns, now)
        if slow_due:
            self._next_slow_ns = _next_due(self._next_slow_ns, self._slow_period_ns, now)
        if not (send_fast or slow_due):
            return
        self._take_loads()
        # Every value is clamped into its field's range before it gets here (ERPM, currents, duty,
        # tachometer, voltage), so the encoders skip cantools' strict range check. The frame order is the
        # firmware's schedule as before: every controller's STATUS, then each one's STATUS_4 and STATUS_5.
        # Each frame's values in its encoder's order (FieldEncoder): numbers, no dict per frame.
        frames: list[tuple[FieldEncoder, tuple[float, ...]]] = []
        if send_fast:
            # Every 20 ms, six wheels: their lists walked together rather than indexed (hot path).
            for status, rebooting, motor_erpm, current, duty in zip(
                self._status_of_wheel,
                self._rebooting,
                self._measured_erpm,
                self._motor_current_a,
                self._duty_cycle,
                strict=True,
            ):
                if not rebooting:
                    erpm = round(motor_erpm)  # clamped to the int32 field by comparisons (hot path)
                    if not -_INT32_MAX <= erpm <= _INT32_MAX:
                        erpm = _INT32_MAX if erpm > 0 else -_INT32_MAX
                    frames.append((status, (erpm, current, duty)))
        if slow_due:
            voltage = self._input_voltage_v
            for i, (_, status_4, status_5) in enumerate(self._status_encoders):
                if self._rebooting[i]:
                    continue
                # What the motor takes from the pack: I x duty, signed as power flows. A braking motor
                # generates and gives it back, down to the controller's regeneration floor (as the physics'
                # battery current, hil.dynamics_kernel).
                current_in = max(self._motor_current_a[i] * self._duty_cycle[i], self._regen_floor_a)
                frames.append((status_4, (current_in,)))
                frames.append((status_5, (_wrap_tacho(self._tacho_erev[i]), voltage)))
        self._send_all(frames)

    def _send_all(self, frames: list[tuple[FieldEncoder, tuple[float, ...]]]) -> None:
        """Encode each frame, then send them in order; one that fails is counted and the rest still go."""
        msgs: list[can.Message] = []
        for encoder, values in frames:
            try:
                msgs.append(encoder.encode(values))
            except _SEND_ERRORS as err:
                self._send_failed(encoder.message.name, err)
        if self._batch_bus is not None:
            # Hot path (6-18 frames per status period): one call for them all on the lockstep bus.
            try:
                self._batch_bus.send_all(msgs)
                return
            except can.CanError:
                pass  # it sent none of them: one by one below, so each failure is counted as before
        send = self._bus.send
        for msg in msgs:
            try:
                send(msg)
            except _SEND_ERRORS as err:
                self._send_failed(self._status_names[msg.arbitration_id], err)

    def _send_failed(self, name: str, err: Exception) -> None:
        self.send_errors += 1
        logger.debug("simulated VESC: cannot send %s: %s", name, err)

    # --- accessors -----------------------------------------------------------------------------
    @property
    def command_timeout_ns(self) -> int:
        """A controller that hears no command for longer than this stops its motor (firmware behaviour)."""
        return self._timeout_ns

    def wheel_speeds_mps(self) -> list[float]:
        """The speeds (m/s) the motors' speed loops drive the wheels to: the physics' wheel speeds given."""
        # VescProfile.speed_from_erpm's arithmetic, inline: every physics step asks, six wheels.
        erpm_per_mps = self.profile.erpm_per_mps
        return [e / erpm_per_mps for e in self._erpm]

    def targets_erpm(self) -> list[float]:
        return list(self._targets)

    def erpm(self) -> list[float]:
        """The motors' speeds as measured (what STATUS reports)."""
        return list(self._measured_erpm)


def _next_due(previous_due: int, period: int, now: int) -> int:
    """Keep a fixed cadence, but after a long pause resume from now instead of sending a burst."""
    due = previous_due + period
    return due if due > now else now + period


def _wrap_tacho(erev: float) -> float:
    """The firmware's tachometer is an int32 of steps (6 per erev) that wraps; so does ours."""
    steps = round(erev * 6.0)
    steps = (steps + (1 << 31)) % (1 << 32) - (1 << 31)
    return steps / 6.0
