"""A battery pack: open-circuit voltage falling with charge drawn, plus sag across internal resistance.

Current flows both ways: the motors' controllers return what braking motors generate (regenerative
braking, as a VESC does), each down to its battery current floor ``REGEN_CURRENT_LIMIT_A``.
"""

from __future__ import annotations

from dataclasses import dataclass

# Each of the six motor controllers' battery current floor while braking, as a magnitude (VESC Tool's
# "Battery Current Max Regen", l_in_current_min): set for the pack's charge rate, 12 A for the six, 0.6 C of
# the 20 Ah pack below. The default rover regenerates ~1 A per motor braking down 20 deg at 0.5 m/s.
REGEN_CURRENT_LIMIT_A = 2.0


@dataclass(frozen=True)
class BatteryParams:
    """A 6S lithium-ion pack, a common choice on small rovers (typical cell figures)."""

    full_voltage_v: float = 25.2  # 6 x 4.2 V
    empty_voltage_v: float = 19.8  # 6 x 3.3 V
    capacity_ah: float = 20.0
    internal_resistance_ohm: float = 0.06


class Battery:
    """Tracks charge used and net energy drawn; ``draw`` returns the terminal voltage under that current.

    A charging current (negative) raises the terminal voltage by ``I R`` and gives charge and energy back.
    A full pack's charge cut-off is not modelled: charge returned past full is kept (the state of charge
    reads at most 1, the open-circuit voltage at most full), a few mWh in a trial that brakes first.
    """

    def __init__(self, params: BatteryParams | None = None) -> None:
        self.params = params or BatteryParams()
        self.charge_used_ah = 0.0
        self.energy_wh = 0.0
        self.voltage_v = self.params.full_voltage_v
        self.current_a = 0.0
        self.sag_v = 0.0  # fault: a weak cell or a bad connector
        self.extra_resistance_ohm = 0.0

    def set_sag(self, sag_v: float, extra_resistance_ohm: float) -> None:
        """Battery-sag fault: ``sag_v`` lower and more internal resistance (both 0 clears it)."""
        self.sag_v = sag_v
        self.extra_resistance_ohm = extra_resistance_ohm

    @property
    def state_of_charge(self) -> float:
        return min(1.0, max(0.0, 1.0 - self.charge_used_ah / self.params.capacity_ah))

    def open_circuit_voltage(self) -> float:
        p = self.params
        return p.empty_voltage_v + (p.full_voltage_v - p.empty_voltage_v) * self.state_of_charge

    def draw(self, current_a: float, dt_s: float) -> float:
        """Draw ``current_a`` (A: > 0 drawn from the pack, < 0 returned to it) for ``dt_s`` seconds;
        returns terminal volts. A current that is not a number reads 0.

        Energy is the integral of terminal voltage times current (rectangle rule over each draw).
        """
        # Every physics tick: the clamps are comparisons (a NaN fails every one: it reads 0.0) and
        # open_circuit_voltage's arithmetic is inline.
        current = current_a if current_a == current_a else 0.0
        p = self.params
        resistance = p.internal_resistance_ohm + self.extra_resistance_ohm
        charge = 1.0 - self.charge_used_ah / p.capacity_ah
        charge = charge if charge < 1.0 else 1.0
        open_circuit = p.empty_voltage_v + (p.full_voltage_v - p.empty_voltage_v) * (
            charge if charge > 0.0 else 0.0
        )
        terminal = open_circuit - self.sag_v - current * resistance
        self.voltage_v = voltage = terminal if terminal > 0.0 else 0.0
        self.current_a = current
        self.charge_used_ah += current * dt_s / 3600.0
        self.energy_wh += voltage * current * dt_s / 3600.0
        return voltage
