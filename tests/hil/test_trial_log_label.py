"""A campaign trial's log lines name the trial; the handlers are as before afterwards."""

import logging

import pytest

from hil.trial_log_label import trial_log_label


def test_lines_name_the_trial_and_the_format_is_restored(caplog: pytest.LogCaptureFixture) -> None:
    root = logging.getLogger()
    before = [(h, h.formatter) for h in root.handlers]
    with trial_log_label("muddy/classical%/seed1"):
        line = root.handlers[0].format(logging.makeLogRecord({"msg": "wheels spinning", "name": "estimator"}))
    assert "muddy/classical%/seed1 estimator: wheels spinning" in line
    assert [(h, h.formatter) for h in root.handlers] == before


def test_a_worker_without_logging_gets_a_labelled_stderr_handler(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    root = logging.getLogger()
    monkeypatch.setattr(root, "handlers", [])
    with trial_log_label("rocky/terrain-aware/seed2"):
        logging.getLogger("estimator.estimator").warning("odometry left out")
    assert (
        "WARNING rocky/terrain-aware/seed2 estimator.estimator: odometry left out" in capsys.readouterr().err
    )
    assert root.handlers == []
