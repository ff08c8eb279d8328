"""Which runs a report compares point by point: files given one by one, or a campaign's variants."""

from types import SimpleNamespace
from typing import Any, cast

from logs.analysis import TrialAnalysis
from logs.report import comparison_pairs


def _run(name: str, seed: int, variant: str) -> TrialAnalysis:
    metadata = {"scenario": {"name": name, "seed": str(seed)}, "trial": {"variant": variant}}
    run: Any = SimpleNamespace(path=f"{name}/{variant}/seed{seed}", metadata=metadata)
    return cast(TrialAnalysis, run)


def test_a_campaign_compares_variants_of_the_same_scenario_and_seed_only() -> None:
    runs = [
        _run(terrain, seed, variant)
        for terrain in ("rocky", "muddy")
        for variant in ("classical", "terrain-aware")
        for seed in (1, 2)
    ]
    pairs = [(a.path, b.path) for a, b in comparison_pairs(runs, campaign=True)]
    assert pairs == [
        ("rocky/classical/seed1", "rocky/terrain-aware/seed1"),
        ("rocky/classical/seed2", "rocky/terrain-aware/seed2"),
        ("muddy/classical/seed1", "muddy/terrain-aware/seed1"),
        ("muddy/classical/seed2", "muddy/terrain-aware/seed2"),
    ]
    # One variant only: nothing is compared point by point (the per-terrain table does that).
    assert comparison_pairs([_run("rocky", s, "a") for s in (1, 2, 3)], campaign=True) == []


def test_files_given_one_by_one_compare_the_first_with_each_other() -> None:
    sim, real_1, real_2 = _run("sim", 1, ""), _run("real", 1, ""), _run("real", 2, "")
    assert comparison_pairs([sim, real_1, real_2], campaign=False) == [(sim, real_1), (sim, real_2)]
