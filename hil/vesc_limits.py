"""When a simulated VESC lets go of its motor, what it brakes with then, and its battery cut-off.

A real VESC stops driving its motor in three ways the physics must see (``RoverDynamics.step(controls=)``):

* Command timeout: no command for ``app_conf.timeout_msec`` and the firmware applies its *timeout brake
  current* (``app_conf.timeout_brake_current``, VESC Tool's "Timeout Brake Current"): the motor is released
  and braked with at most that current, against the wheel's turning (0 in the firmware's defaults: it
  rolls free).
* Rebooting: nothing drives the motor; the wheel rolls free (brake 0).
* Under-voltage: below ``l_min_vin`` the firmware faults (FAULT_CODE_UNDER_VOLTAGE) and releases the motor
  (brake 0) until the input voltage is back above it. No CAN status frame carries the fault code
  (STATUS 1-5 in /work/shared/reference/vesc_can.md: ERPM, currents, duty, temperatures, tachometer,
  voltage), so the rover sees it only as a wheel that rolls with no current, and as the input voltage.

And between ``l_battery_cut_start`` and ``l_battery_cut_end`` it ramps its current limit linearly down to 0
(the soft battery cut-off; at or below the end: 0). The firmware ramps its battery (input) current limit
there (``l_in_current_max``); this model has no input current limit of its own, so it ramps the motor
current limit, which at full duty is the same and at low duty lets less through than the firmware would.

Each controller's state for one physics step is 12 numbers (``WheelControls``): per wheel the brake current
(A, >= 0) of a released motor or ``DRIVEN``; then per wheel the fraction (0-1) of its motor current limit
it may use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# In the first six of a wheel-controls tuple: the controller drives its motor (speed loop, current limit).
DRIVEN = -1.0
WheelControls = tuple[float, ...]
# Every controller driving at its full current limit: what the physics takes when nothing else was given.
ALL_DRIVEN: WheelControls = (DRIVEN,) * 6 + (1.0,) * 6

# The timeout brake current of this rover's controllers (A). The firmware's default is 0 (the wheel rolls
# free); teams set it so a rover that loses its CAN link on a slope does not roll away. 10 A is the motors'
# current limit (l_current_max, hil.dynamics' motor_current_limit_a): the most a controller brakes with, so
# the rover is held on any slope its tyres hold (at the friction's limit, atan 0.8 = 38.7 deg on firm
# ground, the 45 kg rover needs 3.6 A per wheel: m g sin / 6 x r / (gear k_t)), and a rover whose link drops
# at 1.5 m/s stops as it did before this was modelled (its controllers then held a speed of 0 at their full
# current), so the fault tests written against that keep their meaning.
DEFAULT_TIMEOUT_BRAKE_CURRENT_A = 10.0

# The 6S pack's voltages (hil.battery: 19.8 V empty at 3.3 V a cell under no load, 25.2 V full). The VESC's
# own defaults (mcconf_default.h: l_min_vin 8 V, cut-off 10 V -> 8 V) are for packs of any size and would
# never act on a 6S pack. VESC Tool's setup for a 14S board sets the cut-off from 47.6 V to 42 V: 3.4 V to
# 3.0 V a cell, the usual Li-ion choice (3.0 V: the cells' rated end of discharge under load). For 6 cells:
CELLS = 6
BATTERY_CUT_START_V = CELLS * 3.4  # 20.4 V: from here the current limit falls ...
BATTERY_CUT_END_V = CELLS * 3.0  # 18.0 V: ... to 0 here
# Below this the controller faults and lets go (l_min_vin): 2.5 V a cell, the lowest discharge voltage Li-ion
# cell datasheets allow (below it the cell is damaged). Under the cut-off's end, so with a healthy pack the
# ramp has already taken the current to 0 by then: it acts on a pack that sags with no motor load (a weak
# cell, a bad connector: the battery fault), as l_min_vin does on a real rover.
MIN_INPUT_VOLTAGE_V = CELLS * 2.5  # 15.0 V


class VescLimitsError(ValueError):
    """A simulated VESC's supply limits or brake current that cannot be (named in the message)."""


@dataclass(frozen=True)
class SupplyLimits:
    """A VESC's input voltage limits (V): ``l_min_vin``, ``l_battery_cut_start``, ``l_battery_cut_end``."""

    min_input_voltage_v: float = MIN_INPUT_VOLTAGE_V
    battery_cut_start_v: float = BATTERY_CUT_START_V
    battery_cut_end_v: float = BATTERY_CUT_END_V

    def __post_init__(self) -> None:
        values = (self.min_input_voltage_v, self.battery_cut_end_v, self.battery_cut_start_v)
        if not all(math.isfinite(v) and v >= 0.0 for v in values):
            raise VescLimitsError(f"supply limits must be finite voltages >= 0, got {self}")
        # VESC Tool refuses a cut-off that ends below l_min_vin or starts below its end, for the same reasons.
        if not self.min_input_voltage_v <= self.battery_cut_end_v < self.battery_cut_start_v:
            raise VescLimitsError(
                "supply limits need min_input_voltage_v <= battery_cut_end_v < battery_cut_start_v, got "
                f"{self.min_input_voltage_v:g} V, {self.battery_cut_end_v:g} V, "
                f"{self.battery_cut_start_v:g} V"
            )

    def current_limit_fraction(self, input_voltage_v: float) -> float:
        """The part of its current limit a controller may use at ``input_voltage_v`` (V): 1 at or above the
        cut-off's start, falling linearly to 0 at its end, 0 below (and for a voltage that is not a
        number)."""
        if input_voltage_v >= self.battery_cut_start_v:
            return 1.0
        if not input_voltage_v > self.battery_cut_end_v:
            return 0.0
        span = self.battery_cut_start_v - self.battery_cut_end_v
        return (input_voltage_v - self.battery_cut_end_v) / span

    def under_voltage(self, input_voltage_v: float) -> bool:
        """Whether the controller is in its under-voltage fault (FAULT_CODE_UNDER_VOLTAGE) at this voltage."""
        return not input_voltage_v >= self.min_input_voltage_v


def check_brake_current(brake_current_a: float) -> float:
    """``brake_current_a`` if it is a finite current >= 0 (A), else a VescLimitsError naming it."""
    if not (math.isfinite(brake_current_a) and brake_current_a >= 0.0):
        raise VescLimitsError(f"timeout_brake_current_a must be a current >= 0 A, got {brake_current_a}")
    return brake_current_a
