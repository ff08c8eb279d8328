"""Where ``rover`` points numba's cache when the package and the home directory are read-only."""

from __future__ import annotations

import os
from pathlib import Path

from rover_cli.numba_cache import choose_numba_cache_dir, private_temp_cache, user_cache_dir

PACKAGES = [Path("/opt/rover/navigator"), Path("/opt/rover/estimator")]
FALLBACK = Path("/tmp/rover-numba-cache-999")


def only(*writable: Path):  # type: ignore[no-untyped-def]
    return lambda path: path in writable


def test_read_only_package_and_home_get_a_cache_of_ours() -> None:
    env = {"HOME": "/nonexistent"}
    choice = choose_numba_cache_dir(env, PACKAGES, lambda: FALLBACK, only())
    assert choice is not None and choice.path == FALLBACK
    assert (
        "/opt/rover/navigator/__pycache__" in choice.reason and "/nonexistent/.cache/numba" in choice.reason
    )


def test_numba_is_left_alone_where_it_can_cache_itself() -> None:
    env = {"HOME": "/home/rover"}
    in_tree = only(*(d / "__pycache__" for d in PACKAGES))
    assert choose_numba_cache_dir(env, PACKAGES, lambda: FALLBACK, in_tree) is None
    home = only(Path("/home/rover/.cache/numba"))
    assert choose_numba_cache_dir(env, PACKAGES, lambda: FALLBACK, home) is None
    # One package read-only is enough to need the user-wide cache: numba picks per kernel file.
    one_tree = only(PACKAGES[0] / "__pycache__")
    choice = choose_numba_cache_dir(env, PACKAGES, lambda: FALLBACK, one_tree)
    assert choice is not None and "estimator" in choice.reason


def test_xdg_cache_home_is_where_numba_looks_first() -> None:
    env = {"HOME": "/home/rover", "XDG_CACHE_HOME": "/var/cache/x"}
    assert user_cache_dir(env) == Path("/var/cache/x/numba")
    assert choose_numba_cache_dir(env, PACKAGES, lambda: FALLBACK, only(Path("/var/cache/x/numba"))) is None


def test_the_operators_numba_cache_dir_is_kept() -> None:
    env = {"NUMBA_CACHE_DIR": "/var/cache/rover/numba", "HOME": "/nonexistent"}
    assert choose_numba_cache_dir(env, PACKAGES, lambda: FALLBACK, only()) is None


def test_temp_cache_is_private_or_fresh(tmp_path: Path) -> None:
    uid = os.getuid()
    ours = private_temp_cache(tmp_path, uid)
    assert ours == tmp_path / f"rover-numba-cache-{uid}" and ours.stat().st_mode & 0o777 == 0o700
    assert private_temp_cache(tmp_path, uid) == ours  # kept across runs: the next start is warm
    # Someone else's, or one others can write into: their pickles would be loaded as code.
    other = private_temp_cache(tmp_path, uid + 1)
    assert other.parent == tmp_path and other.name != f"rover-numba-cache-{uid + 1}"
    ours.chmod(0o777)
    shared = private_temp_cache(tmp_path, uid)
    assert shared != ours and shared.is_dir()
