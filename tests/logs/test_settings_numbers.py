"""A number too large for a float is a config error naming the key, not an OverflowError traceback.

TOML (Python's tomllib) reads an integer of any number of digits; ``float()`` of one past ~1.8e308
raises. A hand-written file with a key held down too long reaches every numeric getter this way."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from logs.settings import ConfigError, Table, parse_toml
from tests.logs.small_scenario import SMALL_SCENARIO, load_text

HUGE = "9" * 400


@pytest.mark.parametrize(
    ("text", "read", "said"),
    [
        (f"x = {HUGE}", lambda t: t.number("x"), "x: expected a finite number, got 9999"),
        (
            f"x = [1.0, {HUGE}]",
            lambda t: t.numbers("x"),
            "x: expected a list of finite numbers, got [1.0, 999",
        ),
        (
            f"x = [1.0, {HUGE}]",
            lambda t: t.point("x"),
            "x: expected [x, y] with two finite numbers, got [1.0, 9",
        ),
    ],
)
def test_an_integer_too_large_for_a_float_is_refused_naming_the_key(
    text: str, read: Callable[[Table], object], said: str
) -> None:
    with pytest.raises(ConfigError) as caught:
        read(parse_toml(text, "a.toml"))
    assert str(caught.value).startswith(f"a.toml: {said}"), str(caught.value)
    assert len(str(caught.value)) < 200  # the value is cut, not printed in its 400 digits


@pytest.mark.parametrize(
    ("text", "key"),
    [
        (
            f"{SMALL_SCENARIO}[[moving_obstacles]]\nradius_m = 0.5\nspeed_mps = 1.0\n"
            f"waypoints = [[1, 1], [{HUGE}, 1]]\n",
            "moving_obstacles[0].waypoints",
        ),
        (
            SMALL_SCENARIO.replace(
                'kind = "procedural"\nsize_m = [10.0, 10.0]', f'kind = "maze"\nmatrix = [[2, {HUGE}]]'
            ),
            "terrain",
        ),
    ],
)
def test_a_scenario_with_an_integer_too_large_names_the_key(text: str, key: str) -> None:
    with pytest.raises(ConfigError) as caught:
        load_text(text)
    assert caught.value.key == key, str(caught.value)
