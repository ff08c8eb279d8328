import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from navigator.errors import TerrainError
from navigator.terrain import TerrainMap, disc_mask, from_maze, load_npy_layers, procedural

MAZE = [[1, 1, 1, 1, 1, 1], [1, 2, 2, 1, 1, 1], [1, 2, 1, 1, 1, 1], [1, 2, 1, 2, 2, 1], [1, 1, 1, 2, 1, 1]]


def flat(rows=4, cols=6, res=0.5, origin=(10.0, -2.0)):
    return TerrainMap(
        np.zeros((rows, cols)),
        np.zeros((rows, cols), dtype=np.uint8),
        np.zeros((rows, cols), bool),
        res,
        origin,
    )


def test_cell_geometry():
    terrain = flat()
    assert terrain.shape == (4, 6)
    assert terrain.cell_of(10.0, -2.0) == (0, 0)
    assert terrain.cell_of(12.74, -0.9) == (2, 5)
    assert terrain.center_of(2, 5) == (12.75, -0.75)
    assert terrain.contains(12.99, -0.01) and not terrain.contains(13.0, -1.0)
    with pytest.raises(TerrainError, match="off the map"):
        terrain.cell_of(9.99, 0.0)
    with pytest.raises(TerrainError):
        terrain.center_of(4, 0)


def test_validation_errors():
    good = np.zeros((3, 3))
    with pytest.raises(TerrainError, match="terrain_class layer is 3 x 2 cells but elevation layer is 3 x 3"):
        TerrainMap(good, np.zeros((3, 2), np.uint8), np.zeros((3, 3), bool), 1.0)
    nan = good.copy()
    nan[1, 2] = np.nan
    with pytest.raises(TerrainError, match=r"row 1, col 2"):
        TerrainMap(nan, np.zeros((3, 3), np.uint8), np.zeros((3, 3), bool), 1.0)
    with pytest.raises(
        TerrainError, match=r"terrain_class layer holds 9 at cell \(row 0, col 0\), not a terrain class id"
    ):
        TerrainMap(good, np.full((3, 3), 9, np.uint8), np.zeros((3, 3), bool), 1.0)
    with pytest.raises(TerrainError, match="resolution"):
        TerrainMap(good, np.zeros((3, 3), np.uint8), np.zeros((3, 3), bool), 0.0)


def test_layers_are_read_only():
    terrain = flat()
    with pytest.raises(ValueError):
        terrain.elevation_m[0, 0] = 1.0


def test_maze_orientation_and_errors():
    maze = from_maze(MAZE, 2.0)
    assert maze.shape == (5, 6)
    assert maze.obstacles[0].all()  # row 0 = southern wall
    assert not maze.obstacles[1, 1] and not maze.obstacles[4, 3]
    assert maze.cell_of(7.0, 9.0) == (4, 3)  # x picks the column, y the row
    assert maze.obstacles[maze.cell_of(3.0, 9.0)]  # matrix row 4, col 1 is a wall
    fine = from_maze(MAZE, 3.0, resolution_m=0.5)
    assert fine.shape == (30, 36)
    assert not fine.obstacles[fine.cell_of(4.5, 4.5)]  # maze cell (1, 1)
    assert fine.obstacles[fine.cell_of(4.5, 1.4)]  # maze cell (0, 1)
    bad = [row[:] for row in MAZE]
    bad[2][3] = 7
    with pytest.raises(TerrainError, match=r"row 2, col 3\) holds 7"):
        from_maze(bad, 1.0)
    with pytest.raises(TerrainError, match="divide"):
        from_maze(MAZE, 1.0, resolution_m=0.3)


def test_elevation_and_tilt_on_a_plane():
    rows, cols, res = 20, 30, 0.5
    xs = (np.arange(cols) + 0.5) * res
    ys = (np.arange(rows) + 0.5) * res
    elevation = 0.3 * xs[np.newaxis, :] - 0.1 * ys[:, np.newaxis]
    terrain = TerrainMap(elevation, np.zeros((rows, cols), np.uint8), np.zeros((rows, cols), bool), res)
    assert terrain.elevation_at(5.1, 4.2) == pytest.approx(0.3 * 5.1 - 0.1 * 4.2)
    grad_x, grad_y = terrain.slope_gradient()
    np.testing.assert_allclose(grad_x, 0.3)
    np.testing.assert_allclose(grad_y, -0.1)
    roll, pitch = terrain.tilt_at(5.0, 5.0, 0.0)  # heading east: uphill, ground falls to the left
    assert pitch == pytest.approx(math.atan(0.3))
    assert roll < 0.0  # left side lower
    roll, pitch = terrain.tilt_at(5.0, 5.0, math.pi / 2.0)  # heading north: downhill slightly, west is left
    assert pitch == pytest.approx(math.atan(-0.1))
    assert roll == pytest.approx(math.atan2(-0.3, math.sqrt(1.0 + 0.01)))
    # On any heading the slope-normal component of gravity is the same.
    for yaw in np.linspace(-3.0, 3.0, 7):
        roll, pitch = terrain.tilt_at(5.0, 5.0, yaw)
        assert math.cos(roll) * math.cos(pitch) == pytest.approx(1.0 / math.sqrt(1.0 + 0.09 + 0.01))


def test_procedural_is_seeded():
    def make(seed):
        return procedural((40, 50), 0.25, np.random.default_rng(seed), 1, 0.6, 4, class_patch_count=5)

    a, b, c = make(3), make(3), make(4)
    np.testing.assert_array_equal(a.elevation_m, b.elevation_m)
    np.testing.assert_array_equal(a.terrain_class, b.terrain_class)
    assert not np.array_equal(a.elevation_m, c.elevation_m)
    assert a.elevation_m.max() > 0.1 and a.elevation_m.max() <= 0.6 * 4
    assert set(np.unique(a.terrain_class)) > {1}


def test_disc_mask_and_with_obstacles():
    terrain = flat(rows=10, cols=10, res=1.0, origin=(0.0, 0.0))
    mask = disc_mask(terrain, 5.0, 5.0, 1.0)
    assert mask.sum() == 4  # the four cells whose centres are 0.71 m away
    tiny = disc_mask(terrain, 2.2, 7.7, 0.1)
    assert tiny.sum() == 1 and tiny[7, 2]
    blocked = terrain.with_obstacles(mask)
    assert blocked.obstacles.sum() == 4 and terrain.obstacles.sum() == 0


def test_load_npy_layers(tmp_path):
    elevation = np.arange(12, dtype=float).reshape(3, 4)
    classes = np.full((3, 4), 2, dtype=np.uint8)
    np.save(tmp_path / "z.npy", elevation)
    np.save(tmp_path / "c.npy", classes)
    terrain = load_npy_layers(tmp_path / "z.npy", tmp_path / "c.npy", resolution_m=0.5, origin=(1.0, 2.0))
    np.testing.assert_array_equal(terrain.elevation_m, elevation)
    assert terrain.class_at(1.1, 2.1) == 2 and not terrain.obstacles.any()
    with pytest.raises(TerrainError, match="not found"):
        load_npy_layers(tmp_path / "missing.npy", resolution_m=1.0)
    (tmp_path / "junk.npy").write_bytes(b"not numpy")
    with pytest.raises(TerrainError, match=r"junk\.npy' is not a \.npy array \(it starts with b'not nu'"):
        load_npy_layers(obstacles=tmp_path / "junk.npy", resolution_m=1.0)
    (tmp_path / "one-byte.npy").write_bytes(b"\x93")  # numpy alone would call it pickled data
    with pytest.raises(TerrainError, match=r"is not a \.npy array"):
        load_npy_layers(tmp_path / "one-byte.npy", resolution_m=1.0)


@pytest.mark.parametrize("elevation", [np.full((2, 2), "1.0"), np.ones((2, 2), dtype=bool)])
def test_an_elevation_layer_of_text_or_booleans_is_not_quietly_converted(elevation: np.ndarray) -> None:
    with pytest.raises(TerrainError, match="real numbers"):
        TerrainMap(elevation, np.zeros((2, 2), dtype=int), np.zeros((2, 2), dtype=bool), 1.0)


def test_with_obstacles_is_the_map_made_anew_with_the_added_cells_sharing_its_layers():
    rng = np.random.default_rng(3)
    terrain = TerrainMap(rng.normal(0.0, 0.2, (8, 9)), rng.integers(0, 3, (8, 9)).astype(np.uint8),
                         np.zeros((8, 9), bool), 0.5, (1.0, -2.0))  # fmt: skip
    mask = disc_mask(terrain, 3.0, 0.0, 0.6)
    added = terrain.with_obstacles(mask)
    anew = TerrainMap(terrain.elevation_m, terrain.terrain_class, mask, 0.5, (1.0, -2.0))
    for layer in ("elevation_m", "terrain_class", "obstacles", "_grad_x", "_grad_y"):
        np.testing.assert_array_equal(getattr(added, layer), getattr(anew, layer))
        assert not getattr(added, layer).flags.writeable
    assert (
        added.elevation_m is terrain.elevation_m and added.slope_gradient()[0] is terrain.slope_gradient()[0]
    )
    assert (added.resolution_m, added.origin_xy) == (0.5, (1.0, -2.0)) and not terrain.obstacles.any()
    with pytest.raises(TerrainError, match="obstacle mask has shape"):
        terrain.with_obstacles(np.zeros((3, 3), bool))


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-3.0, 15.0),
    y=st.floats(-3.0, 15.0),
    radius=st.floats(0.0, 8.0),
    res=st.sampled_from([0.1, 0.25, 0.3, 1.0]),
)
@example(x=5.0, y=2.75, radius=2.0, res=1.0)  # cells exactly on the circle: its first, last row and column
def test_disc_mask_computed_in_its_block_is_the_whole_map_formula(x, y, radius, res):
    """disc_mask computes only the rows and columns within the radius; the same cells as the formula over
    every cell of the map (discs partly or wholly off the map, radius 0 included)."""
    terrain = flat(rows=41, cols=37, res=res, origin=(-0.5, 0.25))
    xs = terrain.origin_xy[0] + (np.arange(37) + 0.5) * res
    ys = terrain.origin_xy[1] + (np.arange(41) + 0.5) * res
    expected = (xs[np.newaxis, :] - x) ** 2 + (ys[:, np.newaxis] - y) ** 2 <= radius**2
    if terrain.contains(x, y):
        expected[terrain.cell_of(x, y)] = True
    np.testing.assert_array_equal(disc_mask(terrain, x, y, radius), expected)
