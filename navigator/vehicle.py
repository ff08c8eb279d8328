"""The rover's body and the paper's physics, written once.

The planner calls these functions with the parameters it *believes*, the simulator (``hil.dynamics``)
with the *true* ones, so a mismatch between assumed and real terrain can be simulated.

Conventions (body axes x forward, y left, z up):

* ``pitch`` is positive **nose up**; ``roll`` is positive when the **right side is lower** (a right-hand
  rotation about the forward axis lifts the left side). Note that nose-up pitch is a *negative* right-hand
  rotation about the left (y) axis; we keep the spec's "nose up positive" because it reads naturally for
  slopes.
* Wheel order: ``[left front, left middle, left rear, right front, right middle, right rear]``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import cached_property

import numba
import numpy as np
from numpy.typing import NDArray

from logs.settings import Table
from navigator.errors import ParameterError

G = 9.81  # m/s^2

# Axle positions along the body x axis in units of half the wheelbase: front, middle, rear.
_AXLE_X_UNITS = (1.0, 0.0, -1.0)
# The body's lengths (metres). None of them reaches this on a rover this stack drives; a config that
# gives one in millimetres (wheel_radius_m = 110) does, and would otherwise load and drive wrong.
_LENGTH_KEYS = (
    "cg_height_m",
    "wheelbase_m",
    "track_m",
    "wheel_radius_m",
    "footprint_length_m",
    "footprint_width_m",
)
MAX_LENGTH_M = 10.0


@dataclass(frozen=True)
class VehicleParams:
    """Geometry and mass of the six-wheeled skid-steer rover (SI units)."""

    mass_kg: float = 45.0
    cg_height_m: float = 0.30
    wheelbase_m: float = 0.70  # front to rear axle; the middle axle sits halfway
    track_m: float = 0.55  # left to right wheel centres
    wheel_radius_m: float = 0.11
    max_wheel_speed_mps: float = 1.5
    footprint_length_m: float = 0.90
    footprint_width_m: float = 0.70
    # Skid-steer turns need more wheel-speed difference than the geometric track suggests (the tyres scrub
    # sideways); effective track = track x skid_factor. Mixing, odometry and the simulator all use it.
    skid_factor: float = 1.6

    def __post_init__(self) -> None:
        for field in fields(self):
            value = getattr(self, field.name)
            if not isinstance(value, int | float) or not math.isfinite(value) or value <= 0.0:
                raise ParameterError(
                    f"vehicle parameter {field.name} must be a finite number > 0, got {value!r}"
                )
        if self.skid_factor < 1.0:
            raise ParameterError(
                f"vehicle parameter skid_factor must be >= 1 (skidding only widens the track), "
                f"got {self.skid_factor}"
            )

    @classmethod
    def from_table(cls, table: Table) -> VehicleParams:
        """Read a ``[vehicle]`` table; every key optional, unknown keys are errors (ConfigError)."""
        defaults = cls()
        values: dict[str, float] = {}
        for field in fields(cls):
            lower = 1.0 if field.name == "skid_factor" else 0.0
            value = table.number(field.name, getattr(defaults, field.name), lo=lower)
            if value <= 0.0:
                raise table.error(field.name, f"must be > 0, got {value}")
            if field.name in _LENGTH_KEYS and value > MAX_LENGTH_M:
                raise table.error(
                    field.name,
                    f"{value:g} m is more than {MAX_LENGTH_M:g} m: lengths are in metres (a 110 mm wheel "
                    "radius is 0.11)",
                )
            values[field.name] = value
        # Three wheels a side, wheelbase_m / 2 apart: a wheel wider than that would overlap its neighbour,
        # the mark of a radius in the wrong unit (cm, or mm with a long wheelbase) or a diameter.
        most_m = values["wheelbase_m"] / 4.0
        if values["wheel_radius_m"] > most_m:
            raise table.error(
                "wheel_radius_m",
                f"{values['wheel_radius_m']:g} m is more than wheelbase_m {values['wheelbase_m']:g} m / 4 = "
                f"{most_m:g} m: the three wheels of a side would overlap; give the radius (not the "
                "diameter) in metres",
            )
        # The planner keeps the footprint clear of obstacles: the wheels must stand inside it.
        for outer, inner in (("footprint_width_m", "track_m"), ("footprint_length_m", "wheelbase_m")):
            if values[outer] < values[inner]:
                raise table.error(
                    outer,
                    f"{values[outer]:g} m is less than {inner} {values[inner]:g} m: the wheels would stand "
                    "outside the footprint the planner keeps clear of obstacles",
                )
        table.finish()
        return cls(**values)

    # Derived once per (frozen) parameter set: the control tick and the physics step read them every time.
    # cached_property stores in the instance's __dict__, which the frozen dataclass's __setattr__ guard
    # does not cover; fields, equality and replace() are untouched.
    @cached_property
    def effective_track_m(self) -> float:
        return self.track_m * self.skid_factor

    @cached_property
    def footprint_radius_m(self) -> float:
        """Radius of the circle around the footprint rectangle (half its diagonal)."""
        return 0.5 * math.hypot(self.footprint_length_m, self.footprint_width_m)

    @cached_property
    def tip_roll_rad(self) -> float:
        """Static side tilt at which the centre of gravity is above the downhill wheels."""
        return math.atan((self.track_m / 2.0) / self.cg_height_m)

    @cached_property
    def tip_pitch_rad(self) -> float:
        """Static fore/aft tilt at which the centre of gravity is above the downhill (end) axle."""
        return math.atan((self.wheelbase_m / 2.0) / self.cg_height_m)


def slope_acceleration(theta_rad: float, mu: float) -> float:
    """The paper's law ``a = g (sin θ − μ cos θ)`` along a slope of angle θ, in m/s².

    Positive means a body resting on friction μ slides down the slope with that acceleration; zero or
    negative means friction can hold it (the caller treats it as no motion).
    """
    return G * (math.sin(theta_rad) - mu * math.cos(theta_rad))


def max_climbable_slope_rad(mu: float, rolling_resistance: float, margin_rad: float = 0.0) -> float:
    """Steepest slope the rover can drive up: traction μN must beat gravity and rolling resistance.

    ``μ m g cos θ >= m g sin θ + crr m g cos θ``  <=>  ``tan θ <= μ − crr``; minus ``margin_rad``,
    never negative.
    """
    return max(0.0, math.atan(max(0.0, mu - rolling_resistance)) - margin_rad)


# Axle positions along the body in units of half the wheelbase (front, middle, rear), as an array for the
# compiled load balance.
_AXLE_UNITS = np.array(_AXLE_X_UNITS)


@numba.njit(cache=True)
def _axle_loads(moment_rear: float, total: float, half_wheelbase: float) -> tuple[float, float, float]:
    """Normal load on the front, middle and rear axles (N), summing to ``total``.

    The load varies linearly along the body (a rigid chassis on equally stiff wheels) and balances the
    pitching moment ``moment_rear`` (N·m, positive loads the rear). An axle that would carry a negative load
    lifts: it is dropped and the rest re-balance, so the last axle standing carries everything (that is the
    tip-over point ``tan θ = (wheelbase/2) / h``).

    Compiled: the simulator's physics step (``hil.dynamics_kernel``) runs it inside its own kernel.
    """
    if total <= 0.0:
        return 0.0, 0.0, 0.0
    # The usual case, every physics step: all three axles on the ground. The loop's first pass written out
    # (the same expressions, so the same floats); anything else (an axle lifting, or a NaN) goes through
    # the loop from the start.
    x0, x1, x2 = half_wheelbase, 0.0 * half_wheelbase, -1.0 * half_wheelbase
    sx = 0.0 + x0 + x1 + x2
    sxx = 0.0 + x0 * x0 + x1 * x1 + x2 * x2
    det = 3.0 * sxx - sx * sx
    a = (total * sxx + moment_rear * sx) / det
    b = (-moment_rear * 3.0 - sx * total) / det
    front, middle, rear = a + b * x0, a + b * x1, a + b * x2
    if front >= 0.0 and middle >= 0.0 and rear >= 0.0:
        return front, middle, rear
    return _axle_loads_lifting(moment_rear, total, half_wheelbase)


@numba.njit(cache=True)
def _axle_loads_lifting(
    moment_rear: float, total: float, half_wheelbase: float
) -> tuple[float, float, float]:
    """``_axle_loads`` when an axle may lift: balance on those in contact, lift the most negative, repeat."""
    loads = np.zeros(3)
    in_contact = np.ones(3, dtype=np.bool_)
    contact_loads = np.empty(3)
    while True:
        # The axles in contact's positions (m) and the sums the balance needs, in axle order.
        n = 0
        sx = sxx = 0.0
        for axle in range(3):
            if in_contact[axle]:
                xi = _AXLE_UNITS[axle] * half_wheelbase
                n += 1
                sx += xi
                sxx += xi * xi
        if n == 1:
            for axle in range(3):
                if in_contact[axle]:
                    loads[axle] = total
            return loads[0], loads[1], loads[2]
        det = n * sxx - sx * sx
        # N_i = a + b x_i with sum N_i = total and sum N_i x_i = -moment_rear.
        a = (total * sxx + moment_rear * sx) / det
        b = (-moment_rear * n - sx * total) / det
        lowest = math.nan
        lifted = -1
        for axle in range(3):
            if in_contact[axle]:
                contact_loads[axle] = a + b * (_AXLE_UNITS[axle] * half_wheelbase)
                # The first axle with the lowest load (as min() and list.index() pick it).
                if lifted < 0 or contact_loads[axle] < lowest:
                    lowest, lifted = contact_loads[axle], axle
        if lowest >= 0.0:
            for axle in range(3):
                if in_contact[axle]:
                    loads[axle] = contact_loads[axle]
            return loads[0], loads[1], loads[2]
        # Lift the axle with the most negative load and re-balance on the others.
        in_contact[lifted] = False


@numba.njit(cache=True)
def normal_forces_into(
    mass_kg: float,
    cg_height_m: float,
    track_m: float,
    half_wheelbase_m: float,
    roll_rad: float,
    pitch_rad: float,
    ax_mps2: float,
    ay_mps2: float,
    out: NDArray[np.float64],
) -> None:
    """``wheel_normal_forces`` written into ``out`` (six, wheel order), from the parameters it reads."""
    cos_pitch = math.cos(pitch_rad)
    total = mass_kg * G * math.cos(roll_rad) * cos_pitch
    if total <= 0.0:
        out[:] = 0.0
        return
    moment_rear = mass_kg * cg_height_m * (G * math.sin(pitch_rad) + ax_mps2)
    moment_right = mass_kg * cg_height_m * (G * cos_pitch * math.sin(roll_rad) + ay_mps2)
    right_share = min(1.0, max(0.0, 0.5 + moment_right / (track_m * total)))
    left_share = 1.0 - right_share
    front, middle, rear = _axle_loads(moment_rear, total, half_wheelbase_m)
    # Each wheel's load as (side share x axle share) x total, in that order (the simulator's physics step
    # is pinned to these bits).
    front, middle, rear = front / total, middle / total, rear / total
    out[0] = left_share * front * total
    out[1] = left_share * middle * total
    out[2] = left_share * rear * total
    out[3] = right_share * front * total
    out[4] = right_share * middle * total
    out[5] = right_share * rear * total


def wheel_normal_forces(
    params: VehicleParams, roll_rad: float, pitch_rad: float, ax_mps2: float = 0.0, ay_mps2: float = 0.0
) -> np.ndarray:
    """Normal force on each wheel (N, wheel order), from the slope and the body's acceleration.

    Total load ``m g cos(roll) cos(pitch)`` (the slope-normal part of gravity). Load moves to the rear by
    ``m h (g sin(pitch) + ax) / ...`` and to the right by ``m h (g cos(pitch) sin(roll) + ay) / track``,
    where ``ax`` is the forward and ``ay`` the leftward acceleration of the body (a left turn loads the
    right side). Sides split the load linearly and clamp at zero when a side lifts; axles per
    ``_axle_loads``. The sum is always the total load (until the whole rover is airborne: never here).
    """
    forces = np.empty(6)
    normal_forces_into(
        params.mass_kg, params.cg_height_m, params.track_m, params.wheelbase_m / 2.0,
        roll_rad, pitch_rad, ax_mps2, ay_mps2, forces,
    )  # fmt: skip
    return forces


def stability_margins(
    params: VehicleParams,
    roll_rad: float,
    pitch_rad: float,
    lateral_accel_mps2: float = 0.0,
    longitudinal_accel_mps2: float = 0.0,
) -> tuple[float, float]:
    """(roll margin, pitch margin) in rad: tip angle minus the tilt of the specific force; < 0 means
    tip-over.

    The specific force in body axes (x forward, y left, z up) is the body's acceleration less gravity,
    ``(a_x + g sin(pitch), a_y + g cos(pitch) sin(roll), g cos(pitch) cos(roll))``, as the simulator's
    ``specific_force`` computes it; ``tilt_margins`` has the law. At rest the tilts are the roll and pitch
    themselves; a left turn (``a_y > 0``) tips the rover over its right wheels, like a positive roll.
    """
    cos_pitch = math.cos(pitch_rad)
    return tilt_margins(
        params.tip_roll_rad,
        params.tip_pitch_rad,
        longitudinal_accel_mps2 + G * math.sin(pitch_rad),
        lateral_accel_mps2 + G * cos_pitch * math.sin(roll_rad),
        G * cos_pitch * math.cos(roll_rad),
    )


def tilt_margins(
    tip_roll_rad: float, tip_pitch_rad: float, force_x: float, force_y: float, force_z: float
) -> tuple[float, float]:
    """(roll margin, pitch margin) in rad from the specific force in body axes (m/s^2, any scale):
    ``tip_roll - atan2(|f_y|, f_z)``, ``tip_pitch - atan2(|f_x|, f_z)``.

    The same law as the wheel loads' (``normal_forces_into``): a side lifts when the moment ``m h f_y``
    reaches ``m f_z track / 2``, i.e. when ``|f_y| / f_z`` reaches ``(track / 2) / h = tan(tip_roll)``; an
    axle likewise with ``f_x`` and the wheelbase. A force pointing away from the ground (``f_z <= 0``) gives
    a tilt of 90 deg or more: past any tip angle. Roll and pitch are checked separately (the support
    polygon is treated as a rectangle's two axes).
    """
    return (
        tip_roll_rad - math.atan2(abs(force_y), force_z),
        tip_pitch_rad - math.atan2(abs(force_x), force_z),
    )


# The same function compiled, for the simulator's physics kernel (hil.dynamics_kernel); the planner's
# safety checks call the plain one (a compiled call from Python costs more than these few operations).
tilt_margins_kernel = numba.njit(cache=True)(tilt_margins)


def turn_acceleration_room(tilt_limit_rad: float, roll_rad: float, pitch_rad: float) -> float:
    """The sideways acceleration (m/s^2, >= 0) a turn may add towards the downhill side, on ground tilted by
    ``roll_rad`` and ``pitch_rad``, before the roll tilt of ``tilt_margins`` reaches ``tilt_limit_rad``.

    As in ``stability_margins``, gravity's part of the specific force is ``f_y = g cos θ sin φ``,
    ``f_z = g cos θ cos φ``, and a turn adds ``a`` to ``f_y``. ``atan2(|f_y|, f_z) = limit`` gives
    ``a = g cos θ (cos φ tan(limit) - sin φ)``: pitch takes room too, since it shrinks the ``f_z`` that holds
    the side down. The worst side (the turn's acceleration added
    to the downhill pull) is assumed, so the sign of the roll does not matter. 0.0 when the tilt already
    reaches the limit.
    """
    if tilt_limit_rad <= 0.0:
        return 0.0
    roll = abs(roll_rad)
    room = G * math.cos(pitch_rad) * (math.cos(roll) * math.tan(tilt_limit_rad) - math.sin(roll))
    return room if room > 0.0 else 0.0


def critical_sliding_speed(track_m: float, cg_height_m: float, margin_rad: float) -> float:
    """The sideways speed (m/s) at which a slide stopped dead by a contact trips the rover over the edge of
    the wheels it slid towards; ``margin_rad``: that side's static margin angle (tip angle less the tilt
    towards it). 0.0 when the margin is already gone.

    The impact stops the slide in an instant; the body keeps its angular momentum about the edge,
    ``L = m v h_cg``, and pivots about it with ``L^2 / (2 I_edge)`` of energy. It trips when that lifts the
    centre of gravity over the edge, ``m g R (1 - cos(margin))``, ``R = sqrt((track/2)^2 + h_cg^2)``:
    ``v^2 = 2 g I_edge R (1 - cos(margin)) / (m h_cg^2)``, the critical sliding velocity (CSV) of tripped
    rollovers (Chrstos and Guenther, "The Measurement of Static Rollover Metrics", SAE 920582, 1992; NHTSA's
    rollover resistance metrics). ``I_edge = I_cg + m R^2`` with ``I_cg = 0`` (all the mass at the centre of
    gravity): the least ``I_edge``, so the lowest tripping speed, the cautious side for a rover whose roll
    inertia about its centre of gravity is not known (any real ``I_cg > 0`` raises the speed).
    """
    if margin_rad <= 0.0:
        return 0.0
    lever = math.hypot(0.5 * track_m, cg_height_m)
    return math.sqrt(2.0 * G * lever**3 * (1.0 - math.cos(margin_rad))) / cg_height_m


critical_sliding_speed_kernel = numba.njit(cache=True)(critical_sliding_speed)
