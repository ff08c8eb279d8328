"""What a terrain layer may hold, checked once for every way a map is made: a ``TerrainMap`` built from
arrays, and the layer files (``.npy``, PNG) a map is loaded from.

An error is a ``TerrainError`` that names the layer (its file, when it came from one, and then the map
table's key of that file as ``key``) and what was wrong: the dtype, the shape, or the first bad cell and
the value in it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn

import numpy as np

from navigator.errors import TerrainError
from navigator.terrain_classes import TERRAIN_CLASSES

# The dtypes each kind of layer may hold; anything else (text, objects, complex, dates) is a mistake, even
# where numpy would convert it without a word ("1.5" as text becomes 1.5 m of elevation).
_KINDS = {
    "elevation": (np.integer, np.floating),  # metres
    "classes": (np.integer, np.floating),  # class ids; floats must be whole
    "obstacles": (np.bool_, np.integer, np.floating),  # 0/1
}
_WANTED = {"elevation": "real numbers (metres)", "classes": "class ids", "obstacles": "booleans or 0/1"}
_DTYPE_WORDS = {"U": "text", "S": "bytes", "O": "Python objects", "b": "booleans", "c": "complex numbers"}


@dataclass(frozen=True)
class Layer:
    """One layer as an error names it. ``kind``: ``elevation``, ``classes`` or ``obstacles`` (what it may
    hold); ``label``: how a message names it; ``key``: the map table's key of its file (None for arrays)."""

    kind: str
    label: str
    key: str | None = None

    @classmethod
    def file(cls, kind: str, path: str | Path) -> Layer:
        """The layer read from ``path``, named by the key ``kind`` (as a map table names its file)."""
        return cls(kind, f"{kind} layer file {str(path)!r}", kind)

    @classmethod
    def array(cls, kind: str, name: str) -> Layer:
        """A layer given as an array (``TerrainMap``'s field ``name``)."""
        return cls(kind, f"{name} layer")


def checked_layer(values: np.ndarray, layer: Layer) -> np.ndarray:
    """``values`` as a map holds that kind of layer (elevation float64 metres, classes uint8 ids, obstacles
    bool), or a ``TerrainError``: not one non-empty 2-D array; a dtype the kind may not hold; a non-finite
    value; a class id that is not whole or not in ``TERRAIN_CLASSES``; an obstacle value other than 0/1."""
    if values.ndim != 2:
        _refuse(layer, f"must hold one 2-D array, got shape {values.shape}")
    if not any(np.issubdtype(values.dtype, kind) for kind in _KINDS[layer.kind]):
        what = _DTYPE_WORDS.get(values.dtype.kind, "values")
        _refuse(layer, f"holds {what} (dtype {values.dtype.str}), not {_WANTED[layer.kind]}")
    if values.size == 0:
        _refuse(layer, f"holds an empty array (shape {values.shape})")
    if np.issubdtype(values.dtype, np.floating) and not np.all(np.isfinite(values)):
        row, col = np.argwhere(~np.isfinite(values))[0]
        _refuse(layer, f"holds a non-finite value ({values[row, col]}) at cell (row {row}, col {col})")
    if layer.kind == "classes":
        if np.issubdtype(values.dtype, np.floating):
            _refuse_cells(values, layer, values != np.round(values), "a whole-number class id")
        known = f"a terrain class id (known ids: {sorted(TERRAIN_CLASSES)})"
        _refuse_cells(values, layer, ~np.isin(values, list(TERRAIN_CLASSES)), known)
        return values.astype(np.uint8)
    if layer.kind == "obstacles":
        if values.dtype != np.bool_:
            _refuse_cells(values, layer, ~np.isin(values, (0, 1)), "0 or 1")
        return values.astype(bool)
    return values.astype(np.float64)


def check_one_grid(layers: Sequence[tuple[Layer, tuple[int, ...]]]) -> None:
    """``TerrainError`` naming the first layer whose shape (rows, cols) is not the first layer's, and
    both shapes: a map's layers share one grid."""
    (first, shape), *others = layers
    for layer, other in others:
        if tuple(other) != tuple(shape):
            grid = f"{first.label} is {_cells(shape)}: all layers must share one grid"
            _refuse(layer, f"is {_cells(other)} cells but {grid}")


def _refuse_cells(values: np.ndarray, layer: Layer, bad: np.ndarray, wanted: str) -> None:
    """``TerrainError`` naming the first cell where ``bad`` is set, its value and what it should hold."""
    if np.any(bad):
        row, col = np.argwhere(bad)[0]
        _refuse(layer, f"holds {values[row, col].item():g} at cell (row {row}, col {col}), not {wanted}")


def _refuse(layer: Layer, problem: str) -> NoReturn:
    raise TerrainError(f"{layer.label} {problem}", key=layer.key)


def _cells(shape: Sequence[int]) -> str:
    return " x ".join(str(n) for n in shape)
