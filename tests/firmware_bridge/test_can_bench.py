import json

import pytest

from firmware_bridge.can_bench import bus_load, frame_bits, run_can_bench
from firmware_bridge.can_bus import CanConfig
from rover_cli.main import main
from tests.firmware_bridge.swapped_dbc import SWAPPED_IDS, swapped_dbc_text


def test_frame_bits_match_the_classic_can_budget():
    # ../shared/reference/vesc_can.md: 8-byte frame, 29-bit id: 131 bits unstuffed, 160 worst case
    assert frame_bits(8, worst_case=False) == 131
    assert frame_bits(8, worst_case=True) == 160
    assert frame_bits(4, worst_case=False) == 99


def test_bus_load_of_the_reference_example():
    # six wheels x (1 command + 3 status) at 100 Hz = 2400 frames/s, about 40 % worst case
    config = CanConfig(command_rate_hz=100.0, status_rate_hz=100.0)
    load = bus_load(config, slow_status_rate_hz=100.0)
    assert load.frames_per_s == 2400
    assert load.load_pct_worst == pytest.approx(
        100 * 6 * 100 * (160 * 3 + frame_bits(4, worst_case=True)) / 1e6
    )
    assert 35 < load.load_pct_worst < 40


def test_bench_runs_and_reports_every_figure():
    result = run_can_bench(300)
    figures = result.as_dict()
    assert figures["ours"]["rounds_per_s"] > 0
    assert [p["name"] for p in figures["peers"]] == [
        "python-can + struct (no DBC)",
        "cantools strict encode + decode",
    ]
    assert 0 < result.latency_p50_us <= result.latency_p99_us
    assert result.bus_load.frames_per_s == 6 * (50 + 50 + 10 + 10)


@pytest.mark.parametrize("rounds", ["0", "-5", "199"])
def test_bench_can_refuses_too_few_rounds_instead_of_running_others(rounds, capsys):
    # It used to run 200 frames whatever smaller number was asked for.
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "can", "--rounds", rounds])
    assert exit_info.value.code == 2
    assert f"--rounds: must be 200 to 10000000, got {int(rounds)}" in capsys.readouterr().err


def test_bench_can_measures_the_configs_own_dbc_profile_and_can_rates(tmp_path, capsys):
    # It used to measure the shipped DBC and default rates whatever the rover was configured with.
    dbc = tmp_path / "team.dbc"
    dbc.write_text(swapped_dbc_text(), encoding="ascii")
    config = tmp_path / "rover.toml"
    config.write_text(
        f'[vesc]\ncontroller_ids = {list(SWAPPED_IDS)}\ndbc = "team.dbc"\n[can]\ncommand_rate_hz = 100.0\n',
        encoding="ascii",
    )
    assert main(["bench", "can", "--rounds", "200", "--config", str(config), "--json"]) == 0
    figures = json.loads(capsys.readouterr().out)
    assert figures["dbc"] == str(dbc)
    assert figures["ours"]["rounds_per_s"] > 0
    assert figures["bus_load"]["frames_per_s"] == 6 * (100 + 50 + 10 + 10)


def test_bench_can_refuses_a_broken_config_on_one_line(tmp_path, capsys):
    config = tmp_path / "rover.toml"
    config.write_text('[vesc]\ndbc = "missing.dbc"\n', encoding="ascii")
    assert main(["bench", "can", "--rounds", "200", "--config", str(config)]) == 2
    assert "vesc.dbc" in capsys.readouterr().out
