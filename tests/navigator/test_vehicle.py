import math

import numpy as np
import pytest

from logs.settings import ConfigError, parse_toml
from navigator.errors import ParameterError
from navigator.vehicle import (
    G,
    VehicleParams,
    _axle_loads,
    _axle_loads_lifting,
    max_climbable_slope_rad,
    slope_acceleration,
    stability_margins,
    turn_acceleration_room,
    wheel_normal_forces,
)

PARAMS = VehicleParams()


def test_slope_acceleration_is_the_papers_law():
    theta = math.radians(30.0)
    assert slope_acceleration(theta, 0.2) == pytest.approx(9.81 * (0.5 - 0.2 * math.cos(theta)))
    assert slope_acceleration(0.0, 0.5) < 0.0  # friction holds on the level


def test_max_climbable_slope():
    assert max_climbable_slope_rad(0.8, 0.02) == pytest.approx(math.atan(0.78))
    assert max_climbable_slope_rad(0.8, 0.02, margin_rad=0.1) == pytest.approx(math.atan(0.78) - 0.1)
    assert max_climbable_slope_rad(0.1, 0.2) == 0.0
    assert max_climbable_slope_rad(0.1, 0.05, margin_rad=1.0) == 0.0


def test_geometry_properties():
    assert PARAMS.footprint_radius_m == pytest.approx(0.5 * math.hypot(0.9, 0.7))
    assert PARAMS.tip_roll_rad == pytest.approx(math.atan(0.275 / 0.30))
    assert PARAMS.tip_pitch_rad == pytest.approx(math.atan(0.35 / 0.30))
    assert PARAMS.effective_track_m == pytest.approx(0.55 * 1.6)


@pytest.mark.parametrize(("roll", "pitch"), [(0.0, 0.0), (0.2, 0.0), (0.0, -0.3), (0.25, 0.35), (-0.6, 0.1)])
def test_normal_forces_sum_to_slope_normal_weight(roll, pitch):
    forces = wheel_normal_forces(PARAMS, roll, pitch)
    assert forces.shape == (6,)
    assert np.all(forces >= 0.0)
    assert forces.sum() == pytest.approx(PARAMS.mass_kg * G * math.cos(roll) * math.cos(pitch))


def test_level_load_is_even_and_transfers_the_right_way():
    level = wheel_normal_forces(PARAMS, 0.0, 0.0)
    np.testing.assert_allclose(level, PARAMS.mass_kg * G / 6.0)
    nose_up = wheel_normal_forces(PARAMS, 0.0, 0.2)
    assert nose_up[2] > nose_up[1] > nose_up[0]  # rear heaviest when climbing
    right_low = wheel_normal_forces(PARAMS, 0.2, 0.0)
    assert right_low[3:].sum() > right_low[:3].sum()
    left_turn = wheel_normal_forces(PARAMS, 0.0, 0.0, ay_mps2=2.0)
    assert left_turn[3:].sum() > left_turn[:3].sum()  # the outer (right) side carries more
    braking = wheel_normal_forces(PARAMS, 0.0, 0.0, ax_mps2=-2.0)
    assert braking[0] > braking[2]


def test_a_lifting_axle_clamps_at_zero_and_keeps_the_sum():
    pitch = math.atan(0.3 / 0.30)  # past the front-lift point, short of tip-over
    forces = wheel_normal_forces(PARAMS, 0.0, pitch)
    assert forces[0] == 0.0 and forces[3] == 0.0
    assert forces.sum() == pytest.approx(PARAMS.mass_kg * G * math.cos(pitch))
    past_tip = wheel_normal_forces(PARAMS, 0.0, PARAMS.tip_pitch_rad + 0.05)
    assert past_tip[[0, 1, 3, 4]].sum() == 0.0  # all on the rear axle


def test_stability_margins():
    roll_margin, pitch_margin = stability_margins(PARAMS, 0.1, -0.2)
    assert roll_margin == pytest.approx(PARAMS.tip_roll_rad - 0.1)
    assert pitch_margin == pytest.approx(PARAMS.tip_pitch_rad - math.atan(math.tan(0.2) / math.cos(0.1)))
    turning, _ = stability_margins(PARAMS, 0.0, 0.0, lateral_accel_mps2=G)
    assert turning == pytest.approx(PARAMS.tip_roll_rad - math.pi / 4.0)
    assert stability_margins(PARAMS, PARAMS.tip_roll_rad + 0.01, 0.0)[0] < 0.0
    _, braking = stability_margins(PARAMS, 0.0, 0.0, longitudinal_accel_mps2=-G)
    assert braking == pytest.approx(PARAMS.tip_pitch_rad - math.pi / 4.0)


@pytest.mark.parametrize("roll", [0.0, 0.3, 0.7, -0.5])
def test_the_roll_margin_is_zero_where_the_wheel_loads_lift_a_side(roll):
    """The margin's law is the load transfer's: at the sideways acceleration that empties the uphill side
    (bisection on ``wheel_normal_forces``), the roll margin is 0; the tilt is ``atan(f_y / f_z)``, not
    ``roll + atan(a_y / g)`` (they differ on a slope: 3 deg at 51 deg of roll)."""
    pitch = 0.2
    low, high = 0.0, 3.0 * G
    for _ in range(60):
        mid = 0.5 * (low + high)
        lifted = wheel_normal_forces(PARAMS, roll, pitch, 0.0, mid)[:3].sum() == 0.0
        low, high = (low, mid) if lifted else (mid, high)
    margin, _ = stability_margins(PARAMS, roll, pitch, lateral_accel_mps2=high)
    assert margin == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("roll_deg", [0.0, 15.0, -15.0, 25.0])
@pytest.mark.parametrize("pitch_deg", [0.0, 20.0, -35.0])
def test_a_turn_at_the_room_guidance_allows_leaves_exactly_the_margin_it_keeps(roll_deg, pitch_deg):
    """Guidance's turn limit and the simulator's tip law agree: a turn's sideways acceleration at
    ``turn_acceleration_room``, added towards the downhill side, brings the roll margin of
    ``stability_margins`` to exactly the margin kept (12 deg), whatever the pitch. The older law,
    ``g tan(limit - |roll|)``, left 10.8 deg at roll 15, pitch 35."""
    kept = math.radians(12.0)
    roll, pitch = math.radians(roll_deg), math.radians(pitch_deg)
    room = turn_acceleration_room(PARAMS.tip_roll_rad - kept, roll, pitch)
    downhill = math.copysign(1.0, roll) if roll != 0.0 else 1.0
    margin, _ = stability_margins(PARAMS, roll, pitch, lateral_accel_mps2=downhill * room)
    assert margin == pytest.approx(kept, abs=1e-12)
    # Turning the other way (uphill) with the same acceleration keeps more than the margin.
    uphill, _ = stability_margins(PARAMS, roll, pitch, lateral_accel_mps2=-downhill * room)
    assert uphill >= kept - 1e-12


def test_no_turn_room_once_the_tilt_already_reaches_the_limit():
    limit = PARAMS.tip_roll_rad - math.radians(12.0)
    assert turn_acceleration_room(limit, limit, 0.0) == pytest.approx(0.0, abs=1e-12)
    assert turn_acceleration_room(limit, limit + 0.1, 0.3) == 0.0
    assert turn_acceleration_room(0.0, 0.0, 0.0) == 0.0
    # Level, the room is g tan(limit): the tilt is atan(a / g).
    assert turn_acceleration_room(limit, 0.0, 0.0) == pytest.approx(G * math.tan(limit))


def test_params_validation_and_strict_table():
    with pytest.raises(ParameterError, match="mass_kg"):
        VehicleParams(mass_kg=0.0)
    with pytest.raises(ParameterError, match="skid_factor"):
        VehicleParams(skid_factor=0.5)
    table = parse_toml("mass_kg = 50.0\ntrack_m = 0.6\n", "rover.toml")
    params = VehicleParams.from_table(table)
    assert params.mass_kg == 50.0 and params.track_m == 0.6 and params.wheelbase_m == 0.70
    with pytest.raises(ConfigError, match="masss_kg"):
        VehicleParams.from_table(parse_toml("masss_kg = 50.0\n", "rover.toml"))
    with pytest.raises(ConfigError, match="cg_height_m"):
        VehicleParams.from_table(parse_toml("cg_height_m = 0\n", "rover.toml"))


def test_all_axles_fast_path_gives_the_balancing_loops_loads():
    """``_axle_loads`` settles the all-axles-down case without the loop; the loop
    (``_axle_loads_lifting``) must give the very same floats, and both must lift axles alike."""
    rng = np.random.default_rng(7)
    lifted = 0
    for moment_rear, total, half_wheelbase in zip(
        rng.uniform(-800.0, 800.0, 2000).tolist(),
        rng.uniform(1.0, 600.0, 2000).tolist(),
        rng.uniform(0.1, 0.6, 2000).tolist(),
        strict=True,
    ):
        loads = _axle_loads(moment_rear, total, half_wheelbase)
        assert loads == _axle_loads_lifting(moment_rear, total, half_wheelbase)
        assert sum(loads) == pytest.approx(total)
        lifted += min(loads) == 0.0
    assert 0 < lifted < 2000  # both paths were taken
