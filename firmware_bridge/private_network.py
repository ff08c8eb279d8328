"""Where python-can's ``udp_multicast`` may run: only in a network namespace whose one interface is loopback.

``udp_multicast`` sends real IP multicast datagrams; on a host with a network card they would leave the
machine. ``scripts/in-private-netns`` runs a command in a namespace of its own with loopback alone (and
multicast routed to it); this checks the namespace the process is actually in, so a stray config, an
environment variable set by hand or a tool started outside the script cannot put CAN traffic on a network.
"""

from __future__ import annotations

import socket

from firmware_bridge.errors import BridgeSetupError

LOOPBACK = "lo"


def other_interfaces() -> list[str]:
    """This process's network interfaces other than loopback."""
    return [name for _, name in socket.if_nameindex() if name != LOOPBACK]


def require_loopback_only(what: str) -> None:
    """Raise ``BridgeSetupError`` naming the interfaces if ``what`` would run where more than loopback is."""
    others = other_interfaces()
    if others:
        raise BridgeSetupError(
            f"{what} runs only inside a private network namespace whose one interface is loopback "
            f"(scripts/in-private-netns); this one also has {', '.join(others)}: run it under "
            "scripts/in-private-netns, or use socketcan on vcan0 (python-can's virtual bus joins one process "
            "only, not a peer and a rover)"
        )
