"""``rover`` imports only the picked command family, and no family imports a benchmark's peers up front."""

from __future__ import annotations

import subprocess
import sys

import pytest

from rover_cli.main import FAMILIES, picked_family

# Modules that cost seconds of start-up and belong to one benchmark each (filterpy -> scipy.stats, ...).
BENCHMARK_PEERS = ("scipy.stats", "filterpy", "scipy.sparse.csgraph", "firmware_bridge.can_bench")


@pytest.mark.parametrize(
    ("argv", "family"),
    [
        (["hil", "trial", "x.toml"], "hil"),
        (["-vv", "bench", "hil"], "bench"),
        (["--help"], None),
        (["nope"], None),
    ],
)
def test_picked_family(argv: list[str], family: str | None) -> None:
    assert picked_family(argv) == family


def _imported_after(code: str) -> set[str]:
    probe = f"import sys\n{code}\nprint(' '.join(sorted(sys.modules)))"
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    return set(result.stdout.split())


def test_every_family_registers_without_benchmark_peers() -> None:
    imported = _imported_after("from rover_cli.main import build_parser\nbuild_parser()")
    assert imported.isdisjoint(BENCHMARK_PEERS)


def test_a_picked_family_leaves_the_others_unimported() -> None:
    imported = _imported_after("from rover_cli.main import build_parser\nbuild_parser('logs')")
    others = {module for name, module in FAMILIES.items() if name != "logs"}
    assert imported.isdisjoint(others)
    assert "rover_cli.logs_commands" in imported


def test_bench_plan_help_shows_the_default_sizes_themselves() -> None:
    from navigator.plan_bench_sizes import DEFAULT_SIZES
    from rover_cli.main import build_parser

    parser = build_parser("bench")
    args = parser.parse_args(["bench", "plan"])
    assert args.sizes == list(DEFAULT_SIZES)
    result = subprocess.run(
        [sys.executable, "-m", "rover_cli.main", "bench", "plan", "--help"], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    help_text = " ".join(result.stdout.split())  # argparse wraps lines at the terminal's width
    assert f"(default: {' '.join(map(str, DEFAULT_SIZES))})" in help_text
    assert "DEFAULT_SIZES" not in help_text
