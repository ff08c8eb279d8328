"""Terrain layers from PNG images: elevation (grey), terrain class (palette index or grey) and obstacles.

Pixels are read with ``matplotlib.image.imread`` (matplotlib is already a dependency); the PNG header is
parsed here for what imread hides: the bit depth (to turn its 0..1 floats back into whole grey levels) and
the palette (imread expands palette images to colours; the palette maps them back to indices).

Encoding (docs/planning.md, "Map formats"):

* elevation: 8- or 16-bit grey; ``elevation_m = level * elevation_scale_m + elevation_offset_m``;
* terrain class: palette indices, or grey levels, each mapped to a class through ``class_values``;
* obstacles: grey; a pixel darker than ``obstacle_threshold`` (fraction of white) is an obstacle.

Grey stored as RGB(A) with equal channels (what ``matplotlib.image.imsave`` writes) counts as grey. A
pixel that is not fully opaque is "no data" (the image's NaN) and an error. Image row 0 is the NORTH edge
(images are drawn top-down) while the map's row 0 is the southern one, so every layer is flipped.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from navigator.errors import TerrainError
from navigator.layer_checks import Layer, check_one_grid
from navigator.terrain import TerrainMap, check_map_cells
from navigator.terrain_classes import TERRAIN_CLASSES

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_GREY, _RGB, _PALETTE, _GREY_ALPHA, _RGBA = 0, 2, 3, 4, 6


@dataclass(frozen=True)
class PngHeader:
    """What the pixels alone do not say: bit depth, PNG colour type and the palette (``(n, 3)`` uint8)."""

    bit_depth: int
    colour_type: int
    palette: np.ndarray | None

    @property
    def max_level(self) -> int:
        """The largest channel value: palette entries are always 8-bit."""
        return 255 if self.colour_type == _PALETTE else (1 << self.bit_depth) - 1


@dataclass(frozen=True)
class PngImage:
    """One decoded layer; ``channels``: ``(rows, cols, k)`` floats in [0, 1], row 0 south (map order)."""

    path: Path
    name: str
    header: PngHeader
    channels: np.ndarray

    def grey_levels(self) -> np.ndarray:
        """Whole grey levels ``(rows, cols)`` int64, 0..max_level; TerrainError for colour pixels."""
        colour = self.channels[..., :3]
        if colour.shape[-1] == 3 and not (
            np.array_equal(colour[..., 0], colour[..., 1]) and np.array_equal(colour[..., 0], colour[..., 2])
        ):
            row, col = _first(np.any(colour != colour[..., :1], axis=-1), self.channels.shape[0])
            raise TerrainError(
                f"{self.name} layer {str(self.path)!r} must be greyscale but pixel (image row {row}, col "
                f"{col}) has colour; save it as grey (equal R, G, B)",
                key=self.name,
            )
        return np.rint(colour[..., 0].astype(np.float64) * self.header.max_level).astype(np.int64)

    def palette_indices(self) -> np.ndarray:
        """The palette index of each pixel ``(rows, cols)`` int64 (first index when colours repeat)."""
        palette = self.header.palette
        if palette is None:
            raise TerrainError(f"{self.name} layer {str(self.path)!r} has no palette", key=self.name)
        rgb = np.rint(self.channels[..., :3].astype(np.float64) * 255.0).astype(np.int64)
        packed = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]
        entries = palette.astype(np.int64)
        keys = (entries[:, 0] << 16) | (entries[:, 1] << 8) | entries[:, 2]
        # np.unique keeps the first occurrence of each colour, so a repeated colour reads as its lowest index.
        unique_keys, first_index = np.unique(keys, return_index=True)
        position = np.clip(np.searchsorted(unique_keys, packed), 0, unique_keys.size - 1)
        if not np.all(unique_keys[position] == packed):
            raise TerrainError(
                f"{self.name} layer {str(self.path)!r} holds a colour not in its palette", key=self.name
            )
        return first_index[position].astype(np.int64)


def read_png_header(path: Path, name: str) -> PngHeader:
    """Bit depth, colour type and palette from the file's chunks; TerrainError if it is not a PNG."""
    try:
        data = path.read_bytes()
    except FileNotFoundError as err:
        raise TerrainError(f"{name} layer file {str(path)!r} not found", key=name) from err
    except OSError as err:
        raise TerrainError(f"{name} layer file {str(path)!r} is not readable: {err}", key=name) from err
    if not data.startswith(PNG_SIGNATURE) or data[12:16] != b"IHDR" or len(data) < 33:
        raise TerrainError(f"{name} layer file {str(path)!r} is not a PNG image", key=name)
    width, height = struct.unpack(">II", data[16:24])
    # Before any pixel is decoded: a small file can claim (and inflate to) a huge image.
    check_map_cells(height, width, f"{name} layer file {str(path)!r}", "downsample the layers", key=name)
    bit_depth, colour_type = data[24], data[25]
    palette = None
    offset = 8
    while offset + 8 <= len(data):
        (length,) = struct.unpack(">I", data[offset : offset + 4])
        kind = data[offset + 4 : offset + 8]
        if kind == b"PLTE":
            raw = np.frombuffer(data[offset + 8 : offset + 8 + length], dtype=np.uint8)
            palette = raw[: raw.size - raw.size % 3].reshape(-1, 3)
        if kind in (b"IDAT", b"IEND"):
            break  # PLTE must come before the image data
        offset += 12 + length  # length, type, data, CRC
    if colour_type == _PALETTE and palette is None:
        raise TerrainError(f"{name} layer file {str(path)!r} is a palette PNG without a palette", key=name)
    return PngHeader(bit_depth, colour_type, palette)


def read_png(path: str | Path, name: str) -> PngImage:
    """Decode one PNG layer, flipped to map orientation, with transparent pixels rejected."""
    from matplotlib import image as mpl_image  # imported when a PNG map is used: it is slow to import

    file = Path(path)
    header = read_png_header(file, name)
    try:
        pixels = np.asarray(mpl_image.imread(file, format="png"))
    except (OSError, ValueError, SyntaxError) as err:  # Pillow signals a corrupt PNG with SyntaxError
        raise TerrainError(f"{name} layer file {str(file)!r} is not a readable PNG: {err}", key=name) from err
    if pixels.ndim == 2:
        pixels = pixels[..., np.newaxis]
    if pixels.ndim != 3 or pixels.shape[0] == 0 or pixels.shape[1] == 0:
        raise TerrainError(
            f"{name} layer file {str(file)!r} has an unusable image shape {pixels.shape}", key=name
        )
    if pixels.shape[-1] in (2, 4):
        transparent = pixels[..., -1] < 1.0
        if np.any(transparent):
            row, col = _first(transparent, 0)
            raise TerrainError(
                f"{name} layer {str(file)!r}: pixel (image row {row}, col {col}) is transparent, i.e. no "
                "data; every pixel of a terrain layer must be opaque",
                key=name,
            )
        pixels = pixels[..., :-1]
    return PngImage(file, name, header, pixels[::-1])


def load_png_layers(
    elevation: str | Path | None = None,
    classes: str | Path | None = None,
    obstacles: str | Path | None = None,
    *,
    resolution_m: float,
    origin: tuple[float, float] = (0.0, 0.0),
    elevation_scale_m: float = 0.01,
    elevation_offset_m: float = 0.0,
    class_values: Mapping[int, int] | None = None,
    obstacle_threshold: float = 0.5,
    base_class: int = 0,
) -> TerrainMap:
    """A map from PNG layers (encoding in the module docstring); a missing layer is flat / ``base_class``
    / obstacle-free. ``class_values`` maps a palette index or grey level to a terrain class id."""
    for key, value in (("elevation_scale_m", elevation_scale_m), ("elevation_offset_m", elevation_offset_m)):
        if not np.isfinite(value):
            raise TerrainError(f"PNG {key} must be a finite number, got {value}")
    if not 0.0 < obstacle_threshold <= 1.0:
        raise TerrainError(f"PNG obstacle_threshold must be in (0, 1], got {obstacle_threshold}")
    images = {
        name: read_png(path, name)
        for name, path in (("elevation", elevation), ("classes", classes), ("obstacles", obstacles))
        if path is not None
    }
    if not images:
        raise TerrainError("load_png_layers needs at least one layer file to know the map's shape")
    check_one_grid(
        [(Layer.file(name, image.path), image.channels.shape[:2]) for name, image in images.items()]
    )
    shape = next(iter(images.values())).channels.shape[:2]

    elevation_m = np.zeros(shape)
    if "elevation" in images:
        elevation_m = images["elevation"].grey_levels() * elevation_scale_m + elevation_offset_m
    class_ids = np.full(shape, base_class, dtype=np.int64)
    if "classes" in images:
        class_ids = _class_ids(images["classes"], class_values or {})
    obstacle_mask = np.zeros(shape, dtype=bool)
    if "obstacles" in images:
        image = images["obstacles"]
        obstacle_mask = image.grey_levels() < obstacle_threshold * image.header.max_level
    return TerrainMap(elevation_m, class_ids, obstacle_mask, resolution_m, origin)


def _class_ids(image: PngImage, class_values: Mapping[int, int]) -> np.ndarray:
    if not class_values:
        raise TerrainError(f"classes layer {str(image.path)!r} needs a class_values table (value -> class)")
    bad_ids = sorted(c for c in class_values.values() if c not in TERRAIN_CLASSES)
    if bad_ids:
        raise TerrainError(
            f"class_values names unknown class ids {bad_ids}; known: {sorted(TERRAIN_CLASSES)}"
        )
    values = image.palette_indices() if image.header.colour_type == _PALETTE else image.grey_levels()
    known = np.array(sorted(class_values), dtype=np.int64)
    unknown = ~np.isin(values, known)
    if np.any(unknown):
        row, col = _first(unknown, values.shape[0])
        kind = "palette index" if image.header.colour_type == _PALETTE else "grey level"
        raise TerrainError(
            f"classes layer {str(image.path)!r}: {kind} {int(values[np.nonzero(unknown)][0])} at image "
            f"(row {row}, col {col}) has no entry in class_values (known values: {known.tolist()})"
        )
    lookup = np.zeros(int(known.max()) + 1, dtype=np.int64)
    lookup[known] = [class_values[int(v)] for v in known]
    return lookup[values]


def _first(mask: np.ndarray, flipped_rows: int) -> tuple[int, int]:
    """(row, col) of the first True cell, in the image's own rows when the mask was flipped to the map's."""
    row, col = (int(v) for v in np.argwhere(mask)[0])
    return (flipped_rows - 1 - row if flipped_rows else row), col
