"""One check of what a terrain layer may hold (``navigator.layer_checks``), for a ``TerrainMap`` built from
arrays and for the ``.npy`` files a map is loaded from: the same bad layer is refused with the same words
either way, the array named by its field and the file by its path and key. (The two used to be separate
checks: the map said ``obstacles layer must be boolean (or 0/1)`` where the file's check named the cell
and its value, and the map refused whole-number float class ids a file may hold.)"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from navigator.errors import TerrainError
from navigator.terrain import TerrainMap, load_npy_layers

SHAPE = (3, 4)
FIELD_LABELS = {"elevation": "elevation", "classes": "terrain_class", "obstacles": "obstacles"}


def _with(value: object, dtype: type | str, at: tuple[int, int] = (1, 2)) -> np.ndarray:
    layer = np.zeros(SHAPE, dtype=dtype)
    layer[at] = value
    return layer


def _as_array(kind: str, values: np.ndarray) -> TerrainMap:
    layers: dict[str, np.ndarray] = {
        "elevation": np.zeros(values.shape),
        "classes": np.zeros(values.shape, np.uint8),
        "obstacles": np.zeros(values.shape, bool),
    }
    layers[kind] = values
    return TerrainMap(layers["elevation"], layers["classes"], layers["obstacles"], 0.5)


def _as_file(kind: str, values: np.ndarray, folder: Path) -> tuple[TerrainMap, Path]:
    path = folder / f"{kind}.npy"
    np.save(path, values)
    files = {name: path if name == kind else None for name in ("elevation", "classes", "obstacles")}
    return load_npy_layers(files["elevation"], files["classes"], files["obstacles"], resolution_m=0.5), path


@pytest.mark.parametrize(
    ("kind", "values", "problem"),
    [
        ("obstacles", _with(255, np.uint8), "holds 255 at cell (row 1, col 2), not 0 or 1"),
        ("obstacles", _with(np.nan, np.float64), "holds a non-finite value (nan) at cell (row 1, col 2)"),
        ("classes", _with(9, np.uint8), "holds 9 at cell (row 1, col 2), not a terrain class id"),
        ("classes", _with(1.5, np.float64), "holds 1.5 at cell (row 1, col 2), not a whole-number class id"),
        ("classes", np.full(SHAPE, "firm"), "holds text (dtype <U4), not class ids"),
        ("elevation", _with(np.inf, np.float64), "holds a non-finite value (inf) at cell (row 1, col 2)"),
        ("elevation", np.full(SHAPE, "1.5"), "holds text (dtype <U3), not real numbers (metres)"),
        ("elevation", np.zeros((0, 4)), "holds an empty array (shape (0, 4))"),
        ("elevation", np.zeros(4), "must hold one 2-D array, got shape (4,)"),
    ],
)
def test_a_bad_layer_is_refused_in_the_same_words_as_an_array_and_as_a_file(
    tmp_path: Path, kind: str, values: np.ndarray, problem: str
) -> None:
    with pytest.raises(TerrainError) as from_array:
        _as_array(kind, values)
    with pytest.raises(TerrainError) as from_file:
        _as_file(kind, values, tmp_path)
    path = tmp_path / f"{kind}.npy"
    assert str(from_array.value).startswith(f"{FIELD_LABELS[kind]} layer {problem}"), from_array.value
    assert str(from_file.value).startswith(f"{kind} layer file {str(path)!r} {problem}"), from_file.value
    assert (from_array.value.key, from_file.value.key) == (None, kind)  # a key only for a table's file


def test_whole_float_class_ids_are_taken_as_an_array_as_from_a_file(tmp_path: Path) -> None:
    classes = _with(2.0, np.float64)
    from_array = _as_array("classes", classes)
    from_file, _ = _as_file("classes", classes, tmp_path)
    for terrain in (from_array, from_file):
        assert terrain.terrain_class.dtype == np.uint8 and terrain.terrain_class[1, 2] == 2


def test_layers_of_two_grids_name_both_shapes_as_arrays_and_as_files(tmp_path: Path) -> None:
    with pytest.raises(TerrainError) as from_array:
        TerrainMap(np.zeros(SHAPE), np.zeros((4, 4), np.uint8), np.zeros(SHAPE, bool), 0.5)
    assert str(from_array.value) == (
        "terrain_class layer is 4 x 4 cells but elevation layer is 3 x 4: all layers must share one grid"
    )
    np.save(tmp_path / "e.npy", np.zeros(SHAPE))
    np.save(tmp_path / "c.npy", np.zeros((4, 4), np.uint8))
    with pytest.raises(TerrainError) as from_file:
        load_npy_layers(tmp_path / "e.npy", tmp_path / "c.npy", resolution_m=0.5)
    assert str(from_file.value) == (
        f"classes layer file {str(tmp_path / 'c.npy')!r} is 4 x 4 cells but elevation layer file "
        f"{str(tmp_path / 'e.npy')!r} is 3 x 4: all layers must share one grid"
    )
    assert from_file.value.key == "classes"
