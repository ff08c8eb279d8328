"""Kill test: a real lockstep trial SIGKILLed at random points; recover keeps every complete chunk, each
chunk spans at most about one second, and the report runs on the recovered file."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from logs.doctor import diagnose
from logs.frames import FrameWalk, chunk_of
from logs.reader import ReadStats, read_messages
from logs.recorder import DEFAULT_CHUNK_DURATION_NS
from logs.recover import recover
from logs.report import write_report
from logs.topics import TRUTH_POSE

ROOT = Path(__file__).resolve().parents[2]
# The default scenario: about 40 s simulated, ~0.8 s of wall time alone at full speed (~50x real time),
# longer with three trials on two cores. The latest kill point, KILL_WINDOW_S after the first chunk (1 s
# simulated, ~20 ms in), falls inside the recording even on a machine twice as fast; 1.5 s, chosen when a
# trial took several seconds, once fell after the recorder had closed the file.
SCENARIO = ROOT / "scenarios" / "default.toml"
KILL_WINDOW_S = 0.4
KILL_POINTS = 3
# Three trials start at once: on a loaded 2-core machine (another suite beside this one) their first chunk
# took longer than 60 s to appear once; a cold numba cache is a compile on top. Waiting is all this bounds.
START_TIMEOUT_S = 150.0


def _start(out: Path) -> subprocess.Popen[bytes]:
    command = [sys.executable, "-m", "rover_cli.main", "hil", "trial", str(SCENARIO), "--no-telemetry"]
    return subprocess.Popen(
        [*command, "--out", str(out)], cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )


def _holds_a_chunk(path: Path) -> bool:
    """Whether a complete chunk record is on disk yet (the file is still growing; a cut is expected)."""
    with path.open("rb") as stream:
        return any(frame.opcode == 0x06 for frame in FrameWalk(stream, str(path)).frames())


def _kill_each_after(runs: list[tuple[subprocess.Popen[bytes], Path, float]]) -> None:
    """SIGKILL each trial its own delay after its recording holds the first chunk (it is then truly
    recording). One loop watches all of them, so every delay counts from that trial's own first chunk."""
    deadline = time.monotonic() + START_TIMEOUT_S
    kill_at: dict[int, float] = {}
    pending = list(range(len(runs)))
    while pending and time.monotonic() < deadline:
        for index in list(pending):
            process, recording, delay_s = runs[index]
            if process.poll() is not None:
                _, err = process.communicate()
                pytest.fail(
                    f"trial {index} ended (rc {process.returncode}) before its kill point: "
                    f"{err.decode()[-800:]}"
                )
            started = recording.exists() and _holds_a_chunk(recording)
            if index not in kill_at and started:
                kill_at[index] = time.monotonic() + delay_s
            if index in kill_at and time.monotonic() >= kill_at[index]:
                os.kill(process.pid, signal.SIGKILL)
                process.wait(timeout=10)
                pending.remove(index)
        time.sleep(0.005)
    if pending:
        pytest.fail(f"trials {pending} never reached their kill points in {START_TIMEOUT_S} s")


def _chunk_spans_ns(path: Path) -> list[int]:
    with path.open("rb") as stream:
        walk = FrameWalk(stream, str(path))
        spans = []
        for frame in walk.frames():
            if frame.opcode == 0x06:
                chunk = chunk_of(frame)
                spans.append(chunk.message_end_time - chunk.message_start_time)
        return spans


@pytest.mark.realtime  # kill points in wall time, trials started within a wall-clock budget
def test_sigkill_then_recover_then_report(tmp_path: Path) -> None:
    # Random kill points (seeded, so a failure reproduces): a delay after the first chunk is on disk.
    # Wall-time points, not sizes: the trial's real-time factor varies with the machine's load.
    delays = np.random.default_rng(20240607).uniform(0.0, KILL_WINDOW_S, KILL_POINTS).tolist()
    runs = [(tmp_path / f"kill{i}", delay) for i, delay in enumerate(delays)]
    processes = [_start(out) for out, _ in runs]  # concurrently: the three trials share the wait
    try:
        _kill_each_after(
            [
                (process, out / "trial.mcap", delay)
                for process, (out, delay) in zip(processes, runs, strict=True)
            ]
        )
    finally:
        for process in processes:
            if process.poll() is None:
                process.kill()
                process.wait()

    for index, (out, delay) in enumerate(runs):
        cut = out / "trial.mcap"
        findings = diagnose(cut)
        assert not findings.complete and not findings.healthy, (
            f"killed {delay:.2f} s in, yet the file looks complete"
        )
        assert findings.chunks >= 1 and findings.chunks_damaged == 0
        # The reader reads a cut file up to the cut, without raising.
        stats = ReadStats()
        read_before = sum(1 for _ in read_messages(cut, stats=stats))
        assert stats.truncated and read_before == findings.messages

        recovered = out / "recovered.mcap"
        result = recover(cut, recovered)
        assert not result.was_complete and result.chunks_dropped == 0 and result.orphan_messages == 0
        assert result.chunks_kept == findings.chunks  # every complete chunk is kept ...
        assert result.messages == findings.messages  # ... with every message in it
        # Written before the first chunk: scenario, trial, config and world metadata; scenario.toml,
        # map.npz and config.effective.json attachments.
        assert result.metadata == 4 and result.attachments == 3
        again = diagnose(recovered)
        assert again.healthy and again.complete and again.footer_present, again.problems
        assert again.messages == result.messages
        # A crash loses at most about one second: no chunk spans more than the recorder's time limit
        # (plus one 10 ms physics tick, the message that closes the chunk).
        assert max(_chunk_spans_ns(cut)) <= DEFAULT_CHUNK_DURATION_NS + 10_000_000

        report = write_report([recovered], out / "report", plots=index == 0)  # plots cost ~1 s each
        assert not report.failed and len(report.runs) == 1
        # The report covers exactly what was recovered: the truth trajectory's time span in the file.
        truth_ns = [m.log_time_ns for m in read_messages(recovered, topics=[TRUTH_POSE])]
        assert len(truth_ns) > 1
        assert report.runs[0].metrics.duration_s == pytest.approx((truth_ns[-1] - truth_ns[0]) / 1e9)
        assert ("<svg" in report.html.read_text(encoding="utf-8")) == (index == 0)
