"""Our own frames coming back on buses that echo them, told apart from frames other nodes sent.

python-can's ``udp_multicast`` bus sends and receives on one socket with the kernel's default
``IP_MULTICAST_LOOP`` on, so every frame we send is also received by us (checked: a second bus on the same
group and the sender itself both receive it). Turning the loop off would also cut off the peers in other
processes on this host, which is the whole point of that bus here; so the link forgets its own echoes
instead. socketcan and virtual buses do not echo (``receive_own_messages=False``).
"""

from __future__ import annotations

from collections import Counter, deque

import can

# Frames sent whose echo has not come back yet; older ones are forgotten (an echo lost on the way must
# not leave a stale entry forever). Several seconds of the link's command traffic (300 frames/s).
_CAPACITY = 2048

_FrameKey = tuple[int, bool, bytes]


def echoes_own_sends(bus: can.BusABC) -> bool:
    """Whether ``bus`` delivers our own sends back to us."""
    from can.interfaces.udp_multicast import UdpMulticastBus  # only the check needs it

    return isinstance(bus, UdpMulticastBus)


def _key(msg: can.Message) -> _FrameKey:
    return (msg.arbitration_id, msg.is_extended_id, bytes(msg.data))


class OwnEchoFilter:
    """Remembers frames sent; a received frame equal to one still pending is its echo (and uses it up).

    A frame from another node that is byte-identical to one we just sent would be taken for our echo;
    on our buses only the companion sends command frames, so that does not happen.
    """

    def __init__(self, capacity: int = _CAPACITY) -> None:
        self._pending: Counter[_FrameKey] = Counter()
        self._order: deque[_FrameKey] = deque()
        self._capacity = capacity
        self.forgotten = 0  # sent frames whose echo never came within the capacity

    def sent(self, msg: can.Message) -> None:
        if len(self._order) >= self._capacity:
            self._use(self._order.popleft())
            self.forgotten += 1
        key = _key(msg)
        self._order.append(key)
        self._pending[key] += 1

    def is_echo(self, msg: can.Message) -> bool:
        key = _key(msg)
        if not self._pending.get(key):
            return False
        self._use(key)
        # Echoes come back in send order, so the match is almost always the oldest pending frame.
        if self._order[0] == key:
            self._order.popleft()
        else:
            self._order.remove(key)
        return True

    def _use(self, key: _FrameKey) -> None:
        left = self._pending[key] - 1
        if left:
            self._pending[key] = left
        else:
            del self._pending[key]
