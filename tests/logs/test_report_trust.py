"""What ``rover logs report`` tells an analyst: where each figure comes from (truth or estimate), what ran
(scenario, seed, variant, config), a campaign grouped and ordered as the campaign, and no point-by-point
gap between runs of different scenarios."""

from __future__ import annotations

import re
import warnings
from pathlib import Path

from logs.recorder import McapRecorder
from logs.report import _fmt, write_report
from logs.synthetic import synthetic_metadata, synthetic_trial
from logs.topics import LOG, NAVIGATOR_PATH, TRUTH_CONTACTS, planar_pose, stamp

DURATION_S = 20.0
TRUTH_TOPICS = frozenset({"truth/pose", "truth/wheels", "truth/stability", "truth/contacts"})


def _write(
    path: Path,
    *,
    name: str = "synthetic-rocky",
    terrain: str = "rocky",
    trial: dict[str, str] | None = None,
    skip: frozenset[str] = frozenset(),
    contact_at: tuple[float, float] | None = None,
) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    scenario = synthetic_metadata(DURATION_S, terrain) | {"name": name, "seed": "3"}
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", scenario)
        if trial is not None:
            recorder.add_metadata("trial", trial)
        for topic, t, message in synthetic_trial(DURATION_S, terrain=terrain):
            if topic not in skip:
                recorder.publish(topic, t, message)
        if contact_at is not None:
            t = int(DURATION_S * 1e9 / 2)
            x, y = contact_at
            contact = {"timestamp": stamp(t), "kind": "collision", "obstacle_id": "far", "x": x, "y": y}
            recorder.publish(TRUTH_CONTACTS, t, contact)
            replan = [planar_pose(x, y, 0.0), planar_pose(x + 5.0, 1.0, 0.0)]
            recorder.publish(
                NAVIGATOR_PATH,
                t,
                {"timestamp": stamp(t), "frame_id": "enu", "poses": replan, "cost": 1.0, "length_m": 5.0},
            )
    return path


def test_figures_from_the_estimate_say_so(tmp_path: Path) -> None:
    real = _write(tmp_path / "real.mcap", skip=TRUTH_TOPICS)  # what a `rover run` recording holds
    text = write_report([real], tmp_path / "out", plots=False).markdown.read_text(encoding="utf-8")
    assert "| distance to goal at end (m, estimate) |" in text
    assert "| distance (m, estimate) |" in text
    assert "| path accuracy (% of driven, estimate) |" in text
    assert ", truth)" not in text and "truth distance" not in text  # no figure claims to be the truth


def test_the_report_says_what_ran_in_words(tmp_path: Path) -> None:
    trial = {"mode": "sim-lockstep", "config": "configs/fast.toml", "variant": "fast"}
    run = _write(tmp_path / "sim.mcap", trial=trial, contact_at=(6.0, 0.2))
    result = write_report([run], tmp_path / "out")
    text = result.markdown.read_text(encoding="utf-8")
    for fact in ("scenario: synthetic-rocky", "seed: 3", "variant: fast", "config: configs/fast.toml"):
        assert fact in text
    assert "| estimator position error RMS (m, vs truth) |" in text and "error rms m" not in text
    assert "| CAN bitrate (bit/s) |" in text and "can bitrate" not in text
    assert "| cross-track error RMS (m, rover's estimate) |" in text
    per_metre = re.search(r"\| energy per metre \(Wh/m, truth distance\) \| ([0-9.e-]+) \|", text)
    assert per_metre is not None
    assert len(per_metre.group(1).replace(".", "").lstrip("0")) == 4  # 4 significant digits
    trajectory = result.html.read_text(encoding="utf-8").split("<svg")[1]
    for legend in (">start<", ">goal<", ">contacts<", ">obstacle<", ">plans<", ">last plan<"):
        assert legend in trajectory
    assert "rover's estimate" in result.html.read_text(encoding="utf-8").split("<svg")[2]  # cross-track


def test_runs_of_different_scenarios_are_not_compared_point_by_point(tmp_path: Path) -> None:
    a = _write(tmp_path / "a.mcap", name="rocky-boulders")
    b = _write(tmp_path / "b.mcap", name="te-crossing")
    result = write_report([a, b], tmp_path / "out", plots=False)
    comparison = result.comparisons[0]
    assert comparison.not_comparable == ["scenario name 'rocky-boulders' vs 'te-crossing'"]
    assert comparison.gap_rms_m is None and comparison.s_m == []
    text = result.markdown.read_text(encoding="utf-8")
    assert "different scenarios" in text and "gap RMS" not in text
    assert comparison.metrics["distance_m"]["a"] is not None  # per-run metrics still compared


def test_a_campaign_is_grouped_and_ordered_as_the_campaign(tmp_path: Path) -> None:
    campaign = tmp_path / "campaign"
    # two campaign terrains of one class; variants listed terrain-aware first, classical second
    for terrain_index, terrain in enumerate(("field-b", "field-a")):
        for variant_index, variant in enumerate(("terrain-aware", "classical")):
            trial = {
                "terrain": terrain,
                "terrain_index": str(terrain_index),
                "variant": variant,
                "variant_index": str(variant_index),
            }
            contact = (6.0, 0.2) if variant == "classical" else None
            _write(
                campaign / terrain / variant / "seed3" / "trial.mcap",
                terrain="sandy",
                trial=trial,
                contact_at=contact,
            )
    result = write_report([campaign], tmp_path / "out", plots=False)
    rows = [(row["terrain"], row["variant"], row["collisions"]) for row in result.terrain_table]
    assert rows == [
        ("field-b", "terrain-aware", 0),
        ("field-b", "classical", 1),
        ("field-a", "terrain-aware", 0),
        ("field-a", "classical", 1),
    ]
    assert all(row["terrain_class"] == "sandy" for row in result.terrain_table)
    baselines = {Path(c.a).parent.parent.name for c in result.comparisons}
    assert baselines == {"terrain-aware"}
    assert "collisions (total)" in result.markdown.read_text(encoding="utf-8")


def test_files_given_one_by_one_are_compared_in_the_order_given(tmp_path: Path) -> None:
    """The first file given is A, each other one B (docs/reports.md). `rover logs report trial.mcap
    campaign/rocky/classical/seed1/trial.mcap` once made the campaign's trial A, the file given first B:
    every B - A had its sign turned, since the campaign order was applied to files given one by one."""
    lone = _write(tmp_path / "trial.mcap", trial={"mode": "sim-lockstep"})
    placed = {"terrain": "rocky", "terrain_index": "0", "variant": "classical", "variant_index": "1"}
    campaign_trial = _write(tmp_path / "classical.mcap", trial=placed, contact_at=(6.0, 0.2))
    result = write_report([lone, campaign_trial], tmp_path / "out", plots=False)
    assert [run.path for run in result.runs] == [str(lone), str(campaign_trial)]
    (comparison,) = result.comparisons
    assert (comparison.a, comparison.b) == (str(lone), str(campaign_trial))
    text = result.markdown.read_text(encoding="utf-8")
    assert f"## Comparison: A = {lone}, B = {campaign_trial}" in text


def test_a_run_without_a_trajectory_draws_its_plots_without_a_warning(tmp_path: Path) -> None:
    """`rover logs report` of a recording with no pose (a rover stopped in its warm-up, another tool's
    file) printed matplotlib's "/.../logs/plots.py:75: UserWarning: No artists with labels found to put
    in legend" amid its own output: the trajectory plot asked for a legend with nothing in it."""
    path = tmp_path / "warm-up.mcap"
    with McapRecorder(path) as recorder:
        message = {
            "timestamp": stamp(0),
            "level": 3,
            "message": "start-up",
            "name": "rover",
            "file": "",
            "line": 0,
        }
        recorder.publish(LOG, 0, message)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = write_report([path], tmp_path / "out")
    assert "trajectory" in result.html.read_text(encoding="utf-8")


def test_two_campaign_directories_are_kept_apart(tmp_path: Path) -> None:
    """`rover logs report before/ after/` (a campaign run twice, before and after a change) pooled the two:
    one row per terrain and variant with runs 6 for 3 + 3, the means of both, and the terrain-aware run
    of one folder compared with the classical run of the other."""
    for folder, contact in (("before", None), ("after", (6.0, 0.2))):
        for variant_index, variant in enumerate(("terrain-aware", "classical")):
            placed = {"terrain": "rocky", "terrain_index": "0", "variant": variant}
            _write(
                tmp_path / folder / "rocky" / variant / "seed3" / "trial.mcap",
                trial=placed | {"variant_index": str(variant_index)},
                contact_at=contact if variant == "classical" else None,
            )
    before, after = tmp_path / "before", tmp_path / "after"
    result = write_report([before, after], tmp_path / "out", plots=False)
    rows = [(r["campaign"], r["variant"], r["runs"], r["collisions"]) for r in result.terrain_table]
    assert rows == [
        (str(before), "terrain-aware", 1, 0),
        (str(before), "classical", 1, 0),
        (str(after), "terrain-aware", 1, 0),
        (str(after), "classical", 1, 1),
    ]
    pairs = [
        (Path(c.a).relative_to(tmp_path).parts[0], Path(c.b).relative_to(tmp_path).parts[0])
        for c in result.comparisons
    ]
    assert pairs == [("before", "before"), ("after", "after")]
    assert "| campaign (folder) |" in result.markdown.read_text(encoding="utf-8")


def test_energy_per_metre_keeps_its_4_significant_digits() -> None:
    """docs/reports.md: energy per metre with 4 significant digits. A run of 0.02500 Wh/m read "0.025" beside
    another's "0.0249", and their difference "9.7e-05": trailing zeros were dropped, small numbers went
    to scientific notation."""
    assert _fmt(0.025, "energy_wh_per_m") == "0.02500"
    assert _fmt(0.0244013, "energy_wh_per_m") == "0.02440"
    assert _fmt(9.7e-05, "energy_wh_per_m") == "0.00009700"
    assert _fmt(-2e-05, "energy_wh_per_m") == "-0.00002000"
    assert _fmt(0.0, "energy_wh_per_m") == "0.000"
    assert _fmt(1.23456, "energy_wh_per_m") == "1.235"
    # A value that rounds up past a power of ten keeps 4 digits, not 5.
    assert _fmt(0.099996, "energy_wh_per_m") == "0.1000" and _fmt(9.99996, "energy_wh_per_m") == "10.00"
