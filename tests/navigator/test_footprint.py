"""The oriented-rectangle footprint: hand-computed geometry, a sampled cross-check and path walking."""

import math

import numpy as np
import pytest

from navigator.errors import ParameterError
from navigator.footprint import (
    Footprint,
    disc_gap_m,
    first_collision,
    footprint_collides,
    overlapped_cells,
    path_poses,
)
from navigator.terrain import TerrainMap
from navigator.vehicle import VehicleParams

ROVER = Footprint(0.9, 0.7)  # the default vehicle: diagonal 1.14 m


def _map(obstacles: np.ndarray, res: float = 0.1) -> TerrainMap:
    shape = obstacles.shape
    return TerrainMap(np.zeros(shape), np.zeros(shape, np.uint8), obstacles, res)


def _corridor(width_m: float) -> TerrainMap:
    """A 4 x 4 m map at 0.1 m, walls everywhere but an east-west corridor from y = 1.6 to 1.6 + width."""
    walls = np.ones((40, 40), dtype=bool)
    walls[16 : 16 + round(width_m / 0.1), :] = False
    return _map(walls)


def test_footprint_from_vehicle_and_radii() -> None:
    footprint = Footprint.of(VehicleParams())
    assert footprint == ROVER
    assert footprint.inscribed_radius_m == pytest.approx(0.35)
    assert footprint.circumscribed_radius_m == pytest.approx(VehicleParams().footprint_radius_m)
    with pytest.raises(ParameterError):
        Footprint(0.0, 0.5)


def test_lengthwise_through_a_corridor_narrower_than_the_diagonal() -> None:
    corridor = _corridor(0.8)  # wider than the rover (0.7) but narrower than its length and diagonal
    assert not footprint_collides(corridor, (2.0, 2.0, 0.0), ROVER, edge_is_obstacle=False)
    assert not footprint_collides(corridor, (2.0, 2.0, math.pi), ROVER, edge_is_obstacle=False)
    assert footprint_collides(corridor, (2.0, 2.0, math.pi / 2), ROVER, edge_is_obstacle=False)  # sideways
    # 0.8 m: at 2.0 the sides are at 1.65 / 2.35, 0.05 m from the walls; 0.06 m off centre one side touches.
    assert not footprint_collides(corridor, (2.0, 2.04, 0.0), ROVER, edge_is_obstacle=False)
    assert footprint_collides(corridor, (2.0, 2.06, 0.0), ROVER, edge_is_obstacle=False)
    # Driving along it is clear; turning north in it is not (the turn on the spot sweeps the walls).
    assert (
        first_collision(np.array([[0.6, 2.0], [3.4, 2.0]]), corridor, ROVER, edge_is_obstacle=False) is None
    )
    hit = first_collision(
        np.array([[0.6, 2.0], [2.0, 2.0], [2.0, 2.3]]), corridor, ROVER, edge_is_obstacle=False
    )
    assert hit is not None and hit.index == 1 and (hit.x, hit.y) == (2.0, 2.0) and 0.0 < hit.yaw < math.pi / 2
    assert hit.distance_m == pytest.approx(1.4) and len(hit.cells) > 0


def test_rotated_45_degrees_against_one_cell_hand_computed() -> None:
    cell = np.zeros((30, 30), dtype=bool)
    cell[10, 10] = True  # x, y in [1.0, 1.1)
    terrain = _map(cell)
    yaw = math.radians(45.0)
    # Nose first onto the cell's south-west corner (1, 1), which lies on the rover's forward axis at
    # distance d * sqrt(2) from the centre (1 - d, 1 - d): contact iff d * sqrt(2) < half length 0.45.
    limit = 0.45 / math.sqrt(2.0)  # 0.31820
    assert footprint_collides(terrain, (1.0 - (limit - 1e-4), 1.0 - (limit - 1e-4), yaw), ROVER)
    assert not footprint_collides(terrain, (1.0 - (limit + 1e-4), 1.0 - (limit + 1e-4), yaw), ROVER)
    # Side first: the south-east corner (1.1, 1.0) on the rover's left axis, contact iff t * sqrt(2) < 0.35.
    limit = 0.35 / math.sqrt(2.0)  # 0.24749
    assert footprint_collides(terrain, (1.1 + limit - 1e-4, 1.0 - (limit - 1e-4), yaw), ROVER)
    assert not footprint_collides(terrain, (1.1 + limit + 1e-4, 1.0 - (limit + 1e-4), yaw), ROVER)
    # Axis-aligned the same centre is further: the rectangle's corner (x + 0.35, y + 0.45) must pass 1.0.
    assert not footprint_collides(terrain, (1.0 - 0.36, 1.0 - 0.46, math.pi / 2), ROVER)
    assert footprint_collides(terrain, (1.0 - 0.34, 1.0 - 0.44, math.pi / 2), ROVER)
    np.testing.assert_array_equal(
        overlapped_cells(terrain, (1.0 - 0.34, 1.0 - 0.44, math.pi / 2), ROVER), [[10, 10]]
    )


def test_map_edge_is_an_obstacle() -> None:
    open_map = _map(np.zeros((20, 20), dtype=bool))  # 2 x 2 m
    assert not footprint_collides(open_map, (1.0, 1.0, 0.3), ROVER)
    assert footprint_collides(open_map, (0.44, 1.0, 0.0), ROVER)  # the back sticks out west
    assert not footprint_collides(open_map, (0.44, 1.0, 0.0), ROVER, edge_is_obstacle=False)
    assert footprint_collides(open_map, (50.0, 50.0, 0.0), ROVER)  # far off the map
    cells = overlapped_cells(open_map, (0.44, 1.0, 0.0), ROVER)
    assert len(cells) > 0 and np.all(cells[:, 1] == -1)  # the ring just west of the map


def test_agrees_with_dense_point_sampling() -> None:
    """Random poses: sampled points of a slightly smaller rectangle inside an obstacle => collides; the
    kernel reports a collision => sampled points of a slightly larger rectangle reach an obstacle."""
    rng = np.random.default_rng(7)
    obstacles = rng.random((30, 30)) < 0.03
    terrain = _map(obstacles)
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, 91), np.linspace(-0.5, 0.5, 71))
    for _ in range(150):
        x, y, yaw = rng.uniform(0.7, 2.3), rng.uniform(0.7, 2.3), rng.uniform(-math.pi, math.pi)

        def sampled_hit(grow: float, x: float = x, y: float = y, yaw: float = yaw) -> bool:
            fwd, left = u * (0.9 + grow), v * (0.7 + grow)
            px = x + fwd * math.cos(yaw) - left * math.sin(yaw)
            py = y + fwd * math.sin(yaw) + left * math.cos(yaw)
            return bool(obstacles[(py / 0.1).astype(int), (px / 0.1).astype(int)].any())

        collides = footprint_collides(terrain, (x, y, yaw), ROVER)
        if sampled_hit(-0.004):
            assert collides
        if collides:
            assert sampled_hit(0.03)


def test_path_poses_sampling_and_turns() -> None:
    poses, segments, distances = path_poses(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [1.0, 1.0]]), 0.3)
    assert np.all(np.diff(distances) >= 0.0) and distances[-1] == pytest.approx(2.0)
    assert np.max(np.hypot(*np.diff(poses[:, :2], axis=0).T)) <= 0.3 + 1e-12
    turn = poses[(poses[:, 0] == 1.0) & (poses[:, 1] == 0.0), 2]
    assert turn.min() == 0.0 and turn.max() == pytest.approx(math.pi / 2)
    assert np.max(np.diff(np.sort(turn))) <= math.radians(5.0) + 1e-12
    assert set(segments.tolist()) == {0, 2}  # the zero-length segment adds nothing
    with pytest.raises(ParameterError):
        path_poses(np.array([[0.0, np.nan]]), 0.1)


def test_disc_gap_hand_computed() -> None:
    # Rover at the origin heading north (yaw 90 deg): its front edge is y = 0.45, its left side x = -0.35.
    pose = (0.0, 0.0, math.pi / 2)
    assert disc_gap_m(pose, ROVER, (0.0, 1.0), 0.5) == pytest.approx(0.05)
    assert disc_gap_m(pose, ROVER, (-0.8, 0.0), 0.5) == pytest.approx(-0.05)
    assert disc_gap_m(pose, ROVER, (0.35 + 0.3, 0.45 + 0.4), 0.4) == pytest.approx(0.1)  # off a corner
    assert disc_gap_m(pose, ROVER, (0.1, 0.1), 0.2) == pytest.approx(-0.2)  # inside
