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
