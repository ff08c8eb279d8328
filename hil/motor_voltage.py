"""The motors' voltage limit on wheel speed (back-EMF at the controller's top duty), compiled with numba.

A brushed or FOC-driven DC motor turns only as fast as its supply lets it: the voltage its controller puts
across it, ``duty x V_pack``, meets the back-EMF ``k_e omega`` and the winding's drop ``I R``, so

    k_e omega + I R <= duty_max V_pack        (k_e = k_t in SI units, V s/rad = N m/A)

and a wheel commanded faster turns at ``omega_max = (duty_max V - I R) / k_e`` (motor rad/s), its surface
at ``omega_max r / gear``. Backwards the same with the signs turned: ``k_e omega + I R >= -duty_max V``. A
VESC never drives past its ``l_max_duty`` (VESC firmware ``mcconf_default.h``, ``MCCONF_L_MAX_DUTY``: 0.95
by default, VESC Tool's "Maximum Duty Cycle"), so a sagging or empty pack slows a rover commanded near top
speed: 1.5 m/s on firm level ground needs ~20.1 V at the default rover's motors (docs/physics.md).

The current ``I`` is the wheel's last step's (the physics' ``motor_currents_a``): this step's depends on the
wheel speed the limit sets (through the slip and the force), so the limit takes the current of the force
the wheel pulled with a step ago rather than solving for it. On a steady drive the two agree; as the load
changes, the drop ``I R`` is a step behind (at most 10 A x 0.1 ohm = 1 V at the default current limit).
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@numba.njit(cache=True)
def limit_to_voltage(
    wheels: Array, currents: Array, motor: Array, battery_voltage: float, max_duty: float, out_limits: Array
) -> None:
    """Cap each of the six wheel surface speeds (m/s, ``wheels``, in place) at what its motor can turn at
    ``max_duty`` of ``battery_voltage`` (V) with its ``currents`` (A, signed as the wheel's force), on the
    command's sign; a speed within its limit keeps its float. ``motor``: ``hil.traction.wheel_outputs``'s
    vector (wheel radius m, gear ratio, torque constant N m/A, winding resistance ohm, ...).

    Writes each wheel's limit (m/s, >= 0: the fastest it can turn in the direction it was given, forward
    for 0) into ``out_limits``; 0 where the supply does not cover the winding's drop (no pack left: it
    cannot turn that way at all, and is never driven the other way by the cap).
    """
    radius, gear, k_t, resistance = motor[0], motor[1], motor[2], motor[3]
    speed_per_volt = radius / (gear * k_t)  # wheel surface m/s per volt of back-EMF
    supply = max_duty * battery_voltage if battery_voltage > 0.0 else 0.0
    for i in range(6):
        drop = currents[i] * resistance
        if wheels[i] >= 0.0:
            limit = max(supply - drop, 0.0) * speed_per_volt
            if wheels[i] > limit:
                wheels[i] = limit
        else:
            limit = max(supply + drop, 0.0) * speed_per_volt
            if wheels[i] < -limit:
                wheels[i] = -limit
        out_limits[i] = limit
