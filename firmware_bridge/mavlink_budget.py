"""How many received MAVLink bytes the link parses, so a flood is bounded work for the loop that polls it.

pymavlink parses in Python, about 0.2 us per byte of garbage on the build VM (``docs/firmware_bridge.md``,
"Garbage and floods"): a 5 MB/s flood costs a whole core, and the sensor-paced loop, which reads the link
before every tick, then spends its period parsing instead of ticking. So the link parses at most
``rate_bytes_per_s`` of its clock's time (a token bucket holding at most ``burst_s`` of it) and drops the
rest unread, counted. Dropping is cheap: the bytes were already read off the socket.

What is kept when there is too much:

* Datagrams (UDP): each MAVLink datagram carries whole frames and starts with one, so datagrams that start
  like a frame (a start marker and a length that fits) go first, in arrival order; the others (noise)
  fill what is left. A random-byte flood starts like a frame once in ~30 000 datagrams, so the autopilot's
  IMU datagram is parsed whatever the flood around it.
* A byte stream (serial, TCP, the in-memory pipe): the newest bytes, for the loop acts on the newest
  measurement; the older ones are dropped.
"""

from __future__ import annotations

from collections.abc import Sequence

from logs.clock import NS_PER_S

DEFAULT_RATE_BYTES_PER_S = 256 * 1024
# A burst of this much of the rate is parsed at once (after a stall of the loop, or at start-up).
BURST_S = 0.1

_MARKER_V2 = 0xFD
_MARKER_V1 = 0xFE
_V2_OVERHEAD = 12  # 10 header + 2 CRC
_V1_OVERHEAD = 8  # 6 header + 2 CRC
_SIGNATURE_LEN = 13
_SIGNED_FLAG = 0x01


def starts_like_a_frame(datagram: bytes) -> bool:
    """A start marker, then a declared frame length that fits in the datagram."""
    if len(datagram) < 3:
        return False
    marker, payload_len = datagram[0], datagram[1]
    if marker == _MARKER_V2:
        signed = _SIGNATURE_LEN if datagram[2] & _SIGNED_FLAG else 0
        return payload_len + _V2_OVERHEAD + signed <= len(datagram)
    return marker == _MARKER_V1 and payload_len + _V1_OVERHEAD <= len(datagram)


class ReceiveBudget:
    """Bytes the link may parse now: ``rate_bytes_per_s`` accrue on the link's clock, up to a burst."""

    def __init__(self, rate_bytes_per_s: int, start_ns: int, burst_s: float = BURST_S) -> None:
        if rate_bytes_per_s <= 0:
            raise ValueError(f"rate_bytes_per_s must be > 0, got {rate_bytes_per_s}")
        self._rate = rate_bytes_per_s
        self._burst = max(1, round(rate_bytes_per_s * burst_s))
        self._available = float(self._burst)
        self._last_ns = start_ns

    def allowance(self, now_ns: int) -> int:
        if now_ns > self._last_ns:
            accrued = self._rate * (now_ns - self._last_ns) / NS_PER_S
            self._available = min(self._burst, self._available + accrued)
            self._last_ns = now_ns
        return int(self._available)

    def spend(self, n_bytes: int) -> None:
        self._available -= n_bytes


def admit_datagrams(datagrams: Sequence[bytes], allowance: int) -> tuple[list[bytes], int]:
    """The datagrams to parse (arrival order) within ``allowance`` bytes, frame-like ones first, and the
    number of bytes dropped."""
    kept = [False] * len(datagrams)
    left = allowance
    for frame_like in (True, False):
        for index, datagram in enumerate(datagrams):
            if starts_like_a_frame(datagram) is frame_like and len(datagram) <= left:
                kept[index] = True
                left -= len(datagram)
    admitted = [d for d, keep in zip(datagrams, kept, strict=True) if keep]
    dropped = sum(len(d) for d, keep in zip(datagrams, kept, strict=True) if not keep)
    return admitted, dropped


def admit_stream(data: bytes, allowance: int) -> tuple[bytes, int]:
    """The newest ``allowance`` bytes of ``data`` and the number of older bytes dropped."""
    if len(data) <= allowance:
        return data, 0
    keep = max(allowance, 0)
    return data[len(data) - keep :], len(data) - keep
