"""The soak's seeded plan: which faults, when, for how long, what each must show, and the scenario file.

Faults come from a fixed catalog, in a seeded order (every kind once before any repeats), one at a time
with a recovery gap after each, from ``warmup_s`` on. All but the e-stop are scenario ``[[faults]]`` that
the real-time peer applies (``hil.faults``); the e-stop is a command the soak sends over Zenoh. Each
entry names the evidence that it was seen on the rover: a ``failsafe.<name>`` on ``safety/events``
(recovered: the matching ``cleared.<name>``), or for a silent IMU (the pacing sensor), ticks run on the
fixed-rate deadline in ``runtime/timing`` (recovered: sensor-paced ticks again).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Evidence kinds.
FAILSAFE = "failsafe"
DEADLINE_TICKS = "deadline_ticks"


@dataclass(frozen=True)
class SoakFault:
    """One fault of the soak. ``target``/``kind`` as in a scenario (``estop``: a Zenoh command)."""

    target: str
    kind: str
    start_s: float  # from the scenario's start: the rover's first wheel command (hil.soak)
    duration_s: float
    evidence: str  # FAILSAFE or DEADLINE_TICKS
    failsafe: str = ""  # the failsafe name when evidence is FAILSAFE
    controller: int = 0

    @property
    def name(self) -> str:
        suffix = f"[{self.controller}]" if self.target == "vesc" else ""
        return f"{self.target}{suffix}/{self.kind}"

    @property
    def end_s(self) -> float:
        return self.start_s + self.duration_s

    @property
    def may_raise(self) -> tuple[str, ...]:
        """The failsafes this fault explains on the rover (its evidence first), see ``RAISES``."""
        return RAISES.get(f"{self.target}/{self.kind}", (self.failsafe,) if self.failsafe else ())


# (target, kind, duration s, evidence, failsafe): each long enough to trip its failsafe's threshold
# (docs/safety.md: GPS 3 s, heartbeat 3 s, wheel status 0.25 s).
CATALOG: tuple[tuple[str, str, float, str, str], ...] = (
    ("gps", "off", 5.0, FAILSAFE, "gps_lost"),
    # The peer tells the rover its controller is bus-off with a CAN_ERR_BUSOFF error frame on the shared
    # bus (hil.bus_off.BusOffAnnouncer), as Linux tells its host, so the rover's link goes bus-off.
    ("can", "off", 1.0, FAILSAFE, "can_bus_off"),
    ("vesc", "off", 1.5, FAILSAFE, "wheel_silent"),  # a controller reboots
    ("mavlink", "off", 4.5, FAILSAFE, "heartbeat_lost"),
    ("imu", "off", 3.0, DEADLINE_TICKS, ""),
    ("estop", "command", 3.0, FAILSAFE, "estop"),
)


# The failsafes each fault of the catalog may raise on the rover, during it or within the report's slack
# after it: its own evidence, and what the loss takes with it. GPS, IMU and the AHRS attitude come over
# MAVLink, so a MAVLink loss is also a GPS loss and an attitude loss (attitude_lost 1 s in, before the
# heartbeat's 3 s, which stays the evidence: both fire within the 4.5 s loss); without fixes (or without
# the IMU) the estimate's uncertainty grows until it may be judged unhealthy. A CAN bus-off also silences
# the controllers (no frame reaches the rover), so their STATUS goes stale 0.25 s in, as on the vehicle.
# Any other failsafe during a soak is unexplained and makes it NOT OK.
RAISES: dict[str, tuple[str, ...]] = {
    "gps/off": ("gps_lost", "estimator_unhealthy"),
    "can/off": ("can_bus_off", "wheel_silent"),
    "vesc/off": ("wheel_silent",),
    "mavlink/off": ("heartbeat_lost", "attitude_lost", "gps_lost", "estimator_unhealthy"),
    "imu/off": ("estimator_unhealthy",),
    "estop/command": ("estop",),
}


def fault_plan(seed: int, duration_s: float, warmup_s: float, gap_s: tuple[float, float]) -> list[SoakFault]:
    """Faults from ``warmup_s`` until ``duration_s``, each followed by a recovery gap drawn from ``gap_s``;
    a fault that would not end (plus the shortest gap) before ``duration_s`` is left out."""
    rng = np.random.default_rng(seed)
    faults: list[SoakFault] = []
    order: list[int] = []
    t = warmup_s
    while True:
        if not order:
            order = [int(i) for i in rng.permutation(len(CATALOG))]
        target, kind, length, evidence, failsafe = CATALOG[order[0]]
        if t + length + gap_s[0] > duration_s:
            return faults
        order.pop(0)
        controller = int(rng.integers(6)) if target == "vesc" else 0
        faults.append(SoakFault(target, kind, round(t, 3), length, evidence, failsafe, controller))
        t += length + float(rng.uniform(*gap_s))


def scenario_text(name: str, duration_s: float, seed: int, faults: list[SoakFault]) -> str:
    """A scenario for the peer: open firm ground (30 m x 30 m, gentle hills, one rock), the faults."""
    lines = [
        "# Written by `rover hil soak`: open ground and a seeded fault schedule.",
        f'name = "{name}"',
        f"duration_s = {duration_s + 60.0!r}",
        f"seed = {seed}",
        "",
        "[terrain]",
        'kind = "procedural"',
        "size_m = [30.0, 30.0]",
        "resolution_m = 0.25",
        'class = "firm"',
        f"seed = {seed}",
        "hill_height_m = 0.3",
        "hill_count = 3",
        "",
        "[start]",
        "xy = [4.0, 4.0]",
        "yaw_deg = 45.0",
        "",
        "[[goals]]",
        "xy = [26.0, 26.0]",
        "tolerance_m = 0.5",
        "",
        "[[obstacles]]",
        'id = "rock"',
        "xy = [15.0, 12.0]",
        "radius_m = 1.0",
    ]
    for fault in faults:
        if fault.target == "estop":
            continue
        lines += [
            "",
            "[[faults]]",
            f'target = "{fault.target}"',
            f'kind = "{fault.kind}"',
            f"start_s = {fault.start_s!r}",
            f"duration_s = {fault.duration_s!r}",
        ]
        if fault.target == "vesc":
            lines.append(f"controller = {fault.controller}")
    return "\n".join(lines) + "\n"


# The rover drives a patrol between these (ENU m), a new goal on arrival or after PATROL_PERIOD_S.
PATROL = ((26.0, 26.0), (4.0, 26.0), (26.0, 4.0), (4.0, 4.0))
PATROL_PERIOD_S = 45.0
