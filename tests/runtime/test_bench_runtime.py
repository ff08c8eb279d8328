"""``rover bench runtime`` runs end to end and reports figures for both peers (a short run)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_runtime_reports_jitter_and_latency_for_both_peers() -> None:
    command = [sys.executable, "-m", "rover_cli.main", "bench", "runtime", "--seconds", "2", "--json"]
    done = subprocess.run(
        [*command, "--no-telemetry"], cwd=ROOT, capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, done.stderr[-2000:]
    figures = json.loads(done.stdout)
    empty, stack = figures["peers"]["empty tick (scheduler only)"], figures["peers"]["stack + recording"]
    assert empty["ticks"] >= 90 and empty["latency"]["p99_ms"] is None  # an empty tick commands nothing
    # The stack ticked on its sensor about 50 times a second and measured its sensor-to-command latency.
    assert stack["ticks"] >= 80 and stack["sensor_ticks"] > 0
    assert 0.0 < stack["latency"]["p50_ms"] <= stack["latency"]["p99_ms"] <= stack["latency"]["max_ms"]
    assert stack["simulated_rover"] in ("process", "thread")
