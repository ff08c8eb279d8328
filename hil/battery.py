"""A battery pack: open-circuit voltage falling with charge drawn, plus sag across internal resistance."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class BatteryParams:
    """A 6S lithium-ion pack, a common choice on small rovers (typical cell figures)."""

    full_voltage_v: float = 25.2  # 6 x 4.2 V
    empty_voltage_v: float = 19.8  # 6 x 3.3 V
    capacity_ah: float = 20.0
    internal_resistance_ohm: float = 0.06


class Battery:
    """Tracks charge used and energy drawn; ``draw`` returns the terminal voltage under that current."""

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
        return max(0.0, 1.0 - self.charge_used_ah / self.params.capacity_ah)

    def open_circuit_voltage(self) -> float:
        p = self.params
        return p.empty_voltage_v + (p.full_voltage_v - p.empty_voltage_v) * self.state_of_charge

    def draw(self, current_a: float, dt_s: float) -> float:
        """Draw ``current_a`` (A, >= 0 drawn from the pack) for ``dt_s`` seconds; returns terminal volts.

        Energy is the integral of terminal voltage times current (rectangle rule over each draw).
        """
        current = max(0.0, current_a)  # regeneration into the pack is not modelled
        resistance = self.params.internal_resistance_ohm + self.extra_resistance_ohm
        self.voltage_v = max(0.0, self.open_circuit_voltage() - self.sag_v - current * resistance)
        self.current_a = current
        self.charge_used_ah += current * dt_s / 3600.0
        self.energy_wh += self.voltage_v * current * dt_s / 3600.0
        return self.voltage_v
