"""CAN bus load, defined once for the link that measures it, the report and the live view.

A classic CAN frame occupies ``47 + 8 * dlc`` bits with an 11-bit id and ``67 + 8 * dlc`` with a 29-bit id
(SOF, id, control, CRC, ACK, EOF and interframe space; before bit stuffing, so the real load is up to
~20 % higher). Load is bits per second as a share of the bitrate, in windows of ``WINDOW_NS`` of log time.

Both ways of getting the figures below define the mean as a duration-weighted mean of the windows' loads
and the peak as the busiest window, so the peak is never below the mean. Definitions: docs/metrics.md.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

WINDOW_NS = 1_000_000_000
_OVERHEAD_BITS = (47, 67)  # indexed by "extended id"
_MAX_DLC = 8  # classic CAN: a dlc above 8 still carries 8 bytes


def frame_bits(extended: bool, dlc: int) -> int:
    """Bits one classic CAN frame occupies on the wire, before bit stuffing, interframe space included."""
    return _OVERHEAD_BITS[extended] + 8 * min(dlc, _MAX_DLC)


@dataclass(frozen=True)
class BusLoad:
    """Mean and peak load (% of the bitrate) over ``windows`` windows; ``None`` without a whole window."""

    mean_pct: float | None
    peak_pct: float | None
    windows: int


_NO_LOAD = BusLoad(None, None, 0)


def load_from_frame_windows(
    bits_by_window: Mapping[int, int], first_ns: int, last_ns: int, bitrate: int, window_ns: int = WINDOW_NS
) -> BusLoad:
    """Load from every frame on the bus, binned by ``(t - first_ns) // window_ns``.

    Only whole windows count: window ``k`` covers ``[first + k w, first + (k + 1) w)`` and is whole when the
    frames go on to at least its end (``last_ns >= first + (k + 1) w``). The frames after the last whole
    window are left out, so a frame at either end of the span is never counted without its share of time.
    Windows without frames count as zero load.
    """
    whole = (last_ns - first_ns) // window_ns
    if whole <= 0 or bitrate <= 0:
        return _NO_LOAD
    bits = [bits_by_window.get(k, 0) for k in range(whole)]
    per_window_pct = 100.0 * 1e9 / window_ns / bitrate
    return BusLoad(per_window_pct * sum(bits) / whole, per_window_pct * max(bits), whole)


def load_from_stats(windows: Iterable[tuple[float, int, int]]) -> BusLoad:
    """Load from the link's own counts: ``(window_s, bits, bitrate)`` per ``can/stats`` message.

    Mean = duration-weighted mean of the windows' loads (total bits over total time when the bitrate is
    the same throughout); peak = the busiest window. Windows of no duration or bitrate are skipped.
    """
    weighted = 0.0
    duration = 0.0
    peak = 0.0
    count = 0
    for window_s, bits, bitrate in windows:
        if window_s <= 0.0 or bitrate <= 0:
            continue
        load = 100.0 * bits / window_s / bitrate
        weighted += load * window_s
        duration += window_s
        peak = max(peak, load)
        count += 1
    if count == 0:
        return _NO_LOAD
    # A weighted mean of values can round a hair above their maximum; it never is above it in exact terms.
    return BusLoad(min(weighted / duration, peak), peak, count)
