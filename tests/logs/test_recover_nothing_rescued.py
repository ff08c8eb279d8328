"""A recording cut before its first chunk's end holds a trial's metadata and attachments and no message:
recover once wrote those into a valid MCAP ("kept 0 chunks, 0 messages", exit 0) that doctor then called
healthy. And recover's counts are ones the reader can check against the file it wrote."""

from __future__ import annotations

import json
from io import BytesIO
from pathlib import Path

import pytest
from mcap.opcode import Opcode

from logs.doctor import diagnose
from logs.errors import RecordingError
from logs.frames import FrameWalk
from logs.recorder import McapRecorder
from logs.recover import NothingRecoverable, recover
from logs.synthetic import synthetic_metadata, write_synthetic_trial
from rover_cli.main import main

SECONDS = 4.0


@pytest.fixture(scope="module")
def trial(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """As a trial writes it: metadata and attachments first, then a chunk a second of log time."""
    path = tmp_path_factory.mktemp("trial") / "trial.mcap"
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", synthetic_metadata(SECONDS))
        recorder.add_attachment("scenario.toml", "application/toml", b"name = 'synthetic'\n", 0)
        write_synthetic_trial(recorder, SECONDS)
    return path


def _cut_inside_the_first_chunk(trial: Path, folder: Path) -> tuple[Path, int]:
    data = trial.read_bytes()
    first = next(f for f in FrameWalk(BytesIO(data), "trial").frames() if f.opcode == Opcode.CHUNK)
    cut = folder / "cut.mcap"
    cut.write_bytes(data[: first.offset + first.size // 2])
    return cut, first.offset


def test_recover_of_a_file_cut_before_its_first_chunk_ends_writes_nothing(
    trial: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cut, chunk_at = _cut_inside_the_first_chunk(trial, tmp_path)
    out = tmp_path / "rescued.mcap"
    with pytest.raises(
        NothingRecoverable, match=f"cut short at byte {chunk_at} .*before its first chunk's end"
    ):
        recover(cut, out)
    assert not out.exists() and not list(tmp_path.glob("rescued*"))
    assert main(["logs", "recover", str(cut), str(out)]) == 2
    printed = " ".join(capsys.readouterr().out.split())
    assert "no complete chunk" in printed and "1 metadata and 1 attachment record(s)" in printed, printed
    # A file already at the output path is neither replaced nor removed by a recover that fails.
    out.write_bytes(b"an earlier rescue")
    assert main(["logs", "recover", str(cut), str(out)]) == 2
    assert out.read_bytes() == b"an earlier rescue"


def test_doctor_says_a_cut_before_the_first_chunk_has_nothing_to_recover(trial: Path, tmp_path: Path) -> None:
    cut, _ = _cut_inside_the_first_chunk(trial, tmp_path)
    (problem,) = diagnose(cut).problems
    assert problem.endswith("no complete chunk before it: no message to recover")


def test_doctor_calls_a_recording_without_messages_unhealthy(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # What recover used to write of such a cut: a whole MCAP of metadata and attachments only.
    path = tmp_path / "metadata-only.mcap"
    with McapRecorder(path) as recorder:
        recorder.add_metadata("scenario", synthetic_metadata(SECONDS))
        recorder.add_attachment("scenario.toml", "application/toml", b"name = 'synthetic'\n", 0)
    findings = diagnose(path)
    assert findings.complete and findings.footer_present and findings.messages == 0
    assert not findings.healthy
    assert findings.problems == ["no messages: the recording holds none, only 1 metadata and 1 attachment(s)"]
    assert main(["logs", "doctor", str(path)]) == 1
    assert "problems found" in capsys.readouterr().out


def test_recover_counts_what_the_output_holds(
    trial: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = trial.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 3 // 4])
    out = tmp_path / "rescued.mcap"
    assert main(["logs", "recover", str(cut), str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    written = diagnose(out)
    # The writer chunks the messages anew (by size, not a chunk a second): its chunks are not those read.
    assert result["chunks_kept"] == diagnose(cut).chunks > written.chunks == result["chunks_written"]
    assert result["messages"] == written.messages
    out.unlink()
    assert main(["logs", "recover", str(cut), str(out)]) == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert f"kept {written.messages} messages" in printed
    assert f"from {result['chunks_kept']} complete chunks read; written as {written.chunks} chunks" in printed


def test_recover_into_a_folder_is_refused_before_anything_is_copied(trial: Path, tmp_path: Path) -> None:
    # The output goes to a temporary name first: a folder given as the output failed only at the rename,
    # after the whole copy (a reviewer's case). Said at once now, and nothing is written.
    folder = tmp_path / "out"
    folder.mkdir()
    with pytest.raises(RecordingError, match="is a folder: give recover a file path"):
        recover(trial, folder)
    assert list(tmp_path.iterdir()) == [folder] and not list(folder.iterdir())
