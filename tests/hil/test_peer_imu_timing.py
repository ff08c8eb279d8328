"""The real-time peer's IMU samples on its 100 Hz step grid, however late each step wakes.

A real autopilot's IMU samples on a hardware timer; the rover's sensor-paced loop takes whatever jitter
the IMU's send has as its own. The peer runs here on a clock that the test moves: every wait wakes up
0-3 ms late, as an OS wake-up does, so each step starts somewhere in the first few ms after its
deadline.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from hil.lockstep import lockstep_wires
from logs.clock import NS_PER_S
from logs.settings import parse_toml
from navigator.config import rover_config_from_table
from tests.hil.world_harness import run_peer_on_test_clock, scenario_with

MS = 1_000_000
RUN_NS = 3 * NS_PER_S


class LateWakingClock:
    """Virtual time that moves only by waiting; each wait returns 0-3 ms past what was asked (seeded).

    Each read also moves it on by 1-500 us (the process preempted between two reads of a busy machine),
    so a spin on it ends and a step takes some time.
    """

    def __init__(self, seed: int) -> None:
        self._rng = np.random.default_rng(seed)
        self.t = 1_000 * NS_PER_S  # a monotonic clock's epoch is arbitrary; not zero

    def now_ns(self) -> int:
        self.t += int(self._rng.integers(1_000, 500_000))
        return self.t

    def wait(self, seconds: float) -> None:
        self.t += round(seconds * NS_PER_S) + int(self._rng.integers(0, 3 * MS))


def imu_stamps_ms(data: bytes) -> list[int]:
    """``time_boot_ms`` of every SCALED_IMU in a MAVLink byte stream, in order."""
    parser = mavlink2.MAVLink(None)
    messages = parser.parse_buffer(data) or []
    return [m.time_boot_ms for m in messages if m.get_type() == "SCALED_IMU"]


def test_imu_samples_are_20ms_apart_by_their_time_stamps_when_steps_wake_late(tmp_path: Path) -> None:
    scenario = scenario_with("")
    config = rover_config_from_table(parse_toml("", "<defaults>"))
    clock = LateWakingClock(seed=7)
    with lockstep_wires(config.can) as wires:
        # Nothing spun: every step starts on a late wake-up.
        result = run_peer_on_test_clock(
            scenario, config, tmp_path / "peer", clock, wires.sim_bus, wires.sim_mavlink, duration_ns=RUN_NS
        )
        stamps = imu_stamps_ms(wires.onboard_mavlink.read())
    # The clock did wake late: the steps started off their deadlines by up to 3 ms.
    worst = result.timing.jitter_ns.summary_ms()["max_ms"]
    assert worst is not None and worst > 1.5
    assert len(stamps) >= RUN_NS // (20 * MS) - 2
    assert set(np.diff(stamps).tolist()) == {20}
