"""The simulated GPS's speed and course are the body's motion over the ground, by the law the simulator
moves it by: on a tilted plane, sliding or not, driving, parked or backing, ``ground_velocity_enu`` of a
step's mean speeds, mid heading and starting tilt is exactly the rate its truth position changed at."""

import math

import numpy as np
import pytest

from hil.dynamics import RoverDynamics
from hil.sensors import course_over_ground_deg, ground_speed_mps, ground_velocity_enu
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TerrainClass
from navigator.vehicle import VehicleParams

DT = 0.01


def tilted_plane(east_deg: float, north_deg: float, size: int = 120, res: float = 0.25) -> TerrainMap:
    """A plane rising ``east_deg`` to the east and ``north_deg`` to the north."""
    centres = (np.arange(size) + 0.5) * res
    xs, ys = np.meshgrid(centres, centres)
    elevation = math.tan(math.radians(east_deg)) * xs + math.tan(math.radians(north_deg)) * ys
    return TerrainMap(elevation, np.zeros((size, size), np.uint8), np.zeros((size, size), bool), res)


@pytest.mark.parametrize(("yaw", "wheels_mps"), [(math.pi, 0.6), (0.3, 0.0), (math.pi, -0.4)])
def test_gps_velocity_is_the_rate_the_truth_position_changes_at(yaw: float, wheels_mps: float) -> None:
    # Mud (mu 0.3) on a plane rising 20 deg to the east and to the north: the rover rolls and pitches, and
    # slides downhill sideways (its roll is past atan 0.3), driving forwards, parked, or backing.
    body = RoverDynamics(
        tilted_plane(20.0, 20.0),
        VehicleParams(),
        {0: TerrainClass(0, "mud", 0.3, 0.1, 1.0, "test")},
        x=15.0,
        y=15.0,
        yaw=yaw,
    )
    last = body.step(DT, [wheels_mps] * 6, 24.0)
    slid = tracked = 0
    for _ in range(150):
        before = (body.x, body.y)
        step = body.step(DT, [wheels_mps] * 6, 24.0)
        moved = np.subtract((body.x, body.y), before) / DT
        mean_speed = 0.5 * (last.speed_mps + step.speed_mps)
        mean_lateral = 0.5 * (last.lateral_speed_mps + step.lateral_speed_mps)
        # The step's mid heading (the yaw moves by the mean yaw rate) and the tilt where it started.
        heading = last.yaw + 0.5 * math.remainder(step.yaw - last.yaw, math.tau)
        in_plane = (mean_speed, mean_lateral, last.roll_rad, last.pitch_rad)
        velocity = ground_velocity_enu(heading, *in_plane)
        assert velocity == pytest.approx(tuple(moved), abs=1e-9)
        speed = math.hypot(*moved)
        assert ground_speed_mps(*in_plane) == pytest.approx(speed, abs=1e-9)
        if mean_lateral != 0.0 and speed > 0.05:
            track = math.degrees(math.atan2(moved[0], moved[1])) % 360.0
            gap = (course_over_ground_deg(heading, *in_plane) - track + 180.0) % 360.0 - 180.0
            assert abs(gap) < 1e-6
            tracked += 1
        slid += step.lateral_speed_mps != 0.0
        last = step
    assert slid > 50 and tracked > 50
