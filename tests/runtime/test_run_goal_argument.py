"""``rover run --goal X,Y``: what the parser takes, and how to give a goal west of the origin."""

from __future__ import annotations

import pytest

from rover_cli.main import build_parser


def test_a_goal_west_of_the_origin_is_given_with_an_equals_sign_as_the_help_says(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # `--goal -5,3` reads as an option to argparse ("argument --goal: expected one argument"): the
    # help must say how to give it, as `rover plan --start` does.
    parser = build_parser("run")
    args = parser.parse_args(["run", "--config", "rover.toml", "--goal=-5,-3.5"])
    assert args.goal == (-5.0, -3.5)
    with pytest.raises(SystemExit):
        parser.parse_args(["run", "--help"])
    assert "--goal=-5,3" in " ".join(capsys.readouterr().out.split())
