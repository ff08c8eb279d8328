"""The rover's end of the lockstep CAN bus during a ``can`` ``off`` fault behaves as a bus-off socketcan
controller: its sends are refused, it hears only the error frames that say bus-off and restarted."""

from __future__ import annotations

import can
import pytest

from firmware_bridge.can_health import CAN_ERR_BUSOFF, CAN_ERR_RESTARTED
from hil.bus_off import BusOffRoverEnd
from hil.faults import Fault, FaultSchedule
from hil.lockstep_bus import lockstep_bus_pair
from logs.clock import SimClock
from tests.hil.world_harness import run_world

MS = 1_000_000


def frame(arbitration_id: int) -> can.Message:
    return can.Message(arbitration_id=arbitration_id, is_extended_id=True, data=b"\x01\x02")


def received(bus: can.BusABC) -> can.Message:
    msg = bus.recv(timeout=0)
    assert msg is not None, "nothing received"
    return msg


def test_sends_fail_and_nothing_is_heard_only_while_the_fault_is_active() -> None:
    clock = SimClock()
    rover, controllers = lockstep_bus_pair("bus-off-test", clock)
    schedule = FaultSchedule((Fault("can", "off", start_ns=100 * MS, end_ns=200 * MS),))
    end = BusOffRoverEnd(rover, schedule, clock)
    try:
        clock.advance(50 * MS)
        end.send(frame(0x301))
        controllers.send(frame(0x901))
        assert controllers.recv(timeout=0) is not None
        assert received(end).arbitration_id == 0x901

        clock.advance(60 * MS)  # 110 ms: bus-off
        controllers.send(frame(0x902))
        with pytest.raises(can.CanOperationError, match="bus-off"):
            end.send(frame(0x301))
        assert controllers.recv(timeout=0) is None  # the refused frame never reached the wire
        error = received(end)
        assert error.is_error_frame and error.arbitration_id == CAN_ERR_BUSOFF
        assert end.recv(timeout=0) is None  # the controller's frame is lost to the rover
        assert (end.refused, end.unheard) == (1, 1)

        clock.advance(100 * MS)  # 210 ms: the controller restarted
        controllers.send(frame(0x903))
        restarted = received(end)
        assert restarted.is_error_frame and restarted.arbitration_id == CAN_ERR_RESTARTED
        assert received(end).arbitration_id == 0x903
        end.send(frame(0x302))
        assert received(controllers).arbitration_id == 0x302
    finally:
        end.shutdown()
        rover.shutdown()
        controllers.shutdown()


def test_the_rovers_link_goes_bus_off_and_recovers_with_the_fault() -> None:
    fault = '[[faults]]\ntarget = "can"\nkind = "off"\nstart_s = 1.0\nduration_s = 1.0\n'
    run = run_world(fault, seconds=3.0)
    bus_states = {"can_bus_off", "can_recovering", "can_recovered"}
    link_events = [
        (ns / 1e9, m["kind"])
        for t, ns, m in run.sink.records
        if t == "safety/events" and m["kind"] in bus_states
    ]
    assert [kind for _t, kind in link_events] == ["can_bus_off", "can_recovering", "can_recovered"]
    # On the first control tick (every 20 ms) at or after the fault's start and its end.
    assert 1.0 <= link_events[0][0] < 1.02 and 2.0 <= link_events[1][0] < 2.02
    tx = [f for f in run.on("can/frames", 1.0, 2.0) if f["direction"] == "tx"]
    assert tx == []  # nothing left the rover while its controller was off the bus
