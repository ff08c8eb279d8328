"""A map too big to plan on is refused before anything is allocated, naming key, limit and size."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from hil.scenario import load_scenario
from logs.settings import ConfigError, parse_toml
from navigator.config import rover_config_from_table
from navigator.terrain import MAX_MAP_CELLS

DATA = Path(__file__).resolve().parents[1] / "data"
LIMIT_TEXT = f"at most {MAX_MAP_CELLS:,}"


def scenario_error(tmp_path: Path, old: str, new: str) -> ConfigError:
    text = (DATA / "small_rocky.toml").read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "huge.toml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    with pytest.raises(ConfigError) as caught:
        load_scenario(path)
    return caught.value


def test_a_procedural_scenario_a_thousand_kilometres_wide(tmp_path: Path) -> None:
    error = scenario_error(tmp_path, "size_m = [14.0, 10.0]", "size_m = [1e6, 1e6]")
    assert error.key == "terrain.size_m"
    assert "4,000,000 x 4,000,000 = 16,000,000,000,000 cells" in error.problem
    assert LIMIT_TEXT in error.problem and "1,000,000 x 1,000,000 m at resolution_m 0.25 m" in error.problem


def test_a_fine_resolution_on_a_modest_map(tmp_path: Path) -> None:
    # 100 m x 100 m is fine at 0.25 m (160,000 cells) but not at 0.01 m.
    error = scenario_error(
        tmp_path, "size_m = [14.0, 10.0]\nresolution_m = 0.25", "size_m = [100.0, 100.0]\nresolution_m = 0.01"
    )
    assert error.key == "terrain.size_m"
    assert "10,000 x 10,000 = 100,000,000 cells" in error.problem
    assert "make size_m smaller or resolution_m coarser" in error.problem


def test_the_rover_configs_map_names_its_own_key() -> None:
    text = '[map]\nkind = "procedural"\nsize_m = [5000.0, 5000.0]\nresolution_m = 0.5\n'
    with pytest.raises(ConfigError) as caught:
        rover_config_from_table(parse_toml(text, "rover.toml"))
    assert caught.value.key == "map.size_m"
    assert "10,000 x 10,000 = 100,000,000 cells" in caught.value.problem


def test_a_maze_split_too_finely_names_resolution_m() -> None:
    text = '[map]\nkind = "maze"\nmatrix = [[2, 1], [2, 2]]\ncell_size_m = 100.0\nresolution_m = 0.01\n'
    with pytest.raises(ConfigError) as caught:
        rover_config_from_table(parse_toml(text, "rover.toml"))
    assert caught.value.key == "map.resolution_m"
    assert "20,000 x 20,000 = 400,000,000 cells" in caught.value.problem
    assert "10000 x 10000 grid cells" in caught.value.problem


def test_a_npy_layer_past_the_limit_is_refused_from_its_header(tmp_path: Path) -> None:
    side = 4097  # one row and column past 4096 x 4096
    # open_memmap writes the header and sizes the file without writing the data (sparse on disk).
    layer = np.lib.format.open_memmap(tmp_path / "z.npy", mode="w+", dtype=np.uint8, shape=(side, side))
    del layer
    text = '[map]\nkind = "npy"\nresolution_m = 0.25\nobstacles = "z.npy"\n'
    with pytest.raises(ConfigError) as caught:
        rover_config_from_table(parse_toml(text, str(tmp_path / "rover.toml")))
    assert caught.value.key == "map.obstacles"
    assert f"{side:,} x {side:,} = {side * side:,} cells" in caught.value.problem


def _png_chunk(kind: bytes, body: bytes) -> bytes:
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def test_a_png_layer_claiming_a_huge_image_is_refused_before_decoding(tmp_path: Path) -> None:
    # A few dozen bytes that claim a 100,000 x 50,000 grey image: a decoder would try to inflate it.
    header = struct.pack(">IIBBBBB", 100_000, 50_000, 8, 0, 0, 0, 0)
    png = b"\x89PNG\r\n\x1a\n" + _png_chunk(b"IHDR", header) + _png_chunk(b"IEND", b"")
    (tmp_path / "e.png").write_bytes(png)
    text = '[map]\nkind = "png"\nresolution_m = 0.25\nelevation = "e.png"\n'
    with pytest.raises(ConfigError) as caught:
        rover_config_from_table(parse_toml(text, str(tmp_path / "rover.toml")))
    assert caught.value.key == "map.elevation"
    assert "50,000 x 100,000 = 5,000,000,000 cells" in caught.value.problem
