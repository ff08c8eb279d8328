"""The simulated rover body on the TRUE terrain: a planar rigid body driven by six velocity-controlled wheels.

The model, per step of ``dt`` (semi-implicit Euler, no randomness):

* The terrain under the rover gives roll and pitch (``TerrainMap.tilt_at``'s numbers at its heading, looked up
  with its class and elevation in one call by ``TerrainMap.ground_at``), the friction
  coefficient μ and rolling resistance crr of its class, and the wheel normal forces
  (``navigator.vehicle.wheel_normal_forces``, with the last step's acceleration for weight transfer).
* Wheels on the ground (``hil.traction``, per wheel, with the class's laws): each rolling wheel meets
  motion resistance ``crr N`` whose sinkage part grows with its load (Bekker); the end axles scrub sideways
  in a turn, a moment ``mu_t sum(N |x|)`` against the yaw with ``mu_t`` falling with the turn radius; a wheel
  pulls along its class's traction-slip curve, at most ``mu N``, at most what its motor's current limit
  gives, and only with the sign of its actual slip (a wheel slower than the ground under it brakes).
* Longitudinal and yaw: the commanded side speeds, minus the steady-state slip the curve needs for the
  forces that hold them (gravity ``m g sin(pitch)``, resistance, scrub), give a target speed and yaw rate
  ``(v_right − v_left) / (track × skid_factor)``. The wheels pull the body toward them within ``tau`` and
  ``tau_yaw``, as far as each side's traction and current limits allow (``F_req = m (v_target − v) / tau +
  m g sin(pitch) + F_resist``, clipped). So with locked wheels on a slope steeper than ``atan μ`` the body
  slides down at the paper's ``a = g (sin θ − μ cos θ)``; with wheels spinning uphill it slides back unless
  ``tan θ <= μ − crr``; in steady driving and turning the ground speed lags the tyres by the curve's slip,
  so a turn falls short of the wheels' kinematic yaw rate by the slip the scrub needs. The scrub is
  Coulomb friction on the yaw (it stops a turn, never reverses it).
* No lateral slip (the body moves along its heading); horizontal displacement is ``v cos(pitch) dt``.
* Rollover when a stability margin (``navigator.vehicle.stability_margins``, lateral acceleration ``v ω``
  included) goes negative: latched, the rover stays stopped.
* Collision when the footprint, the oriented rectangle ``footprint_length_m`` x ``footprint_width_m`` (the
  planner's exact test, ``navigator.footprint.rectangle_contact``), would overlap an obstacle cell or reach
  past the map edge: a move that pushes it further in is refused and the rover stopped at the contact. If
  the turn alone is free it keeps turning (so it can turn in place and back away); if the turn is what hits
  (a corner swinging into a wall), the turn stops at the contact too. Reported once per entry in
  ``DynamicsStep.collided_obstacle``; ``collided`` is true for as long as it touches.
* Motors: wheel torque ``F r`` -> motor current ``F r / (gear k_t)`` (so never above the current limit; its
  sign is the force's); duty ``(k_t ω_motor + I R) / V``; electrical power ``k_t I ω_motor + I² R`` per
  motor, a generating (braking) motor counting 0 (no regeneration), integrates to energy. Slip: from the
  curve while a wheel pulls below its traction limit, from its surface and ground speeds once it spins or
  slides (or is held at zero pull by the sign of its slip).
* Seized wheels (``stalled``, the simulated VESCs' stuck fault): the wheel is locked (surface speed 0, on
  the ground as any wheel slower than its side), while its motor, commanded to turn, is stalled against
  the lock: its controller drives it at the current limit (signed as the command), duty ``I R / V`` (no
  back-EMF), and it burns ``I² R`` from the pack.

Body axes: x forward, y left, z up; pitch positive nose up, roll positive when the right side is lower.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from hil.traction import drive_forces, wheel_outputs
from navigator.footprint import BOUNDARY, CLEAR, OBSTACLE, rectangle_contact
from navigator.ground_kernel import GroundUnder
from navigator.terrain import TerrainMap
from navigator.terrain_classes import REFERENCE_WHEEL_LOAD_N, TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import G, VehicleParams, stability_margins, wheel_normal_forces

# Within this distance of an obstacle the footprint counts as touching it.
_CONTACT_TOLERANCE_M = 1e-3
_CONTACT_BISECTIONS = 16
# Resolution of how deep an overlapping footprint is: 2^-12 of its half width, ~0.1 mm.
_DEPTH_BISECTIONS = 12


class DynamicsError(ValueError):
    """The simulated body was given something it cannot use (bad time step, wheel speeds, start pose)."""


class DynamicsStep(NamedTuple):
    """What one step produced. Per-wheel tuples are in wheel order (LF LM LR RF RM RR).

    A NamedTuple, not a frozen dataclass: one is built every physics step, and a frozen dataclass's
    ``__init__`` (one ``object.__setattr__`` per field, 27 of them) cost about three times as much."""

    x: float
    y: float
    yaw: float
    speed_mps: float
    yaw_rate_rps: float
    roll_rad: float
    pitch_rad: float
    terrain_class: int
    terrain_name: str
    wheel_speeds_mps: tuple[float, ...]  # wheel surface speeds applied this step
    # From the class's traction curve for each wheel's pull; (surface − ground) / max(|surface|, |ground|)
    # once it spins or slides; in [-1, 1].
    slip: tuple[float, ...]
    normal_forces_n: tuple[float, ...]
    traction_forces_n: tuple[float, ...]  # forward pull of each wheel's motor at the ground contact
    motor_currents_a: tuple[float, ...]
    duty: tuple[float, ...]
    longitudinal_accel_mps2: float
    lateral_accel_mps2: float
    specific_force_body_mps2: tuple[float, float, float]  # what an IMU measures, gravity included
    roll_margin_rad: float
    pitch_margin_rad: float
    rollover: bool  # latched: true from the step it tipped over onwards
    rollover_started: bool  # true only on the step it tipped over
    collided: bool  # the footprint touches an obstacle / the map edge, or a move into one was refused
    collided_obstacle: bool  # true only on the step a contact began
    collision_with: str  # "obstacle", "boundary" or "" (no contact)
    energy_wh: float  # electrical energy used by the six motors so far
    battery_current_a: float  # motor power / battery voltage this step


class RoverDynamics:
    """The rover body on the true terrain, stepped with the wheel speeds the simulated motors achieve."""

    def __init__(
        self,
        terrain: TerrainMap,
        params: VehicleParams,
        classes: dict[int, TerrainClass] = TERRAIN_CLASSES,
        *,
        x: float,
        y: float,
        yaw: float,
        motor_torque_constant_nm_per_a: float = 0.07,  # k_t, ~136 rpm/V: 1.5 m/s at ~19 V back-EMF
        gear_ratio: float = 20.0,  # motor turns per wheel turn
        winding_resistance_ohm: float = 0.1,
        motor_current_limit_a: float = 10.0,  # the VESC's motor current limit (its l_current_max setting)
        drive_time_constant_s: float = 0.1,
        yaw_time_constant_s: float = 0.15,
    ) -> None:
        for name, value in (
            ("motor_torque_constant_nm_per_a", motor_torque_constant_nm_per_a),
            ("gear_ratio", gear_ratio),
            ("motor_current_limit_a", motor_current_limit_a),
            ("drive_time_constant_s", drive_time_constant_s),
            ("yaw_time_constant_s", yaw_time_constant_s),
        ):
            if not (math.isfinite(value) and value > 0.0):
                raise DynamicsError(f"{name} must be a finite number > 0, got {value}")
        if not (math.isfinite(winding_resistance_ohm) and winding_resistance_ohm >= 0.0):
            raise DynamicsError(f"winding_resistance_ohm must be >= 0, got {winding_resistance_ohm}")
        if not all(math.isfinite(v) for v in (x, y, yaw)) or not terrain.contains(x, y):
            raise DynamicsError(f"start pose ({x}, {y}, yaw {yaw}) must be finite and on the map")
        missing = sorted(set(np.unique(terrain.terrain_class).tolist()) - set(classes))
        if missing:
            raise DynamicsError(f"terrain classes {missing} on the map have no entry in the class table")
        self._terrain = terrain
        self._params = params
        self._classes = classes
        self._current_limit_a = motor_current_limit_a
        # Yaw inertia of a uniform box the size of the footprint.
        inertia_z = params.mass_kg * (params.footprint_length_m**2 + params.footprint_width_m**2) / 12.0
        # The current limit caps each wheel's pull at limit x k_t x gear / wheel radius.
        force_cap = (
            motor_current_limit_a * motor_torque_constant_nm_per_a * gear_ratio / params.wheel_radius_m
        )
        # Plain float vectors for the compiled kernels (hil.traction), built once.
        self._vehicle_vector = np.array(
            [
                params.mass_kg,
                inertia_z,
                params.track_m,
                params.effective_track_m,
                params.wheelbase_m / 2.0,
                REFERENCE_WHEEL_LOAD_N,
                force_cap,
                drive_time_constant_s,
                yaw_time_constant_s,
            ]
        )
        self._motor_vector = np.array(
            [
                params.wheel_radius_m,
                gear_ratio,
                motor_torque_constant_nm_per_a,
                winding_resistance_ohm,
                params.effective_track_m,
            ]
        )
        self._ground_params = {
            class_id: np.array(
                [
                    c.friction_mu,
                    c.slip_constant,
                    c.rolling_resistance,
                    c.sinkage_resistance,
                    c.sinkage_exponent,
                    c.lateral_resistance,
                ]
            )
            for class_id, c in classes.items()
        }

        self._x, self._y, self._yaw = float(x), float(y), _wrap(float(yaw))
        self._speed = 0.0
        self._yaw_rate = 0.0
        self._accel = 0.0
        # The terrain where the rover stands (class, elevation, tilt), kept from the end of the last step.
        self._under = terrain.ground_at(self._x, self._y, self._yaw)
        self._energy_j = 0.0
        self._rolled_over = False
        # The wheel speeds and the per-wheel outputs the kernels write each step (read into tuples before
        # the step returns), kept rather than allocated every step.
        self._wheels, self._traction, self._slip, self._currents, self._duty = (np.empty(6) for _ in range(5))
        self._half_length = 0.5 * params.footprint_length_m
        self._half_width = 0.5 * params.footprint_width_m
        self._use_obstacles(terrain)
        self._in_contact = self._overlap_here

    # --- state ------------------------------------------------------------------------------------
    @property
    def x(self) -> float:
        return self._x

    @property
    def y(self) -> float:
        return self._y

    @property
    def yaw(self) -> float:
        return self._yaw

    @property
    def speed(self) -> float:
        """Speed along the heading (m/s, along the ground)."""
        return self._speed

    @property
    def yaw_rate(self) -> float:
        return self._yaw_rate

    @property
    def roll(self) -> float:
        return self._under.roll_rad

    @property
    def pitch(self) -> float:
        return self._under.pitch_rad

    @property
    def elevation_m(self) -> float:
        """The true terrain's elevation under the rover (m)."""
        return self._under.elevation_m

    @property
    def ground(self) -> GroundUnder:
        """The true terrain under the rover: class, elevation, roll and pitch at its heading."""
        return self._under

    @property
    def energy_j(self) -> float:
        return self._energy_j

    @property
    def energy_wh(self) -> float:
        return self._energy_j / 3600.0

    @property
    def motor_current_limit_a(self) -> float:
        return self._current_limit_a

    @property
    def rolled_over(self) -> bool:
        return self._rolled_over

    @property
    def terrain(self) -> TerrainMap:
        return self._terrain

    def set_terrain(self, terrain: TerrainMap) -> None:
        """Swap in a new true terrain (e.g. moved obstacles); it must cover the rover's position."""
        if not terrain.contains(self._x, self._y):
            raise DynamicsError(f"new terrain does not cover the rover at ({self._x:.2f}, {self._y:.2f})")
        self._terrain = terrain
        self._under = self._terrain.ground_at(self._x, self._y, self._yaw)
        self._use_obstacles(terrain)

    def warm_up(self) -> None:
        """Step a throwaway copy once, so the compiled kernels every step runs (traction, ground look-up,
        footprint contact) are loaded from numba's cache, or compiled, now: a real-time peer calls this
        before its clock starts. On a cold cache the first step compiles for seconds, and in real time
        that is seconds of silent controllers and a missing IMU, which the rover's failsafes report."""
        copy.deepcopy(self).step(0.01, [0.0] * 6, 24.0)

    # --- stepping ---------------------------------------------------------------------------------
    def step(
        self,
        dt_s: float,
        wheel_surface_speeds: Sequence[float],
        battery_voltage_v: float,
        stalled: Sequence[float] = (),
    ) -> DynamicsStep:
        """Advance ``dt_s`` seconds with the six wheels turning at ``wheel_surface_speeds`` (m/s).

        ``stalled`` (optional, six values in wheel order): -1 / +1 for a seized wheel whose motor is
        commanded backwards / forwards (it stalls at the current limit), 0 for a wheel that turns freely
        or is not commanded."""
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise DynamicsError(f"time step must be a finite number of seconds > 0, got {dt_s}")
        check_wheel_speeds(wheel_surface_speeds)
        wheels = self._wheels
        wheels[:] = wheel_surface_speeds
        if not math.isfinite(battery_voltage_v):
            raise DynamicsError(f"battery voltage must be finite, got {battery_voltage_v}")
        # Nothing seized: () (the world's, without a vesc fault) or six zeros (the VESCs' own, while a
        # scheduled vesc fault has seized no wheel yet), the latter known by one comparison.
        seized = bool(stalled) and stalled != _NONE_SEIZED
        if seized and (len(stalled) != 6 or any(d not in (-1.0, 0.0, 1.0) for d in stalled)):
            raise DynamicsError(f"stalled must be six values of -1, 0 or +1, got {list(stalled)}")

        p = self._params
        class_id, _, roll, pitch = self._under  # where the rover stands: from the end of the last step
        ground = self._classes[class_id]
        if self._rolled_over:
            return self._rolled_over_step(dt_s, wheels, class_id, ground, roll, pitch)

        normals = wheel_normal_forces(p, roll, pitch, self._accel, self._speed * self._yaw_rate)
        ground_params = self._ground_params[class_id]
        traction = self._traction
        accel, yaw_rate = drive_forces(
            wheels,
            normals,
            ground_params,
            self._vehicle_vector,
            self._speed,
            self._yaw_rate,
            pitch,
            dt_s,
            traction,
        )

        speed = self._speed + accel * dt_s
        mean_speed = 0.5 * (self._speed + speed)
        turn = 0.5 * (self._yaw_rate + yaw_rate) * dt_s
        heading = self._yaw + 0.5 * turn
        new_x = self._x + mean_speed * math.cos(pitch) * math.cos(heading) * dt_s
        new_y = self._y + mean_speed * math.cos(pitch) * math.sin(heading) * dt_s
        new_yaw = _wrap(self._yaw + turn)

        # Contact: refuse a move that pushes the footprint further into an obstacle or over the edge. Most
        # steps touch nothing: one test of the rectangle grown by the tolerance settles them.
        kind = self._contact(new_x, new_y, new_yaw, _CONTACT_TOLERANCE_M)
        touching = kind != CLEAR
        overlapping = False
        if touching and self._refused(new_x, new_y, new_yaw):
            if not self._refused(self._x, self._y, new_yaw):
                # The turn alone is free: keep it, and stop the move at the contact.
                new_x, new_y = self._advance_to_contact(new_x, new_y, new_yaw, 0.0)[:2]
            else:
                # The turn is what hits (a corner swinging in): it stops at the contact too.
                new_x, new_y, new_yaw = self._advance_to_contact(new_x, new_y, self._yaw, turn)
                yaw_rate = 0.0
            accel = (0.0 - self._speed) / dt_s
            speed = 0.0
            kind = self._contact(new_x, new_y, new_yaw, _CONTACT_TOLERANCE_M) or kind
        if touching:
            overlapping = self._contact(new_x, new_y, new_yaw, 0.0) != CLEAR
        self._overlap_here = overlapping
        contact_began = touching and not self._in_contact
        self._in_contact = touching

        self._x, self._y, self._yaw = new_x, new_y, new_yaw
        self._speed, self._yaw_rate, self._accel = speed, yaw_rate, accel
        self._under = under = self._terrain.ground_at(new_x, new_y, new_yaw)
        lateral = speed * yaw_rate
        roll_margin, pitch_margin = stability_margins(p, under.roll_rad, under.pitch_rad, lateral)
        rollover_started = min(roll_margin, pitch_margin) < 0.0
        if rollover_started:
            self._rolled_over = True
            self._speed = self._yaw_rate = self._accel = 0.0

        slip, currents, duty = self._slip, self._currents, self._duty
        power = wheel_outputs(
            wheels,
            normals,
            traction,
            speed,
            yaw_rate,
            ground_params,
            self._motor_vector,
            battery_voltage_v,
            slip,
            currents,
            duty,
        )
        if seized and any(stalled):
            power += self._stall(stalled, battery_voltage_v, currents, duty)
        self._energy_j += power * dt_s

        return DynamicsStep(
            x=self._x,
            y=self._y,
            yaw=self._yaw,
            speed_mps=self._speed,
            yaw_rate_rps=self._yaw_rate,
            roll_rad=self._under.roll_rad,
            pitch_rad=self._under.pitch_rad,
            terrain_class=class_id,
            terrain_name=ground.name,
            wheel_speeds_mps=tuple(wheels.tolist()),
            slip=tuple(slip.tolist()),
            normal_forces_n=tuple(normals.tolist()),
            traction_forces_n=tuple(traction.tolist()),
            motor_currents_a=tuple(currents.tolist()),
            duty=tuple(duty.tolist()),
            longitudinal_accel_mps2=accel,
            lateral_accel_mps2=lateral,
            specific_force_body_mps2=self._specific_force(accel, lateral),
            roll_margin_rad=roll_margin,
            pitch_margin_rad=pitch_margin,
            rollover=self._rolled_over,
            rollover_started=rollover_started,
            collided=touching,
            collided_obstacle=contact_began,
            collision_with=_KIND_NAMES[kind] if touching else "",
            energy_wh=self.energy_wh,
            battery_current_a=power / battery_voltage_v if battery_voltage_v > 0.0 else 0.0,
        )

    # --- pieces -----------------------------------------------------------------------------------
    def _stall(
        self, stalled: Sequence[float], battery_voltage_v: float, currents: np.ndarray, duty: np.ndarray
    ) -> float:
        """Seized motors under command: current limit, duty ``I R / V``; returns their power (W)."""
        resistance = float(self._motor_vector[3])
        power = 0.0
        for i, direction in enumerate(stalled):
            if direction == 0.0:
                continue
            current = direction * self._current_limit_a
            currents[i] = current
            duty[i] = (
                max(-1.0, min(1.0, current * resistance / battery_voltage_v))
                if battery_voltage_v > 0
                else 0.0
            )
            power += current * current * resistance
        return power

    def _rolled_over_step(
        self, dt_s: float, wheels: np.ndarray, class_id: int, ground: TerrainClass, roll: float, pitch: float
    ) -> DynamicsStep:
        """On its side the rover goes nowhere; wheels spin in the air with no load, no current."""
        zeros = (0.0,) * 6
        roll_margin, pitch_margin = stability_margins(self._params, roll, pitch)
        return DynamicsStep(
            x=self._x,
            y=self._y,
            yaw=self._yaw,
            speed_mps=0.0,
            yaw_rate_rps=0.0,
            roll_rad=self._under.roll_rad,
            pitch_rad=self._under.pitch_rad,
            terrain_class=class_id,
            terrain_name=ground.name,
            wheel_speeds_mps=tuple(wheels.tolist()),
            slip=zeros,
            normal_forces_n=zeros,
            traction_forces_n=zeros,
            motor_currents_a=zeros,
            duty=zeros,
            longitudinal_accel_mps2=0.0,
            lateral_accel_mps2=0.0,
            specific_force_body_mps2=self._specific_force(0.0, 0.0),
            roll_margin_rad=roll_margin,
            pitch_margin_rad=pitch_margin,
            rollover=True,
            rollover_started=False,
            collided=self._in_contact,
            collided_obstacle=False,
            collision_with="",
            energy_wh=self.energy_wh,
            battery_current_a=0.0,
        )

    def _specific_force(self, accel: float, lateral: float) -> tuple[float, float, float]:
        """Acceleration minus gravity in body axes (x fwd, y left, z up): (0, 0, +g) at rest on the level."""
        roll, pitch = self._under.roll_rad, self._under.pitch_rad
        cos_pitch = math.cos(pitch)
        return (
            accel + G * math.sin(pitch),
            lateral + G * cos_pitch * math.sin(roll),
            G * cos_pitch * math.cos(roll),
        )

    def _use_obstacles(self, terrain: TerrainMap) -> None:
        """Keep the map's obstacle layer and frame for the per-step contact test, and whether the footprint
        overlaps it where the rover stands."""
        self._obstacles = np.ascontiguousarray(terrain.obstacles)
        self._origin_x, self._origin_y = terrain.origin_xy
        self._resolution_m = terrain.resolution_m
        self._overlap_here = self._contact(self._x, self._y, self._yaw, 0.0) != CLEAR

    def _contact(self, x: float, y: float, yaw: float, grow_m: float) -> int:
        """What the footprint at (x, y, yaw), grown by ``grow_m`` on every side, overlaps (CLEAR, OBSTACLE,
        BOUNDARY of ``navigator.footprint``)."""
        return int(
            rectangle_contact(
                self._obstacles, self._resolution_m, self._origin_x, self._origin_y, x, y, yaw,
                self._half_length + grow_m, self._half_width + grow_m,
            )
        )  # fmt: skip

    def _depth(self, x: float, y: float, yaw: float) -> float:
        """How far the footprint reaches into obstacles or past the edge: the least shrink of every side (m)
        that clears it (bisection); 0 when clear, half its width when even its centre line overlaps."""
        if self._contact(x, y, yaw, 0.0) == CLEAR:
            return 0.0
        lo, hi = 0.0, min(self._half_length, self._half_width)
        if self._contact(x, y, yaw, -hi) != CLEAR:
            return hi
        for _ in range(_DEPTH_BISECTIONS):
            mid = 0.5 * (lo + hi)
            if self._contact(x, y, yaw, -mid) != CLEAR:
                lo = mid
            else:
                hi = mid
        return hi

    def _refused(self, x: float, y: float, yaw: float) -> bool:
        """Whether moving to (x, y, yaw) pushes the footprint further in: into an overlap from clear, or
        deeper into one it already overlaps (e.g. an obstacle appeared on it: it may still back out)."""
        if self._contact(x, y, yaw, 0.0) == CLEAR:
            return False
        return not self._overlap_here or self._depth(x, y, yaw) > self._depth(self._x, self._y, self._yaw)

    def _advance_to_contact(
        self, new_x: float, new_y: float, yaw_from: float, turn: float
    ) -> tuple[float, float, float]:
        """The furthest pose along this step's move (position, and the heading ``yaw_from`` + part of
        ``turn``) that keeps the footprint clear (bisection).

        Stopping at the contact rather than where the step began means a rover pushing on an obstacle stays
        in touch with it instead of creeping up to it again and again.
        """
        if self._overlap_here:
            return self._x, self._y, _wrap(yaw_from)  # already overlapping: no move in, stay put
        lo, hi = 0.0, 1.0
        for _ in range(_CONTACT_BISECTIONS):
            mid = 0.5 * (lo + hi)
            x = self._x + mid * (new_x - self._x)
            y = self._y + mid * (new_y - self._y)
            if self._contact(x, y, yaw_from + mid * turn, 0.0) == CLEAR:
                lo = mid
            else:
                hi = mid
        return self._x + lo * (new_x - self._x), self._y + lo * (new_y - self._y), _wrap(yaw_from + lo * turn)


_KIND_NAMES = {CLEAR: "", BOUNDARY: "boundary", OBSTACLE: "obstacle"}
_NONE_SEIZED = (0.0,) * 6  # what SimVescBank.stalled() says while every wheel turns freely


def check_wheel_speeds(speeds: Sequence[float]) -> None:
    """DynamicsError unless ``speeds`` is six finite numbers (m/s, wheel order)."""
    if len(speeds) != 6:
        raise DynamicsError(f"expected 6 wheel speeds (LF LM LR RF RM RR), got {len(speeds)}")
    # A sum is finite only if every term is (an inf or a NaN never sums away), so one test settles the
    # usual case, every physics step; the per-wheel test runs only when the sum is not (or overflowed).
    if not math.isfinite(sum(speeds)) and not all(math.isfinite(speed) for speed in speeds):
        raise DynamicsError(f"wheel speeds must be finite, got {list(speeds)}")


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi
