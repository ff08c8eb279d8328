"""Idling between ticks until input may have arrived: ``select`` on the links' descriptors, else sleep.

The sensor-synchronous loop measures latency from a sample's receive time, and its jitter from the ticks
the samples start: a loop that only looked every millisecond would add up to a millisecond of random
delay to every tick. Sleeping in ``select`` on the pacing link's socket wakes the loop the moment a
datagram lands. Links without a descriptor (the in-memory pipe, python-can's ``virtual`` bus) fall back to
plain sleeping; the caller's timeout (at most one wait slice) bounds the wait either way.
"""

from __future__ import annotations

import logging
import select
import time
from collections.abc import Callable, Iterable

_log = logging.getLogger(__name__)


def descriptor_of(source: object) -> int | None:
    """``source.fileno()`` if it has a usable one, else None."""
    fileno = getattr(source, "fileno", None)
    if fileno is None:
        return None
    try:
        fd = int(fileno())
    except (NotImplementedError, OSError, ValueError):
        return None
    return fd if fd >= 0 else None


def input_waiter(sources: Iterable[object]) -> Callable[[float], None]:
    """A ``wait(seconds)`` that returns early when any of ``sources`` becomes readable."""
    descriptors = [fd for fd in (descriptor_of(s) for s in sources) if fd is not None]
    if not descriptors:
        return time.sleep

    def wait(timeout_s: float) -> None:
        try:
            select.select(descriptors, [], [], max(timeout_s, 0.0))
        except (OSError, ValueError) as err:
            # A descriptor closed under us (shutdown): sleep instead, the stop flag ends the loop.
            _log.debug("select failed (%s); sleeping instead", err)
            time.sleep(timeout_s)

    return wait


def input_poller(sources: Iterable[object]) -> Callable[[], bool] | None:
    """A ``poll()`` that says, without blocking, whether any of ``sources`` has input waiting; None when
    none of them has a descriptor (nothing to poll: the loop then only waits).

    The sensor-paced loop calls it in a tight loop just before the next sample is due (busy-polling, as
    the kernel's SO_BUSY_POLL does): the sample is read the moment it lands instead of after the OS has
    woken the loop from ``select``, which on a VM takes 0.1-1 ms.
    """
    descriptors = [fd for fd in (descriptor_of(s) for s in sources) if fd is not None]
    if not descriptors:
        return None

    def poll() -> bool:
        try:
            readable, _, _ = select.select(descriptors, [], [], 0.0)
        except (OSError, ValueError) as err:
            # A descriptor closed under us (shutdown): report input so the loop reads and sees the stop.
            _log.debug("poll failed (%s)", err)
            return True
        return bool(readable)

    return poll
