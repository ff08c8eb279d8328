"""Map layer paths are read from the config file's folder; a path written from where the person stands
is named as that mix-up, with the fix."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from logs.settings import ConfigError
from navigator.config import load_rover_config

MAP = '[map]\nkind = "{kind}"\nresolution_m = 0.5\nelevation = "site/elevation.{ext}"\n'


@pytest.mark.parametrize(("kind", "ext"), [("npy", "npy"), ("png", "png")])
def test_a_layer_path_written_from_the_current_directory_is_named_as_such(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, kind: str, ext: str
) -> None:
    (tmp_path / "site").mkdir()
    np.save(tmp_path / "site" / "elevation.npy", np.zeros((4, 4)))
    (tmp_path / "site" / "elevation.png").write_bytes(b"")
    (tmp_path / "etc").mkdir()
    (tmp_path / "etc" / "rover.toml").write_text(MAP.format(kind=kind, ext=ext))
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as caught:
        load_rover_config("etc/rover.toml")
    assert caught.value.key == "map.elevation"
    said = caught.value.problem
    assert f"read from the folder of etc/rover.toml ({tmp_path / 'etc'})" in said, said
    assert f"exists from the current directory ({tmp_path / 'site' / f'elevation.{ext}'})" in said, said


def test_a_layer_missing_everywhere_says_where_it_was_looked_for_and_nothing_more(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "rover.toml").write_text(MAP.format(kind="npy", ext="npy"))
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as caught:
        load_rover_config(tmp_path / "rover.toml")
    said = caught.value.problem
    assert "not found: a relative path is read from the folder of" in said, said
    assert str(tmp_path / "site" / "elevation.npy") in said, said
    assert "current directory" not in said
