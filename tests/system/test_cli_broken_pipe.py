"""A reader that stops early (``rover plan MAP | head -3``) ends the command quietly: exit 1, no traceback.

``rover plan``'s figures are plain ``print`` lines; when ``head`` had gone, the next one raised
``BrokenPipeError`` out of ``main`` as a traceback. (The rich-printing commands already stop with exit 1.)
"""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import pytest

from rover_cli.main import main

REPO = Path(__file__).resolve().parents[2]
MAP = REPO / "tests" / "data" / "small_rocky.toml"


class _GoneReader:
    """A stdout whose reader has gone: every write or flush fails as a closed pipe does."""

    def write(self, _text: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")

    def flush(self) -> None:
        raise BrokenPipeError(32, "Broken pipe")

    def fileno(self) -> int:
        raise io.UnsupportedOperation("no file descriptor")  # so main() leaves the real fd 1 alone


def test_main_stops_quietly_when_stdout_is_gone(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stdout", _GoneReader())
    assert main(["plan", str(MAP)]) == 1


def test_rover_plan_into_a_closed_pipe_prints_no_traceback() -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "rover_cli.main", "plan", str(MAP)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=REPO,
    )
    assert process.stdout is not None and process.stderr is not None
    process.stdout.close()  # the reader is gone before the first line
    stderr = process.stderr.read().decode()
    assert process.wait(timeout=120) == 1
    assert "Traceback" not in stderr and "BrokenPipeError" not in stderr, stderr
