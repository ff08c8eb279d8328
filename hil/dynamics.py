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
* Sideways sliding: the body has a sideways speed (body y, left). Gravity's cross-slope part
  ``-g cos(pitch) sin(roll)`` and the turn's centripetal need ``v ω`` ask for a sideways force; the wheels
  hold it by Coulomb friction, at most ``sum(sqrt((μ N_i)² − F_i²))``, each wheel's friction circle less
  what its longitudinal pull ``F_i`` uses (``hil.traction.sideways_grip``). Within that the sideways speed
  stays exactly 0; past it the body slides, the friction opposing the sliding until it stops (never
  reversing it). Parked across a slope steeper than ``atan μ`` it slides downhill at ``g (sin φ − μ cos φ)``.
  While it slides, each wheel's part of that friction acts at its axle and turns the body by
  ``sum x_i F_y,i`` (``hil.traction.slide_yaw_moment``: with the rear axle loaded, nose up across a slope,
  the nose swings downhill), and an end wheel's friction is shared between the slide and the turn's scrub
  (``hil.traction.slide_share``). Horizontal displacement is ``v cos(pitch) dt`` along the heading plus the
  sideways speed along the body's y axis.
* Rollover when a stability margin (``navigator.vehicle.tilt_margins``: the tilt of the step's specific
  force, with the body's sideways acceleration, the turn's ``v ω`` and any sliding's change, and its
  acceleration along the heading) goes negative, or when an obstacle stops a slide at the critical sliding
  speed (``navigator.vehicle.critical_sliding_speed``): latched, the rover stays stopped. A body sliding
  sideways is tipped by the friction's pull, not gravity's, so on ground with ``μ`` below
  ``(track / 2) / h_cg`` it slides before it tips.
* Collision when the footprint, the oriented rectangle ``footprint_length_m`` x ``footprint_width_m`` (the
  planner's exact test, ``navigator.footprint.rectangle_contact``), would overlap an obstacle cell or reach
  past the map edge: a move that pushes it further in is refused and the rover stopped at the contact. If
  the turn alone is free it keeps turning (so it can turn in place and back away); if the turn is what hits
  (a corner swinging into a wall), the turn stops at the contact too. Reported once per entry in
  ``DynamicsStep.collided_obstacle``; ``collided`` is true for as long as it touches.
* Motors: no wheel turns faster than its motor can at this step's pack voltage: ``k_t ω_motor + I R <=
  max_duty V`` (back-EMF, the winding's drop with the last step's current, the controller's top duty; the
  speeds given are capped there on their sign, ``hil.motor_voltage``, and the step reports the caps in
  ``DynamicsStep.wheel_speed_limits_mps`` for the simulated VESCs). Where the current limit, not the ground's
  ``mu N``, caps a wheel's force, the wheel turns no further in the force's direction than the speed at
  which the traction curve gives that force over the ground under it (``hil.motor_current``: a climb too
  steep for the motors' torque stalls the rover with its wheels nearly still); the step applies it and
  reports it in ``DynamicsStep.held_speeds_mps``, within which the simulated VESCs keep their motors and
  which they report. Wheel torque ``F r`` -> motor current
  ``F r / (gear k_t)`` (so never above the current limit; its sign is the force's); duty
  ``(k_t ω_motor + I R) / V``; electrical power ``k_t I ω_motor + I² R`` per
  motor, integrated to energy; a generating (braking) motor's is negative, returned to the pack as a
  VESC's regenerative braking does, down to ``-limit x V`` (``regen_current_limit_a``, each controller's
  battery current floor; past it the rest is lost and the braking force kept). Slip: from the
  curve while a wheel pulls below its traction limit, from its surface and ground speeds once it spins or
  slides (or is held at zero pull by the sign of its slip).
* Seized wheels (``stalled``, the simulated VESCs' stuck fault): the wheel is locked (surface speed 0), so
  while the rover moves it skids: full slip, dragging ``μ N`` against its motion over the ground (its lock
  holds it, not its motor: no current limit on that), and its side's other wheels pull that on top of
  their share, slipping more, so the rover slows and turns toward it (``hil.traction``: a wheel turning
  apart from its side). Its motor, commanded to turn, is stalled against the lock: its controller drives
  it at the current limit (signed as the command), duty ``I R / V`` (no back-EMF), and it burns ``I² R``
  from the pack; the drag costs the motor nothing.

Body axes: x forward, y left, z up; pitch positive nose up, roll positive when the right side is lower.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence

import numpy as np

from hil import dynamics_kernel as k
from hil.battery import REGEN_CURRENT_LIMIT_A
from hil.dynamics_kernel import WHEELS, BodyState, DynamicsStep
from hil.traction import released_controls
from hil.vesc_limits import ALL_DRIVEN, DRIVEN
from navigator.footprint import CLEAR
from navigator.ground_kernel import GroundUnder
from navigator.terrain import TerrainMap
from navigator.terrain_classes import REFERENCE_WHEEL_LOAD_N, TERRAIN_CLASSES, TerrainClass
from navigator.vehicle import VehicleParams, stability_margins

# The motor controllers' top duty cycle: VESC firmware's default l_max_duty (mcconf_default.h,
# MCCONF_L_MAX_DUTY 0.95; VESC Tool's "Maximum Duty Cycle"). It caps each wheel's speed (hil.motor_voltage).
DEFAULT_MAX_DUTY = 0.95


class DynamicsError(ValueError):
    """The simulated body was given something it cannot use (bad time step, wheel speeds, start pose)."""


class RoverDynamics:
    """The rover body on the true terrain, stepped with the wheel speeds the simulated motors achieve.

    A step runs as one compiled call (``hil.dynamics_kernel.step_kernel``) on a float vector holding the
    state; the properties read the ``BodyState`` it returns (plain numbers) with the step's record."""

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
        max_duty: float = DEFAULT_MAX_DUTY,
        regen_current_limit_a: float = REGEN_CURRENT_LIMIT_A,
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
        for name, value in (
            ("winding_resistance_ohm", winding_resistance_ohm),
            ("regen_current_limit_a", regen_current_limit_a),
        ):
            if not (math.isfinite(value) and value >= 0.0):
                raise DynamicsError(f"{name} must be a finite number >= 0, got {value}")
        if not 0.0 < max_duty <= 1.0:  # also refuses NaN
            raise DynamicsError(f"max_duty must be in (0, 1], got {max_duty}")
        if not all(math.isfinite(v) for v in (x, y, yaw)) or not terrain.contains(x, y):
            raise DynamicsError(f"start pose ({x}, {y}, yaw {yaw}) must be finite and on the map")
        _check_classes(terrain, classes)
        self._params = params
        self._classes = classes
        self._class_names = {class_id: c.name for class_id, c in classes.items()}
        self._current_limit_a = motor_current_limit_a
        self._body = _body_vector(
            params,
            motor_torque_constant_nm_per_a=motor_torque_constant_nm_per_a,
            gear_ratio=gear_ratio,
            winding_resistance_ohm=winding_resistance_ohm,
            motor_current_limit_a=motor_current_limit_a,
            max_duty=max_duty,
            regen_current_limit_a=regen_current_limit_a,
            drive_time_constant_s=drive_time_constant_s,
            yaw_time_constant_s=yaw_time_constant_s,
        )
        self._ground_table = _ground_table(classes)
        # The controllers' state for the kernel (hil.traction.drive_forces' controls, forces in N): every
        # wheel driven at the motors' force cap, unless a step is given other controls.
        self._newtons_per_amp = motor_torque_constant_nm_per_a * gear_ratio / params.wheel_radius_m
        self._force_cap_n = float(self._body[k.VEHICLE + k.FORCE_CAP])
        self._all_driven = released_controls(self._force_cap_n)
        self._controls = released_controls(self._force_cap_n)
        # Per wheel -1 / 0 / +1 for the kernel: the seized wheels given to this step, or none.
        self._stalled = np.zeros(6)
        self._none_stalled = np.zeros(6)

        self._values = values = np.zeros(k.VALUES_SIZE)
        values[k.X], values[k.Y], values[k.YAW] = float(x), float(y), k.wrap_angle(float(yaw))
        values[k.HELD_FLOORS : k.HELD_FLOORS + 6] = -math.inf  # no wheel held before the first step
        values[k.HELD_CEILINGS : k.HELD_CEILINGS + 6] = math.inf
        self._rolled_over = False
        self._state: BodyState  # the state after the last step (plain numbers; _read_state)
        self._use_terrain(terrain)
        values[k.IN_CONTACT] = values[k.OVERLAP_HERE]
        self._read_state()

    # --- state ------------------------------------------------------------------------------------
    @property
    def x(self) -> float:
        return self._state.x

    @property
    def y(self) -> float:
        return self._state.y

    @property
    def yaw(self) -> float:
        return self._state.yaw

    @property
    def speed(self) -> float:
        """Speed along the heading (m/s, along the ground)."""
        return self._state.speed

    @property
    def lateral_speed(self) -> float:
        """Sideways speed (m/s, body y: left positive); 0.0 unless the body slides."""
        return self._state.lateral_speed

    @property
    def yaw_rate(self) -> float:
        return self._state.yaw_rate

    @property
    def roll(self) -> float:
        return self._state.roll

    @property
    def pitch(self) -> float:
        return self._state.pitch

    @property
    def elevation_m(self) -> float:
        """The true terrain's elevation under the rover (m)."""
        return self._state.elevation

    @property
    def ground(self) -> GroundUnder:
        """The true terrain under the rover: class, elevation, roll and pitch at its heading."""
        state = self._state
        return GroundUnder(state.class_id, state.elevation, state.roll, state.pitch)

    @property
    def energy_j(self) -> float:
        return self._state.energy_j

    @property
    def energy_wh(self) -> float:
        return self._state.energy_j / 3600.0

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
        x, y = self._state.x, self._state.y
        if not terrain.contains(x, y):
            raise DynamicsError(f"new terrain does not cover the rover at ({x:.2f}, {y:.2f})")
        _check_classes(terrain, self._classes)
        self._use_terrain(terrain)
        self._read_state()

    def warm_up(self) -> None:
        """Step a throwaway copy once, so the compiled kernels every step runs (traction, ground look-up,
        footprint contact) are loaded from numba's cache, or compiled, now: a real-time peer calls this
        before its clock starts. On a cold cache the first step compiles for seconds, and in real time
        that is seconds of silent controllers and a missing IMU, which the rover's failsafes report.

        The copy shares the map's layers: a deep copy of a read-only layer is writable, which numba types
        apart, so the kernel compiled for the copy was compiled again on the real body's first step
        (~4 s with a cold cache, on a running peer's clock)."""
        shared = (self._terrain, self._obstacles, self._class_layer, self._surface)
        throwaway = copy.deepcopy(self, memo={id(layer): layer for layer in shared})
        throwaway.step(0.01, [0.0] * 6, 24.0)

    # --- stepping ---------------------------------------------------------------------------------
    def step(
        self,
        dt_s: float,
        wheel_surface_speeds: Sequence[float],
        battery_voltage_v: float,
        stalled: Sequence[float] = (),
        controls: Sequence[float] = (),
    ) -> DynamicsStep:
        """Advance ``dt_s`` seconds with the six wheels turning at ``wheel_surface_speeds`` (m/s), each within
        what its motor can turn at ``battery_voltage_v`` (``hil.motor_voltage``: the step's
        ``wheel_speeds_mps`` are the speeds applied, ``wheel_speed_limits_mps`` the limits).

        ``stalled`` (optional, six values in wheel order): -1 / +1 for a seized wheel whose motor is
        commanded backwards / forwards (it stalls at the current limit), 0 for a wheel that turns freely
        or is not commanded.

        ``controls`` (optional, ``hil.vesc_limits.WheelControls``: twelve values): per wheel the brake
        current (A, >= 0) of a motor its controller has let go of (it rolls with the ground, braked with at
        most that current's force against its turning) or ``DRIVEN``; then per wheel the fraction (0-1) of
        its motor current limit it may use (the battery cut-off). None given: every wheel driven in full."""
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise DynamicsError(f"time step must be a finite number of seconds > 0, got {dt_s}")
        # The usual case settled here without a call, every physics step: six speeds with a finite sum (an
        # inf or a NaN never sums away). Anything else goes to check_wheel_speeds, which names the fault.
        if len(wheel_surface_speeds) != 6 or not math.isfinite(sum(wheel_surface_speeds)):
            check_wheel_speeds(wheel_surface_speeds)
        values = self._values
        values[WHEELS : WHEELS + 6] = wheel_surface_speeds
        if not math.isfinite(battery_voltage_v):
            raise DynamicsError(f"battery voltage must be finite, got {battery_voltage_v}")
        # Nothing seized: () (the world's, without a vesc fault) or six zeros (the VESCs' own, while a
        # scheduled vesc fault has seized no wheel yet), the latter known by one comparison.
        seized = bool(stalled) and stalled != _NONE_SEIZED
        if seized and (len(stalled) != 6 or any(d not in (-1.0, 0.0, 1.0) for d in stalled)):
            raise DynamicsError(f"stalled must be six values of -1, 0 or +1, got {list(stalled)}")

        class_id = self._state.class_id  # where the rover stands: from the end of the last step
        terrain_name = self._class_names[class_id]  # every class on the map has one (_check_classes)
        if self._rolled_over:
            return self._rolled_over_step(class_id, terrain_name)
        if seized:
            self._stalled[:] = stalled
        wheel_controls = self._all_driven
        if controls and controls is not ALL_DRIVEN and controls != ALL_DRIVEN:
            wheel_controls = self._controls_in_newtons(controls)
        # The kernel hands back the state and the step's record as plain numbers and tuples it boxes itself.
        status, state_fields, fields = k.step_kernel(
            values, self._body, self._ground_table, self._stalled if seized else self._none_stalled,
            wheel_controls, self._obstacles, self._class_layer, self._surface, dt_s, battery_voltage_v,
        )  # fmt: skip
        self._state = state = BodyState._make(state_fields)
        if status == k.OFF_MAP:
            self._terrain.ground_at(state.x, state.y, state.yaw)  # raises the map's error, naming the point
        step = DynamicsStep._make((*fields, terrain_name))
        if step.rollover_started:
            self._rolled_over = True
        return step

    # --- pieces -----------------------------------------------------------------------------------
    def _controls_in_newtons(self, controls: Sequence[float]) -> np.ndarray:
        """The controllers' state (A, fractions: ``step``'s ``controls``) as the kernel's forces (N), in
        ``self._controls``; DynamicsError naming anything that cannot be."""
        if len(controls) != 12:
            raise DynamicsError(f"controls must be 12 values (brakes, then fractions), got {len(controls)}")
        brakes, fractions = controls[:6], controls[6:]
        if not all(b == DRIVEN or (math.isfinite(b) and b >= 0.0) for b in brakes):
            raise DynamicsError(f"controls' brake currents must be >= 0 A or DRIVEN, got {list(brakes)}")
        if not all(0.0 <= f <= 1.0 for f in fractions):  # also refuses NaN
            raise DynamicsError(f"controls' current limit fractions must be in [0, 1], got {list(fractions)}")
        out = self._controls
        for i, (brake, fraction) in enumerate(zip(brakes, fractions, strict=True)):
            out[i] = brake * self._newtons_per_amp if brake != DRIVEN else -1.0
            out[6 + i] = fraction * self._force_cap_n
        return out

    def _read_state(self) -> None:
        """Keep the state in the kernel's vector for the properties (after a change made outside a step)."""
        self._state = BodyState._make(k.state(self._values))

    def _rolled_over_step(self, class_id: int, terrain_name: str) -> DynamicsStep:
        """On its side the rover goes nowhere; wheels spin in the air with no load, no current."""
        zeros = (0.0,) * 6
        values = self._values
        state = self._state
        roll_margin, pitch_margin = stability_margins(self._params, state.roll, state.pitch)
        values[k.STEP_ACCEL] = 0.0
        k.specific_force(values, 0.0)
        v = values.tolist()
        return DynamicsStep(
            x=state.x,
            y=state.y,
            yaw=state.yaw,
            speed_mps=0.0,
            lateral_speed_mps=0.0,
            yaw_rate_rps=0.0,
            roll_rad=state.roll,
            pitch_rad=state.pitch,
            terrain_class=class_id,
            terrain_name=terrain_name,
            wheel_speeds_mps=tuple(v[k.WHEELS : k.WHEELS + 6]),
            slip=zeros,
            normal_forces_n=zeros,
            traction_forces_n=zeros,
            motor_currents_a=zeros,
            duty=zeros,
            longitudinal_accel_mps2=0.0,
            lateral_accel_mps2=0.0,
            specific_force_body_mps2=(v[k.FORCE_X], v[k.FORCE_Y], v[k.FORCE_Z]),
            roll_margin_rad=roll_margin,
            pitch_margin_rad=pitch_margin,
            rollover=True,
            rollover_started=False,
            collided=v[k.IN_CONTACT] != 0.0,
            collided_obstacle=False,
            collision_with="",
            energy_wh=self.energy_wh,
            battery_current_a=0.0,
            motor_input_current_a=0.0,
            # The last step's: a rover on its side is stepped no further (its wheels spin in the air).
            wheel_speed_limits_mps=tuple(v[k.SPEED_LIMITS : k.SPEED_LIMITS + 6]),
            # On its side no wheel pulls: no current limit holds one.
            held_speeds_mps=((-math.inf,) * 6, (math.inf,) * 6),
        )

    def _use_terrain(self, terrain: TerrainMap) -> None:
        """Keep the map's layers and frame for the kernel, the terrain under the rover, and whether the
        footprint overlaps an obstacle where it stands."""
        values = self._values
        x, y, yaw = values[k.X], values[k.Y], values[k.YAW]
        self._terrain = terrain
        self._obstacles = np.ascontiguousarray(terrain.obstacles)
        self._class_layer = terrain.terrain_class
        # One stacked copy of the float layers: one kernel argument instead of three (dynamics_kernel).
        surface = np.empty((3, *terrain.elevation_m.shape))
        surface[k.ELEVATION_LAYER] = terrain.elevation_m
        surface[k.GRAD_X_LAYER], surface[k.GRAD_Y_LAYER] = terrain.slope_gradient()
        self._surface = surface
        values[k.ORIGIN_X], values[k.ORIGIN_Y] = terrain.origin_xy
        values[k.RESOLUTION] = terrain.resolution_m
        under = terrain.ground_at(x, y, yaw)
        values[k.CLASS], values[k.ELEVATION], values[k.ROLL], values[k.PITCH] = under
        grid = (self._obstacles, terrain.resolution_m, terrain.origin_xy[0], terrain.origin_xy[1])
        overlapping = k.contact_kind(grid, self._body, x, y, yaw, 0.0) != CLEAR
        values[k.OVERLAP_HERE] = 1.0 if overlapping else 0.0


def _check_classes(terrain: TerrainMap, classes: dict[int, TerrainClass]) -> None:
    """DynamicsError unless every class on the map has an entry in ``classes`` (the kernel's class table is
    indexed by the class id under the rover, unchecked)."""
    missing = sorted(set(np.unique(terrain.terrain_class).tolist()) - set(classes))
    if missing:
        raise DynamicsError(f"terrain classes {missing} on the map have no entry in the class table")


def _body_vector(
    params: VehicleParams,
    *,
    motor_torque_constant_nm_per_a: float,
    gear_ratio: float,
    winding_resistance_ohm: float,
    motor_current_limit_a: float,
    max_duty: float,
    regen_current_limit_a: float,
    drive_time_constant_s: float,
    yaw_time_constant_s: float,
) -> np.ndarray:
    """The vehicle's and motors' constants as the kernel reads them (``hil.dynamics_kernel``'s ``body``)."""
    body = np.empty(k.BODY_SIZE)
    # Yaw inertia of a uniform box the size of the footprint.
    inertia_z = params.mass_kg * (params.footprint_length_m**2 + params.footprint_width_m**2) / 12.0
    # The current limit caps each wheel's pull at limit x k_t x gear / wheel radius.
    force_cap = motor_current_limit_a * motor_torque_constant_nm_per_a * gear_ratio / params.wheel_radius_m
    body[k.VEHICLE : k.MOTOR] = (
        params.mass_kg,
        inertia_z,
        params.track_m,
        params.effective_track_m,
        params.wheelbase_m / 2.0,
        REFERENCE_WHEEL_LOAD_N,
        force_cap,
        drive_time_constant_s,
        yaw_time_constant_s,
    )
    body[k.MOTOR : k.MOTOR_END] = (
        params.wheel_radius_m,
        gear_ratio,
        motor_torque_constant_nm_per_a,
        winding_resistance_ohm,
        params.effective_track_m,
        regen_current_limit_a,
    )
    body[k.CG_HEIGHT] = params.cg_height_m
    body[k.TIP_ROLL], body[k.TIP_PITCH] = params.tip_roll_rad, params.tip_pitch_rad
    body[k.CURRENT_LIMIT] = motor_current_limit_a
    body[k.MAX_DUTY] = max_duty
    body[k.HALF_LENGTH] = 0.5 * params.footprint_length_m
    body[k.HALF_WIDTH] = 0.5 * params.footprint_width_m
    return body


def _ground_table(classes: dict[int, TerrainClass]) -> np.ndarray:
    """Row ``c``: class ``c``'s traction parameters in ``hil.traction.drive_forces``'s order (NaN for ids
    not in the table: the constructor checked that the map has none)."""
    table = np.full((max(classes) + 1, 6), math.nan)
    for class_id, c in classes.items():
        table[class_id] = (
            c.friction_mu,
            c.slip_constant,
            c.rolling_resistance,
            c.sinkage_resistance,
            c.sinkage_exponent,
            c.lateral_resistance,
        )
    return table


_NONE_SEIZED = (0.0,) * 6  # what SimVescBank.stalled() says while every wheel turns freely


def check_wheel_speeds(speeds: Sequence[float]) -> None:
    """DynamicsError unless ``speeds`` is six finite numbers (m/s, wheel order)."""
    if len(speeds) != 6:
        raise DynamicsError(f"expected 6 wheel speeds (LF LM LR RF RM RR), got {len(speeds)}")
    # A sum is finite only if every term is (an inf or a NaN never sums away), so one test settles the
    # usual case, every physics step; the per-wheel test runs only when the sum is not (or overflowed).
    if not math.isfinite(sum(speeds)) and not all(math.isfinite(speed) for speed in speeds):
        raise DynamicsError(f"wheel speeds must be finite, got {list(speeds)}")
