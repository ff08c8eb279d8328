"""A sliding body's yaw: the sideways friction's moment about the centre of gravity, and the end wheels'
friction shared between the slide and the turn's scrub (docs/physics.md, the sliding rows).

Closed forms, by direct calls: the slide's friction, each wheel's part at its axle's x, turns the body by
``sum x_i F_y,i / I_z``; gravity's cross-slope pull acts at the centre of gravity, so with equal axle loads
nothing turns. While the body slides, an end wheel's sideways friction is split between the slide and the
turn in proportion to their sideways speeds at its contact, ``v_y`` and ``w x_i`` (``slide_share``).
"""

import math

import numpy as np
import pytest

from hil.dynamics import RoverDynamics
from hil.traction import drive_forces, released_controls, sideways_grip, sideways_share, slide_share
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TerrainClass
from navigator.vehicle import VehicleParams

PARAMS = VehicleParams()
DT = 0.01
VOLTS = 24.0
HALF_BASE = PARAMS.wheelbase_m / 2.0
# Yaw inertia of the simulator's body: a uniform box the size of the footprint (hil.dynamics).
INERTIA = PARAMS.mass_kg * (PARAMS.footprint_length_m**2 + PARAMS.footprint_width_m**2) / 12.0
# x of each wheel, wheel order LF LM LR RF RM RR.
LEVERS = np.array([HALF_BASE, 0.0, -HALF_BASE] * 2)


def plane(degrees: float, size: tuple[int, int] = (160, 160), res: float = 0.25) -> TerrainMap:
    """A plane rising to the north (+y) at ``degrees``."""
    ys = (np.arange(size[0]) + 0.5) * res
    elevation = np.broadcast_to(math.tan(math.radians(degrees)) * ys[:, np.newaxis], size).copy()
    return TerrainMap(elevation, np.zeros(size, np.uint8), np.zeros(size, bool), res)


def ground(mu: float, lateral_resistance: float = 0.2) -> dict[int, TerrainClass]:
    """One class, no rolling resistance (so no wheel's pull but the slope's and the motors')."""
    return {0: TerrainClass(0, "test", mu, 0.0, 1.0, "test", lateral_resistance=lateral_resistance)}


def test_parked_across_a_pure_side_slope_it_slides_without_turning():
    """Heading along the contour of a 20 deg plane (pitch 0: equal axle loads), mu 0.3 < tan 20 deg: it
    slides downhill, and the friction's moment is 0 by symmetry, so its heading stays exactly where it
    was (the front and rear wheels' parts are the same floats)."""
    body = RoverDynamics(plane(20.0), PARAMS, ground(0.3), x=20.0, y=20.0, yaw=0.0)
    steps = [body.step(DT, [0.0] * 6, VOLTS) for _ in range(100)]
    assert steps[-1].lateral_speed_mps < -0.5  # sliding to the right: downhill
    assert all(s.yaw_rate_rps == 0.0 for s in steps)
    assert body.yaw == 0.0


@pytest.mark.parametrize("yaw_deg", [7.0, 173.0])
def test_parked_on_a_diagonal_its_nose_swings_downhill(yaw_deg):
    """Heading 7 deg off the contour of a 28 deg plane, nose uphill (pitch 3.7 deg, roll 27.8 deg), mu 0.5
    < tan 28 deg: the wheels hold it along its heading and it slides sideways. The pitch loads the rear
    axle, whose wheels hold more, so the nose swings downhill: clockwise heading east, anticlockwise
    heading west (the mirror).

    On the first step (yaw rate 0) every wheel's friction opposes the slide at its whole sideways grip,
    its friction circle's rest ``b_i = sqrt((mu N_i)^2 - F_i^2)`` after the pull ``F_i`` that holds it
    along: the yaw acceleration is ``-sign(v_y) sum x_i b_i / I_z``, to 1e-9 relative, from the step's
    loads and pulls. The pulls are small (``F_i / mu N_i`` 0.34 on the light uphill side, 0.09 on the
    other), so that is within 2 % (1.6 %) of the ``sum x_i mu N_i`` the loads alone give."""
    body = RoverDynamics(plane(28.0), PARAMS, ground(0.5), x=20.0, y=20.0, yaw=math.radians(yaw_deg))
    first = body.step(DT, [0.0] * 6, VOLTS)
    assert math.degrees(first.pitch_rad) == pytest.approx(3.71, abs=0.01)
    assert first.lateral_speed_mps * math.cos(math.radians(yaw_deg)) < 0.0  # downhill: south
    loads, pulls = np.array(first.normal_forces_n), np.array(first.traction_forces_n)
    assert loads[2] > loads[0] and loads[5] > loads[3]  # the rear axle carries more
    grips = np.sqrt((0.5 * loads) ** 2 - pulls**2)
    sign = math.copysign(1.0, first.lateral_speed_mps)
    expected = -sign * float(LEVERS @ grips) / INERTIA
    assert first.yaw_rate_rps / DT == pytest.approx(expected, rel=1e-9)
    by_loads = -sign * float(LEVERS @ (0.5 * loads)) / INERTIA
    assert expected == pytest.approx(by_loads, rel=0.02)
    for _ in range(50):
        body.step(DT, [0.0] * 6, VOLTS)
    downhill = -1.0 if math.cos(math.radians(yaw_deg)) > 0.0 else 1.0  # clockwise heading east
    assert downhill * (body.yaw - math.radians(yaw_deg)) > math.radians(0.05)


def test_a_turn_uses_the_end_wheels_sideways_grip_the_slide_needs():
    """Sliding at ``v_y`` while turning at ``w``, an end wheel's contact slides sideways with both; its
    friction goes to the slide in the part ``|v_y| / hypot(v_y, w x)``, the rest to the scrub. Middle
    wheels (x = 0) give the slide all of theirs. Not sliding, every wheel gives all (as before)."""
    normals = np.array([50.0, 60.0, 70.0, 40.0, 50.0, 60.0])
    forces = np.zeros(6)
    wheels = np.zeros(6)
    mu, w, v_y = 0.5, 1.2, -0.3

    def grip(lateral: float, yaw_rate: float) -> float:
        return sideways_grip(normals, forces, mu, wheels, 0.0, yaw_rate, 0.9, lateral, HALF_BASE)

    share = 0.3 / math.hypot(0.3, w * HALF_BASE)
    assert slide_share(v_y, w * HALF_BASE) == pytest.approx(share, rel=1e-15)
    ends = normals[[0, 2, 3, 5]].sum()
    middles = normals[[1, 4]].sum()
    assert grip(v_y, w) == pytest.approx(mu * (middles + share * ends), rel=1e-12)
    assert grip(v_y, 0.0) == pytest.approx(mu * normals.sum(), rel=1e-12)  # no turn: all of it
    assert grip(0.0, w) == pytest.approx(mu * normals.sum(), rel=1e-12)  # not sliding: as before


@pytest.mark.parametrize(("lateral", "weaker"), [(-0.05, False), (-0.4, True), (1.0, True)])
def test_a_turn_on_the_spot_while_sliding_meets_less_scrub(lateral, weaker):
    """Spinning on the spot at ``w`` = 0.6 rad/s with the wheels locked (the motors brake the turn within
    the yaw time constant, not at their limit), the same loads, level or sliding at ``v_y``: the scrub,
    Coulomb after the motors' moment, takes ``M dt / I`` off the yaw rate. Level it is Wong's
    ``M = mu_t sum_end N_i x share_i`` (on the spot ``mu_t' = mu_t``); sliding each end wheel's part is
    capped at what the slide leaves of its friction, ``mu N_i |w x| / hypot(v_y, w x)``:
    ``M = sum_end N_i x min(mu_t share_i, mu |w x| / hypot(v_y, w x))``. To 1e-9 relative. A slide slower
    than the end wheels' scrub (0.05 m/s against 0.21) leaves the scrub all it needs; faster ones cut it."""
    normals = np.array([60.0, 62.0, 64.0, 80.0, 82.0, 84.0])
    mu, mu_t = 0.3, 0.28
    ground_vector = np.array([mu, 0.2, 0.0, 0.0, 1.0, mu_t])
    tau_yaw = 0.15
    # drive_forces' vehicle vector: mass, yaw inertia, track, effective track, half wheelbase, reference
    # load, a motor cap that never binds, drive and yaw time constants.
    tracks = [PARAMS.track_m, PARAMS.effective_track_m]
    vehicle = np.array([PARAMS.mass_kg, INERTIA, *tracks, HALF_BASE, 73.6, 1e3, 0.1, tau_yaw])
    w = 0.6
    wheels = np.zeros(6)

    def scrub_moment(lateral_speed: float) -> float:
        _, new_yaw_rate = drive_forces(
            wheels,
            normals,
            ground_vector,
            vehicle,
            0.0,
            w,
            0.0,
            DT,
            np.zeros(6),
            np.empty(6),
            lateral_speed,
            released_controls(vehicle[6]),
        )
        free = w * (1.0 - DT / tau_yaw)  # after the motors' moment I (0 - w) / tau_yaw
        return (free - new_yaw_rate) * INERTIA / DT

    end_speed = w * HALF_BASE
    shares = {
        side: sideways_share(end_speed, -side * 0.5 * w * PARAMS.effective_track_m) for side in (-1.0, 1.0)
    }
    left, right = (normals[0] + normals[2]) * HALF_BASE, (normals[3] + normals[5]) * HALF_BASE
    level = mu_t * (left * shares[-1.0] + right * shares[1.0])
    assert scrub_moment(0.0) == pytest.approx(level, rel=1e-9)
    left_over = mu * end_speed / math.hypot(lateral, end_speed)
    sliding = left * min(mu_t * shares[-1.0], left_over) + right * min(mu_t * shares[1.0], left_over)
    assert scrub_moment(lateral) == pytest.approx(sliding, rel=1e-9)
    if weaker:
        assert scrub_moment(lateral) < 0.9 * level
    else:
        assert scrub_moment(lateral) == pytest.approx(level, rel=1e-12)


def test_the_scrub_does_not_jump_as_a_slide_starts_on_ground_resisting_turns_past_its_grip() -> None:
    """mu_t above mu (a [terrain_classes] override may set it): on the spot, an end wheel scrubs with at most
    mu N whether or not the body slides, so the scrub at v_y = 0 is its limit as v_y -> 0 (it was 19.0 N m
    held, 2.94 N m at v_y = 1e-9)."""
    mu, mu_t, w, tau_yaw = 0.1, 0.4, 0.6, 0.15
    ground_vector = np.array([mu, 0.2, 0.0, 0.0, 1.0, mu_t])
    tracks = [PARAMS.track_m, PARAMS.effective_track_m]
    vehicle = np.array([PARAMS.mass_kg, INERTIA, *tracks, HALF_BASE, 73.6, 1e3, 0.1, tau_yaw])
    normals = np.full(6, PARAMS.mass_kg * 9.81 / 6.0)

    def scrub_moment(lateral_speed: float) -> float:
        _, new_yaw_rate = drive_forces(
            np.zeros(6),
            normals,
            ground_vector,
            vehicle,
            0.0,
            w,
            0.0,
            DT,
            np.zeros(6),
            np.empty(6),
            lateral_speed,
            released_controls(vehicle[6]),
        )
        return (w * (1.0 - DT / tau_yaw) - new_yaw_rate) * INERTIA / DT

    held, sliding = scrub_moment(0.0), scrub_moment(1e-9)
    assert held == pytest.approx(sliding, rel=1e-6)
    ground_vector[0] = 0.5  # the same turn resistance on ground with grip to spare: the cap does not bind
    assert held < 0.5 * scrub_moment(0.0)
