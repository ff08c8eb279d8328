"""``rover run`` that cannot start, or fails once started: no stray recording, or one that says why.

A run that fails its start-up checks (a link that does not open, a lockstep-only config) creates nothing
in ``--out``, and an ``--out`` that cannot be made is a setup error, not a traceback; a run that fails
after its recording was opened closes it as a readable MCAP with the error on the ``log`` topic.
"""

from __future__ import annotations

import itertools
import logging
import threading
from pathlib import Path

import pytest

from firmware_bridge.errors import BridgeSetupError
from logs.clock import MonotonicClock
from logs.reader import read_messages
from navigator.config import load_rover_config
from navigator.rover_process import RoverSetupError, run_rover
from rover_cli.main import main
from tests.runtime.run_config import rover_run_config

REPO = Path(__file__).resolve().parents[2]
_channels = itertools.count()


def write_config(tmp_path: Path, connection: str) -> Path:
    path = tmp_path / "rover.toml"
    path.write_text(rover_run_config("failtest", f"failtest-{next(_channels)}", connection))
    return path


def test_a_link_that_cannot_open_leaves_nothing_in_out(tmp_path: Path) -> None:
    # Well formed (a misspelt one is refused when the config loads), but no such device is plugged in.
    config = load_rover_config(write_config(tmp_path, "serial:/dev/no-such-rover-tty:57600"))
    out = tmp_path / "run"
    with pytest.raises(BridgeSetupError, match=r"no-such-rover-tty.*cannot open"):
        run_rover(config, MonotonicClock(), out, stop=threading.Event(), telemetry=False)
    assert not out.exists()


def test_an_out_folder_that_cannot_be_made_is_a_setup_error(tmp_path: Path) -> None:
    config = load_rover_config(write_config(tmp_path, "udpin:127.0.0.1:0"))
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    with pytest.raises(RoverSetupError, match="cannot create recording"):
        run_rover(config, MonotonicClock(), blocker / "run", stop=threading.Event(), telemetry=False)


def test_a_failure_after_the_recording_opened_leaves_a_readable_mcap_saying_why(tmp_path: Path) -> None:
    config = load_rover_config(write_config(tmp_path, "udpin:127.0.0.1:0"))
    out = tmp_path / "run"

    def broken_wait(timeout_s: float) -> None:
        raise OSError(f"select on the MAVLink socket failed (waiting {timeout_s:.3f} s)")

    with pytest.raises(OSError, match="select on the MAVLink socket failed"):
        run_rover(config, MonotonicClock(), out, stop=threading.Event(), wait=broken_wait, telemetry=False)
    logged = [m.message for m in read_messages(out / "rover.mcap", topics=["log"])]
    assert len(logged) == 1
    assert logged[0]["level"] == 5  # foxglove.Log FATAL: the run ended on it
    assert "rover run failed" in logged[0]["message"]
    assert "select on the MAVLink socket failed" in logged[0]["message"]
    # The rest of what was recorded is still there: the zero wheel commands sent on the way out.
    frames = [m.message for m in read_messages(out / "rover.mcap", topics=["can/frames"])]
    assert frames and all(f["direction"] == "tx" for f in frames)


def test_the_lockstep_config_is_refused_with_a_pointer_to_the_right_ones(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    out = tmp_path / "run"
    with caplog.at_level(logging.ERROR):
        code = main(["run", "--config", str(REPO / "configs" / "rover.toml"), "--out", str(out)])
    assert code == 2
    said = caplog.text
    assert "lockstep" in said
    assert "configs/rover.example-hardware.toml" in said
    assert "rover hil peer" in said and "rover-hil.toml" in said
    assert not out.exists()


def test_an_earlier_recording_in_out_is_refused_and_left_untouched(tmp_path: Path) -> None:
    # Running twice with the same --out (a field test re-run, a service restarted on a fixed folder)
    # had emptied the first run's recording as the second opened its file.
    out = tmp_path / "run"
    out.mkdir()
    earlier = out / "rover.mcap"
    earlier.write_bytes(b"the first run's recording")
    config = write_config(tmp_path, "udpin:127.0.0.1:0")
    code = main(["run", "--config", str(config), "--out", str(out), "--duration", "0.2", "--no-telemetry"])
    assert code == 2
    assert earlier.read_bytes() == b"the first run's recording"
    assert sorted(p.name for p in out.iterdir()) == ["rover.mcap"]


def test_the_refusal_of_an_earlier_recording_names_it_and_the_fix(tmp_path: Path) -> None:
    config = load_rover_config(write_config(tmp_path, "udpin:127.0.0.1:0"))
    out = tmp_path / "run"
    out.mkdir()
    (out / "rover.mcap").write_bytes(b"")
    stop, until = threading.Event(), 200_000_000  # a bound, should the run start after all
    with pytest.raises(RoverSetupError, match=r"rover\.mcap already exists.*--out a new folder"):
        run_rover(config, MonotonicClock(), out, stop=stop, telemetry=False, duration_ns=until)


def test_a_link_that_cannot_open_is_one_line_naming_the_config_exit_2(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    config = write_config(tmp_path, "serial:/dev/no-such-rover-tty:57600")
    out = tmp_path / "run"
    with caplog.at_level(logging.ERROR):
        code = main(["run", "--config", str(config), "--out", str(out), "--no-telemetry"])
    assert code == 2
    errors = [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR]
    assert len(errors) == 1 and "\n" not in errors[0]
    assert errors[0].startswith(f"{config}: cannot start: ") and "no-such-rover-tty" in errors[0], errors
    assert not out.exists()
