import math

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.mavlink_commands import FORCE_DISARM_MAGIC, StopRequest
from firmware_bridge.mavlink_link import MavlinkLink
from firmware_bridge.mavlink_transport import memory_pipe_pair
from logs.clock import SimClock
from logs.sink import MemorySink
from logs.topics import SAFETY_EVENTS

KEY = bytes(range(32))
DISARM = mavlink2.MAV_CMD_COMPONENT_ARM_DISARM
TERMINATE = mavlink2.MAV_CMD_DO_FLIGHTTERMINATION


def gcs(key=None):
    mav = mavlink2.MAVLink(None, 255, 190)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.link_id = 1
        mav.signing.timestamp = 1000
    return mav


def command(kind, cmd, param1, param2=0.0, target=(1, 191)):
    if kind == "COMMAND_LONG":
        return mavlink2.MAVLink_command_long_message(*target, cmd, 0, param1, param2, 0, 0, 0, 0, 0)
    return mavlink2.MAVLink_command_int_message(
        *target, mavlink2.MAV_FRAME_GLOBAL_INT, cmd, 0, 0, param1, param2, 0, 0, 0, 0, 0
    )


def rig(**kwargs):
    companion, ground = memory_pipe_pair()
    sink = MemorySink()
    link = MavlinkLink(companion, SimClock(42), sink, system_id=1, component_id=191, **kwargs)
    return link, ground, sink


def answers(wire):
    return mavlink2.MAVLink(None).parse_buffer(wire) or []


@pytest.mark.parametrize("kind", ["COMMAND_LONG", "COMMAND_INT"])
@pytest.mark.parametrize(
    ("cmd", "param1", "param2", "source"),
    [
        (DISARM, 0.0, FORCE_DISARM_MAGIC, "MAV_CMD_COMPONENT_ARM_DISARM"),
        (DISARM, 0.0, 0.0, "MAV_CMD_COMPONENT_ARM_DISARM"),
        (TERMINATE, 1.0, 0.0, "MAV_CMD_DO_FLIGHTTERMINATION"),
    ],
)
def test_stop_commands_become_a_stop_request_acked_and_recorded(kind, cmd, param1, param2, source):
    link, ground, sink = rig()
    ground.write(bytes(command(kind, cmd, param1, param2).pack(gcs())))
    (stop,) = link.poll()
    assert stop == StopRequest(42, source, 255, 190)
    (ack,) = answers(ground.read())
    assert ack.get_type() == "COMMAND_ACK"
    assert (ack.command, ack.result) == (cmd, mavlink2.MAV_RESULT_ACCEPTED)
    assert (ack.target_system, ack.target_component) == (255, 190)
    (event,) = sink.on(SAFETY_EVENTS)
    assert event["kind"] == "mavlink_stop_request" and source in event["detail"]
    assert link.counters.stops_accepted == 1 and link.counters.commands_rejected == 0


@pytest.mark.parametrize(
    ("cmd", "param1", "result"),
    [
        (DISARM, 1.0, mavlink2.MAV_RESULT_UNSUPPORTED),  # arm: never from a ground station via us
        (DISARM, 7.0, mavlink2.MAV_RESULT_DENIED),
        (DISARM, math.nan, mavlink2.MAV_RESULT_DENIED),
        (TERMINATE, 0.0, mavlink2.MAV_RESULT_UNSUPPORTED),  # clearing termination
    ],
)
def test_non_stop_variants_are_refused_with_a_reason(cmd, param1, result):
    link, ground, sink = rig()
    ground.write(bytes(command("COMMAND_LONG", cmd, param1).pack(gcs())))
    assert link.poll() == []
    ack, *texts = answers(ground.read())
    assert (ack.command, ack.result) == (cmd, result)
    assert texts[0].get_type() == "STATUSTEXT" and "refused" in texts[0].text
    assert link.counters.stops_accepted == 0 and link.counters.commands_rejected == 1
    assert sink.on(SAFETY_EVENTS) == []


def test_stop_for_another_system_is_ignored_and_broadcast_is_taken():
    link, ground, _ = rig()
    ground.write(bytes(command("COMMAND_LONG", DISARM, 0.0, target=(2, 191)).pack(gcs())))
    assert link.poll() == [] and ground.read() == b""
    ground.write(bytes(command("COMMAND_LONG", DISARM, 0.0, target=(0, 0)).pack(gcs())))
    assert [type(r) for r in link.poll()] == [StopRequest]


def test_with_signing_on_only_a_signed_stop_is_taken():
    link, ground, _ = rig(signing_key=KEY)
    ground.write(bytes(command("COMMAND_LONG", TERMINATE, 1.0).pack(gcs())))
    assert link.poll() == []
    assert link.counters.signature_rejected == 1 and link.counters.stops_accepted == 0
    ground.write(bytes(command("COMMAND_LONG", TERMINATE, 1.0).pack(gcs(KEY))))
    (stop,) = link.poll()
    assert isinstance(stop, StopRequest) and stop.source == "MAV_CMD_DO_FLIGHTTERMINATION"
