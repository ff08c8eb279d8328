"""Seeds: every command and file that takes one refuses a negative or too large seed before anything runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from hil.campaign import load_campaign
from hil.scenario import load_scenario
from logs.settings import MAX_SEED, ConfigError
from rover_cli.main import main

DATA = Path(__file__).resolve().parents[1] / "data"
SCENARIO = DATA / "small_rocky.toml"

# Every command with --seed; each is refused by argparse, so none starts (the soak would run for minutes).
SEEDED_COMMANDS = [
    ["hil", "trial", str(SCENARIO), "--no-telemetry"],
    ["hil", "peer", str(SCENARIO)],
    ["hil", "soak", "--minutes", "0.01"],
    ["bench", "estimator"],
    ["bench", "plan"],
]


@pytest.mark.parametrize("command", SEEDED_COMMANDS, ids=lambda c: " ".join(c[:2]))
@pytest.mark.parametrize("seed", ["-1", str(MAX_SEED + 1), "1.5", "seven"])
def test_every_seed_option_refuses_a_bad_seed_at_the_command_line(
    command: list[str], seed: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    argv = [*command, "--seed", seed]
    if command[0] == "hil":
        argv += ["--out", str(out)]
    with pytest.raises(SystemExit) as stopped:
        main(argv)
    assert stopped.value.code == 2
    error = capsys.readouterr().err
    assert "--seed" in error and f"0 to {MAX_SEED}" in error, error
    assert not out.exists()


def test_the_largest_seed_is_accepted_by_the_parser() -> None:
    from rover_cli.main import build_parser

    args = build_parser("hil").parse_args(["hil", "trial", str(SCENARIO), "--seed", str(MAX_SEED)])
    assert args.seed == MAX_SEED


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("seed = 3", "seed = -1", "seed"),
        ("seed = 3", f"seed = {MAX_SEED + 1}", "seed"),
        ("seed = 2", "seed = -4", "terrain.seed"),
        ("seed = 2", f"seed = {MAX_SEED + 1}", "terrain.seed"),
    ],
)
def test_scenario_seeds_are_bounded(tmp_path: Path, old: str, new: str, key: str) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(SCENARIO.read_text().replace(old, new, 1))
    with pytest.raises(ConfigError) as caught:
        load_scenario(bad)
    assert caught.value.key == key


def test_campaign_seeds_are_bounded(tmp_path: Path) -> None:
    path = tmp_path / "c.toml"
    path.write_text(
        f'name = "c"\nseeds = [1, {MAX_SEED + 1}]\n[[terrains]]\nname = "t"\nscenario = "{SCENARIO}"\n'
    )
    with pytest.raises(ConfigError) as caught:
        load_campaign(path)
    assert caught.value.key == "seeds" and str(MAX_SEED) in caught.value.problem
