"""udp_multicast CAN opens only where loopback is the process's one network interface."""

import socket

import pytest

from firmware_bridge.can_bus import CanConfig, open_bus
from firmware_bridge.errors import BridgeSetupError
from firmware_bridge.private_network import require_loopback_only


def _interfaces(monkeypatch: pytest.MonkeyPatch, names: list[str]) -> None:
    monkeypatch.setattr(socket, "if_nameindex", lambda: list(enumerate(names, start=1)))


def test_udp_multicast_is_refused_where_the_namespace_has_a_network_card(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    _interfaces(monkeypatch, ["lo", "eth0", "wlan0"])
    with pytest.raises(BridgeSetupError, match="eth0, wlan0") as caught:
        open_bus(CanConfig(interface="udp_multicast", channel="239.74.163.2"))
    # What to do instead: not python-can's virtual bus, which two processes (peer, rover) cannot share.
    assert "run it under scripts/in-private-netns, or use socketcan on vcan0" in str(caught.value)


def test_loopback_alone_is_allowed_and_other_interfaces_are_not_checked(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    _interfaces(monkeypatch, ["lo"])
    require_loopback_only("udp_multicast")  # no error
    _interfaces(monkeypatch, ["lo", "eth0"])
    with open_bus(CanConfig(interface="virtual", channel="private-network-test")) as bus:
        assert bus.channel_info  # the virtual bus never leaves the process: no check
