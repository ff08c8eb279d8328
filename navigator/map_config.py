"""Terrain maps from a TOML table: the paper's maze matrix, .npy or PNG layers, or procedural from a seed.

Shared by scenario files (the simulator's true world) and the rover config's ``[map]`` (the map the
navigator believes), so both read terrain the same way with the same errors.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from logs.settings import MAX_SEED, Table
from navigator.errors import TerrainError
from navigator.png_layers import load_png_layers
from navigator.terrain import TerrainMap, check_map_cells, from_maze, load_npy_layers, procedural
from navigator.terrain_classes import class_by_name

TERRAIN_KINDS = ("maze", "procedural", "npy", "png")
_LAYERS = ("elevation", "classes", "obstacles")  # the layer file keys of the npy and png kinds


def terrain_from_table(table: Table, base_dir: Path) -> tuple[TerrainMap, str]:
    """The terrain a ``[terrain]``-style table describes, and a one-line summary of it.

    Paths of .npy / PNG layers are relative to ``base_dir`` (the directory of the file the table came from).
    """
    kind = table.text("kind", choices=TERRAIN_KINDS)
    if kind in ("npy", "png") and not any(table.has(layer) for layer in _LAYERS):
        # The map's shape comes from its layers: at least one is needed.
        raise table.absent(
            "", f'kind = "{kind}" needs at least one layer file: elevation, classes or obstacles'
        )
    try:
        if kind == "maze":
            matrix = table.raw("matrix")
            cell_size = table.number("cell_size_m", 2.0, lo=0.05, hi=100.0)
            resolution = table.number("resolution_m", cell_size, lo=0.01, hi=cell_size)
            class_id = _class_id(table, "class", "firm")
            terrain = from_maze(matrix, cell_size, terrain_class=class_id, resolution_m=resolution)
            summary = f"maze of {cell_size} m cells at {resolution} m"
        elif kind == "procedural":
            width, height = table.point("size_m")
            resolution = table.number("resolution_m", 0.25, lo=0.01, hi=10.0)
            rows, cols = round(height / resolution), round(width / resolution)
            if rows < 2 or cols < 2:
                raise table.error("size_m", "the map must be at least two cells each way")
            check_map_cells(
                rows,
                cols,
                f"{width:,.10g} x {height:,.10g} m at resolution_m {resolution:g} m",
                "make size_m smaller or resolution_m coarser",
                key="size_m",
            )
            terrain = procedural(
                (rows, cols),
                resolution,
                np.random.default_rng(table.integer("seed", 0, lo=0, hi=MAX_SEED)),
                base_class=_class_id(table, "class", "firm"),
                hill_height_m=table.number("hill_height_m", 0.5, lo=0.0, hi=100.0),
                hill_count=table.integer("hill_count", 3, lo=0, hi=1000),
                class_patch_count=table.integer("class_patch_count", 0, lo=0, hi=1000),
            )
            summary = f"procedural {width:g}x{height:g} m at {resolution} m"
        elif kind == "png":
            terrain = _png_terrain(table, base_dir)
            summary = f"PNG layers {terrain.shape[0]}x{terrain.shape[1]} at {terrain.resolution_m} m"
        else:
            resolution = table.number("resolution_m", lo=0.01, hi=100.0)

            terrain = load_npy_layers(
                elevation=_layer_path(table, "elevation", base_dir),
                classes=_layer_path(table, "classes", base_dir),
                obstacles=_layer_path(table, "obstacles", base_dir),
                resolution_m=resolution,
                origin=table.point("origin", [0.0, 0.0]),
            )
            summary = f"npy layers {terrain.shape[0]}x{terrain.shape[1]} at {resolution} m"
    except TerrainError as err:
        # Layer files and the class table are read only when present: a misspelt one reads as absent.
        raise table.absent(err.key or "", str(err)) from err
    table.finish()
    return terrain, summary


def _png_terrain(table: Table, base_dir: Path) -> TerrainMap:
    """``kind = "png"``: layer paths, the elevation scale, the class table and the obstacle threshold."""

    class_values: dict[int, int] = {}
    if table.has("class_values"):
        values = table.table("class_values")
        for key in list(values.keys()):
            if not key.isdigit() or int(key) > 65535:
                raise values.error(key, "keys are palette indices or grey levels: whole numbers 0..65535")
            class_values[int(key)] = _class_id(values, key, "firm")
        values.finish()
    return load_png_layers(
        elevation=_layer_path(table, "elevation", base_dir),
        classes=_layer_path(table, "classes", base_dir),
        obstacles=_layer_path(table, "obstacles", base_dir),
        resolution_m=table.number("resolution_m", lo=0.01, hi=100.0),
        origin=table.point("origin", [0.0, 0.0]),
        elevation_scale_m=table.number("elevation_scale_m", 0.01, lo=-1000.0, hi=1000.0),
        elevation_offset_m=table.number("elevation_offset_m", 0.0, lo=-1e5, hi=1e5),
        class_values=class_values,
        obstacle_threshold=table.number("obstacle_threshold", 0.5, lo=1e-6, hi=1.0),
        base_class=_class_id(table, "class", "firm"),
    )


def _layer_path(table: Table, key: str, base_dir: Path) -> Path | None:
    """The layer file ``key`` names, relative to ``base_dir`` (``Table.file_path``); None if absent."""
    return table.file_path(key, base_dir, f"{key} layer file") if table.has(key) else None


def _class_id(table: Table, key: str, default: str) -> int:
    name = table.text(key, default)
    try:
        return class_by_name(name).id
    except (KeyError, ValueError) as err:
        raise table.error(key, str(err)) from err
