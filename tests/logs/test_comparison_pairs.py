"""Which runs a report compares point by point: files given one by one, or a campaign's variants."""

from types import SimpleNamespace
from typing import Any, cast

from logs.analysis import TrialAnalysis
from logs.report import comparison_pairs


def _run(name: str, seed: int, variant: str, terrain: str = "") -> TrialAnalysis:
    trial = {"variant": variant, **({"terrain": terrain} if terrain else {})}
    metadata = {"scenario": {"name": name, "seed": str(seed)}, "trial": trial}
    path = f"{terrain or name}/{variant}/seed{seed}"
    run: Any = SimpleNamespace(path=path, metadata=metadata, terrain_class="sandy")
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


def test_a_campaign_compares_within_a_terrain_only() -> None:
    """Two campaign terrains whose scenario files share a name (field-b.toml copied from field-a.toml, its
    map changed): field-a's terrain-aware run was compared with field-b's classical one, across maps, and
    field-b's two variants not at all."""
    runs = [_run("sandy-boulders", 1, v, terrain) for terrain in ("field-a", "field-b") for v in ("ta", "cl")]
    pairs = [(a.path, b.path) for a, b in comparison_pairs(runs, campaign=True)]
    assert pairs == [("field-a/ta/seed1", "field-a/cl/seed1"), ("field-b/ta/seed1", "field-b/cl/seed1")]
