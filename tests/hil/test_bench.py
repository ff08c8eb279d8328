"""``rover bench hil``'s bookkeeping: exclusive timing, encoded-sink timing and the report's figures."""

from __future__ import annotations

import time

import pytest

from hil.bench import GOAL_REAL_TIME_FACTOR, NAMED_BASELINES, BenchReport, ExclusiveTimer, PeerFigure
from logs.sink import FanoutSink, MemorySink, Message


class _Sleeper:
    def __init__(self, seconds: float, inner: _Sleeper | None = None) -> None:
        self.seconds = seconds
        self.inner = inner

    def step(self) -> None:
        time.sleep(self.seconds)
        if self.inner is not None:
            self.inner.step()


@pytest.mark.realtime
def test_nested_calls_count_once_for_their_own_component() -> None:
    timer = ExclusiveTimer()
    inner = _Sleeper(0.2)
    outer = _Sleeper(0.02, inner)
    timer.instrument({"onboard": outer, "dynamics": inner})
    outer.step()
    assert timer.calls == {"onboard": 1, "dynamics": 1}
    # The outer one slept 20 ms itself and does not also carry the inner one's 200 ms (a sleep overruns
    # on a loaded machine, hence the slack: 200 ms counted twice would be far past it).
    assert timer.totals_s["dynamics"] >= 0.2
    assert 0.02 <= timer.totals_s["onboard"] < 0.15


class _EncodedMemory(MemorySink):
    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None:
        time.sleep(0.01)
        self.publish(topic, log_time_ns, message)


def test_sinks_wired_before_instrumenting_are_still_timed() -> None:
    recorder, telemetry = _EncodedMemory(), _EncodedMemory()
    fanout = FanoutSink([recorder, telemetry])  # wired first, as run_trial does
    timer = ExclusiveTimer()
    timer.instrument({"encoding": fanout, "recorder": recorder, "telemetry": telemetry})
    fanout.publish("log", 0, {"a": 1})
    assert timer.calls == {"encoding": 1, "recorder": 1, "telemetry": 1}
    assert timer.totals_s["encoding"] < timer.totals_s["recorder"]


def test_report_gives_wall_and_cpu_factors_against_the_goal_and_baselines() -> None:
    report = BenchReport(
        scenario="s",
        cpu=0,
        zenoh=True,
        peers=(PeerFigure("lockstep", 2.0, 40.0, cpu_s=1.0), PeerFigure("world-only", 0.5, 40.0, cpu_s=0.4)),
        breakdown_s={"onboard": 0.3, "dynamics": 0.1},
        breakdown_calls={"onboard": 10, "dynamics": 20},
        instrumented_wall_s=2.5,
        metrics_s=0.2,
        simulated_s=40.0,
        warmup_s=0.3,
    )
    figures = report.as_dict()
    assert figures["real_time_factor"] == {"lockstep": 20.0, "world-only": 80.0}
    assert figures["cpu_real_time_factor"] == {"lockstep": 40.0, "world-only": 100.0}
    assert figures["goal_real_time_factor"] == GOAL_REAL_TIME_FACTOR
    assert figures["named_baselines"] == {name: list(span) for name, span in NAMED_BASELINES.items()}
    assert [entry["share_pct"] for entry in figures["breakdown"].values()] == [75.0, 25.0]


def test_repeated_runs_report_their_median_and_keep_every_wall_time() -> None:
    runs = [PeerFigure("lockstep", wall, 40.0, cpu_s=wall - 0.1) for wall in (2.5, 1.8, 2.0)]
    median = PeerFigure.median_of(runs)
    assert (median.wall_s, median.cpu_s, median.runs_wall_s) == (2.0, pytest.approx(1.9), (2.5, 1.8, 2.0))
    assert median.real_time_factor == 20.0
    report = BenchReport("s", None, False, (median,), {}, {}, 0.0, 0.0, 40.0).as_dict()
    assert report["runs_wall_s"] == {"lockstep": [2.5, 1.8, 2.0]}


def test_bench_command_reports_every_peer_and_what_zenoh_put(capsys: pytest.CaptureFixture[str]) -> None:
    """The whole command on a small scenario: each peer timed, and with nobody subscribed every live message
    is counted as unheard, none put (the figure says Zenoh cost the matching check, not a delivery)."""
    import json
    import platform
    from pathlib import Path

    from rover_cli.main import main

    small = Path(__file__).resolve().parents[1] / "data" / "small_rocky.toml"
    code = main(["bench", "hil", "--scenario", str(small), "--repeats", "1", "--all-cores", "--json"])
    assert code == 0
    figures = json.loads(capsys.readouterr().out)
    assert set(figures["real_time_factor"]) == {"lockstep", "lockstep-virtual-can", "world-only"}
    assert len(figures["host_probe_s"]) == 1 and figures["host_probe_s"][0] > 0  # once per round
    assert figures["python"]["version"] == platform.python_version()
    assert all(factor > 0 for factor in figures["real_time_factor"].values())
    assert figures["breakdown"]["telemetry"]["calls"] > 0
    assert figures["zenoh_instrumented_run"]["put"] == 0
    # Each message the rate limits pass reaches the stream once (the limits thin can/frames and innovations).
    assert figures["zenoh_instrumented_run"]["unheard"] > 0.5 * figures["breakdown"]["telemetry"]["calls"]


def _printed_figures(lockstep_runs: list[float]) -> str:
    import io

    from rich.console import Console

    from rover_cli.bench_hil import print_figures

    runs = [PeerFigure("lockstep", wall, 41.1, cpu_s=wall) for wall in lockstep_runs]
    world = PeerFigure("world-only", 0.15, 41.1, cpu_s=0.15)
    peers = (PeerFigure.median_of(runs), world)
    report = BenchReport("rocky", 0, True, peers, {"onboard": 0.2}, {"onboard": 2056}, 1.1, 0.06, 41.1)
    figures = report.as_dict()
    out = io.StringIO()
    print_figures(Console(file=out, width=80), figures, "rocky-boulders", len(lockstep_runs))
    return out.getvalue()


def test_bench_table_keeps_every_figure_whole_at_80_columns() -> None:
    """A CI log or a pipe is 80 columns wide: the figures must read whole there (labels wrap instead)."""
    text = _printed_figures([0.82, 0.80, 0.84])
    assert all(len(line) <= 80 for line in text.splitlines())
    lockstep = next(line for line in text.splitlines() if "lockstep" in line)
    for figure in ("0.82", "50.1x", "100 %", "0.80-0.84"):
        assert figure in lockstep
    assert "note:" not in text


def test_bench_says_when_the_runs_differ_enough_to_doubt_the_median() -> None:
    text = " ".join(_printed_figures([0.70, 0.95, 0.72, 0.90, 0.75]).split())
    assert "the lockstep runs took 0.70 to 0.95 s, 36 % apart" in text


def test_the_note_puts_the_host_probes_spread_beside_the_trials() -> None:
    from rover_cli.bench_hil import unsteady_note

    note = unsteady_note([0.70, 0.95, 0.72], [0.040, 0.052, 0.041])
    assert "0.70 to 0.95 s, 36 % apart" in note
    assert "took 40 to 52 ms, 30 % apart" in note
    assert unsteady_note([0.70, 0.80, 0.72], [0.040, 0.080]) == ""  # the trials steady: nothing to say


def test_host_probe_times_fixed_work() -> None:
    from hil.host_probe import time_host_probe

    short, long = time_host_probe(steps=1_000), time_host_probe(steps=400_000)  # 400x the work
    assert 0.0 < short < long
