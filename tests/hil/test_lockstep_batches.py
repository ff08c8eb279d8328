"""The lockstep bus's batches (``send_all``, ``recv_all``: ``firmware_bridge.can_bus.BatchBus``) and what the
CAN link and the simulated controllers do with them: the same as frame by frame, record for record."""

import dataclasses
import logging
from typing import Any

import can
import pytest

from firmware_bridge.can_bus import BatchBus
from firmware_bridge.can_link import CanLink
from hil.lockstep_bus import lockstep_bus_pair
from hil.vesc_sim import SimVescBank
from logs.clock import SimClock
from logs.sink import MemorySink
from tests.firmware_bridge.virtual_can import make_codec


def ext(can_id: int, data: bytes) -> can.Message:
    return can.Message(arbitration_id=can_id, is_extended_id=True, data=data, dlc=len(data))


class OneByOne(can.BusABC):
    """A lockstep end seen through python-can's plain API only (no ``send_all`` / ``recv_all``): the link
    and the controllers then send and receive frame by frame, as on any other bus."""

    def __init__(self, inner: can.BusABC) -> None:
        super().__init__(channel="one-by-one")
        self._inner = inner

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._inner.send(msg)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        return self._inner.recv(timeout=0), False


class LogLines(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.lines: list[tuple[str, int, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.lines.append((record.name, record.levelno, record.getMessage()))


class BytesRecorder(MemorySink):
    """Records everything, frames as the bytes a bytes-only sink (the recorder, Zenoh) gets."""

    records_bytes_only = True

    def __init__(self) -> None:
        super().__init__()
        self.frames: list[tuple[int, int, bytes]] = []  # (place among the records, log time, bytes)

    def publish_bytes(self, topic: str, log_time_ns: int, data: bytes) -> None:
        self.frames.append((len(self.records), log_time_ns, data))

    def publish_bytes_many(self, topic: str, log_time_ns: int, datas: Any) -> None:
        self.frames.extend((len(self.records), log_time_ns, data) for data in datas)


def test_send_all_and_recv_all_move_what_send_and_recv_move():
    clock = SimClock(2_500_000_000)
    rover, sim = lockstep_bus_pair("batches", clock)
    try:
        assert isinstance(rover, BatchBus) and not isinstance(OneByOne(rover), BatchBus)
        assert sim.recv_all() == ()  # nothing waiting
        frames = [ext(0x100 + i, bytes([i])) for i in range(3)]
        rover.send_all(frames)
        rover.send(ext(0x103, b"\x03"))
        received = sim.recv_all()
        assert [m.arbitration_id for m in received] == [0x100, 0x101, 0x102, 0x103]
        assert all(m.timestamp == 2.5 and m.channel == sim.channel_info for m in received)
        assert rover.frames_sent == 4 and not sim.recv_all()
        # With filters, python-can's semantics: recv(timeout=0) gives None at a frame they reject, and so
        # recv_all stops there; the next call goes on after it.
        sim.set_filters([{"can_id": 0x101, "can_mask": 0x7FF, "extended": True}])
        rover.send_all([ext(0x101, b""), ext(0x100, b""), ext(0x101, b"\x01")])
        assert [m.arbitration_id for m in sim.recv_all()] == [0x101]
        assert [m.data for m in sim.recv_all()] == [bytearray(b"\x01")]
    finally:
        rover.shutdown()
        sim.shutdown()
    with pytest.raises(can.CanOperationError):
        rover.send_all([ext(0x100, b"")])
    assert rover.frames_sent == 7  # a refused batch sends none


def _exchange(batched: bool) -> dict[str, Any]:
    """A scripted stretch of driving with bad traffic mixed in, then a bus that refuses every send."""
    clock, sink = SimClock(), BytesRecorder()
    rover_end, sim_end = lockstep_bus_pair("exchange", clock)
    rover_bus = rover_end if batched else OneByOne(rover_end)
    sim_bus = sim_end if batched else OneByOne(sim_end)
    codec = make_codec()
    link = CanLink(rover_bus, codec, clock, sink)
    sim = SimVescBank(sim_bus, make_codec(), clock)
    stranger = lockstep_bus_pair("stranger")[0]  # sends on the rover's bus as a third node would
    stranger._connect(rover_end)
    logs = LogLines()
    root = logging.getLogger()
    level = root.level
    root.addHandler(logs)
    root.setLevel(logging.DEBUG)
    try:
        for tick in range(1, 61):
            clock.advance(10_000_000)
            sim.poll()
            sim.set_electrical([1.0 * tick, 2.0, 3.0, -4.0, 5.0, 6.0], 24.0, [0.1, 0.2, 0.3, -0.4, 0.5, 1.5])
            sim.step(0.01)
            if tick == 20:  # garbage among the status frames: unknown, wrong length, standard id, error
                stranger.send(ext((9 << 8) | 42, bytes(8)))
                stranger.send(ext((9 << 8) | 1, bytes(6)))
                stranger.send(can.Message(arbitration_id=0x7, is_extended_id=False, data=b"\x00"))
                stranger.send(can.Message(arbitration_id=0x4, is_error_frame=True))
            if tick % 2 == 0:
                link.poll()
                link.send_wheel_speeds([0.5, 0.5, 0.5, -0.5, -0.5, 0.02 * tick])
        rover_end.shutdown()  # every send refused: six failures, then bus-off
        link.send_wheel_speeds([0.5] * 6)
        sim_end.shutdown()  # the controllers' eighteen status frames refused, each counted
        clock.advance(100_000_000)
        sim.step(0.01)
        return {
            "records": sink.records,
            "frames": sink.frames,
            "counters": link.counters.as_dict(),
            "state": link.state,
            "readings": [dataclasses.asdict(r) for r in link.readings()],
            "sim": (sim.commands_applied, sim.ignored_frames, sim.bad_frames, sim.send_errors, sim.erpm()),
            "logs": logs.lines,
        }
    finally:
        root.removeHandler(logs)
        root.setLevel(level)
        rover_end.shutdown()
        sim_end.shutdown()
        stranger.shutdown()


def test_batches_give_the_records_counters_and_readings_of_frame_by_frame():
    batched, one_by_one = _exchange(batched=True), _exchange(batched=False)
    assert batched == one_by_one
    counters = batched["counters"]
    assert counters["unknown_id"] == 2 and counters["wrong_dlc"] == 1 and counters["bus_errors"] == 7
    assert batched["state"].name == "BUS_OFF"
    assert any("cannot send VESC_STATUS_5_C6" in line for _, _, line in batched["logs"])
    assert batched["sim"][0] > 100 and batched["sim"][3] == 18 and batched["readings"][0]["erpm"] != 0.0
