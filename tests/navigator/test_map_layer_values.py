"""A ``kind = "npy"`` map layer whose contents are wrong is named as the layer's key, with its file and the
first bad cell, whichever layer it is (the elevation layer was; the classes and obstacles layers, an empty
array and layers of different sizes said only ``map``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from logs.settings import ConfigError
from navigator.config import load_rover_config

SHAPE = (6, 8)


def _config(tmp_path: Path, layers: dict[str, np.ndarray]) -> Path:
    lines = ["[map]", 'kind = "npy"', "resolution_m = 0.25"]
    for name, array in layers.items():
        np.save(tmp_path / f"{name}.npy", array)
        lines.append(f'{name} = "{name}.npy"')
    config = tmp_path / "rover.toml"
    config.write_text("\n".join(lines) + "\n")
    return config


def _with(value: int | float, dtype: type, at: tuple[int, int] = (2, 3)) -> np.ndarray:
    layer: np.ndarray = np.zeros(SHAPE, dtype=dtype)
    layer[at] = value
    return layer


@pytest.mark.parametrize(
    ("layer", "array", "said"),
    [
        # An obstacle mask exported from an image tool: 0 and 255.
        ("obstacles", _with(255, np.uint8), "holds 255 at cell (row 2, col 3), not 0 or 1"),
        ("classes", _with(99, np.uint8), "holds 99 at cell (row 2, col 3), not a terrain class id"),
        ("classes", _with(1.5, np.float64), "holds 1.5 at cell (row 2, col 3), not a whole-number class id"),
        ("elevation", np.zeros((0, 8)), "holds an empty array (shape (0, 8))"),
    ],
)
def test_a_layer_holding_what_it_cannot_names_its_key_file_and_cell(
    tmp_path: Path, layer: str, array: np.ndarray, said: str
) -> None:
    config = _config(tmp_path, {layer: array})
    with pytest.raises(ConfigError) as caught:
        load_rover_config(config)
    assert caught.value.key == f"map.{layer}"
    assert f"{layer} layer file '{tmp_path / f'{layer}.npy'}' {said}" in caught.value.problem, (
        caught.value.problem
    )


def test_layers_of_different_sizes_name_the_one_that_differs_and_both_files(tmp_path: Path) -> None:
    config = _config(tmp_path, {"elevation": np.zeros(SHAPE), "classes": np.zeros((10, 10), dtype=np.uint8)})
    with pytest.raises(ConfigError) as caught:
        load_rover_config(config)
    assert caught.value.key == "map.classes"
    said = caught.value.problem
    assert f"classes layer file '{tmp_path / 'classes.npy'}' is 10 x 10 cells" in said, said
    assert f"elevation layer file '{tmp_path / 'elevation.npy'}' is 6 x 8" in said, said


@pytest.mark.parametrize("kind", ["npy", "png"])
def test_a_map_of_layers_without_any_layer_names_the_keys_it_needs(tmp_path: Path, kind: str) -> None:
    config = tmp_path / "rover.toml"
    config.write_text(f'[map]\nkind = "{kind}"\nresolution_m = 0.25\n')
    with pytest.raises(ConfigError) as caught:
        load_rover_config(config)
    assert caught.value.key == "map"
    assert caught.value.problem == (
        f'kind = "{kind}" needs at least one layer file: elevation, classes or obstacles'
    ), caught.value.problem
