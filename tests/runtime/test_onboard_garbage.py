"""Property tests on a running onboard stack: odd CAN frames and MAVLink garbage arriving between the valid
traffic of a drive never raise out of a tick, are counted where the stack can see them, leave every tick's
records in place, and (when the link must refuse them) do not stop the rover.

The links alone are fuzzed in tests/firmware_bridge/test_garbage_properties.py; here the same kind of input
reaches the estimator, the safety supervisor and the mixer through a lockstep rig (``tests.runtime.rig``)
driven by its simulated clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import TypeVar

import can
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from tests.firmware_bridge.virtual_can import make_codec
from tests.runtime.rig import MSG_ATTITUDE, Rig, rig_config

T = TypeVar("T")
PROPERTY = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
CONTROLLER_IDS = (1, 2, 3, 4, 5, 6)
CODEC = make_codec()
# The ids our controllers' status frames use (29-bit): the frames most likely to be mistaken for ours.
OUR_STATUS_IDS = [
    CODEC.encode("STATUS", cid, erpm=0.0, current=0.0, duty=0.0).arbitration_id for cid in CONTROLLER_IDS
]


def _frame(
    can_id: int, extended: bool, data: bytes, dlc: int | None = None, remote: bool = False
) -> can.Message:
    return can.Message(
        arbitration_id=can_id if extended else can_id & 0x7FF,
        is_extended_id=extended,
        data=b"" if remote else data,
        dlc=len(data) if dlc is None else dlc,
        is_remote_frame=remote,
    )


# Frames the link must refuse whatever they hold: one of our status ids with the wrong length, as a remote
# frame, or as an 11-bit id; and ids nothing on our bus uses (the VESC command numbers go up to 64).
wrong_length = st.builds(
    lambda can_id, data: _frame(can_id, True, data),
    st.sampled_from(OUR_STATUS_IDS),
    st.binary(max_size=7),
)
remote = st.builds(
    lambda can_id, dlc: _frame(can_id, True, b"", dlc=dlc, remote=True),
    st.sampled_from(OUR_STATUS_IDS),
    st.integers(0, 8),
)
standard_id = st.builds(
    lambda can_id, data: _frame(can_id, False, data), st.sampled_from(OUR_STATUS_IDS), st.binary(max_size=8)
)
unknown_id = st.builds(
    lambda command, cid, data: _frame((command << 8) | cid, True, data),
    st.integers(100, 0xFF),
    st.integers(0, 0xFF),
    st.binary(max_size=8),
)
refused_frames = wrong_length | remote | standard_id | unknown_id
# Error frames with any class and data: what a controller's error reporting says about the bus.
error_frame = st.builds(
    lambda error_class, data: can.Message(
        arbitration_id=error_class, is_extended_id=False, is_error_frame=True, data=data, dlc=len(data)
    ),
    st.integers(0, 0x1FFFFFFF),
    st.binary(max_size=8),
)


@contextmanager
def _driving_rig() -> Iterator[Rig]:
    """A rig whose rover has passed its start-up checks and is driving to its goal."""
    rig = Rig(rig_config())
    try:
        rig.drive()
        yield rig
    finally:
        rig.close()


def _tick_through(
    rig: Rig, bursts: Sequence[Sequence[T]], send: Callable[[T], None]
) -> Iterator[Sequence[T]]:
    """For each burst: ``send`` each of it, run one control tick, then yield the burst (to check the tick)."""
    for burst in bursts:
        for item in burst:
            send(item)
        rig.control_tick()
        yield burst


def _driving(rig: Rig) -> bool:
    return rig.stack.safety_mode.value == "DRIVING"


def _ticks_recorded(rig: Rig, since_ns: int) -> list[int]:
    return [t for topic, t, _ in rig.sink.records if topic == "wheels/command" and t > since_ns]


@PROPERTY
@given(bursts=st.lists(st.lists(refused_frames, max_size=6), min_size=1, max_size=25))
def test_frames_the_link_refuses_are_counted_and_the_rover_drives_on(bursts: list[list[can.Message]]) -> None:
    with _driving_rig() as rig:
        began = rig.now_ns
        rejected_before = rig.stack._can.counters.rejected
        for burst in _tick_through(rig, bursts, rig._sim_bus.send):
            assert _driving(rig), f"stopped driving: {rig.stack.safety.mode} after {burst}"
        injected = sum(len(burst) for burst in bursts)
        assert rig.stack._can.counters.rejected - rejected_before == injected
        assert len(_ticks_recorded(rig, began)) == len(bursts)
        # The refused frames are in the recording too, as received (rx) frames.
        foreign = [m for topic, t, m in rig.sink.records if topic == "can/frames" and t > began]
        recorded = sum(m["direction"] == "rx" and m["id"] not in OUR_STATUS_IDS for m in foreign)
        assert recorded >= sum(msg.arbitration_id not in OUR_STATUS_IDS for burst in bursts for msg in burst)


@PROPERTY
@given(bursts=st.lists(st.lists(error_frame | refused_frames, max_size=4), min_size=1, max_size=20))
def test_error_frames_never_raise_out_of_a_tick_and_each_is_counted(bursts: list[list[can.Message]]) -> None:
    with _driving_rig() as rig:
        began = rig.now_ns
        errors_before = rig.stack._can.counters.bus_errors
        for _ in _tick_through(rig, bursts, rig._sim_bus.send):
            pass
        errors = sum(msg.is_error_frame for burst in bursts for msg in burst)
        assert rig.stack._can.counters.bus_errors - errors_before >= errors
        assert len(_ticks_recorded(rig, began)) == len(bursts)
        # Whatever the error frames said of the bus, a restart announcement and the controllers' status
        # bring it back: the rover drives again.
        rig._sim_bus.send(can.Message(arbitration_id=0x100, is_error_frame=True, is_extended_id=False, dlc=0))
        rig.run_until(lambda: _driving(rig) and rig.body.speed > 0.3, 10.0, "driving again")


def _pack(msg: mavlink2.MAVLink_message) -> bytes:
    """A whole MAVLink 2 frame from the autopilot (system 1, component 1)."""
    return bytes(msg.pack(mavlink2.MAVLink(None, 1, 1)))


def _attitude_frame(roll: float, pitch: float, yaw: float) -> bytes:
    return _pack(mavlink2.MAVLink_attitude_message(0, roll, pitch, yaw, 0.0, 0.0, 0.0))


not_finite = st.sampled_from([math.nan, math.inf, -math.inf])
# An ATTITUDE whose roll or pitch (or both) the AHRS could not give (NaN) or overflowed (inf); yaw as sent.
unusable_attitude = st.builds(
    lambda roll, pitch, yaw, which: _attitude_frame(
        roll if which != "pitch" else 0.0, pitch if which != "roll" else 0.0, yaw
    ),
    not_finite,
    not_finite,
    st.floats(-math.pi, math.pi) | not_finite,
    st.sampled_from(["roll", "pitch", "both"]),
)


@PROPERTY
@given(after=st.lists(unusable_attitude, min_size=1, max_size=3))
def test_an_attitude_without_roll_or_pitch_does_not_hide_a_tip_over(after: list[bytes]) -> None:
    with _driving_rig() as rig:
        rig.wire.dropped = {MSG_ATTITUDE}  # the attitude the rover sees is only what the test sends
        tipped = rig.stack._config.vehicle.tip_roll_rad  # no margin left at all
        rig.wire._inner.write(_attitude_frame(tipped, 0.0, 0.5) + b"".join(after))
        rig.control_tick()
        # The unusable samples carry nothing to judge the tilt by: the tipped one before them stands.
        assert rig.first_event_ns("failsafe.tip_over") is not None, rig.stack.safety.mode
        assert rig.stack.safety_mode.value == "HOLD"
        assert rig.stack.attitude_rejected == len(after)  # each counted (and the first logged)


any_float = st.floats(width=32)  # NaN and +/-inf included
small_int = st.integers(0, 255)


# Well-formed frames (the CRC is right) whose fields hold anything their types allow: what a buggy or
# differently configured autopilot can send, which no checksum catches.
odd_messages = st.one_of(
    st.builds(mavlink2.MAVLink_attitude_message, st.just(0), *[any_float] * 6),
    st.builds(mavlink2.MAVLink_highres_imu_message, st.just(0), *[any_float] * 13, st.just(0)),
    st.builds(mavlink2.MAVLink_scaled_imu_message, st.just(0), *[st.integers(-32768, 32767)] * 9),
    st.builds(
        mavlink2.MAVLink_gps_raw_int_message,
        st.just(0),
        st.integers(0, 8),
        st.integers(-(2**31), 2**31 - 1),
        st.integers(-(2**31), 2**31 - 1),
        st.integers(-(2**31), 2**31 - 1),
        *[st.integers(0, 65535)] * 4,
        small_int,
    ),
    st.builds(
        mavlink2.MAVLink_heartbeat_message,
        small_int,
        small_int,
        small_int,
        st.integers(0, 2**32 - 1),
        small_int,
        small_int,
    ),
    st.builds(
        mavlink2.MAVLink_command_long_message,
        st.sampled_from([0, 1]),
        st.sampled_from([0, 191]),
        st.sampled_from([400, 185, 192, 16]),
        small_int,
        *[any_float] * 7,
    ),
).map(_pack)
mavlink_garbage = st.binary(min_size=1, max_size=40) | st.builds(
    lambda frame, cut: frame[: max(1, len(frame) - cut)], odd_messages, st.integers(1, 20)
)


@PROPERTY
@given(bursts=st.lists(st.lists(odd_messages | mavlink_garbage, max_size=4), min_size=1, max_size=25))
def test_mavlink_garbage_and_odd_values_never_raise_out_of_a_tick(bursts: list[list[bytes]]) -> None:
    with _driving_rig() as rig:
        began = rig.now_ns
        for _ in _tick_through(rig, bursts, rig.wire._inner.write):
            pass
        assert len(_ticks_recorded(rig, began)) == len(bursts)
        states = [t for topic, t, _ in rig.sink.records if topic == "navigator/state" and t > began]
        assert len(states) == len(bursts)
