"""Home taken from the estimator, not from a raw fix: a first fix 25 m off (a GPS glitch that started the
filter there) does not stay home once the estimator re-anchors on GPS; a re-anchoring after fixes had
agreed with the estimate (drift, or a long glitch later on) leaves home where it was. A ground station
asking where home is does not fix it: the correction is told to it as a move."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from estimator.config import EstimatorConfig
from estimator.estimator import Estimator
from estimator.geodesy import Datum, to_geodetic
from firmware_bridge.mavlink_health import MavlinkCounters
from logs.clock import SimClock
from logs.sink import MemorySink
from navigator.onboard_home import HomeKeeper
from tests.firmware_bridge.ground_station import command_long

DATUM = Datum(47.397742, 8.545594, 488.0)
PERIOD_S = 0.2  # a 5 Hz GPS


class Follower:
    """A ground station's link following the mission: the HOME_POSITIONs it is told."""

    name = "follower"

    def __init__(self) -> None:
        self.counters = MavlinkCounters()
        self.sent: list[Any] = []

    def send(self, msg: Any) -> None:
        self.sent.append(msg)

    def send_status_text(self, text: str, severity: int = 6) -> None:
        raise AssertionError(f"no STATUSTEXT expected: {text}")


class Standing:
    """A real estimator (heading known, as from an AHRS: the gate is on) fed a rover standing still, and
    the home keeper on it, looking every fix as the control tick does."""

    def __init__(self) -> None:
        self.clock = SimClock()
        config = EstimatorConfig(
            datum_lat_deg=DATUM.lat_deg, datum_lon_deg=DATUM.lon_deg, datum_alt_m=DATUM.alt_m
        )
        self.estimator = Estimator(config, self.clock, MemorySink())
        self.estimator.set_initial_heading(0.0, 0.05)
        self.events: list[tuple[str, str, str]] = []
        self.follower = Follower()
        self.keeper = HomeKeeper(
            self.clock,
            self.estimator,
            lambda lat, lon: None,
            lambda x, y: False,
            lambda kind, severity, detail: self.events.append((kind, severity, detail)),
            listeners=lambda: [self.follower],
        )
        self.k = 0

    def fixes_at(self, x: float, y: float, seconds: float) -> None:
        """GPS fixes at (x, y) ENU metres for ``seconds``, the wheels and gyro still, a tick after each."""
        for _ in range(round(seconds / PERIOD_S)):
            t = round(self.k * PERIOD_S * 1e9)
            if t > self.clock.now_ns():
                self.clock.advance(t - self.clock.now_ns())
            if self.k:
                self.estimator.on_wheels(t, 0.0, 0.0)
                self.estimator.on_imu(t, 0.0, 0.0, 0.0)
            lat, lon, alt = to_geodetic(DATUM, x, y, 0.0)
            self.estimator.on_gps(t, lat, lon, alt, 3, 0.5, 12, fix_time_ns=t)
            self.keeper.observe()
            self.k += 1


def test_a_glitched_first_fix_does_not_stay_home_once_the_estimator_re_anchors() -> None:
    rover = Standing()
    rover.fixes_at(25.0, 0.0, PERIOD_S)  # the glitch: the first fix 25 m east, the filter starts there
    rover.fixes_at(0.0, 0.0, 15.0)  # where the rover stands: gated out, then re-anchored on
    reset = rover.estimator.last_gps_reset
    assert reset is not None and reset.agreed_until_ns == 0  # no fix agreed after the first one
    assert (reset.east_m, reset.north_m) == pytest.approx((-25.0, 0.0), abs=0.5)
    home = rover.keeper.home()
    assert home is not None
    assert math.hypot(home.x, home.y) < 0.5  # where it stands, not where the glitch put it
    ((kind, _, detail),) = rover.events
    assert kind == "home" and "its first healthy one, moved 25.00 m by the estimator's re-anchoring" in detail


def test_a_re_anchoring_after_fixes_agreed_leaves_home_where_the_rover_stood() -> None:
    rover = Standing()
    rover.fixes_at(0.0, 0.0, 2.0)  # home here, and fixes agreeing with it
    rover.fixes_at(25.0, 0.0, 15.0)  # a long glitch later on: the estimator re-anchors on it
    reset = rover.estimator.last_gps_reset
    assert reset is not None and reset.agreed_until_ns is not None and reset.agreed_until_ns > 0
    home = rover.keeper.home()
    assert home is not None and math.hypot(home.x, home.y) < 0.5
    assert rover.events[0][2].endswith("its first healthy one")


def test_a_second_re_anchoring_right_after_the_first_does_not_move_home_again() -> None:
    rover = Standing()
    rover.fixes_at(25.0, 0.0, PERIOD_S)  # the glitched first fix
    rover.fixes_at(0.0, 0.0, 10.2)  # the truth, gated out until the re-anchoring on its last fix
    first = rover.estimator.last_gps_reset
    assert first is not None and (first.east_m, first.north_m) == pytest.approx((-25.0, 0.0), abs=0.5)
    assert first.t_ns == rover.clock.now_ns()  # no truth fix accepted after it
    rover.fixes_at(0.0, 25.0, 15.0)  # then at once a long glitch 25 m north: re-anchored on it too
    second = rover.estimator.last_gps_reset
    assert second is not None and second is not first
    assert (second.east_m, second.north_m) == pytest.approx((0.0, 25.0), abs=0.5)
    assert second.agreed_until_ns == first.t_ns  # the first re-anchoring is the last agreement
    home = rover.keeper.home()
    assert home is not None and math.hypot(home.x, home.y) < 0.5  # moved once, to where the rover stands
    ((_, _, detail),) = rover.events
    assert detail.count("moved") == 1


def test_once_used_home_stays_as_told() -> None:
    rover = Standing()
    rover.fixes_at(25.0, 0.0, PERIOD_S)
    rover.fixes_at(25.0, 0.0, PERIOD_S)  # healthy at the glitch
    told = rover.keeper.home()
    assert told is not None and told.x == pytest.approx(25.0, abs=0.5)
    rover.fixes_at(0.0, 0.0, 15.0)
    assert rover.estimator.last_gps_reset is not None
    assert rover.keeper.home() == told  # a home told and driven to moves only by DO_SET_HOME


def test_home_asked_for_is_not_fixed_and_the_correction_is_told_as_a_move() -> None:
    rover = Standing()
    rover.fixes_at(25.0, 0.0, PERIOD_S)  # the glitched first fix: healthy there at once
    # A ground station asks on connect (MAV_CMD_REQUEST_MESSAGE HOME_POSITION), then asks again.
    ask = command_long(mavlink2.MAV_CMD_REQUEST_MESSAGE, float(mavlink2.MAVLINK_MSG_ID_HOME_POSITION))
    assert rover.keeper.take(rover.follower, ask) is None
    assert rover.keeper.take(rover.follower, ask) is None
    assert len(rover.events) == 1  # told once: home at the glitch
    rover.fixes_at(0.0, 0.0, 15.0)  # the truth: the estimator re-anchors, home with it
    assert [detail.split(" (")[0] for _, _, detail in rover.events] == ["home at", "home moved to"]
    told = [m for m in rover.follower.sent if m.get_type() == "HOME_POSITION"]
    assert [round(m.y) for m in told] == [25, 25, 0]  # the two answers, the move (NED: y is east, m)
    home = rover.keeper.home()  # driven to: fixed as told, not told again
    assert home is not None and math.hypot(home.x, home.y) < 0.5
    assert len(rover.events) == 2
    rover.fixes_at(0.0, 25.0, 15.0)
    assert rover.keeper.home() == home and len(rover.events) == 2  # fixed: a later glitch moves it not
