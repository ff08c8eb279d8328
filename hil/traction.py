"""The wheel-ground laws of a terrain class, compiled with numba: traction-slip curve, sinkage resistance,
lateral scrub of skid-steer turns, and the drive forces of the six wheels under traction and current limits.

The laws (parameters per class in ``navigator.terrain_classes``, sources in docs/physics.md):

* Traction curve: a wheel slipping by ``s`` (0 rolling, 1 spinning on the spot or sliding locked) pulls with
  ``F / N = mu (1 - exp(-s / s_k)) / (1 - exp(-1 / s_k))``: the Janosi-Hanamoto shear-displacement law
  (Wong, *Theory of Ground Vehicles*, ch. 2), normalised so a fully slipping wheel gives exactly ``mu N``.
* Motion resistance of a rolling wheel: ``N (crr - c_s + c_s (N / N_ref)^(1 / (2n + 1)))``: the tyre's own
  part plus the compaction part ``c_s`` of the class, which grows with the wheel load as Bekker's
  rigid-wheel sinkage law says (compaction resistance ~ W^((2n+2)/(2n+1))). At ``N_ref`` it is the table's
  crr. It fades in below ``ROLLING_SPEED_EPS_MPS`` of wheel speed (a wheel at rest does not roll).
* Lateral scrub: in a skid-steer turn the end axles slide sideways; with the lateral resistance
  coefficient ``mu_t`` each wheel resists with ``mu_t N`` at a lever of its distance from the middle axle,
  a moment ``M = mu_t sum(N_i |x_i| share_i)`` against the yaw (Wong ch. 7 for tracks; Yu et al. 2010 for
  skid-steered wheels). ``mu_t`` falls with the turn radius R as ``mu_t / (0.925 + 0.15 R / B)``, the
  empirical fit Wong quotes for tracked vehicles (B = track), never above ``mu_t``. ``share_i`` is the
  sideways part of the wheel's sliding velocity (``sideways_share``): a wheel spinning in place resists
  little sideways, which is how a skid-steer still turns on slippery ground.
* Sharing a side's force: the wheels on one side roll over the same ground speed, so at equal wheel speeds
  they slip alike and pull in proportion to their load, each at most ``mu N_i`` and at most the force its
  motor's current limit gives; a wheel at its current limit pulls less and the others take the rest. A
  wheel turning apart from its side (a seized one while the others drive) has a slip of its own; where it
  opposes the side's force it drags at the curve's force for that slip (a locked wheel on a moving rover:
  ``mu N_i`` against its motion over the ground, Wong ch. 1) and the others share the side's force plus
  that drag.

* Sideways grip (``sideways_grip``, ``sideways_speed``): the body slides sideways when gravity's
  cross-slope part and the turn's centripetal need exceed what the wheels' friction circles leave after
  their longitudinal pull, ``sqrt((mu N_i)^2 - F_i^2)`` each; a wheel at its friction limit (spinning, or
  locked and sliding) resists sideways by the sideways part of its contact's sliding velocity,
  ``mu N_i share_i``; Coulomb friction, as the scrub's.
* A sliding body's yaw (``slide_yaw_moment``, ``slide_share``): the slide's friction acts at each wheel's
  axle, ``sum x_i F_y,i``, and an end wheel's friction is shared between the slide and the turn's scrub in
  proportion to their sideways speeds at its contact.

``drive_forces`` turns these into one step of the body's motion (see ``hil.dynamics``): the body is pulled
toward the ground speeds the wheel speeds give once the curve's steady-state slip is taken off, within the
drive and yaw time constants, as far as the wheels' traction and current limits allow.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

G = 9.81  # m/s^2, as navigator.vehicle.G (a compile-time constant here)
# Below this wheel surface speed rolling resistance fades out linearly (it needs the wheel turning).
ROLLING_SPEED_EPS_MPS = 0.05
# Slip ratios use at least this speed as denominator, so a wheel at rest does not divide by zero.
SLIP_SPEED_EPS_MPS = 0.05
# Within this speed of the ground under it a wheel's slip counts as zero, so it may hold either way (static
# friction): rounding in the state must not flip the sign of the force a wheel at rest holds a slope with.
SLIP_SIGN_EPS_MPS = 1e-6
# Sideways speed added to the end wheels' scrub so a wheel at rest holds with full static friction.
SCRUB_SPEED_EPS_MPS = 0.01
# Indices into drive_forces' class-parameter vector.
MU, SLIP_K, CRR, SINK, SINK_N, MU_LAT = 0, 1, 2, 3, 4, 5


@numba.njit(cache=True)
def traction_ratio(slip: float, mu: float, slip_constant: float) -> float:
    """Drawbar pull / normal load at slip ratio ``slip`` (signed, |slip| <= 1); ``mu`` at full slip."""
    magnitude = min(abs(slip), 1.0)
    value = mu * (1.0 - math.exp(-magnitude / slip_constant)) / (1.0 - math.exp(-1.0 / slip_constant))
    return value if slip >= 0.0 else -value


@numba.njit(cache=True)
def slip_for_ratio(ratio: float, mu: float, slip_constant: float) -> float:
    """The slip ratio at which the curve gives force / load ``ratio`` (signed); +-1 at or beyond ``mu``."""
    fraction = abs(ratio) / mu
    if fraction >= 1.0:
        magnitude = 1.0
    else:
        magnitude = min(
            1.0, -slip_constant * math.log(1.0 - fraction * (1.0 - math.exp(-1.0 / slip_constant)))
        )
    return magnitude if ratio >= 0.0 else -magnitude


@numba.njit(cache=True)
def resistance_coefficient(
    load_n: float, reference_load_n: float, crr: float, sinkage: float, exponent_n: float
) -> float:
    """Motion resistance / load of a wheel carrying ``load_n``: tyre part + Bekker compaction part."""
    if load_n <= 0.0:
        return 0.0
    return crr - sinkage + sinkage * (load_n / reference_load_n) ** (1.0 / (2.0 * exponent_n + 1.0))


@numba.njit(cache=True)
def scrub_coefficient(lateral_resistance: float, turn_radius_m: float, track_m: float) -> float:
    """Lateral resistance coefficient at turn radius ``turn_radius_m`` (inf: straight, no scrub)."""
    if math.isinf(turn_radius_m):
        return 0.0
    return lateral_resistance / max(1.0, 0.925 + 0.15 * turn_radius_m / track_m)


@numba.njit(cache=True)
def sideways_share(lateral_speed: float, sliding_speed: float) -> float:
    """Share of a wheel's friction that resists sideways motion: the sideways part of its sliding velocity.

    Friction acts against the contact's sliding velocity (Wong and Chiang's skid-steering theory, Wong
    ch. 7): a wheel spinning fast (large longitudinal ``sliding_speed``, surface minus ground) offers little
    sideways resistance. At rest both are ~0 and the share is 1 (static friction holds the heading).
    """
    sideways = lateral_speed + SCRUB_SPEED_EPS_MPS
    return sideways / math.hypot(sideways, sliding_speed)


@numba.njit(cache=True)
def slide_share(lateral_speed: float, scrub_speed: float) -> float:
    """The slide's part of a sliding end wheel's sideways friction: ``|v_y| / hypot(v_y, w x)``.

    An end wheel's contact slides sideways with the body (``lateral_speed``, its ``v_y``) and with the turn
    (``scrub_speed``, ``|w x_i|``, what the scrub resists); friction opposes the contact's sliding velocity
    (Wong and Chiang's skid-steering theory, Wong ch. 7, as ``sideways_share``), so its sideways friction is
    shared between the slide and the scrub in proportion to their speeds: the slide takes this part and the
    scrub the rest of a friction circle, ``sqrt(1 - share^2) = |w x| / hypot(v_y, w x)``. 1 with no turn,
    0 with no slide. The two speeds are collinear, so this is a smooth stand-in for the contact's exact
    Coulomb law, under which the end wheel's whole friction goes to whichever of ``v_y + w x_i`` sets its
    sign (the front and rear then switch between holding the slide and resisting the turn as ``|v_y|``
    crosses ``|w x_i|``, a jump an explicit step chatters on).
    """
    if lateral_speed == 0.0:
        return 0.0
    return abs(lateral_speed) / math.hypot(lateral_speed, scrub_speed)


@numba.njit(cache=True)
def _share_side(
    force: float, loads: Array, first: int, mu: float, forward_caps: Array, backward_caps: Array, out: Array
) -> float:
    """Split ``force`` over wheels ``first..first+2`` in proportion to load, each within ``mu N`` and its
    cap in the force's direction (``forward_caps`` or ``backward_caps``, N); a wheel at its cap gives way
    to the others. Writes ``out``; returns the force / load ratio of the uncapped wheels (>= mu: the side
    cannot give ``force``, each wheel gives its most)."""
    magnitude = abs(force)
    sign = 1.0 if force >= 0.0 else -1.0
    caps = forward_caps if force >= 0.0 else backward_caps
    capped = 0  # bit k: wheel first + k is at its cap (bits, not a bool array: no allocation per call)
    ratio = 0.0
    for _ in range(4):
        free_load = 0.0
        taken = 0.0
        for k in range(3):
            if capped & (1 << k):
                taken += caps[first + k]
            else:
                free_load += loads[first + k]
        if free_load <= 0.0:
            ratio = math.inf if magnitude > taken else 0.0
            break
        ratio = (magnitude - taken) / free_load
        # Cap first the wheel that reaches its cap at the lowest ratio (with equal caps: the most loaded).
        worst = -1
        for k in range(3):
            load, cap = loads[first + k], caps[first + k]
            over = not capped & (1 << k) and min(ratio, mu) * load > cap
            if over and (worst < 0 or cap * loads[first + worst] < caps[first + worst] * load):
                worst = k
        if worst < 0:
            break
        capped |= 1 << worst
    for k in range(3):
        if capped & (1 << k):
            out[first + k] = sign * caps[first + k]
        else:
            out[first + k] = sign * min(ratio, mu) * loads[first + k]
    return ratio


@numba.njit(cache=True)
def _wheel_caps(
    wheels: Array,
    speed: float,
    yaw_rate: float,
    effective_track: float,
    caps: Array,
    out_forward: Array,
    out_backward: Array,
) -> None:
    """The most each wheel can pull forward and backward (N, magnitudes): its cap in ``caps`` (its motor's,
    or inf for a locked wheel, which its lock holds; ``mu N`` is applied in the sharing), and nothing
    against the sign of its slip. The traction curve's force has the sign of the slip, so a wheel turning
    slower than the ground under it brakes and never pulls forward, and one turning faster never brakes;
    within ``SLIP_SIGN_EPS_MPS`` of the ground it holds either way (static friction). A 0 marks a wheel
    whose slip opposes that direction: it gives nothing that way, or its own drag (``_own_slip_forces``)."""
    for i in range(6):
        side = 1.0 if i >= 3 else -1.0
        sliding = wheels[i] - (speed + side * 0.5 * yaw_rate * effective_track)
        out_forward[i] = caps[i] if sliding > -SLIP_SIGN_EPS_MPS else 0.0
        out_backward[i] = caps[i] if sliding < SLIP_SIGN_EPS_MPS else 0.0


@numba.njit(cache=True)
def _own_slip_forces(
    wheels: Array,
    normals: Array,
    speed: float,
    yaw_rate: float,
    effective_track: float,
    mu: float,
    slip_constant: float,
    caps: Array,
    locked: Array,
    stop_gain: float,
    out: Array,
) -> None:
    """The force (N, signed as its slip) at which a wheel turning apart from its side drags where its slip
    opposes its side's force: the traction curve's for its own slip. 0 for the others, and for a wheel
    within ``SLIP_SIGN_EPS_MPS`` of the ground under it.

    A side's wheels turn alike and slip alike, so they share its force (``_share_side``) and approach the
    steady slip within the drive's time constant. A wheel turning apart from them has a slip of its own,
    its surface and ground speeds', ``(u - v) / max(|u|, |v|, SLIP_SPEED_EPS_MPS)``, and where that
    opposes the side's force it is not one of the wheels that give it: it drags at ``traction_ratio(slip)
    N``. Apart: a ``locked`` (seized) wheel on a side with a turning one. Only a seized wheel: a wheel whose
    controller let go of it (rebooting, past its command timeout, under-voltage) rolls with the ground under
    it (``drive_forces``' ``controls``), so it has no slip of its own. A locked
    wheel on a moving rover slides at full slip and drags ``mu N`` against its motion over the ground
    (Wong, *Theory of Ground Vehicles*, ch. 1: a locked, skidding tyre at 100 % slip), falling smoothly to
    0 as the rover stops (below ``SLIP_SPEED_EPS_MPS`` the slip falls with the ground speed; at
    ``SLIP_SIGN_EPS_MPS``, below which a wheel holds either way and shares, the force is 3e-4 of the load
    on firm ground, less on the others). A turning wheel's motor holds it, so at most its cap in
    ``caps``; a locked wheel's lock holds it (cap inf). A side of three locked wheels shares its force as
    any side whose wheels turn alike (and so stops smoothly).

    And at most ``stop_gain`` (N per m/s) times its sliding speed: half the force that would stop the
    contact's sliding in one step (``drive_forces``: its effective mass / 2 dt). Coulomb friction stepped
    explicitly reverses the sliding it opposes where the curve is steep (on firm ground it reaches
    ``mu N`` by about 1 cm/s of sliding under a locked wheel): a rover pivoting about a seized wheel, its
    contact near rest, had the drag flip between ``+-mu N`` every step. Above 4.4 cm/s of sliding (firm
    ground, the default rover, 10 ms steps) the bound is above ``mu N`` and the curve's force is the drag."""
    for first in (0, 3):
        seized = (locked[first] != 0.0) + (locked[first + 1] != 0.0) + (locked[first + 2] != 0.0)
        side = 1.0 if first else -1.0
        ground_speed = speed + side * 0.5 * yaw_rate * effective_track
        for i in range(first, first + 3):
            apart = locked[i] != 0.0 and seized < 3
            sliding = wheels[i] - ground_speed
            if not apart or abs(sliding) < SLIP_SIGN_EPS_MPS:
                out[i] = 0.0
                continue
            scale = max(abs(wheels[i]), abs(ground_speed), SLIP_SPEED_EPS_MPS)
            slip = max(-1.0, min(1.0, sliding / scale))
            force = traction_ratio(slip, mu, slip_constant) * normals[i]
            limit = min(caps[i], stop_gain * abs(sliding))
            out[i] = max(-limit, min(limit, force))


@numba.njit(cache=True)
def _side_drags(first: int, forward_caps: Array, backward_caps: Array, drags: Array) -> tuple[float, float]:
    """The drag (N) of the side's wheels from ``first`` that turn apart from it (``_own_slip_forces``) and
    whose slip opposes a forward force (<= 0: slower than the ground), and a backward one (>= 0)."""
    forward = backward = 0.0
    for k in range(first, first + 3):
        if forward_caps[k] == 0.0:
            forward += drags[k]
        if backward_caps[k] == 0.0:
            backward += drags[k]
    return forward, backward


@numba.njit(cache=True)
def _drags_forward(force: float, forward_drag: float, backward_drag: float) -> bool:
    """Whether a side gives ``force`` (N) with its sharing wheels pulling forward, its wheels slower than
    the ground and turning apart from it dragging at ``forward_drag`` (<= 0); else with them braking, the
    faster ones dragging at ``backward_drag`` (>= 0).

    Either way can give a force between the two drags (forward: the sharing wheels pull less than the drag;
    backward: they brake less than the other one); there the larger drag is the one kept, as the wheel
    turning apart is the one with a slip of its own: a seized wheel's ``mu N`` whether its side gives a
    little forward or a little backward, and driving in reverse the same. With no drag: forward for
    ``force >= 0``, as before drags were modelled."""
    if -forward_drag >= backward_drag:
        return force >= forward_drag
    return force > backward_drag


@numba.njit(cache=True)
def _dragging_limits(
    forward: float, backward: float, forward_drag: float, backward_drag: float
) -> tuple[float, float]:
    """A side's most forward and most backward force (N, magnitudes; the backward one may be < 0: the side
    must pull), from what its sharing wheels can give each way (``forward``, ``backward``) and the drags
    of its wheels turning apart (``_side_drags``), for the choice ``_drags_forward`` makes: forward, the
    side gives ``forward_drag`` plus its sharing wheels' pull; backward, ``backward_drag`` less their
    braking."""
    most = forward_drag + forward
    least = backward_drag - backward
    if -forward_drag >= backward_drag:
        return most, -min(least, forward_drag)
    return max(most, backward_drag), -least


@numba.njit(cache=True)
def _share_side_dragging(
    force: float,
    side_drags: tuple[float, float],
    loads: Array,
    first: int,
    mu: float,
    forward_caps: Array,
    backward_caps: Array,
    drags: Array,
    out: Array,
) -> None:
    """``_share_side`` with the side's wheels that turn apart from it and whose slip opposes the way it
    gives ``force`` (``_drags_forward``) at their own slip's force (``drags``; ``side_drags`` the side's
    sums, ``_side_drags``): they give that, and the rest share ``force`` less it, which keeps that way's
    sign. Writes ``out``."""
    forward_drag, backward_drag = side_drags
    forward = _drags_forward(force, forward_drag, backward_drag)
    caps = forward_caps if forward else backward_caps
    dragging = forward_drag if forward else backward_drag
    _share_side(force - dragging, loads, first, mu, forward_caps, backward_caps, out)
    for k in range(first, first + 3):
        if caps[k] == 0.0 and drags[k] != 0.0:
            out[k] = drags[k]


@numba.njit(cache=True)
def _side_ground_speed(
    surface: float, force: float, loads: Array, first: int, mu: float, k: float, caps: Array, scratch: Array
) -> float:
    """Ground speed a side's wheels at ``surface`` m/s settle at while transmitting ``force`` (N).

    In the steady state the slip has the force's sign by construction, so only the motor cap bounds it:
    ``caps`` holds it for every wheel (inf for a locked one); ``scratch`` (six) takes the split, which is
    not kept. A side with a wheel dragging: ``_dragging_ground_speed``."""
    ratio = _share_side(force, loads, first, mu, caps, caps, scratch)
    if ratio >= mu:
        return surface  # cannot hold it: the wheels spin; the force limit, not slip, sets the motion
    slip = slip_for_ratio(ratio, mu, k)
    if force * surface >= 0.0:
        return surface * (1.0 - slip)  # driving: the ground lags the tyre
    # Braking: the ground runs ahead of the tyre. ``slip`` is below 1 while ``ratio < mu``, but a ratio
    # within a few ulps of mu can round it to 1: bound the quotient instead of dividing by zero.
    return surface / max(1.0 - slip, 1e-6)


@numba.njit(cache=True)
def _dragging_ground_speed(
    force: float,
    side_drags: tuple[float, float],
    wheels: Array,
    loads: Array,
    first: int,
    mu: float,
    k: float,
    caps: Array,
    forward_caps: Array,
    backward_caps: Array,
    drags: Array,
    sharing_caps: Array,
    scratch: Array,
) -> float:
    """``_side_ground_speed`` of a side with a wheel turning apart from it that drags now
    (``_share_side_dragging``, ``side_drags`` not both 0), such as a seized wheel while the others drive.

    It stays so in the steady state: the side's other wheels carry ``force`` less its drag, and they, not
    the dragging wheel (it slides), set the ground speed, at their mean surface speed (there is one: a
    wheel turns apart from others). ``sharing_caps`` (six) takes ``caps`` with 0 for the dragging wheels."""
    forward_drag, backward_drag = side_drags
    forward = _drags_forward(force, forward_drag, backward_drag)
    direction = forward_caps if forward else backward_caps
    sharing = 0
    surface = 0.0
    for j in range(first, first + 3):
        dragging = direction[j] == 0.0 and drags[j] != 0.0
        sharing_caps[j] = 0.0 if dragging else caps[j]
        if not dragging:
            sharing += 1
            surface += wheels[j]
    surface /= sharing
    sharing_force = force - (forward_drag if forward else backward_drag)  # keeps its sign: _drags_forward
    return _side_ground_speed(surface, sharing_force, loads, first, mu, k, sharing_caps, scratch)


@numba.njit(cache=True)
def released_controls(cap_n: float) -> Array:
    """``drive_forces``' ``controls`` with every wheel driven at the force cap ``cap_n`` (N)."""
    controls = np.full(12, -1.0)
    controls[6:] = cap_n
    return controls


@numba.njit(cache=True)
def roll_released(
    wheels: Array, controls: Array, locked: Array, speed: float, yaw_rate: float, effective_track: float
) -> bool:
    """Set each released wheel's surface speed (``controls[i] >= 0``, not ``locked``: a seized wheel does
    not roll) to the ground speed under it, as ``_wheel_caps`` reckons it (so its slip is exactly 0);
    whether any wheel is released."""
    any_released = False
    for i in range(6):
        if controls[i] >= 0.0 and locked[i] == 0.0:
            side = 1.0 if i >= 3 else -1.0
            wheels[i] = speed + side * 0.5 * yaw_rate * effective_track
            any_released = True
    return any_released


@numba.njit(cache=True)
def _none_driven(controls: Array) -> bool:
    """Whether every wheel's controller has let go of its motor (``drive_forces``' ``controls``)."""
    for i in range(6):  # noqa: SIM110 (a loop: numba compiles all() of a generator poorly)
        if controls[i] < 0.0:
            return False
    return True


@numba.njit(cache=True)
def _side_command(wheels: Array, controls: Array, first: int, ground_speed: float) -> float:
    """The surface speed (m/s) the motors of the side from ``first`` drive at: the mean of its driven
    wheels'; with none driven, 0 if a wheel brakes (its brake aims to stop it) else ``ground_speed``."""
    total = 0.0
    driven = 0
    braking = False
    for i in range(first, first + 3):
        if controls[i] < 0.0:
            total += wheels[i]
            driven += 1
        elif controls[i] > 0.0:
            braking = True
    if driven:
        return total / driven
    return 0.0 if braking else ground_speed


@numba.njit(cache=True)
def _brake_against_turning(
    wheels: Array, controls: Array, locked: Array, forward_caps: Array, backward_caps: Array
) -> None:
    """A released wheel's brake acts only against its turning: nothing forward while it turns forward,
    nothing backward while it turns backward; within ``SLIP_SIGN_EPS_MPS`` of rest, either way (it holds).
    A locked wheel keeps its lock's caps (a seized wheel does not roll, whatever its controller does)."""
    for i in range(6):
        if controls[i] < 0.0 or locked[i] != 0.0:
            continue
        if wheels[i] > SLIP_SIGN_EPS_MPS:
            forward_caps[i] = 0.0
        elif wheels[i] < -SLIP_SIGN_EPS_MPS:
            backward_caps[i] = 0.0


@numba.njit(cache=True)
def drive_forces(
    wheels: Array,
    normals: Array,
    ground: Array,
    vehicle: Array,
    speed: float,
    yaw_rate: float,
    pitch: float,
    dt: float,
    locked: Array,
    out_forces: Array,
    lateral_speed: float,
    controls: Array,
    rolling: Array | None = None,
) -> tuple[float, float]:
    """One step of the wheels' pull on the body: (longitudinal acceleration m/s^2, new yaw rate rad/s).

    ``wheels`` surface speeds (m/s) and ``normals`` (N), wheel order LF LM LR RF RM RR. ``ground`` =
    [mu, slip_constant, crr, sinkage_resistance, sinkage_exponent, lateral_resistance].
    ``vehicle`` = [mass kg, yaw inertia kg m^2, track m, effective track m, half wheelbase m,
    reference wheel load N, per-wheel force cap N (motor current limit), drive tau s, yaw tau s].
    ``locked``: per wheel, nonzero for a seized one (its lock, not its motor, holds it: no motor cap).
    Writes each wheel's drive force (N, forward positive) into ``out_forces``: a wheel turning apart from
    its side whose slip opposes the side's force (a seized wheel while the others drive) at the curve's
    force for its own slip, the rest of the side sharing the side's force plus that drag.

    ``controls`` (12, ``released_controls``'s layout): per wheel its released motor's brake force (N, >= 0),
    or < 0 for a wheel its controller drives; then per wheel its motor's force cap (N: its current limit's,
    the battery cut-off's share of it). A released wheel (its controller gives no drive torque: timed out,
    rebooting, under-voltage) turns at the ground speed under it (written into ``wheels``): no slip, no
    drive force, its rolling resistance as any rolling wheel's; its brake force acts only against its
    turning (at rest: either way, it holds), within ``mu N``. A side's motors drive at the mean speed of its
    driven wheels; a side with none aims at 0 where a wheel brakes (the brake stops the body within the
    drive's time constant, no harder than the brake forces), else at the ground speed (nothing drives it).
    A released wheel shares its side's force as any wheel, so on a side that drives it gives nothing (with a
    brake current it does not drag a driving side: not modelled). With every wheel released, the brakes
    are Coulomb friction on the turning: they stop the body within a step if their force can, else they
    give all of it against the turning.

    ``lateral_speed``: the body's sideways speed (m/s, y left). While it slides (not 0) the scrub shares
    each end wheel's friction with the slide: it is at most what the slide leaves of ``mu N_i``,
    ``mu N_i |w x_i| / hypot(v_y, w x_i)`` (``slide_share``), so a turn on the spot while sliding meets
    ``sum N_i |x_i| min(mu_t' share_i, mu |w x_i| / hypot(v_y, w x_i))``: less than on the level with the
    same loads, and none with no turn (a sliding contact has no static friction to hold the heading). The
    cap is on ``mu N_i``, not on what the wheel's pull leaves: the scrub has never shared with the
    longitudinal force in this model, and still does not.

    ``rolling``: the speeds the wheels turn at (m/s), where they differ from ``wheels``, the speeds their
    controllers drive them to (a wheel its motor's current limit holds slower: ``hil.motor_current``);
    the rolling resistance opposes the turning. None: ``wheels``.
    """
    turning = wheels if rolling is None else rolling
    mass, inertia, track, effective_track = vehicle[0], vehicle[1], vehicle[2], vehicle[3]
    half_base, reference_load, cap = vehicle[4], vehicle[5], vehicle[6]
    tau_drive, tau_yaw = max(vehicle[7], dt), max(vehicle[8], dt)
    mu, slip_k = ground[MU], ground[SLIP_K]

    # A released wheel rolls with the ground under it (before its resistance, which needs its turning).
    any_released = roll_released(wheels, controls, locked, speed, yaw_rate, effective_track)
    if any_released and _none_driven(controls):
        # Every controller has let go: a brake current is a torque against the wheel's turning, not a speed
        # loop, so the brakes are Coulomb friction: they give what stops the body within this step, at most
        # their force. Pulled toward rest within the drive's 0.1 s instead, gravity could outrun that pull
        # and the brakes would give nothing while the wheels still turned (a rover coasting up a slope).
        tau_drive = tau_yaw = dt
    if any_released and rolling is not None:
        # A released wheel turns with the ground: that, not a speed its current limit held, is what its
        # rolling resistance opposes.
        for i in range(6):
            if controls[i] >= 0.0 and locked[i] == 0.0:
                rolling[i] = wheels[i]

    # Motion resistance of each wheel against its own rolling, and its moment about the vertical axis.
    resist_total = 0.0
    resist_moment = 0.0
    left_lever = 0.0
    right_lever = 0.0
    for i in range(6):
        fade = max(-1.0, min(1.0, turning[i] / ROLLING_SPEED_EPS_MPS))
        coefficient = resistance_coefficient(
            normals[i], reference_load, ground[CRR], ground[SINK], ground[SINK_N]
        )
        force = -coefficient * normals[i] * fade
        resist_total += force
        resist_moment += force * (0.5 * track if i >= 3 else -0.5 * track)  # forward on the right yaws left
        if i % 3 != 1:  # the middle axle turns about itself: no scrub
            if i < 3:
                left_lever += normals[i] * half_base
            else:
                right_lever += normals[i] * half_base
    gravity_along = -mass * G * math.sin(pitch)

    # The turn the wheels ask for, and the scrub resisting it at the tighter of the asked and actual radius.
    if any_released:
        left = _side_command(wheels, controls, 0, speed - 0.5 * yaw_rate * effective_track)
        right = _side_command(wheels, controls, 3, speed + 0.5 * yaw_rate * effective_track)
    else:
        left = (wheels[0] + wheels[1] + wheels[2]) / 3.0
        right = (wheels[3] + wheels[4] + wheels[5]) / 3.0
    v_cmd = 0.5 * (left + right)
    yaw_cmd = (right - left) / effective_track
    radius = math.inf
    if abs(yaw_cmd) > 1e-9:
        radius = abs(v_cmd) / abs(yaw_cmd)
    if abs(yaw_rate) > 1e-9:
        radius = min(radius, abs(speed) / abs(yaw_rate))
    elif math.isinf(radius):
        radius = 0.0  # not turning and not asked to: static friction holds the heading in full
    end_scrub_speed = abs(yaw_rate) * half_base  # the end wheels' sideways speed in the turn
    left_sliding = left - (speed - 0.5 * yaw_rate * effective_track)
    right_sliding = right - (speed + 0.5 * yaw_rate * effective_track)
    if lateral_speed == 0.0:
        coefficient = scrub_coefficient(ground[MU_LAT], radius, track)
        left_share = sideways_share(end_scrub_speed, left_sliding)
        right_share = sideways_share(end_scrub_speed, right_sliding)
        if coefficient * max(left_share, right_share) <= mu:
            scrub = coefficient * (left_lever * left_share + right_lever * right_share)
        else:
            # A class whose turn resistance passes its friction (mu_t > mu, as [terrain_classes] allows): an
            # end wheel scrubs with at most mu N, the sliding branch's limit as v_y -> 0, so the scrub does
            # not jump down when the body starts to slide. The table's classes never get here.
            scrub = left_lever * min(coefficient * left_share, mu)
            scrub += right_lever * min(coefficient * right_share, mu)
    else:
        # Sliding: each end wheel's scrub within what the slide leaves of its friction, the turn's part of
        # its sideways sliding, sqrt(1 - slide_share^2) (written so, it keeps its digits when that is small).
        coefficient = scrub_coefficient(ground[MU_LAT], radius, track)
        left_over = mu * end_scrub_speed / math.hypot(lateral_speed, end_scrub_speed)
        scrub = left_lever * min(coefficient * sideways_share(end_scrub_speed, left_sliding), left_over)
        scrub += right_lever * min(coefficient * sideways_share(end_scrub_speed, right_sliding), left_over)
    turn_sign = 1.0 if yaw_cmd > 0.0 else (-1.0 if yaw_cmd < 0.0 else 0.0)

    # Steady state: the sides' forces that hold this speed and turn, and the ground speeds their slip gives.
    hold_force = -gravity_along - resist_total
    hold_moment = turn_sign * scrub - resist_moment
    # One scratch allocation per step for every per-wheel vector below (slices are views).
    work = np.empty(36)
    motor_caps, scratch, forward_caps, backward_caps = work[0:6], work[6:12], work[12:18], work[18:24]
    drags, sharing_caps = work[24:30], work[30:36]
    for i in range(6):
        # A locked wheel: its lock holds it. A released one: its brake. A driven one: its motor's cap (the
        # vehicle's, unless the controls lower it: the battery cut-off).
        if locked[i] != 0.0:
            motor_caps[i] = math.inf
        elif controls[i] >= 0.0:
            motor_caps[i] = controls[i]
        else:
            motor_caps[i] = min(cap, controls[6 + i])
    # Which way each wheel's slip lets it pull, and how a wheel turning apart from its side (a seized one
    # while the others drive) drags where its slip opposes its side's force: the steady state counts it.
    _wheel_caps(wheels, speed, yaw_rate, effective_track, motor_caps, forward_caps, backward_caps)
    if any_released:
        _brake_against_turning(wheels, controls, locked, forward_caps, backward_caps)
    # A drag's lever is half the track: its contact moves as a mass of m I / (I + m (track / 2)^2); half
    # of what stops it in a step, as the body answers a side's changed limit through the yaw as well.
    stop_gain = 0.5 * mass * inertia / (inertia + mass * (0.5 * track) ** 2) / dt
    _own_slip_forces(
        wheels, normals, speed, yaw_rate, effective_track, mu, slip_k, motor_caps, locked, stop_gain, drags
    )
    left_drags = _side_drags(0, forward_caps, backward_caps, drags)
    right_drags = _side_drags(3, forward_caps, backward_caps, drags)
    left_dragging = left_drags[0] != 0.0 or left_drags[1] != 0.0
    right_dragging = right_drags[0] != 0.0 or right_drags[1] != 0.0
    left_hold, right_hold = 0.5 * hold_force - hold_moment / track, 0.5 * hold_force + hold_moment / track
    if left_dragging:
        left_ground = _dragging_ground_speed(
            left_hold, left_drags, wheels, normals, 0, mu, slip_k, motor_caps, forward_caps,
            backward_caps, drags, sharing_caps, scratch,
        )  # fmt: skip
    else:
        left_ground = _side_ground_speed(left, left_hold, normals, 0, mu, slip_k, motor_caps, scratch)
    if right_dragging:
        right_ground = _dragging_ground_speed(
            right_hold, right_drags, wheels, normals, 3, mu, slip_k, motor_caps, forward_caps,
            backward_caps, drags, sharing_caps, scratch,
        )  # fmt: skip
    else:
        right_ground = _side_ground_speed(right, right_hold, normals, 3, mu, slip_k, motor_caps, scratch)
    v_target = 0.5 * (left_ground + right_ground)
    yaw_target = (right_ground - left_ground) / effective_track

    # Longitudinal: toward the target within tau, as far as the sides' traction and current limits and the
    # sign of each wheel's slip allow (a wheel slower than the ground brakes, one faster pulls).
    left_forward = left_backward = right_forward = right_backward = 0.0
    for i in range(6):
        grip = mu * normals[i]
        if i < 3:
            left_forward += min(grip, forward_caps[i])
            left_backward += min(grip, backward_caps[i])
        else:
            right_forward += min(grip, forward_caps[i])
            right_backward += min(grip, backward_caps[i])
    # A dragging wheel takes from what its side can give that way, and through the track makes a moment.
    if left_dragging:
        left_forward, left_backward = _dragging_limits(left_forward, left_backward, *left_drags)
    if right_dragging:
        right_forward, right_backward = _dragging_limits(right_forward, right_backward, *right_drags)
    required = mass * (v_target - speed) / tau_drive - gravity_along - resist_total
    drive = max(-(left_backward + right_backward), min(left_forward + right_forward, required))
    accel = (drive + gravity_along + resist_total) / mass

    # Yaw: the moment toward the target turn plus the scrub, within what each side has left over.
    required_moment = inertia * (yaw_target - yaw_rate) / tau_yaw + turn_sign * scrub - resist_moment
    low = track * max(-right_backward - 0.5 * drive, 0.5 * drive - left_forward)
    high = track * min(right_forward - 0.5 * drive, 0.5 * drive + left_backward)
    if low > high:
        low = high = 0.5 * (low + high)
    moment = max(low, min(high, required_moment))
    # The scrub is Coulomb friction: it stops the yaw rather than reversing it (implicit, so no chatter).
    free_yaw_rate = yaw_rate + (moment + resist_moment) * dt / inertia
    scrub_change = scrub * dt / inertia
    if abs(free_yaw_rate) <= scrub_change:
        new_yaw_rate = 0.0
    elif free_yaw_rate > 0.0:
        new_yaw_rate = free_yaw_rate - scrub_change
    else:
        new_yaw_rate = free_yaw_rate + scrub_change

    left_force, right_force = 0.5 * drive - moment / track, 0.5 * drive + moment / track
    if left_dragging:
        _share_side_dragging(
            left_force, left_drags, normals, 0, mu, forward_caps, backward_caps, drags, out_forces
        )
    else:
        _share_side(left_force, normals, 0, mu, forward_caps, backward_caps, out_forces)
    if right_dragging:
        _share_side_dragging(
            right_force, right_drags, normals, 3, mu, forward_caps, backward_caps, drags, out_forces
        )
    else:
        _share_side(right_force, normals, 3, mu, forward_caps, backward_caps, out_forces)
    return accel, new_yaw_rate


@numba.njit(cache=True)
def sideways_grip(
    normals: Array,
    forces: Array,
    mu: float,
    wheels: Array,
    speed: float,
    yaw_rate: float,
    effective_track: float,
    lateral_speed: float,
    half_wheelbase: float = 0.0,
) -> float:
    """The most sideways force the six wheels can hold the body with (N).

    A wheel below its friction limit: its friction circle less what its longitudinal force ``F_i`` uses,
    ``sqrt((mu N_i)^2 - F_i^2)``. The longitudinal force comes first (the motors hold each wheel's speed and
    the curve sets its pull, ``drive_forces``); the sideways friction gets what is left of the circle
    (Pacejka, *Tire and Vehicle Dynamics*, ch. 1, the friction circle; Wong, *Theory of Ground Vehicles*,
    ch. 1, a tyre's cornering force falling as its tractive effort grows).

    A wheel whose contact slides sideways (the body's ``lateral_speed`` is not 0) also has Coulomb friction
    against its contact's sliding velocity (Coulomb; Wong ch. 7, as ``sideways_share`` for the scrub): the
    sideways part ``share_i`` of that velocity, the body's ``lateral_speed`` against the wheel's
    longitudinal ``surface - ground`` speed (``wheels``, and the ground under each side from ``speed``,
    ``yaw_rate`` and ``effective_track``). Its sideways grip is the larger of the two,
    ``max(sqrt((mu N_i)^2 - F_i^2), |F_i| share_i)``: with no pull the circle's rest (all of ``mu N_i``), at
    the limit (``|F_i| = mu N_i``: it spins, or is locked and slides) ``mu N_i share_i``, so a locked wheel
    sliding mostly sideways resists with nearly ``mu N_i``; and in between it changes continuously with the
    pull (before, a wheel went from the circle's ~0 just below its limit to ``mu N_i share_i`` at it, and a
    locked rover's slide jumped with its heading). The Coulomb part is weighted by ``|F_i|``, not ``mu N_i``,
    so that a wheel pulling well below its limit keeps the circle's rest: a driven wheel's small slip would
    otherwise turn all its friction sideways and hold a rover the circle lets slide (``g (sin phi -
    sqrt(mu^2 - crr^2) cos phi)`` across a slope). A body not sliding sideways has ``share_i`` 0 (no
    at-rest epsilon as the scrub's), so its grip is the circle's rest exactly as before.

    Its limits: the longitudinal force stays the one ``drive_forces`` gave it (it is not cut back to the
    sliding direction's share), so a wheel sliding obliquely has up to ``sqrt(2) mu N_i`` of friction in
    all; a locked rover whose wheels hold it along its heading while it slides sideways therefore slides
    less than a block would (a locked-wheel body is a block: ``docs/physics.md``); and the share's
    sideways speed is the body's ``lateral_speed`` at every wheel. A lifted wheel holds nothing.

    While the body slides, an end wheel (at ``+-half_wheelbase``) also scrubs sideways with the turn, at
    ``|yaw_rate| half_wheelbase``: the slide has only its part ``slide_share`` of that wheel's sideways
    friction, the scrub the rest (``drive_forces``), so a turn uses grip the slide needs. The default
    ``half_wheelbase`` 0 leaves that out (every wheel at the middle axle).
    """
    grip = 0.0
    for i in range(6):
        grip += _wheel_sideways_grip(
            i, normals, forces, mu, wheels, speed, yaw_rate, effective_track, lateral_speed, half_wheelbase
        )
    return grip


@numba.njit(cache=True)
def _wheel_sideways_grip(
    i: int,
    normals: Array,
    forces: Array,
    mu: float,
    wheels: Array,
    speed: float,
    yaw_rate: float,
    effective_track: float,
    lateral_speed: float,
    half_wheelbase: float,
) -> float:
    """Wheel ``i``'s part of ``sideways_grip`` (N; its arguments, the law in its docstring)."""
    limit = mu * normals[i]
    if limit <= 0.0:
        return 0.0  # lifted
    left_over = math.sqrt(max(limit * limit - forces[i] * forces[i], 0.0))
    sideways = abs(lateral_speed)
    if sideways == 0.0:
        return left_over  # share 0: the circle's rest (below the limit, the float it always was)
    side = 1.0 if i >= 3 else -1.0
    sliding = wheels[i] - (speed + side * yaw_rate * 0.5 * effective_track)
    grip = max(left_over, abs(forces[i]) * sideways / math.hypot(sideways, sliding))
    if i % 3 != 1:  # an end wheel (wheel order LF LM LR RF RM RR): the turn's scrub has the rest
        grip *= slide_share(lateral_speed, yaw_rate * half_wheelbase)
    return grip


@numba.njit(cache=True)
def slide_yaw_moment(
    normals: Array,
    forces: Array,
    mu: float,
    wheels: Array,
    speed: float,
    yaw_rate: float,
    effective_track: float,
    lateral_speed: float,
    half_wheelbase: float,
    friction_n: float,
) -> float:
    """The yaw moment (N m, counter-clockwise positive) of a sliding body's sideways friction.

    ``friction_n`` (N, y left) is the sideways friction the Coulomb step applied (``sideways_speed``: all
    of ``sideways_grip`` while the body keeps sliding, less on the step it stops); the other arguments are
    ``sideways_grip``'s, as it was called for that step. Each wheel takes its part in proportion to its own
    sideways grip (``_wheel_sideways_grip``) and applies it at its axle's x (front ``+half_wheelbase``,
    middle 0, rear ``-half_wheelbase``): ``sum x_i F_y,i``. Gravity's cross-slope pull acts at the centre
    of gravity (x = 0), so with equal axle loads the moment is 0; with unequal ones (pitch, a longitudinal
    acceleration) the more loaded axle holds and the other slides ahead: a rover pitched nose-up across a
    slope swings its nose downhill (Wong, *Theory of Ground Vehicles*, ch. 7: each contact's lateral
    friction at its own lever).

    The direction: every wheel's part opposes the body's slide ``v_y`` (the friction applied), and an end
    wheel's part is its ``slide_share`` of its friction: the rest of its sideways sliding, ``w x_i``, is
    the turn's, and its friction there is the scrub's (``drive_forces``). So the end wheels' own sideways
    speed ``v_y + w x_i`` splits each one's friction between this moment and the scrub, rather than setting
    its sign (see ``slide_share``).
    """
    total = 0.0
    lever = 0.0
    for i in range(6):
        grip = _wheel_sideways_grip(
            i, normals, forces, mu, wheels, speed, yaw_rate, effective_track, lateral_speed, half_wheelbase
        )
        total += grip
        axle = i % 3  # wheel order LF LM LR RF RM RR: 0 front, 1 middle, 2 rear
        if axle == 0:
            lever += half_wheelbase * grip
        elif axle == 2:
            lever -= half_wheelbase * grip
    if total <= 0.0:
        return 0.0
    return friction_n * lever / total


@numba.njit(cache=True)
def sideways_speed(speed: float, demand_mps2: float, grip_mps2: float, dt: float) -> float:
    """The body's sideways speed (m/s, y left) after ``dt`` s, from ``speed`` under the sideways
    acceleration ``demand_mps2`` (gravity's cross-slope part less the turn's centripetal need) with the
    wheels' Coulomb friction ``grip_mps2`` (the deceleration it can give: ``sideways_grip``, N, / mass)
    against it.

    Coulomb friction, implicit as the yaw scrub's in ``drive_forces``: within the grip it holds the body
    (a body that was not sliding stays at exactly 0.0); past it, it opposes the sliding and can stop it,
    never reverse it.
    """
    free = speed + demand_mps2 * dt
    change = grip_mps2 * dt
    if abs(free) <= change:
        return 0.0
    if free > 0.0:
        return free - change
    return free + change


@numba.njit(cache=True)
def wheel_outputs(
    wheels: Array,
    normals: Array,
    forces: Array,
    speed: float,
    yaw_rate: float,
    ground: Array,
    motor: Array,
    battery_voltage: float,
    locked: Array,
    out_slip: Array,
    out_current: Array,
    out_duty: Array,
) -> float:
    """Per-wheel slip, motor current (A) and duty, and the six motors' electrical power (W, returned).

    ``motor`` = [wheel radius m, gear ratio, torque constant N m/A, winding resistance ohm, effective
    track m, regeneration limit A]. A wheel pulling below its traction limit slips as the class's curve
    says; a saturated or lifted wheel, or one held at zero pull because its slip opposes its side's force,
    slips as its surface and ground speeds say (it spins or slides). The current has the sign of the
    wheel's force (negative when braking a forward-turning wheel); a motor that generates (braking,
    ``k_t omega I + I^2 R < 0``) gives it back to the pack, as a VESC does, up to its controller's
    regeneration limit (its battery current floor, ``l_in_current_min``: at most ``limit x V`` W back; 0:
    none); past the limit the rest is lost, the braking force kept.

    A wheel dragging at its own slip's force (``_own_slip_forces``) is on the curve as well: the curve
    gives its slip back. A ``locked`` wheel (nonzero: seized) slips as its speeds say, -1 / +1 while the
    rover moves over it at ``SLIP_SPEED_EPS_MPS`` or more, whatever force it has; its lock, not its motor,
    takes that force, so it gives its motor no current, duty or power here (``out_current`` /
    ``out_duty`` are left as they are: the caller sets the stall's, ``hil.dynamics_kernel._stall``).
    """
    radius, gear, k_t, resistance, effective_track = motor[0], motor[1], motor[2], motor[3], motor[4]
    regen_floor_w = -motor[5] * battery_voltage
    mu, slip_k = ground[MU], ground[SLIP_K]
    power = 0.0
    for i in range(6):
        side = 1.0 if i >= 3 else -1.0
        ground_speed = speed + side * yaw_rate * 0.5 * effective_track
        sliding = wheels[i] - ground_speed
        # A wheel held at zero pull by the sign of its slip (see _wheel_caps) is not on the curve either.
        held_off = forces[i] == 0.0 and abs(sliding) >= SLIP_SIGN_EPS_MPS
        on_curve = normals[i] > 0.0 and abs(forces[i]) < mu * normals[i] * (1.0 - 1e-9)
        if on_curve and not held_off and locked[i] == 0.0:
            out_slip[i] = slip_for_ratio(forces[i] / normals[i], mu, slip_k)
        else:
            scale = max(abs(wheels[i]), abs(ground_speed), SLIP_SPEED_EPS_MPS)
            out_slip[i] = max(-1.0, min(1.0, sliding / scale))
        if locked[i] != 0.0:
            continue
        current = forces[i] * radius / (gear * k_t)
        back_emf = k_t * wheels[i] / radius * gear
        out_current[i] = current
        if battery_voltage > 0.0:
            out_duty[i] = max(-1.0, min(1.0, (back_emf + current * resistance) / battery_voltage))
        else:
            out_duty[i] = 0.0
        power += max(back_emf * current + current * current * resistance, regen_floor_w)
    return power
