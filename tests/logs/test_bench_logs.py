"""``rover bench logs`` runs end to end on a tiny workload and prints one JSON object with every figure."""

from __future__ import annotations

import json

import pytest

from rover_cli.main import main


def test_bench_logs_json_has_every_contender(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "logs", "--messages", "1000", "--duration-s", "2", "--repeat", "1", "--json"]) == 0
    figures = json.loads(capsys.readouterr().out)
    recorder = figures["recorder"]
    assert recorder["messages"] == 1000
    for name in ("mcap_writer_json", "mcap_writer_raw", "recorder", "recorder_size_chunks"):
        assert recorder[name]["messages_per_s"] > 0 and recorder[name]["file_mb"] > 0
    report = figures["report"]
    assert report["messages"] > 2 * 1000  # ~1100 messages per simulated second
    for step in ("mcap_reader_decode_all_s", "analyse_s", "report_tables_s", "report_with_plots_s"):
        assert report[step] > 0
