"""One physics step of ``hil.dynamics.RoverDynamics`` as one compiled call.

The step's model is described in ``hil.dynamics``; this module holds its arithmetic. Every physics tick
used to make about a dozen Python-level calls (normal forces, the traction kernels, the footprint contact
test, the terrain look-up, the stability margins, the motor outputs), each with its own dispatch and
boxing; here they run in one numba kernel on preallocated arrays, which returns the body's state and the
step's record (``BodyState``, ``DynamicsStep``) as plain numbers and tuples.

The floats are the ones the Python form gave, bit for bit (the recorded trials' digests pin them): numba
without ``fastmath`` uses the same IEEE operations and the same libm calls, and every expression keeps the
Python form's operation order.

The kernel reads and writes one float vector, ``values``, laid out by the index constants below: the
body's state (kept from step to step), the wheel speeds given, what the step produced, and the map's frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from hil import motor_current, motor_voltage, traction
from hil.motor_current import hold_at_current_limit, rolling_speeds
from hil.motor_voltage import limit_to_voltage
from hil.traction import (
    MU,
    drive_forces,
    roll_released,
    sideways_grip,
    sideways_speed,
    slide_yaw_moment,
    wheel_outputs,
)
from navigator import footprint, ground_kernel, vehicle
from navigator.footprint import BOUNDARY, CLEAR, OBSTACLE, rectangle_contact
from navigator.ground_kernel import ground_at_kernel
from navigator.kernel_cache import sources_fingerprint
from navigator.vehicle import G, critical_sliding_speed_kernel, normal_forces_into, tilt_margins_kernel

Array = NDArray[np.float64]
# A map's obstacle layer and frame (resolution m, origin x and y m), as rectangle_contact takes them.
Grid = tuple[NDArray[np.bool_], float, float, float]

# Within this distance of an obstacle the footprint counts as touching it.
CONTACT_TOLERANCE_M = 1e-3
_CONTACT_BISECTIONS = 16
# Resolution of how deep an overlapping footprint is: 2^-12 of its half width, ~0.1 mm.
_DEPTH_BISECTIONS = 12

# --- ``values``: the state, kept between steps ---
X, Y, YAW, SPEED, YAW_RATE, ACCEL, ENERGY_J = 0, 1, 2, 3, 4, 5, 6
# The terrain under the rover (class id, elevation m, roll and pitch rad at its heading).
CLASS, ELEVATION, ROLL, PITCH = 7, 8, 9, 10
OVERLAP_HERE, IN_CONTACT = 11, 12  # 1.0 / 0.0: the footprint overlaps where it stands; it touches
# --- what one step produced ---
STEP_ACCEL, LATERAL, ROLL_MARGIN, PITCH_MARGIN = 13, 14, 15, 16  # accel before a rollover zeroes the state
ROLLOVER_STARTED, TOUCHING, CONTACT_BEGAN, CONTACT_KIND = 17, 18, 19, 20
POWER_W, INPUT_CURRENT_A = 21, 22
FORCE_X, FORCE_Y, FORCE_Z = 23, 24, 25  # specific force in body axes
# --- per wheel, six each in wheel order: the speeds given (an input, capped in place at the motors' voltage
# limit), then the step's outputs ---
WHEELS, SLIP, NORMALS, TRACTION, CURRENTS, DUTY = 26, 32, 38, 44, 50, 56
# --- the map's frame (TerrainMap.origin_xy, resolution_m), set with the terrain ---
ORIGIN_X, ORIGIN_Y, RESOLUTION = 62, 63, 64
# --- more of the state: the body's sideways speed (m/s, y left)
LATERAL_SPEED = 65
# --- per wheel, six: the most surface speed its motor could turn at this step (m/s, >= 0; motor_voltage)
SPEED_LIMITS = 66
# --- per wheel, six each: the slowest and the fastest its motor's current limit let it turn at this step
# (m/s, signed; -inf / +inf where it did not hold it: motor_current)
HELD_FLOORS, HELD_CEILINGS = 72, 78
# --- per wheel, six: the speed it turns at, for its rolling resistance: as given, within the last step's
# held speeds (motor_current.rolling_speeds)
ROLLING = 84
VALUES_SIZE = 90

# --- ``surface``: the map's float layers stacked, one (rows, cols) plane each ---
ELEVATION_LAYER, GRAD_X_LAYER, GRAD_Y_LAYER = 0, 1, 2

# --- ``body``: the vehicle and motor constants, built once ---
# drive_forces' ``vehicle`` vector (its docstring has the layout), then wheel_outputs' ``motor`` vector.
VEHICLE, MOTOR, MOTOR_END = 0, 9, 15
MASS, YAW_INERTIA, TRACK, EFFECTIVE_TRACK, HALF_WHEELBASE = 0, 1, 2, 3, 4
FORCE_CAP = 6  # the most a wheel's motor pulls with at its current limit (N)
RESISTANCE, REGEN_LIMIT = 12, 14  # the motor vector's winding resistance; each controller's regen limit (A)
CG_HEIGHT, TIP_ROLL, TIP_PITCH, CURRENT_LIMIT, HALF_LENGTH, HALF_WIDTH = 15, 16, 17, 18, 19, 20
MAX_DUTY = 21  # the controllers' top duty (VESC l_max_duty): the voltage limit on wheel speed
BODY_SIZE = 22

# How ``step_kernel``'s step ended (the first of the three things it returns).
STEPPED, OFF_MAP = 0, 1


class BodyState(NamedTuple):
    """The body's state in ``values`` as plain numbers: ``state``'s fields, in order (``step_kernel``
    returns them too)."""

    x: float
    y: float
    yaw: float
    speed: float  # m/s along the heading
    lateral_speed: float  # m/s sideways (y left): 0.0 unless the body slides
    yaw_rate: float
    energy_j: float  # electrical energy used by the motors so far
    class_id: int  # the terrain under the rover: its class, elevation, roll and pitch at its heading
    elevation: float
    roll: float
    pitch: float


class DynamicsStep(NamedTuple):
    """What one step produced. Per-wheel tuples are in wheel order (LF LM LR RF RM RR).

    Its fields but the last come from the compiled step itself (``step_kernel``, in this order: numba boxes
    the floats, bools and tuples straight from the vector), so Python neither reads the vector back nor
    assembles 29 fields every physics step; it adds the terrain's name and makes the tuple this class with
    ``_make``. (numba could box this class itself, but its boxing looks the class up anew every call
    through a Python function: more than it saves.) A NamedTuple, not a frozen dataclass: one is built
    every physics step."""

    x: float
    y: float
    yaw: float
    speed_mps: float
    lateral_speed_mps: float  # sideways (y left): 0.0 unless the body slides
    yaw_rate_rps: float
    roll_rad: float
    pitch_rad: float
    terrain_class: int
    # Wheel surface speeds applied this step: the ones given, each within its motor's voltage limit, and
    # within what its current-limited torque turns it at (held_speeds_mps).
    wheel_speeds_mps: tuple[float, ...]
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
    # What the six motors draw from the pack: the sum of each one's current x duty that is positive (a
    # braking motor generates, and with no regeneration gives nothing back, nor draws).
    motor_input_current_a: float
    # The most surface speed each wheel's motor could turn at this step, in the direction it was given (m/s,
    # >= 0): duty max x the pack's voltage against back-EMF and the winding's drop (hil.motor_voltage).
    wheel_speed_limits_mps: tuple[float, ...]
    # (floors, ceilings): the slowest and the fastest each wheel turns at because its motor's current limit,
    # not the ground, caps its force (m/s, signed; -inf / +inf where it does not): the held speed on the
    # side the force pushes to, what the wheel turned at this step if given more (hil.motor_current).
    held_speeds_mps: tuple[tuple[float, ...], tuple[float, ...]]
    # Last: the one field the compiled step leaves to Python (a str passed into a numba call costs about
    # as much as the rest of the call's arguments together).
    terrain_name: str


StateFields = tuple[float, float, float, float, float, float, float, int, float, float, float]


@numba.njit(cache=True)
def state(values: Array) -> StateFields:
    """The body's state in ``values``: ``BodyState``'s fields."""
    return (
        values[X], values[Y], values[YAW], values[SPEED], values[LATERAL_SPEED], values[YAW_RATE],
        values[ENERGY_J],
        int(values[CLASS]), values[ELEVATION], values[ROLL], values[PITCH],
    )  # fmt: skip


@numba.njit(cache=True)
def _six(values: Array, start: int) -> tuple[float, float, float, float, float, float]:
    """The six per-wheel values from ``start`` on, as a tuple."""
    v = values
    return (v[start], v[start + 1], v[start + 2], v[start + 3], v[start + 4], v[start + 5])


# Not cached on their own (_kind_name, _record, _depth, _refused, _advance_to_contact): they compile in
# navigator.footprint's code or constants and run only inside step_kernel, whose cache key carries
# footprint's fingerprint. A cached copy of their own would be checked against this file only, and could
# bring stale footprint code into a freshly compiled step_kernel.
@numba.njit
def _kind_name(kind: float) -> str:
    """What a touching footprint touches (``DynamicsStep.collision_with``), from ``values[CONTACT_KIND]``."""
    if kind == BOUNDARY:
        return "boundary"
    if kind == OBSTACLE:
        return "obstacle"
    return ""


@numba.njit  # not cached on its own: see _kind_name
def _record(values: Array, terrain_class: int, battery_voltage: float) -> tuple[Any, ...]:
    """The fields of the ``DynamicsStep`` of the step just taken on ``values``, in order but the last
    (``terrain_name``), by a body that had not rolled over before it (so ``rollover`` is whether it tipped
    over now); ``terrain_class``: the class it stood on when the step began."""
    touching = values[TOUCHING] != 0.0
    rollover_started = values[ROLLOVER_STARTED] != 0.0
    power = values[POWER_W]
    return (
        values[X],
        values[Y],
        values[YAW],
        values[SPEED],  # speed_mps
        values[LATERAL_SPEED],  # lateral_speed_mps
        values[YAW_RATE],  # yaw_rate_rps
        values[ROLL],  # roll_rad
        values[PITCH],  # pitch_rad
        terrain_class,
        _six(values, WHEELS),  # wheel_speeds_mps
        _six(values, SLIP),
        _six(values, NORMALS),  # normal_forces_n
        _six(values, TRACTION),  # traction_forces_n
        _six(values, CURRENTS),  # motor_currents_a
        _six(values, DUTY),
        values[STEP_ACCEL],  # longitudinal_accel_mps2
        values[LATERAL],  # lateral_accel_mps2
        (values[FORCE_X], values[FORCE_Y], values[FORCE_Z]),  # specific_force_body_mps2
        values[ROLL_MARGIN],
        values[PITCH_MARGIN],
        rollover_started,  # rollover: latched from here on by RoverDynamics
        rollover_started,
        touching,  # collided
        values[CONTACT_BEGAN] != 0.0,  # collided_obstacle
        _kind_name(values[CONTACT_KIND]) if touching else "",  # collision_with
        values[ENERGY_J] / 3600.0,  # energy_wh
        power / battery_voltage if battery_voltage > 0.0 else 0.0,  # battery_current_a
        values[INPUT_CURRENT_A],  # motor_input_current_a
        _six(values, SPEED_LIMITS),  # wheel_speed_limits_mps
        (_six(values, HELD_FLOORS), _six(values, HELD_CEILINGS)),  # held_speeds_mps
    )


@numba.njit(cache=True)
def wrap_angle(angle: float) -> float:
    """Into [-pi, pi) (Python's float modulo, which numba's ``%`` follows)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _compile_contact_kind(fingerprint: str) -> Callable[[Grid, Array, float, float, float, float], int]:
    """``contact_kind``, with ``fingerprint`` (of ``navigator.footprint``, whose contact test it compiles
    in) in numba's cache key: see ``navigator.kernel_cache``."""

    @numba.njit(cache=True)
    def contact_kind(grid: Grid, body: Array, x: float, y: float, yaw: float, grow_m: float) -> int:
        """What the footprint at (x, y, yaw), grown by ``grow_m`` on every side, overlaps (CLEAR, OBSTACLE,
        BOUNDARY of ``navigator.footprint``)."""
        _ = fingerprint  # in the closure, so in numba's cache key (see _compile_contact_kind)
        obstacles, res, ox, oy = grid
        return rectangle_contact(
            obstacles, res, ox, oy, x, y, yaw, body[HALF_LENGTH] + grow_m, body[HALF_WIDTH] + grow_m
        )

    return contact_kind


contact_kind = _compile_contact_kind(sources_fingerprint(footprint))


@numba.njit  # not cached on its own: see _kind_name
def _depth(grid: Grid, body: Array, x: float, y: float, yaw: float) -> float:
    """How far the footprint reaches into obstacles or past the edge: the least shrink of every side (m)
    that clears it (bisection); 0 when clear, half its width when even its centre line overlaps."""
    if contact_kind(grid, body, x, y, yaw, 0.0) == CLEAR:
        return 0.0
    lo, hi = 0.0, min(body[HALF_LENGTH], body[HALF_WIDTH])
    if contact_kind(grid, body, x, y, yaw, -hi) != CLEAR:
        return hi
    for _ in range(_DEPTH_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if contact_kind(grid, body, x, y, yaw, -mid) != CLEAR:
            lo = mid
        else:
            hi = mid
    return hi


@numba.njit  # not cached on its own: see _kind_name
def _refused(grid: Grid, body: Array, values: Array, x: float, y: float, yaw: float) -> bool:
    """Whether moving to (x, y, yaw) pushes the footprint further in: into an overlap from clear, or
    deeper into one it already overlaps (e.g. an obstacle appeared on it: it may still back out)."""
    if contact_kind(grid, body, x, y, yaw, 0.0) == CLEAR:
        return False
    if values[OVERLAP_HERE] == 0.0:
        return True
    here = _depth(grid, body, values[X], values[Y], values[YAW])
    return _depth(grid, body, x, y, yaw) > here


@numba.njit  # not cached on its own: see _kind_name
def _advance_to_contact(
    grid: Grid, body: Array, values: Array, new_x: float, new_y: float, yaw_from: float, turn: float
) -> tuple[float, float, float]:
    """The furthest pose along this step's move (position, and the heading ``yaw_from`` + part of
    ``turn``) that keeps the footprint clear (bisection).

    Stopping at the contact rather than where the step began means a rover pushing on an obstacle stays
    in touch with it instead of creeping up to it again and again.
    """
    x0, y0 = values[X], values[Y]
    if values[OVERLAP_HERE] != 0.0:
        return x0, y0, wrap_angle(yaw_from)  # already overlapping: no move in, stay put
    lo, hi = 0.0, 1.0
    for _ in range(_CONTACT_BISECTIONS):
        mid = 0.5 * (lo + hi)
        x = x0 + mid * (new_x - x0)
        y = y0 + mid * (new_y - y0)
        if contact_kind(grid, body, x, y, yaw_from + mid * turn, 0.0) == CLEAR:
            lo = mid
        else:
            hi = mid
    return x0 + lo * (new_x - x0), y0 + lo * (new_y - y0), wrap_angle(yaw_from + lo * turn)


@numba.njit(cache=True)
def _stall(stalled: Array, body: Array, battery_voltage: float, currents: Array, duty: Array) -> float:
    """Seized motors under command: current limit, duty ``I R / V``; returns their power (W)."""
    resistance = body[RESISTANCE]
    power = 0.0
    for i in range(6):
        direction = stalled[i]
        if direction == 0.0:
            continue
        current = direction * body[CURRENT_LIMIT]
        currents[i] = current
        duty[i] = max(-1.0, min(1.0, current * resistance / battery_voltage)) if battery_voltage > 0 else 0.0
        power += current * current * resistance
    return power


def _compile_step_kernel(fingerprint: str) -> Callable[..., tuple[int, StateFields, tuple[Any, ...]]]:
    """``step_kernel``, with ``fingerprint`` (of the modules whose compiled functions it calls: the
    traction laws, the footprint contact test, the terrain look-up, the load balance) in numba's cache
    key: see ``navigator.kernel_cache``."""

    @numba.njit(cache=True)
    def step_kernel(
        values: Array,
        body: Array,
        ground_table: Array,
        stalled: Array,
        controls: Array,
        obstacles: NDArray[np.bool_],
        classes: NDArray[np.uint8],
        surface: Array,
        dt: float,
        battery_voltage: float,
    ) -> tuple[int, StateFields, tuple[Any, ...]]:
        """One step of ``dt`` s of the rover (not rolled over) on ``values``'s state with its wheel speeds.

        ``ground_table`` row ``c``: class ``c``'s traction parameters (``hil.traction.drive_forces``'s
        ``ground``). ``stalled``: per wheel -1 / 0 / +1 (``RoverDynamics.step``). ``controls``: what
        each wheel's controller does (``hil.traction.drive_forces``' ``controls``: released with a brake
        force, or driven within a force cap). The terrain's obstacle and
        class layers as ``TerrainMap``'s, its float layers stacked in ``surface`` (``ELEVATION_LAYER``, ...),
        its frame in ``values`` (``ORIGIN_X``, ...): few arguments, as each costs the call's dispatch time.

        Returns STEPPED, or OFF_MAP when the new position is off the map (the state then holds the new
        pose, and the terrain under it is the old one; the step is not one to use); the body's state
        after the step (``BodyState``'s fields); and the step's ``DynamicsStep`` fields but the last.
        """
        _ = fingerprint  # in the closure, so in numba's cache key (see _compile_step_kernel)
        terrain_class = int(values[CLASS])
        ox, oy, res = values[ORIGIN_X], values[ORIGIN_Y], values[RESOLUTION]
        grid = (obstacles, res, ox, oy)
        x, y, yaw = values[X], values[Y], values[YAW]
        speed0, yaw_rate0 = values[SPEED], values[YAW_RATE]
        roll, pitch = values[ROLL], values[PITCH]  # where the rover stands: from the end of the last step
        wheels = values[WHEELS : WHEELS + 6]
        normals, traction = values[NORMALS : NORMALS + 6], values[TRACTION : TRACTION + 6]
        slip, currents, duty = (
            values[SLIP : SLIP + 6],
            values[CURRENTS : CURRENTS + 6],
            values[DUTY : DUTY + 6],
        )
        ground = ground_table[int(values[CLASS])]
        lateral_speed0 = values[LATERAL_SPEED]
        # No wheel turns faster than its motor can at this pack voltage (back-EMF at the top duty), with the
        # current its force drew a step ago (``currents`` still holds the last step's): motor_voltage.
        limit_to_voltage(
            wheels, currents, body[MOTOR:MOTOR_END], battery_voltage, body[MAX_DUTY],
            values[SPEED_LIMITS : SPEED_LIMITS + 6],
        )  # fmt: skip

        # The body's sideways acceleration at the end of the last step (LATERAL: the turn's v w and any
        # slide's change) loads the downhill / outer wheels.
        normal_forces_into(
            body[MASS], body[CG_HEIGHT], body[TRACK], body[HALF_WHEELBASE], roll, pitch, values[ACCEL],
            values[LATERAL], normals,
        )  # fmt: skip
        # A wheel its motor's current limit held slower at the last step turns at that speed, and meets its
        # rolling resistance there (its controller still asks for the speed given: the pull's target).
        rolling = values[ROLLING : ROLLING + 6]
        rolling_speeds(
            wheels, values[HELD_FLOORS : HELD_FLOORS + 6], values[HELD_CEILINGS : HELD_CEILINGS + 6], rolling
        )
        accel, yaw_rate = drive_forces(
            wheels, normals, ground, body[VEHICLE:MOTOR], speed0, yaw_rate0, pitch, dt, stalled, traction,
            lateral_speed0, controls, rolling,
        )  # fmt: skip

        speed = speed0 + accel * dt
        if lateral_speed0 != 0.0:
            # In the turning body's axes a sliding velocity turns into the heading's (dv_x/dt = a_x + v_y w;
            # dv_y/dt = a_y - v_x w below): it keeps its direction over the ground, and the wheels take the
            # part now along the heading on the next steps, as any difference from the target speed.
            speed += lateral_speed0 * yaw_rate0 * dt
        # Sideways: gravity's cross-slope part (roll positive lowers the right side, so it pulls to -y) less
        # the turn's centripetal need, against the wheels' sideways friction (sideways_grip, N, per kg).
        demand_mps2 = -G * math.cos(pitch) * math.sin(roll) - speed * yaw_rate
        grip_n = sideways_grip(
            normals, traction, ground[MU], wheels, speed, yaw_rate, body[EFFECTIVE_TRACK], lateral_speed0,
            body[HALF_WHEELBASE],
        )  # fmt: skip
        grip_mps2 = grip_n / body[MASS]
        lateral_speed = sideways_speed(lateral_speed0, demand_mps2, grip_mps2, dt)
        if lateral_speed0 != 0.0 or lateral_speed != 0.0:
            # Sliding: the friction the Coulomb step applied (sideways_speed's, N) acts at each wheel's
            # axle, and with unequal axle loads turns the body (only while sliding: a body held across a
            # slope keeps its yaw rate's floats, as its static friction's distribution is not known).
            free = lateral_speed0 + demand_mps2 * dt
            friction_n = body[MASS] * (lateral_speed - free) / dt
            yaw_rate += (
                slide_yaw_moment(
                    normals, traction, ground[MU], wheels, speed, yaw_rate, body[EFFECTIVE_TRACK],
                    lateral_speed0, body[HALF_WHEELBASE], friction_n,
                )
                * dt
                / body[YAW_INERTIA]
            )  # fmt: skip
        mean_speed = 0.5 * (speed0 + speed)
        turn = 0.5 * (yaw_rate0 + yaw_rate) * dt
        heading = yaw + 0.5 * turn
        new_x = x + mean_speed * math.cos(pitch) * math.cos(heading) * dt
        new_y = y + mean_speed * math.cos(pitch) * math.sin(heading) * dt
        mean_lateral = 0.5 * (lateral_speed0 + lateral_speed)
        if mean_lateral != 0.0:
            # The body's y axis over the ground: (-sin(roll) sin(pitch), cos(roll)) in the heading's frame.
            across = -math.sin(roll) * math.sin(pitch)
            along_left = math.cos(roll)
            new_x += mean_lateral * (across * math.cos(heading) - along_left * math.sin(heading)) * dt
            new_y += mean_lateral * (across * math.sin(heading) + along_left * math.cos(heading)) * dt
        new_yaw = wrap_angle(yaw + turn)

        # Contact: refuse a move that pushes the footprint further into an obstacle or over the edge. Most
        # steps touch nothing: one test of the rectangle grown by the tolerance settles them.
        kind = contact_kind(grid, body, new_x, new_y, new_yaw, CONTACT_TOLERANCE_M)
        touching = kind != CLEAR
        overlapping = False
        refused = touching and _refused(grid, body, values, new_x, new_y, new_yaw)
        stopped_slide = 0.0  # the sideways speed a contact stopped this step (m/s, y left)
        stopped_drive = 0.0  # the speed along the heading a contact stopped this step (m/s)
        if refused:
            if not _refused(grid, body, values, x, y, new_yaw):
                # The turn alone is free: keep it, and stop the move at the contact.
                new_x, new_y, _ = _advance_to_contact(grid, body, values, new_x, new_y, new_yaw, 0.0)
            else:
                # The turn is what hits (a corner swinging in): it stops at the contact too.
                new_x, new_y, new_yaw = _advance_to_contact(grid, body, values, new_x, new_y, yaw, turn)
                yaw_rate = 0.0
            accel = (0.0 - speed0) / dt
            stopped_drive = speed
            speed = 0.0
            stopped_slide = lateral_speed
            lateral_speed = 0.0
            again = contact_kind(grid, body, new_x, new_y, new_yaw, CONTACT_TOLERANCE_M)
            kind = again if again != CLEAR else kind
        if touching:
            overlapping = contact_kind(grid, body, new_x, new_y, new_yaw, 0.0) != CLEAR
        values[OVERLAP_HERE] = 1.0 if overlapping else 0.0
        values[CONTACT_BEGAN] = 1.0 if touching and values[IN_CONTACT] == 0.0 else 0.0
        values[IN_CONTACT] = values[TOUCHING] = 1.0 if touching else 0.0
        values[CONTACT_KIND] = kind

        values[X], values[Y], values[YAW] = new_x, new_y, new_yaw
        values[SPEED], values[YAW_RATE] = speed, yaw_rate
        # A refused move's stop is an impact, not a sustained deceleration: as v / dt it would load the next
        # step's front wheels by an amount set by the step length, so the loads see 0. The step's record
        # keeps it (the IMU's specific force x: the mean deceleration over the step the contact stopped).
        values[ACCEL] = 0.0 if refused else accel
        values[STEP_ACCEL] = accel
        # A slide stopped by a contact is an impact, not a sustained sideways acceleration: as v / dt it
        # would load the wheels and tip the margin by an amount set by the step length. The impact's own
        # test is the trip below.
        slide_accel = 0.0 if refused else (lateral_speed - lateral_speed0) / dt
        values[LATERAL_SPEED] = lateral_speed
        class_id, height, new_roll, new_pitch = ground_at_kernel(
            classes,
            surface[ELEVATION_LAYER],
            surface[GRAD_X_LAYER],
            surface[GRAD_Y_LAYER],
            ox,
            oy,
            res,
            new_x,
            new_y,
            new_yaw,
        )
        if class_id < 0:
            return OFF_MAP, state(values), _record(values, terrain_class, battery_voltage)
        values[CLASS], values[ELEVATION], values[ROLL], values[PITCH] = class_id, height, new_roll, new_pitch
        lateral = speed * yaw_rate  # the body's sideways acceleration: the turn's, and any sliding's change
        if slide_accel != 0.0:
            lateral += slide_accel
        # The margins are the specific force's tilt, the same force the wheel loads and the IMU see; but a
        # refused move's stop is an impact, not a sustained deceleration (its v / dt is set by the step
        # length): the pitch margin leaves it out, as the slide's stop is left out of a_y above.
        specific_force(values, lateral)
        force_x = G * math.sin(new_pitch) if refused else values[FORCE_X]
        roll_margin, pitch_margin = tilt_margins_kernel(
            body[TIP_ROLL], body[TIP_PITCH], force_x, values[FORCE_Y], values[FORCE_Z]
        )
        values[LATERAL], values[ROLL_MARGIN], values[PITCH_MARGIN] = lateral, roll_margin, pitch_margin
        rollover_started = min(roll_margin, pitch_margin) < 0.0
        # Tripped, each axis on its own: the contact stops the sideways and the forward motion, and the body
        # pivots about the edge it moved towards with each one's angular momentum about that edge.
        if stopped_slide != 0.0:
            # About the wheels it slid towards (roll > 0 lowers the right side, -y).
            towards = new_roll if stopped_slide < 0.0 else -new_roll
            critical = critical_sliding_speed_kernel(body[TRACK], body[CG_HEIGHT], body[TIP_ROLL] - towards)
            rollover_started = rollover_started or abs(stopped_slide) >= critical
        if stopped_drive != 0.0:
            # Pitch-over about the end axle it moved towards (pitch > 0, nose up, lowers the rear).
            towards = new_pitch if stopped_drive < 0.0 else -new_pitch
            wheelbase = 2.0 * body[HALF_WHEELBASE]
            critical = critical_sliding_speed_kernel(wheelbase, body[CG_HEIGHT], body[TIP_PITCH] - towards)
            rollover_started = rollover_started or abs(stopped_drive) >= critical
        values[ROLLOVER_STARTED] = 1.0 if rollover_started else 0.0
        if rollover_started:
            values[SPEED] = values[YAW_RATE] = values[ACCEL] = 0.0
            values[LATERAL_SPEED] = 0.0

        # A wheel whose motor's current limit caps its force turns at the speed the traction curve gives
        # that force at over the ground under it, not faster: its slip, duty and power below follow it.
        hold_at_current_limit(
            wheels, traction, normals, stalled, speed, yaw_rate, body[EFFECTIVE_TRACK], ground,
            body[FORCE_CAP], values[HELD_FLOORS : HELD_FLOORS + 6], values[HELD_CEILINGS : HELD_CEILINGS + 6],
        )  # fmt: skip
        # A released wheel turns with the ground under it at the step's end too: the speed its encoder
        # reads (recorded, and what its controller reports) and its back-EMF, with no slip against it.
        roll_released(wheels, controls, stalled, speed, yaw_rate, body[EFFECTIVE_TRACK])
        power = wheel_outputs(
            wheels,
            normals,
            traction,
            speed,
            yaw_rate,
            ground,
            body[MOTOR:MOTOR_END],
            battery_voltage,
            stalled,
            slip,
            currents,
            duty,
        )
        for i in range(6):
            if stalled[i] != 0.0:
                power += _stall(stalled, body, battery_voltage, currents, duty)
                break
        for i in range(6):
            # A released motor its controller does not brake is not modulated at all: duty 0 (what a VESC
            # reports with its motor released), whatever its back-EMF.
            if controls[i] == 0.0 and stalled[i] == 0.0:
                duty[i] = 0.0
        values[ENERGY_J] += power * dt
        values[POWER_W] = power
        # What the motors draw from the pack: each I x duty; a braking motor (current against its duty)
        # generates and returns current to the pack, as far as its controller's regeneration limit lets it
        # (the motor power above, wheel_outputs). Summed left to right from 0, as Python's sum() of floats.
        input_current = 0.0
        regen_floor = -body[REGEN_LIMIT]
        for i in range(6):
            input_current += max(currents[i] * duty[i], regen_floor)
        values[INPUT_CURRENT_A] = input_current
        return STEPPED, state(values), _record(values, terrain_class, battery_voltage)

    return step_kernel


# The modules whose compiled functions step_kernel calls (each calls only its own module's in turn).
KERNEL_SOURCES = (traction, motor_voltage, motor_current, footprint, ground_kernel, vehicle)
step_kernel = _compile_step_kernel(sources_fingerprint(*KERNEL_SOURCES))


def _compile_specific_force(fingerprint: str) -> Callable[[Array, float], None]:
    """``specific_force``, with ``fingerprint`` (of ``navigator.vehicle``, whose ``G`` it compiles in) in
    numba's cache key: see ``navigator.kernel_cache``."""

    @numba.njit(cache=True)
    def specific_force(values: Array, lateral: float) -> None:
        """Acceleration minus gravity in body axes (x fwd, y left, z up): (0, 0, +g) at rest on the level,
        from ``values``'s terrain tilt and step acceleration."""
        _ = fingerprint  # in the closure, so in numba's cache key (see _compile_specific_force)
        roll, pitch = values[ROLL], values[PITCH]
        cos_pitch = math.cos(pitch)
        values[FORCE_X] = values[STEP_ACCEL] + G * math.sin(pitch)
        values[FORCE_Y] = lateral + G * cos_pitch * math.sin(roll)
        values[FORCE_Z] = G * cos_pitch * math.cos(roll)

    return specific_force


specific_force = _compile_specific_force(sources_fingerprint(vehicle))
