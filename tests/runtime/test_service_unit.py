"""``deploy/rover.service`` agrees with what ``rover run`` does: which exits are worth a restart, where
numba may cache, the priority ``rover bench runtime`` measures at."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import pytest

from rover_cli.bench_runtime import DEPLOYED_NICE, apply_nice, nice_value
from rover_cli.main import main

UNIT = Path(__file__).resolve().parents[2] / "deploy" / "rover.service"


def service_settings() -> dict[str, list[str]]:
    """The [Service] section's assignments (a key may repeat, as systemd allows)."""
    settings: dict[str, list[str]] = {}
    section = ""
    for raw in UNIT.read_text().splitlines():
        line = raw.strip()
        if line.startswith("["):
            section = line
        elif section == "[Service]" and line and not line.startswith("#"):
            key, _, value = line.partition("=")
            settings.setdefault(key, []).append(value)
    return settings


def test_a_config_error_is_not_restarted_forever(tmp_path: Path) -> None:
    bad = tmp_path / "rover.toml"
    bad.write_text("rover_id = 5\n")
    code = main(["run", "--config", str(bad), "--out", str(tmp_path / "run")])
    service = service_settings()
    assert service["Restart"] == ["on-failure"]
    assert str(code) in service["RestartPreventExitStatus"][0].split()


def test_numba_caches_where_the_service_user_can_write() -> None:
    service = service_settings()
    cache = service["CacheDirectory"][0]  # /var/cache/<it>, owned by User= for the service
    assert f"NUMBA_CACHE_DIR=/var/cache/{cache}/numba" in service["Environment"]
    # A real-time policy would cover every thread (planner, Zenoh, busy-poll): see the unit's comment.
    assert "CPUSchedulingPolicy" not in service and "LimitMEMLOCK" not in service


def test_bench_runtime_measures_at_the_units_nice_value() -> None:
    # `rover bench runtime` runs at the priority the unit gives `rover run`, so its figures are the
    # deployed loop's; the default must follow the unit.
    assert service_settings()["Nice"] == [str(DEPLOYED_NICE)]
    current = os.getpriority(os.PRIO_PROCESS, 0)
    assert apply_nice(None) == f"nice {current} (left as it was)"
    assert apply_nice(current).startswith(f"nice {current}, as deploy/rover.service")
    with pytest.raises(argparse.ArgumentTypeError, match="-20 to 19"):
        nice_value("-25")
    assert nice_value("keep") is None and nice_value("-10") == -10


def test_the_service_records_where_the_service_user_can_write() -> None:
    # rover run records under its working directory (logs/trials/run-<time>) unless given --out; the unit
    # once ran it in the root-owned /opt/rover, where that folder cannot be made: exit 2, never started.
    service = service_settings()
    command = service["ExecStart"][0].split()
    assert command[1:3] == ["run", "--config"] and "--out" not in command
    state = service["StateDirectory"][0]  # /var/lib/<it>, made and owned for User= by systemd
    assert service["WorkingDirectory"] == [f"/var/lib/{state}"]


def test_the_service_command_line_is_one_rover_run_accepts() -> None:
    from rover_cli.main import build_parser

    command = service_settings()["ExecStart"][0].split()
    assert command[0].endswith("/bin/rover")
    args = build_parser("run").parse_args(command[1:])
    assert args.config == Path("/etc/rover/rover.toml")


def test_the_service_user_gets_no_capabilities() -> None:
    # Nothing in rover run uses one: the CAN link is a plain CAN_RAW socket, and bringing can0 up is the
    # ExecStartPre's, which runs with full privileges ("+") while the service itself does not.
    service = service_settings()
    assert "AmbientCapabilities" not in service
    assert all(line.startswith("-+") for line in service["ExecStartPre"])
