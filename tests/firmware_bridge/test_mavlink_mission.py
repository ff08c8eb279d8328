"""The mission protocol's server against a pymavlink ground station over the in-memory MAVLink pipe the
lockstep trials use: upload, download, clear, set current, and the defined answer to everything else."""

from __future__ import annotations

import logging
import math
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_commands import GLOBAL_FRAMES, StartRequest
from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_mission import (
    ITEM_TIMEOUT_NS,
    MAX_RETRIES,
    OPERATION_TIMEOUT_NS,
    CurrentRequested,
    MissionAccepted,
    MissionChange,
    MissionCleared,
    MissionItemRefused,
    MissionMessage,
    MissionServer,
)
from firmware_bridge.mavlink_transport import memory_pipe_pair
from firmware_bridge.mission_hold import MAX_HOLD_S, PlacedWaypoint
from firmware_bridge.mission_speed import SpeedChange, slowest_mission_speed
from firmware_bridge.mission_state import MissionState
from logs.clock import SimClock
from logs.sink import MemorySink
from logs.topics import MAVLINK_STATS
from tests.firmware_bridge.ground_station import (
    MISSION,
    ROVER,
    GroundStation,
    change_speed,
    mission_start,
    waypoint,
)

TICK_NS = 20_000_000  # the onboard loop's 50 Hz
FENCE_LAT = 47.001  # north of it the test's placer refuses: the rover's geofence stands in
PLAN = [(47.0000, 8.0000), (47.0002, 8.0003), (47.0004, 8.0001)]  # lat, lon


def place(lat: float, lon: float) -> tuple[float, float]:
    if lat > FENCE_LAT:
        raise MissionItemRefused(f"waypoint at latitude {lat:.4f} is outside the geofence")
    return (lon - 8.0) * 1e5, (lat - 47.0) * 1e5


def items(plan: list[tuple[float, float]] = PLAN) -> list[Any]:
    return [waypoint(seq, lat, lon) for seq, (lat, lon) in enumerate(plan)]


def count(n: int, mission_type: int = MISSION) -> Any:
    return mavlink2.MAVLink_mission_count_message(*ROVER, n, mission_type)


def ack(result: int) -> Any:
    return mavlink2.MAVLink_mission_ack_message(*ROVER, result, MISSION)


class Rig:
    """The rover's ground-station link and its mission server, stepped at the loop's rate."""

    def __init__(self, **server: Any) -> None:
        rover_end, station_end = memory_pipe_pair()
        self.clock = SimClock()
        self.sink = MemorySink()
        self.link = MavlinkLink(
            rover_end, self.clock, self.sink, system_id=1, component_id=191, link_timeout_s=None, name="gcs"
        )
        self.server = MissionServer(self.clock, place, **server)
        self.gcs = GroundStation(station_end)
        # A second ground station on the same wire (what the rover sends, ``gcs`` reads).
        self.other = GroundStation(station_end, sysid=254, compid=190)
        self.changes: list[MissionChange] = []
        self.progress: tuple[int, MissionState] = (0, MissionState.NONE)

    def step(self, dt_ns: int = TICK_NS) -> list[Any]:
        """One control tick: the link read, mission messages to the server, its tick; what the rover sent
        but the MISSION_CURRENT stream (in ``gcs.heard``, as everything)."""
        self.clock.advance(dt_ns)
        for reading in self.link.poll():
            if isinstance(reading, MissionMessage):
                change = self.server.take(self.link, reading.msg)
                if change is not None:
                    self.changes.append(change)
        self.server.tick(*self.progress)
        return [m for m in self.gcs.receive() if m.get_type() != "MISSION_CURRENT"]

    def exchange(self, msg: Any, station: GroundStation | None = None) -> list[Any]:
        (station or self.gcs).send(msg)
        return self.step()

    def upload(self, plan: list[Any], station: GroundStation | None = None) -> Any:
        """A whole upload, as a ground station drives it; returns the rover's MISSION_ACK."""
        station = station or self.gcs
        received = self.exchange(count(len(plan)), station)
        for _ in range(len(plan) + 5):
            acks = [m for m in received if m.get_type() == "MISSION_ACK"]
            if acks:
                return acks[0]
            station.answer(plan, received)
            received = self.step()
        raise AssertionError(f"no MISSION_ACK; heard {[m.get_type() for m in self.gcs.heard]}")

    def refusal(self, received: list[Any]) -> tuple[int, str]:
        """The MISSION_ACK's result and the STATUSTEXT's reason the rover answered with."""
        (answer,) = [m for m in received if m.get_type() == "MISSION_ACK"]
        return answer.type, "".join(m.text for m in received if m.get_type() == "STATUSTEXT")


def accepted(rig: Rig) -> MissionAccepted:
    assert rig.upload(items()).type == mavlink2.MAV_MISSION_ACCEPTED
    change = rig.changes[-1]
    assert isinstance(change, MissionAccepted)
    return change


def test_upload_asks_for_each_item_in_turn_then_accepts_and_places_them() -> None:
    rig = Rig()
    change = accepted(rig)
    requests = rig.gcs.of_type("MISSION_REQUEST_INT")
    assert [r.seq for r in requests] == [0, 1, 2]
    assert {(r.target_system, r.target_component, r.mission_type) for r in requests} == {(255, 190, MISSION)}
    assert (change.sysid, change.compid) == (255, 190)
    expected = [place(lat, lon) for lat, lon in PLAN]
    assert [c for xy in change.steps if isinstance(xy, tuple) for c in xy[:2]] == pytest.approx(
        [c for xy in expected for c in xy]
    )
    assert [i.seq for i in rig.server.items] == [0, 1, 2]
    assert rig.link.counters.missions_accepted == 1 and rig.link.counters.mission_refused == 0


def test_download_gives_back_what_was_uploaded_field_for_field() -> None:
    rig = Rig()
    accepted(rig)
    received = rig.exchange(mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION))
    (announced,) = [m for m in received if m.get_type() == "MISSION_COUNT"]
    assert announced.count == 3 and (announced.target_system, announced.target_component) == (255, 190)
    sent = items()
    for seq in range(3):
        (item,) = rig.exchange(mavlink2.MAVLink_mission_request_int_message(*ROVER, seq, MISSION))
        assert item.get_type() == "MISSION_ITEM_INT"
        original = sent[seq]
        for name in ("seq", "frame", "command", "autocontinue", "x", "y", "z", "param1", "param2", "param3"):
            assert getattr(item, name) == getattr(original, name), name
    assert rig.exchange(ack(mavlink2.MAV_MISSION_ACCEPTED)) == []  # an ACK is never answered
    assert rig.link.counters.mission_downloads == 1 and not rig.server.transfer_under_way
    # The old request form is answered with MISSION_ITEM_INT too.
    rig.exchange(mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION))
    (item,) = rig.exchange(mavlink2.MAVLink_mission_request_message(*ROVER, 1, MISSION))
    assert item.get_type() == "MISSION_ITEM_INT" and item.seq == 1


def with_speeds() -> list[Any]:
    """PLAN with speed changes, as QGroundControl plans a "Change speed" item: before the first waypoint, one
    back to the default between two waypoints, one faster than any rover after the last."""
    first, second, third = items()
    return [
        change_speed(0, 0.5),
        *renumbered([first], 1),
        change_speed(2, -2.0, speed_type=mavlink2.SPEED_TYPE_AIRSPEED),  # 0: airspeed, read as ground speed
        *renumbered([second, third], 3),
        change_speed(5, 25.0, frame=mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT),  # any frame
    ]


def renumbered(plan: list[Any], first: int) -> list[Any]:
    """``plan``'s items numbered from ``first`` on."""
    for offset, item in enumerate(plan):
        item.seq = first + offset
    return plan


def test_an_upload_with_speed_changes_is_accepted_numbered_as_uploaded() -> None:
    rig = Rig()
    assert rig.upload(with_speeds()).type == mavlink2.MAV_MISSION_ACCEPTED
    assert [r.seq for r in rig.gcs.of_type("MISSION_REQUEST_INT")] == [0, 1, 2, 3, 4, 5]
    change = rig.changes[-1]
    assert isinstance(change, MissionAccepted)
    placed = [PlacedWaypoint(*place(lat, lon)) for lat, lon in PLAN]
    # Speed 25 m/s is accepted: the rover's own top speed stands (docs/firmware_bridge.md "Missions").
    assert change.steps == (
        SpeedChange(0.5),
        placed[0],
        SpeedChange(None),
        placed[1],
        placed[2],
        SpeedChange(25.0),
    )
    assert [i.command for i in rig.server.items] == [178, 16, 178, 16, 16, 178]
    assert rig.link.counters.missions_accepted == 1 and rig.link.counters.mission_refused == 0


def test_a_download_gives_back_speed_changes_field_for_field() -> None:
    rig = Rig()
    sent = with_speeds()
    rig.upload(sent)
    (announced,) = rig.exchange(mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION))
    assert announced.count == 6
    for seq, original in enumerate(sent):
        (item,) = rig.exchange(mavlink2.MAVLink_mission_request_int_message(*ROVER, seq, MISSION))
        assert item.get_type() == "MISSION_ITEM_INT"
        for name in ("seq", "frame", "command", "current", "autocontinue", "x", "y", "z", "mission_type"):
            assert getattr(item, name) == getattr(original, name), (seq, name)
        for name in ("param1", "param2", "param3", "param4"):
            got, want = getattr(item, name), getattr(original, name)
            assert got == want or (math.isnan(got) and math.isnan(want)), (seq, name)
    rig.exchange(ack(mavlink2.MAV_MISSION_ACCEPTED))
    assert rig.link.counters.mission_downloads == 1


def test_an_empty_mission_downloads_as_a_count_of_zero() -> None:
    rig = Rig()
    received = rig.exchange(mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION))
    assert [(m.get_type(), m.count) for m in received] == [("MISSION_COUNT", 0)]
    assert not rig.server.transfer_under_way


@pytest.mark.parametrize(
    "clearing",
    [
        mavlink2.MAVLink_mission_clear_all_message(*ROVER, MISSION),
        mavlink2.MAVLink_mission_clear_all_message(*ROVER, mavlink2.MAV_MISSION_TYPE_ALL),
        count(0),  # the spec: an empty upload clears
    ],
    ids=["clear-mission", "clear-all", "empty-upload"],
)
def test_clearing_empties_the_mission_and_is_acknowledged(clearing: Any) -> None:
    rig = Rig()
    accepted(rig)
    (answer,) = rig.exchange(clearing)
    assert answer.get_type() == "MISSION_ACK" and answer.type == mavlink2.MAV_MISSION_ACCEPTED
    assert rig.server.items == () and isinstance(rig.changes[-1], MissionCleared)


def _held(item: Any, hold_s: float) -> Any:
    """``item`` (a MISSION_ITEM_INT waypoint) with ``hold_s`` in its param1, its hold time."""
    item.param1 = hold_s
    return item


def test_a_waypoints_hold_time_comes_with_it_and_nan_is_none() -> None:
    rig = Rig()
    plan = [
        _held(waypoint(0, 47.0, 8.0), 5.0),
        _held(waypoint(1, 47.0001, 8.0), math.nan),
        waypoint(2, 47.0, 8.0),
    ]
    assert rig.upload(plan).type == mavlink2.MAV_MISSION_ACCEPTED
    change = rig.changes[-1]
    assert isinstance(change, MissionAccepted)
    assert [step.hold_s for step in change.steps if isinstance(step, PlacedWaypoint)] == [5.0, 0.0, 0.0]
    # A download gives back what was sent, NaN included.
    assert math.isnan(rig.server.items[1].params[0]) and rig.server.items[0].params[0] == 5.0


# Each refusal: what the ground station sends after a good upload, the MISSION_ACK result, the reason.
REFUSALS = [
    pytest.param(
        [count(3, mavlink2.MAV_MISSION_TYPE_FENCE)],
        mavlink2.MAV_MISSION_UNSUPPORTED,
        "mission type 1 (MAV_MISSION_TYPE_FENCE)",
        id="fence-upload",
    ),
    pytest.param(
        [mavlink2.MAVLink_mission_request_list_message(*ROVER, mavlink2.MAV_MISSION_TYPE_RALLY)],
        mavlink2.MAV_MISSION_UNSUPPORTED,
        "download of mission type 2 (MAV_MISSION_TYPE_RALLY)",
        id="rally-download",
    ),
    pytest.param(
        [mavlink2.MAVLink_mission_clear_all_message(*ROVER, mavlink2.MAV_MISSION_TYPE_FENCE)],
        mavlink2.MAV_MISSION_UNSUPPORTED,
        "clear of mission type 1",
        id="fence-clear",
    ),
    pytest.param([count(257)], mavlink2.MAV_MISSION_NO_SPACE, "257 items: at most 256", id="too-many"),
    pytest.param(
        [count(2), waypoint(0, 47.0, 8.0, command=mavlink2.MAV_CMD_NAV_LAND)],
        mavlink2.MAV_MISSION_UNSUPPORTED,
        "item 0: command 21 (MAV_CMD_NAV_LAND) is not supported: only MAV_CMD_NAV_WAYPOINT, "
        "MAV_CMD_NAV_LOITER_TIME, MAV_CMD_NAV_LOITER_UNLIM, MAV_CMD_NAV_RETURN_TO_LAUNCH, "
        "MAV_CMD_DO_CHANGE_SPEED, MAV_CMD_DO_JUMP and MAV_CMD_NAV_DELAY",
        id="not-a-waypoint",
    ),
    *[
        pytest.param(
            [count(3), waypoint(0, 47.0, 8.0), change_speed(1, speed)],
            mavlink2.MAV_MISSION_INVALID_PARAM2,
            f"item 1: DO_CHANGE_SPEED speed (param2) {shown} m/s is not a speed",
            id=f"speed-{shown}",
        )
        for speed, shown in [
            (0.0, "0.0"),  # would park the rover mid-mission
            (-0.5, "-0.5"),
            (-3.0, "-3.0"),
            (math.nan, "nan"),
            (math.inf, "inf"),
            (-math.inf, "-inf"),
        ]
    ],
    *[
        pytest.param(
            [count(2), _held(waypoint(0, 47.0, 8.0), hold_s)],
            mavlink2.MAV_MISSION_INVALID_PARAM1,
            f"item 0: MAV_CMD_NAV_WAYPOINT hold time (param1) {shown} s is not a hold",
            id=f"hold-{shown}",
        )
        for hold_s, shown in [(-1.0, "-1.0"), (math.inf, "inf"), (MAX_HOLD_S + 1.0, "3601.0")]
    ],
    *[
        pytest.param(
            [count(2), change_speed(0, 1.0, speed_type=speed_type)],
            mavlink2.MAV_MISSION_INVALID_PARAM1,
            f"item 0: DO_CHANGE_SPEED speed type (param1) {shown} is not taken",
            id=f"speed-type-{shown}",
        )
        for speed_type, shown in [(mavlink2.SPEED_TYPE_CLIMB_SPEED, "2.0"), (0.5, "0.5"), (math.nan, "nan")]
    ],
    pytest.param(
        [count(2), change_speed(0, 1.0), change_speed(1, -2.0)],
        mavlink2.MAV_MISSION_ERROR,
        "a mission of 2 item(s) with no MAV_CMD_NAV_WAYPOINT: it needs at least one waypoint",
        id="speed-changes-alone",
    ),
    pytest.param(
        [count(2), waypoint(0, 47.0, 8.0, frame=mavlink2.MAV_FRAME_LOCAL_NED)],
        mavlink2.MAV_MISSION_UNSUPPORTED_FRAME,
        "item 0: frame 1 (MAV_FRAME_LOCAL_NED) is not global",
        id="local-frame",
    ),
    pytest.param(
        [count(2), waypoint(0, 47.0, 8.0), waypoint(1, 91.0, 8.0)],
        mavlink2.MAV_MISSION_INVALID_PARAM5_X,
        "item 1: latitude 910000000",
        id="latitude",
    ),
    pytest.param(
        [count(2), waypoint(0, 47.0, -181.0)],
        mavlink2.MAV_MISSION_INVALID_PARAM6_Y,
        "item 0: longitude -1810000000",
        id="longitude",
    ),
    pytest.param(
        [count(2), waypoint(0, 47.0, 8.0), waypoint(1, 47.01, 8.0)],
        mavlink2.MAV_MISSION_DENIED,
        "item 1: waypoint at latitude 47.0100 is outside the geofence",
        id="placer-refuses",
    ),
    pytest.param(
        [count(2), waypoint(2, 47.0, 8.0)],
        mavlink2.MAV_MISSION_INVALID_SEQUENCE,
        "item 2 of a mission of 2 items (0..1)",
        id="beyond-the-count",
    ),
    pytest.param(
        [waypoint(0, 47.0, 8.0)],
        mavlink2.MAV_MISSION_INVALID_SEQUENCE,
        "MISSION_ITEM_INT 0 from 255/190, which has no upload under way",
        id="item-without-upload",
    ),
    pytest.param(
        [count(2), waypoint(0, 47.0, 8.0, mission_type=mavlink2.MAV_MISSION_TYPE_RALLY)],
        mavlink2.MAV_MISSION_UNSUPPORTED,
        "upload of mission type 2",
        id="item-of-another-type",
    ),
    pytest.param(
        [
            count(2),
            mavlink2.MAVLink_mission_item_message(*ROVER, 0, 6, 16, 0, 1, 0, 0, 0, 0, 47.0, 8.0, 2, 0),
        ],
        mavlink2.MAV_MISSION_UNSUPPORTED,
        "the float MISSION_ITEM is not taken",
        id="float-item",
    ),
    pytest.param(
        [mavlink2.MAVLink_mission_request_int_message(*ROVER, 0, MISSION)],
        mavlink2.MAV_MISSION_INVALID_SEQUENCE,
        "MISSION_REQUEST_INT 0 from 255/190, which has no download under way",
        id="request-without-download",
    ),
    pytest.param(
        [
            mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION),
            mavlink2.MAVLink_mission_request_int_message(*ROVER, 3, MISSION),
        ],
        mavlink2.MAV_MISSION_INVALID_SEQUENCE,
        "item 3 asked of a mission of 3 items",
        id="request-beyond-the-count",
    ),
]


def test_a_speed_below_the_slowest_the_rover_drives_is_refused_and_the_slowest_taken() -> None:
    rig = Rig(slowest_speed_mps=0.2)
    accepted(rig)
    rig.exchange(count(2))
    rig.exchange(waypoint(0, 47.0, 8.0))
    answer, text = rig.refusal(rig.exchange(change_speed(1, 0.15)))
    assert answer == mavlink2.MAV_MISSION_INVALID_PARAM2 and rig.link.counters.mission_refused == 1
    assert "0.15 m/s is below 0.2 m/s, the slowest this rover drives with its stuck and stall checks" in text
    assert rig.upload([waypoint(0, 47.0, 8.0), change_speed(1, 0.2)]).type == mavlink2.MAV_MISSION_ACCEPTED


def test_the_slowest_mission_speed_keeps_the_follower_and_both_failsafes_awake() -> None:
    assert slowest_mission_speed(0.1, 0.2, 0.1) == 0.2
    assert slowest_mission_speed(0.3, 0.2, 0.1) == 0.3
    assert slowest_mission_speed(0.0, 0.0, 0.25) == 0.25


@pytest.mark.parametrize(("messages", "result", "reason"), REFUSALS)
def test_each_refusal_is_answered_counted_logged_and_leaves_the_mission_in_force(
    messages: list[Any], result: int, reason: str, caplog: pytest.LogCaptureFixture
) -> None:
    rig = Rig()
    accepted(rig)
    in_force = rig.server.items
    caplog.set_level(logging.WARNING, logger="firmware_bridge.mavlink_mission")
    for msg in messages[:-1]:
        rig.exchange(msg)
    received = rig.exchange(messages[-1])
    answer, text = rig.refusal(received)
    assert answer == result
    assert reason in text and text.startswith("mission refused: ")
    assert rig.link.counters.mission_refused == 1
    assert [r.getMessage() for r in caplog.records if reason in r.getMessage()], caplog.text
    assert rig.server.items == in_force and not rig.server.transfer_under_way
    assert len(rig.changes) == 1  # the good upload only


def test_an_item_out_of_sequence_is_dropped_and_the_expected_one_asked_again() -> None:
    rig = Rig()
    plan = items()
    rig.exchange(count(3))
    rig.exchange(plan[0])
    received = rig.exchange(plan[2])  # item 1 lost on the way
    assert [(m.get_type(), m.seq) for m in received] == [("MISSION_REQUEST_INT", 1)]
    assert rig.link.counters.mission_out_of_sequence == 1
    rig.exchange(plan[1])
    (answer,) = rig.exchange(plan[2])
    assert answer.type == mavlink2.MAV_MISSION_ACCEPTED and len(rig.server.items) == 3


def test_a_duplicated_item_is_dropped_silently() -> None:
    rig = Rig()
    plan = items()
    rig.exchange(count(3))
    rig.exchange(plan[0])
    # Not asked again: the request for item 1 is already out, and the partner answers it.
    assert rig.exchange(plan[0]) == []
    rig.exchange(plan[1])
    rig.exchange(plan[2])
    assert len(rig.server.items) == 3 and rig.link.counters.missions_accepted == 1
    assert rig.link.counters.mission_resends == 0


def test_a_late_answer_costs_its_resend_not_a_doubled_upload() -> None:
    """A ground station that answers every request, the resent ones too, and is once slower than the
    item timeout: one resend and one duplicate, no more."""
    rig = Rig()
    plan = items([(47.0 + seq * 1e-5, 8.0) for seq in range(20)])
    late_ticks = round(ITEM_TIMEOUT_NS / TICK_NS) + 3  # item 5's first request answered after 310 ms
    answers: list[tuple[int, int]] = []  # (due tick, seq), answered in that order
    received = rig.exchange(count(20))
    acks: list[Any] = []
    for tick in range(400):
        for msg in received:
            if msg.get_type() == "MISSION_REQUEST_INT":
                late = msg.seq == 5 and not any(seq == 5 for _, seq in answers)
                answers.append((tick + (late_ticks if late else 1), msg.seq))
        acks += [m for m in received if m.get_type() == "MISSION_ACK"]
        if acks:
            break
        for due, seq in sorted(answers):
            if due == tick:
                rig.gcs.send(plan[seq])
        received = rig.step()
    assert [a.type for a in acks] == [mavlink2.MAV_MISSION_ACCEPTED]
    requests = [m.seq for m in rig.gcs.of_type("MISSION_REQUEST_INT")]
    assert rig.link.counters.mission_resends == 1
    assert len(requests) == 20 + 1 and sorted(set(requests)) == list(range(20))
    assert rig.link.counters.mission_refused == 0 and len(rig.server.items) == 20


def test_the_last_item_again_after_the_upload_is_accepted_again_not_refused() -> None:
    """Our MISSION_ACK ACCEPTED lost: the ground station resends the last item until it hears one."""
    rig = Rig()
    plan = items()
    accepted(rig)
    rig.step()
    (again,) = rig.exchange(plan[2])
    assert again.get_type() == "MISSION_ACK" and again.type == mavlink2.MAV_MISSION_ACCEPTED
    counters = rig.link.counters
    assert counters.mission_refused == 0 and counters.missions_accepted == 1 and len(rig.changes) == 1
    # Another ground station's item is no repeat of this upload, nor an earlier item, nor the last item
    # after the operation timeout.
    rig.other.send(plan[2])
    assert rig.refusal(rig.step())[0] == mavlink2.MAV_MISSION_INVALID_SEQUENCE
    assert rig.refusal(rig.exchange(plan[1]))[0] == mavlink2.MAV_MISSION_INVALID_SEQUENCE
    rig.step(OPERATION_TIMEOUT_NS)
    assert rig.refusal(rig.exchange(plan[2]))[0] == mavlink2.MAV_MISSION_INVALID_SEQUENCE
    assert counters.mission_refused == 3 and len(rig.changes) == 1


def test_a_second_ground_station_is_refused_while_an_upload_is_under_way() -> None:
    rig = Rig()
    plan = items()
    rig.exchange(count(3))
    rig.exchange(plan[0])
    # Another system starts an upload, a download and a clear mid-way: each refused, the first goes on.
    for msg in (
        count(1),
        mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION),
        mavlink2.MAVLink_mission_clear_all_message(*ROVER, MISSION),
    ):
        rig.other.send(msg)
        rig.step()
    refusals = [m for m in rig.gcs.of_type("MISSION_ACK") if m.target_system == 254]
    assert [m.type for m in refusals] == [mavlink2.MAV_MISSION_DENIED] * 3
    assert rig.link.counters.mission_refused == 3
    rig.exchange(plan[1])
    rig.exchange(plan[2])
    answer = rig.gcs.of_type("MISSION_ACK")[-1]
    assert answer.type == mavlink2.MAV_MISSION_ACCEPTED and answer.target_system == 255
    assert len(rig.server.items) == 3


def test_the_same_ground_station_starting_over_replaces_its_partial_upload() -> None:
    rig = Rig()
    rig.exchange(count(3))
    rig.exchange(items()[0])
    shorter = items(PLAN[1:])
    assert rig.upload(shorter).type == mavlink2.MAV_MISSION_ACCEPTED
    assert [(i.x, i.y) for i in rig.server.items] == [(m.x, m.y) for m in shorter]


def test_a_partial_upload_is_asked_again_then_abandoned_and_never_replaces_the_mission() -> None:
    rig = Rig()
    accepted(rig)
    in_force = rig.server.items
    rig.gcs.heard.clear()
    rig.exchange(count(2))
    rig.exchange(items()[0])  # then silence
    for _ in range(round((MAX_RETRIES + 1) * ITEM_TIMEOUT_NS / TICK_NS) + 10):
        rig.step()
    requests = [m.seq for m in rig.gcs.of_type("MISSION_REQUEST_INT")]
    assert requests == [0, 1] + [1] * MAX_RETRIES  # item 1 asked again every 250 ms, 5 times
    (cancelled,) = rig.gcs.of_type("MISSION_ACK")
    assert cancelled.type == mavlink2.MAV_MISSION_OPERATION_CANCELLED
    assert rig.link.counters.mission_resends == MAX_RETRIES and rig.link.counters.mission_timeouts == 1
    assert rig.server.items == in_force and not rig.server.transfer_under_way
    # The ground station's late item finds no upload: told so, nothing changes.
    answer, _ = rig.refusal(rig.exchange(items()[1]))
    assert answer == mavlink2.MAV_MISSION_INVALID_SEQUENCE and rig.server.items == in_force


def test_the_partner_cancelling_its_upload_leaves_the_mission_in_force() -> None:
    rig = Rig()
    accepted(rig)
    in_force = rig.server.items
    rig.exchange(count(2))
    assert rig.exchange(ack(mavlink2.MAV_MISSION_OPERATION_CANCELLED)) == []
    assert rig.server.items == in_force and not rig.server.transfer_under_way


def test_a_download_the_partner_stops_following_is_abandoned() -> None:
    rig = Rig()
    accepted(rig)
    rig.gcs.heard.clear()
    rig.exchange(mavlink2.MAVLink_mission_request_list_message(*ROVER, MISSION))
    for _ in range(round((MAX_RETRIES + 1) * OPERATION_TIMEOUT_NS / TICK_NS) + 10):
        rig.step()
    assert [m.count for m in rig.gcs.of_type("MISSION_COUNT")] == [3] * (1 + MAX_RETRIES)
    assert [m.type for m in rig.gcs.of_type("MISSION_ACK")] == [mavlink2.MAV_MISSION_OPERATION_CANCELLED]
    assert not rig.server.transfer_under_way and rig.link.counters.mission_timeouts == 1


def test_an_upload_that_keeps_sending_the_wrong_item_runs_out_of_retries() -> None:
    rig = Rig()
    rig.exchange(count(3))
    for _ in range(MAX_RETRIES + 1):
        rig.exchange(items()[2])
    assert [m.type for m in rig.gcs.of_type("MISSION_ACK")] == [mavlink2.MAV_MISSION_OPERATION_CANCELLED]
    assert rig.server.items == ()


def test_set_current_is_passed_on_for_an_item_the_mission_has_and_refused_otherwise() -> None:
    rig = Rig()
    received = rig.exchange(mavlink2.MAVLink_mission_set_current_message(*ROVER, 0))
    assert [m.text for m in received if m.get_type() == "STATUSTEXT"] == [
        "mission item 0 not set: there is no mission"
    ]
    accepted(rig)
    rig.exchange(mavlink2.MAVLink_mission_set_current_message(*ROVER, 2))
    assert rig.changes[-1] == CurrentRequested(2, 255, 190)
    received = rig.exchange(mavlink2.MAVLink_mission_set_current_message(*ROVER, 3))
    assert [m.text for m in received if m.get_type() == "STATUSTEXT"] == [
        "mission item 3 not set: the mission has items 0..2"
    ]
    assert rig.link.counters.mission_refused == 2 and rig.changes[-1] == CurrentRequested(2, 255, 190)


def test_progress_goes_out_on_change_and_once_a_second_only_to_a_link_that_asked() -> None:
    rig = Rig()
    rig.progress = (0, MissionState.ACTIVE)
    for _ in range(60):
        assert rig.step() == []  # no ground station has talked missions: nothing is streamed
    accepted(rig)
    rig.gcs.heard.clear()
    for _ in range(100):  # 2 s
        rig.step()
    currents = rig.gcs.of_type("MISSION_CURRENT")
    assert len(currents) == 2 and {(c.seq, c.total, c.mission_state) for c in currents} == {
        (0, 3, mavlink2.MISSION_STATE_ACTIVE)
    }
    rig.gcs.heard.clear()
    rig.progress = (1, MissionState.ACTIVE)
    rig.server.item_reached(0)
    rig.step()
    assert [(m.get_type(), m.seq) for m in rig.gcs.heard] == [
        ("MISSION_ITEM_REACHED", 0),
        ("MISSION_CURRENT", 1),
    ]
    rig.progress = (2, MissionState.COMPLETE)
    rig.step()
    current = rig.gcs.heard[-1]
    assert (current.seq, current.total, current.mission_state) == (3, 3, mavlink2.MISSION_STATE_COMPLETE)


def test_mission_messages_for_another_component_or_system_are_left_alone() -> None:
    rig = Rig()
    for target in ((1, 0), (1, 1), (2, 191)):  # component broadcast: the autopilot's business
        assert rig.exchange(mavlink2.MAVLink_mission_count_message(*target, 3, MISSION)) == []
    assert rig.link.counters.mission_messages == 0 and not rig.server.transfer_under_way
    # System broadcast with our component named is ours.
    received = rig.exchange(mavlink2.MAVLink_mission_count_message(0, 191, 3, MISSION))
    assert [m.get_type() for m in received] == ["MISSION_REQUEST_INT"]


def test_mission_counts_reach_mavlink_stats_once_a_mission_message_came() -> None:
    rig = Rig()
    for _ in range(60):
        rig.step()
    assert rig.sink.on(MAVLINK_STATS) and "mission_messages" not in rig.sink.on(MAVLINK_STATS)[-1]
    accepted(rig)
    rig.exchange(count(3, mavlink2.MAV_MISSION_TYPE_RALLY))
    for _ in range(60):
        rig.step()
    totals = {
        name: sum(s.get(name, 0) for s in rig.sink.on(MAVLINK_STATS))
        for name in ("mission_messages", "missions_accepted", "mission_refused")
    }
    assert totals == {"mission_messages": 5, "missions_accepted": 1, "mission_refused": 1}


def test_with_signing_on_an_unsigned_upload_is_refused_by_the_signing_check() -> None:
    key = bytes(range(32))
    rover_end, station_end = memory_pipe_pair()
    clock = SimClock()
    link = MavlinkLink(rover_end, clock, MemorySink(), link_timeout_s=None, signing_key=key)
    station = GroundStation(station_end)
    station.send(count(3))
    clock.advance(TICK_NS)
    assert link.poll() == [] and link.counters.signature_rejected == 1
    station.mav.signing.secret_key = key
    station.mav.signing.sign_outgoing = True
    station.mav.signing.link_id = 1
    station.mav.signing.timestamp = 1000
    station.send(count(3))
    (reading,) = link.poll()
    assert isinstance(reading, MissionMessage) and reading.msg.count == 3


# --- malformed missions (hypothesis) ------------------------------------------------------------------
_u8 = st.integers(0, 255)
_u16 = st.integers(0, 5) | st.integers(0, 65535)
_int32 = st.integers(-(2**31), 2**31 - 1)
_float = st.floats(width=32, allow_nan=True, allow_infinity=True)
_target = st.sampled_from([ROVER, (0, 191), (1, 0), (2, 191)])
_mission_type = st.sampled_from([MISSION, MISSION, 1, 2, 255]) | _u8
_frame = st.sampled_from([mavlink2.MAV_FRAME_GLOBAL_INT, mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 1]) | _u8
_command = (
    st.sampled_from([mavlink2.MAV_CMD_NAV_WAYPOINT] * 3 + [mavlink2.MAV_CMD_DO_CHANGE_SPEED, 17, 21]) | _u16
)
_lat = st.integers(469_990_000, 470_020_000) | _int32  # near the fence, or anything
_lon = st.integers(79_990_000, 80_010_000) | _int32


def _item(
    target: tuple[int, int], seq: int, frame: int, command: int, lat: int, lon: int, **more: Any
) -> Any:
    return mavlink2.MAVLink_mission_item_int_message(
        *target, seq, frame, command, more["current"], more["auto"], *more["params"], lat, lon, more["z"],
        more["mission_type"],
    )  # fmt: skip


_messages = st.one_of(
    st.builds(lambda t, n, k: mavlink2.MAVLink_mission_count_message(*t, n, k), _target, _u16, _mission_type),
    st.builds(
        _item,
        _target,
        _u16,
        _frame,
        _command,
        _lat,
        _lon,
        current=_u8,
        auto=_u8,
        # A speed change's speed type and speed: valid ones too, or hypothesis seldom finds one.
        params=st.tuples(
            st.sampled_from([0.0, 1.0]) | _float,
            st.sampled_from([-1.0, -2.0, 0.5]) | _float,
            _float,
            _float,
        ),
        z=_float,
        mission_type=_mission_type,
    ),
    st.builds(
        lambda t, s, k: mavlink2.MAVLink_mission_item_message(
            *t, s, 6, 16, 0, 1, 0, 0, 0, 0, 47.0, 8.0, 0, k
        ),
        _target,
        _u16,
        _mission_type,
    ),
    st.builds(lambda t, k: mavlink2.MAVLink_mission_request_list_message(*t, k), _target, _mission_type),
    st.builds(
        lambda t, s, k: mavlink2.MAVLink_mission_request_int_message(*t, s, k), _target, _u16, _mission_type
    ),
    st.builds(
        lambda t, s, k: mavlink2.MAVLink_mission_request_message(*t, s, k), _target, _u16, _mission_type
    ),
    st.builds(lambda t, r, k: mavlink2.MAVLink_mission_ack_message(*t, r, k), _target, _u8, _mission_type),
    st.builds(lambda t, k: mavlink2.MAVLink_mission_clear_all_message(*t, k), _target, _mission_type),
    st.builds(lambda t, s: mavlink2.MAVLink_mission_set_current_message(*t, s), _target, _u16),
)
# (which ground station sends, the message) | silence of up to 2 s | bytes on the wire.
_steps = st.lists(
    st.tuples(st.just("send"), st.booleans(), _messages)
    | st.tuples(st.just("wait"), st.integers(1, 2_000_000_000), st.none())
    | st.tuples(st.just("noise"), st.binary(min_size=1, max_size=64), st.none()),
    max_size=40,
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(steps=_steps)
def test_malformed_mission_traffic_never_raises_and_only_a_whole_valid_upload_changes_the_mission(
    steps: list[tuple[str, Any, Any]],
) -> None:
    rig = Rig(max_items=8)
    for kind, first, msg in steps:
        before = rig.server.items
        changes = len(rig.changes)
        if kind == "send":
            (rig.gcs if first else rig.other).send(msg)
            rig.step()
        elif kind == "wait":
            rig.step(first)
        else:
            rig.gcs.end.write(first)
            rig.step()
        new = rig.changes[changes:]
        if rig.server.items != before:
            # Only a completed upload (or a clear) replaces the mission in force, and says so.
            assert new and isinstance(new[-1], MissionAccepted | MissionCleared)
            assert rig.server.items == (new[-1].items if isinstance(new[-1], MissionAccepted) else ())
        assert len(rig.server.items) <= 8
        speed = mavlink2.MAV_CMD_DO_CHANGE_SPEED
        waypoints = [item for item in rig.server.items if item.command != speed]
        assert waypoints or not rig.server.items  # a mission has a waypoint
        for item in waypoints:
            assert item.command == mavlink2.MAV_CMD_NAV_WAYPOINT
            assert item.frame in GLOBAL_FRAMES and -90 <= item.lat_deg <= FENCE_LAT
            assert -180 <= item.lon_deg <= 180
        for item in rig.server.items:
            if item.command == speed:
                # The rule itself: ground or air speed; a positive finite speed, -1 or -2.
                speed_type, value = item.params[0], item.params[1]
                assert speed_type in (0.0, 1.0)
                assert value in (-1.0, -2.0) or (math.isfinite(value) and value > 0.0)
    # After the garbage and the timeouts, a clean upload still gets through: a stray start marker the
    # parser holds (a byte stream) is flushed by the traffic after it, here zeros (what it held is then
    # read), and a transfer left under way is abandoned within 6 timeouts (one per tick past a deadline).
    rig.gcs.end.write(bytes(300))
    rig.step()
    for _ in range(MAX_RETRIES + 2):
        rig.step(OPERATION_TIMEOUT_NS + TICK_NS)
    assert not rig.server.transfer_under_way
    assert rig.upload(items()).type == mavlink2.MAV_MISSION_ACCEPTED
    assert [(i.x, i.y) for i in rig.server.items] == [(m.x, m.y) for m in items()]


@pytest.mark.parametrize("kind", ["COMMAND_LONG", "COMMAND_INT"])
@pytest.mark.parametrize(("first", "last"), [(0, 0), (1, 0), (1, 2), (2, 2)])
def test_mission_start_from_an_item_to_the_end_is_acknowledged_and_passed_on(
    kind: str, first: int, last: int
) -> None:
    rig = Rig()
    accepted(rig)
    (answer,) = rig.exchange(mission_start(first, last, kind=kind))
    assert answer.get_type() == "COMMAND_ACK"
    assert (answer.command, answer.result) == (mavlink2.MAV_CMD_MISSION_START, mavlink2.MAV_RESULT_ACCEPTED)
    assert (answer.target_system, answer.target_component) == (255, 190)
    start = rig.changes[-1]
    assert isinstance(start, StartRequest)
    assert (start.first, start.sysid, start.compid) == (first, 255, 190)


@pytest.mark.parametrize(
    ("first", "last", "result", "reason"),
    [
        (3, 0, mavlink2.MAV_RESULT_DENIED, "mission start: first item 3.0 not in items 0..2"),
        (0.5, 0, mavlink2.MAV_RESULT_DENIED, "first item 0.5 not in items 0..2"),
        (math.nan, 0, mavlink2.MAV_RESULT_DENIED, "first item nan not in items 0..2"),
        (0, 1, mavlink2.MAV_RESULT_UNSUPPORTED, "last item 1.0: only 0 or 2 (to the end) is supported"),
        (0, -1, mavlink2.MAV_RESULT_UNSUPPORTED, "last item -1.0"),
    ],
)
def test_a_mission_start_the_mission_cannot_take_is_refused_naming_why(
    first: float, last: float, result: int, reason: str
) -> None:
    rig = Rig()
    accepted(rig)
    received = rig.exchange(mission_start(first, last))
    (answer,) = [m for m in received if m.get_type() == "COMMAND_ACK"]
    assert answer.result == result
    text = "".join(m.text for m in received if m.get_type() == "STATUSTEXT")
    assert text.startswith("refused: ") and reason in text
    assert rig.link.counters.commands_rejected == 1 and len(rig.changes) == 1  # the upload only


def test_mission_start_without_a_mission_is_denied_and_one_for_another_component_left_alone() -> None:
    rig = Rig()
    received = rig.exchange(mission_start(0, 0))
    (answer,) = [m for m in received if m.get_type() == "COMMAND_ACK"]
    assert answer.result == mavlink2.MAV_RESULT_DENIED
    assert "mission start: there is no mission" in "".join(
        m.text for m in received if m.get_type() == "STATUSTEXT"
    )
    accepted(rig)
    # Component broadcast: the autopilot's mission (as for mission messages), not ours to answer.
    for target in ((1, 0), (1, 1)):
        assert rig.exchange(mission_start(0, 0, target=target)) == []
    assert not any(isinstance(change, StartRequest) for change in rig.changes)
