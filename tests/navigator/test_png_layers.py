"""PNG terrain layers: orientation (image top = north), encodings, the TOML kind and typed errors."""

import json
from pathlib import Path

import numpy as np
import pytest
from matplotlib import image as mpl_image

from logs.settings import ConfigError, load_toml
from navigator.errors import TerrainError
from navigator.map_config import terrain_from_table
from navigator.png_layers import load_png_layers
from navigator.terrain_classes import FIRM, MUDDY, SANDY
from tests.navigator.png_writer import write_png

DATA = Path(__file__).resolve().parents[1] / "data"


def _grey(path: Path, levels: np.ndarray) -> Path:
    """An 8-bit grey image as matplotlib writes it (RGBA with equal channels)."""
    mpl_image.imsave(path, levels.astype(float), cmap="gray", vmin=0, vmax=255, format="png")
    return path


def test_image_top_row_is_the_north_edge(tmp_path: Path) -> None:
    # An asymmetric obstacle image: one dark pixel in the image's top-left corner only.
    image = np.full((3, 4), 255)
    image[0, 0] = 0
    terrain = load_png_layers(
        obstacles=_grey(tmp_path / "o.png", image), resolution_m=1.0, origin=(10.0, 20.0)
    )
    assert terrain.obstacles.sum() == 1
    # Top-left of the picture = north-west corner of the map = last row, first column.
    assert terrain.obstacles[2, 0]
    assert terrain.cell_of(10.5, 22.5) == (2, 0)


def test_elevation_8_and_16_bit_grey_scaled(tmp_path: Path) -> None:
    levels8 = np.array([[0, 10], [200, 255]], dtype=np.uint8)
    write_png(tmp_path / "z8.png", levels8)
    terrain = load_png_layers(
        elevation=tmp_path / "z8.png", resolution_m=0.5, elevation_scale_m=0.02, elevation_offset_m=-1.0
    )
    np.testing.assert_allclose(terrain.elevation_m, levels8[::-1] * 0.02 - 1.0)
    levels16 = np.array([[0, 1000, 40000], [65535, 7, 12345]], dtype=np.uint16)
    write_png(tmp_path / "z16.png", levels16)
    terrain = load_png_layers(elevation=tmp_path / "z16.png", resolution_m=0.5, elevation_scale_m=0.001)
    np.testing.assert_allclose(terrain.elevation_m, levels16[::-1].astype(float) * 0.001)
    # Grey written by matplotlib (RGBA, equal channels) reads as the same levels.
    terrain = load_png_layers(
        elevation=_grey(tmp_path / "zm.png", levels8.astype(int)), resolution_m=0.5, elevation_scale_m=1.0
    )
    np.testing.assert_array_equal(terrain.elevation_m, levels8[::-1])


def test_classes_from_palette_indices_and_grey_levels(tmp_path: Path) -> None:
    indices = np.array([[0, 1, 2], [2, 2, 0]], dtype=np.uint8)
    # Index 3 repeats index 0's colour: a repeated colour reads as its first index.
    palette = np.array([[200, 0, 0], [0, 200, 0], [0, 0, 200], [200, 0, 0]], dtype=np.uint8)
    write_png(tmp_path / "c.png", indices, palette=palette)
    table = {0: FIRM, 1: SANDY, 2: MUDDY}
    terrain = load_png_layers(classes=tmp_path / "c.png", resolution_m=1.0, class_values=table)
    expected = np.vectorize(table.get)(indices[::-1])
    np.testing.assert_array_equal(terrain.terrain_class, expected)

    grey = np.array([[0, 128], [255, 128]])
    terrain = load_png_layers(
        classes=_grey(tmp_path / "g.png", grey),
        resolution_m=1.0,
        class_values={0: FIRM, 128: SANDY, 255: MUDDY},
    )
    np.testing.assert_array_equal(terrain.terrain_class, [[MUDDY, SANDY], [FIRM, SANDY]])


def test_obstacle_threshold(tmp_path: Path) -> None:
    path = _grey(tmp_path / "o.png", np.array([[0, 100, 140, 255]]))
    assert load_png_layers(obstacles=path, resolution_m=1.0).obstacles.tolist() == [
        [True, True, False, False]
    ]
    strict = load_png_layers(obstacles=path, resolution_m=1.0, obstacle_threshold=0.2)
    assert strict.obstacles.tolist() == [[True, False, False, False]]


def test_typed_errors(tmp_path: Path) -> None:
    grey = _grey(tmp_path / "g.png", np.zeros((2, 3)))
    with pytest.raises(TerrainError, match="not found"):
        load_png_layers(obstacles=tmp_path / "missing.png", resolution_m=1.0)
    (tmp_path / "junk.png").write_bytes(b"hello, not an image")
    with pytest.raises(TerrainError, match="not a PNG"):
        load_png_layers(obstacles=tmp_path / "junk.png", resolution_m=1.0)
    truncated = tmp_path / "cut.png"
    truncated.write_bytes(grey.read_bytes()[:60])
    with pytest.raises(TerrainError, match=r"cut\.png"):
        load_png_layers(obstacles=truncated, resolution_m=1.0)
    colour = tmp_path / "rgb.png"
    mpl_image.imsave(colour, np.array([[[1.0, 0.0, 0.0], [0.5, 0.5, 0.5]]]), format="png")
    with pytest.raises(TerrainError, match=r"greyscale.*image row 0, col 0"):
        load_png_layers(elevation=colour, resolution_m=1.0)
    other = _grey(tmp_path / "other.png", np.zeros((3, 3)))
    with pytest.raises(
        TerrainError, match=r"obstacles layer file .*other\.png' is 3 x 3 cells but elevation"
    ):
        load_png_layers(elevation=grey, obstacles=other, resolution_m=1.0)
    with pytest.raises(TerrainError, match=r"grey level 128 .* no entry in class_values"):
        load_png_layers(
            classes=_grey(tmp_path / "c.png", np.array([[0, 128]])), resolution_m=1.0, class_values={0: FIRM}
        )
    with pytest.raises(TerrainError, match="class_values"):
        load_png_layers(classes=grey, resolution_m=1.0)
    see_through = tmp_path / "alpha.png"
    mpl_image.imsave(see_through, np.array([[[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0]]]), format="png")
    with pytest.raises(TerrainError, match=r"image row 0, col 1\) is transparent"):
        load_png_layers(obstacles=see_through, resolution_m=1.0)
    with pytest.raises(TerrainError, match="finite"):
        load_png_layers(elevation=grey, resolution_m=1.0, elevation_scale_m=float("nan"))


def test_png_kind_in_toml_and_example_scenario(tmp_path: Path) -> None:
    terrain, summary = terrain_from_table(load_toml(DATA / "png_walls.toml").table("terrain"), DATA)
    assert summary.startswith("PNG layers 16x24")
    assert terrain.obstacles.any() and {int(c) for c in np.unique(terrain.terrain_class)} == {FIRM, SANDY}
    assert terrain.elevation_m.max() > terrain.elevation_m.min()
    (tmp_path / "bad.toml").write_text(
        '[terrain]\nkind = "png"\nresolution_m = 1.0\nclasses = "c.png"\n[terrain.class_values]\nx = "firm"\n'
    )
    with pytest.raises(ConfigError, match=r"class_values\.x"):
        terrain_from_table(load_toml(tmp_path / "bad.toml").table("terrain"), tmp_path)
    (tmp_path / "typo.toml").write_text('[terrain]\nkind = "png"\nresolution_m = 1.0\nobstacles = "o.png"\n')
    with pytest.raises(ConfigError, match="not found") as missing:
        terrain_from_table(load_toml(tmp_path / "typo.toml").table("terrain"), tmp_path)
    assert missing.value.key == "terrain.obstacles"  # the key to fix, not just the table
    (tmp_path / "npy.toml").write_text('[terrain]\nkind = "npy"\nresolution_m = 1.0\nelevation = "z.npy"\n')
    with pytest.raises(ConfigError, match="not found") as missing:
        terrain_from_table(load_toml(tmp_path / "npy.toml").table("terrain"), tmp_path)
    assert missing.value.key == "terrain.elevation"


def test_rover_plan_takes_a_png_obstacle_image_and_the_png_scenario(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rover_cli.main import main

    # A 10 m wide, 5 m tall map at 0.25 m: a wall down the middle from the image top (north), open at the
    # bottom (south): the path from west to east must dip south of the wall's end.
    image = np.full((20, 40), 255)
    image[:12, 19:21] = 0
    png = _grey(tmp_path / "maze.png", image)
    assert (
        main(["plan", str(png), "--resolution-m", "0.25", "--start", "1,4", "--goal", "9,4", "--json"]) == 0
    )
    straight = 8.0
    assert json.loads(capsys.readouterr().out)["length_m"] > straight + 1.0
    assert main(["plan", str(png), "--start", "1,4", "--goal", "9,4"]) == 2
    assert "--resolution-m" in capsys.readouterr().err
    assert main(["plan", str(DATA / "png_walls.toml"), "--start", "2,6", "--goal", "10,6", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["length_m"] > straight + 1.0
