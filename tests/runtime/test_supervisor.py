"""The supervisor on its own: geofence clearing, config validation, mode reporting."""

from __future__ import annotations

import pytest

from logs.settings import ConfigError, parse_toml
from navigator.fence_shape import inside_polygon
from navigator.safety import SafetyInputs, SafetySupervisor
from navigator.safety_config import SafetyConfig
from navigator.vehicle import VehicleParams

SQUARE = ((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0))


def inputs(now_ns: int, position: tuple[float, float]) -> SafetyInputs:
    return SafetyInputs(
        now_ns=now_ns,
        tick_gap_ns=20_000_000,
        wheel_last_status_ns=(now_ns,) * 6,
        can_bus_off=False,
        can_send_failing_since_ns=None,
        estimator_healthy=True,
        last_gps_ns=now_ns,
        last_heartbeat_ns=now_ns,
        last_ground_contact_ns=None,
        sent_speed_mps=0.0,
        sent_at_ns=now_ns,
        measured_speed_mps=0.0,
        roll_pitch_rad=(0.0, 0.0),
        last_attitude_ns=now_ns,
        lateral_accel_mps2=0.0,
        position_xy=position,
        battery_v=24.0,
    )


def test_geofence_fires_outside_and_clears_back_inside() -> None:
    events: list[tuple[str, str, str]] = []
    supervisor = SafetySupervisor(SafetyConfig(fence=SQUARE), VehicleParams(), 0, lambda *e: events.append(e))
    assert supervisor.update(inputs(20_000_000, (5.0, 5.0)), True).speed_scale == 1.0
    decision = supervisor.update(inputs(40_000_000, (10.5, 5.0)), True)
    assert decision.mode.value == "HOLD" and decision.speed_scale == 0.0 and decision.faults == ("geofence",)
    decision = supervisor.update(inputs(60_000_000, (9.5, 5.0)), True)
    assert decision.mode.value == "DRIVING"
    assert [e[0] for e in events] == ["mode", "failsafe.geofence", "mode", "cleared.geofence", "mode"]


def test_inside_polygon_handles_concave_shapes() -> None:
    notch = (
        (0.0, 0.0),
        (4.0, 0.0),
        (4.0, 6.0),
        (6.0, 6.0),
        (6.0, 0.0),
        (10.0, 0.0),
        (10.0, 10.0),
        (0.0, 10.0),
    )
    assert inside_polygon(2.0, 2.0, notch) and inside_polygon(5.0, 8.0, notch)
    assert not inside_polygon(5.0, 2.0, notch) and not inside_polygon(11.0, 2.0, notch)


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ("fence = [[0, 0], [1, 1]]", "safety.fence"),
        ("fence = [[0, 0], [1, 'x'], [2, 2]]", "safety.fence"),
        ("battery_low_v = 20.0\nbattery_critical_v = 21.0", "safety.battery_critical_v"),
        ("loop_stall_s = 0", "safety.loop_stall_s"),
        ("stall_s = 0.2", "safety.stall_s"),
    ],
)
def test_bad_safety_config_names_the_key(text: str, key: str) -> None:
    table = parse_toml(f"[safety]\n{text}\n", "rover.toml").table("safety")
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        SafetyConfig.from_table(table)


def test_attitude_timeout_loads_and_defaults_to_one_second() -> None:
    assert SafetyConfig().attitude_timeout_s == 1.0
    table = parse_toml("[safety]\nattitude_timeout_s = 0.5\n", "rover.toml").table("safety")
    assert SafetyConfig.from_table(table).attitude_timeout_s == 0.5
    off = parse_toml("[safety]\nattitude_timeout_s = 0\n", "rover.toml").table("safety")
    assert SafetyConfig.from_table(off).attitude_timeout_s == 0.0  # 0 turns it off, as every timeout


@pytest.mark.parametrize(
    ("value", "problem"),
    [
        ("-0.5", "must be >= 0.0, got -0.5"),
        ("3601.0", "must be <= 3600.0, got 3601.0"),
        ("nan", "expected a finite number, got nan"),
        ("'1 s'", "expected a number, got str '1 s'"),
        ("true", "expected a number, got bool True"),
    ],
)
def test_a_bad_attitude_timeout_is_refused_naming_the_key(value: str, problem: str) -> None:
    table = parse_toml(f"[safety]\nattitude_timeout_s = {value}\n", "rover.toml").table("safety")
    with pytest.raises(ConfigError) as refused:
        SafetyConfig.from_table(table)
    assert (refused.value.source, refused.value.key) == ("rover.toml", "safety.attitude_timeout_s")
    assert refused.value.problem == problem


@pytest.mark.parametrize(("measured_mps", "stuck"), [(-0.5, False), (0.0, True)])
def test_reversing_as_commanded_is_not_stuck_but_a_reverse_command_without_motion_is(
    measured_mps: float, stuck: bool
) -> None:
    # Guidance's YIELDING backs the rover off at -0.5 m/s: that is motion, judged by magnitude.
    events: list[tuple[str, str, str]] = []
    supervisor = SafetySupervisor(SafetyConfig(), VehicleParams(), 0, lambda *e: events.append(e))
    for tick in range(1, 251):  # 5 s, past stuck_time_s (2 s)
        now = tick * 20_000_000
        reversing = inputs(now, (5.0, 5.0))._replace(
            sent_speed_mps=-0.5,
            sent_at_ns=20_000_000,
            measured_speed_mps=measured_mps,
        )
        supervisor.update(reversing, True)
    assert ("stuck" in supervisor.faults) is stuck
    assert any(e[0] == "failsafe.stuck" for e in events) is stuck


def test_a_wheel_stall_timer_restarts_after_a_tick_without_the_stall() -> None:
    """The stall check skips its per-wheel bookkeeping on ticks with no wheel stalling; such a tick must
    still end a running stall timer, so 0.8 s + one turning tick + 0.8 s of stall never trips (1 s limit)."""
    events: list[tuple[str, str, str]] = []
    supervisor = SafetySupervisor(SafetyConfig(), VehicleParams(), 0, lambda *e: events.append(e))
    tick = 20_000_000

    def judged(k: int, stalled: bool) -> SafetyInputs:
        speeds = (0.0 if stalled else 0.5,) + (0.5,) * 5
        return inputs(k * tick, (5.0, 5.0))._replace(
            sent_speed_mps=0.5,
            measured_speed_mps=0.5,
            sent_at_ns=0,
            wheel_commands_mps=(0.5,) * 6,
            wheel_speeds_mps=speeds,
            wheel_currents_a=(5.0,) * 6,
        )

    k = 1
    for _ in range(40):  # 0.8 s stalled
        assert supervisor.update(judged(k, True), True).faults == ()
        k += 1
    supervisor.update(judged(k, False), True)  # turning again for one tick
    k += 1
    start = k
    for _ in range(40):  # another 0.8 s: a timer that kept running would pass 1 s here
        assert supervisor.update(judged(k, True)._replace(sent_at_ns=start * tick), True).faults == ()
        k += 1
    for _ in range(15):  # past 1 s of this stall: trips
        decision = supervisor.update(judged(k, True)._replace(sent_at_ns=start * tick), True)
        k += 1
    assert decision.faults == ("wheel_stalled",)


@pytest.mark.parametrize(("timeout_s", "trips"), [(1.0, True), (0.0, False)])
def test_an_attitude_never_seen_trips_after_the_timeout_and_names_the_stream_unless_off(
    timeout_s: float, trips: bool
) -> None:
    events: list[tuple[str, str, str]] = []
    config = SafetyConfig(attitude_timeout_s=timeout_s)
    supervisor = SafetySupervisor(config, VehicleParams(), 0, lambda *e: events.append(e))
    supervisor.start(0)
    never = inputs(1_020_000_000, (5.0, 5.0))._replace(roll_pitch_rad=None, last_attitude_ns=None)
    decision = supervisor.update(never, True)
    assert (decision.faults == ("attitude_lost",)) is trips
    assert (decision.mode.value == "HOLD") is trips
    if trips:
        (detail,) = [e[2] for e in events if e[0] == "failsafe.attitude_lost"]
        assert "since the start" in detail and "SRn_EXTRA1" in detail
