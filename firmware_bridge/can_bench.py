"""CAN throughput, latency and bus-load figures for ``rover bench can``.

A round is one SET_RPM frame: encode -> send on python-can's virtual bus -> receive on the other end ->
decode. Peers measured in the same run: plain ``struct`` packing (python-can alone, no DBC), cantools
with strict encoding, and our link's six-wheel command round. Timing uses ``time.perf_counter_ns``.

The controllers' protocol is the profile's (``[vesc]``: the shipped DBC or a team's own ``dbc``), so a
swapped-in profile is measured as the rover would run it; the bus load uses the config's ``[can]`` rates.
"""

from __future__ import annotations

import itertools
import statistics
import struct
import time
from dataclasses import asdict, dataclass

import can

from firmware_bridge.can_bus import CanConfig
from firmware_bridge.can_link import CanLink
from firmware_bridge.vesc import VescCodec, VescProfile
from firmware_bridge.vesc_dbc import DEFAULT_CONTROLLER_IDS, MESSAGES_BY_KIND, frame_id
from logs.clock import SimClock
from logs.sink import NullSink

_channels = itertools.count()
_INT32 = struct.Struct(">i")


def frame_bits(data_bytes: int, *, worst_case: bool) -> int:
    """Bits one classic CAN frame with a 29-bit id occupies, interframe space included.

    67 + 8n bits unstuffed; the 54 + 8n bits from SOF to the CRC may carry a stuff bit every 4 bits.
    """
    bits = 67 + 8 * data_bytes
    if worst_case:
        bits += (54 + 8 * data_bytes - 1) // 4
    return bits


@dataclass(frozen=True)
class BusLoad:
    frames_per_s: float
    load_pct_nominal: float
    load_pct_worst: float


def bus_load(config: CanConfig, slow_status_rate_hz: float = 10.0, wheels: int = 6) -> BusLoad:
    """Load the default traffic puts on the bus: SET_RPM at the command rate, STATUS at the status rate,
    STATUS_4 and STATUS_5 at the slow rate, for every wheel."""
    traffic = [
        (MESSAGES_BY_KIND["SET_RPM"].length, config.command_rate_hz),
        (MESSAGES_BY_KIND["STATUS"].length, config.status_rate_hz),
        (MESSAGES_BY_KIND["STATUS_4"].length, slow_status_rate_hz),
        (MESSAGES_BY_KIND["STATUS_5"].length, slow_status_rate_hz),
    ]
    frames = sum(rate for _, rate in traffic) * wheels
    nominal = sum(frame_bits(n, worst_case=False) * rate for n, rate in traffic) * wheels
    worst = sum(frame_bits(n, worst_case=True) * rate for n, rate in traffic) * wheels
    return BusLoad(frames, 100.0 * nominal / config.bitrate, 100.0 * worst / config.bitrate)


@dataclass(frozen=True)
class RoundFigures:
    name: str
    rounds_per_s: float
    us_per_round: float


@dataclass(frozen=True)
class CanBenchResult:
    rounds: int
    ours: RoundFigures
    peers: list[RoundFigures]
    link_six_wheel_rounds_per_s: float
    latency_p50_us: float
    latency_p99_us: float
    bus_load: BusLoad
    dbc: str  # the DBC file measured, or "shipped"

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def _bus_pair() -> tuple[can.BusABC, can.BusABC]:
    channel = f"bench-can-{next(_channels)}"
    return (
        can.Bus(interface="virtual", channel=channel, ignore_config=True),
        can.Bus(interface="virtual", channel=channel, ignore_config=True),
    )


def _time_rounds(name: str, rounds: int, one_round: object) -> RoundFigures:
    assert callable(one_round)
    start = time.perf_counter_ns()
    for i in range(rounds):
        one_round(i)
    elapsed = time.perf_counter_ns() - start
    return RoundFigures(name, rounds / (elapsed / 1e9), elapsed / rounds / 1e3)


DEFAULT_PROFILE = VescProfile(DEFAULT_CONTROLLER_IDS, 7, 20.0, 0.11)


def run_can_bench(
    rounds: int = 20_000, profile: VescProfile = DEFAULT_PROFILE, can_config: CanConfig | None = None
) -> CanBenchResult:
    codec = VescCodec.for_profile(profile)
    controller = profile.controller_ids[0]
    tx, rx = _bus_pair()
    try:
        set_rpm_id = frame_id(MESSAGES_BY_KIND["SET_RPM"].command_id, controller)
        # By id, not by name: a team's DBC may name its messages otherwise (its signals are checked).
        strict_message = codec.database.get_message_by_frame_id(set_rpm_id, force_extended_id=True)

        def ours(i: int) -> None:
            tx.send(codec.encode_set_rpm(controller, i))
            msg = rx.recv(timeout=1.0)
            assert msg is not None
            codec.decode(msg)

        def raw_struct(i: int) -> None:
            tx.send(can.Message(arbitration_id=set_rpm_id, is_extended_id=True, data=_INT32.pack(i)))
            msg = rx.recv(timeout=1.0)
            assert msg is not None
            _INT32.unpack(msg.data)

        def cantools_strict(i: int) -> None:
            data = strict_message.encode({"erpm": i})
            tx.send(can.Message(arbitration_id=set_rpm_id, is_extended_id=True, data=data))
            msg = rx.recv(timeout=1.0)
            assert msg is not None
            strict_message.decode(bytes(msg.data))

        _time_rounds("warm-up", 500, ours)
        ours_figures = _time_rounds("ours (DBC packer, strict checks)", rounds, ours)
        peers = [
            _time_rounds("python-can + struct (no DBC)", rounds, raw_struct),
            _time_rounds("cantools strict encode + decode", rounds, cantools_strict),
        ]
        latencies: list[int] = []
        for i in range(rounds):
            msg_out = codec.encode_set_rpm(controller, i)
            t0 = time.perf_counter_ns()
            tx.send(msg_out)
            msg_in = rx.recv(timeout=1.0)
            latencies.append(time.perf_counter_ns() - t0)
            assert msg_in is not None
            codec.decode(msg_in)
        quantiles = statistics.quantiles(latencies, n=100)
    finally:
        tx.shutdown()
        rx.shutdown()

    six_wheel = _link_rounds(codec, max(rounds // 6, 100))
    return CanBenchResult(
        rounds=rounds,
        ours=ours_figures,
        peers=peers,
        link_six_wheel_rounds_per_s=six_wheel,
        latency_p50_us=quantiles[49] / 1e3,
        latency_p99_us=quantiles[98] / 1e3,
        bus_load=bus_load(can_config or CanConfig()),
        dbc=str(profile.dbc_path) if profile.dbc_path is not None else "shipped",
    )


def _link_rounds(codec: VescCodec, rounds: int) -> float:
    """CanLink.send_wheel_speeds (six frames, recorded to a null sink) and the peer reading them."""
    tx, rx = _bus_pair()
    link = CanLink(tx, codec, SimClock(), NullSink())
    speeds = [0.5] * 6
    start = time.perf_counter_ns()
    for _ in range(rounds):
        link.send_wheel_speeds(speeds)
        for _ in range(6):
            rx.recv(timeout=1.0)
    elapsed = time.perf_counter_ns() - start
    link.close()
    rx.shutdown()
    return rounds / (elapsed / 1e9)
