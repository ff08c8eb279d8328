"""A CAN bus or MAVLink link that does not open says what the OS said and what to do about that."""

from __future__ import annotations

import errno
import os
from typing import Any

import can
import pytest

from firmware_bridge.can_bus import CanConfig, open_bus
from firmware_bridge.errors import BridgeSetupError


def _refusing(code: int) -> Any:
    def bus(**kwargs: Any) -> can.BusABC:
        raise OSError(code, os.strerror(code))

    return bus


@pytest.mark.parametrize(
    ("code", "said", "not_said"),
    [
        # A kernel without SocketCAN (this build machine): no interface could exist, so ip link is no help.
        (errno.EAFNOSUPPORT, ("this kernel has no SocketCAN", "modprobe can_raw"), "ip link show"),
        (
            errno.ENODEV,
            ("there is no interface can0", "ip link set can0 up type can bitrate 500000"),
            "modprobe",
        ),
    ],
)
def test_socketcan_failures_say_what_to_do(
    monkeypatch: pytest.MonkeyPatch, code: int, said: tuple[str, ...], not_said: str
) -> None:
    monkeypatch.setattr(can, "Bus", _refusing(code))
    with pytest.raises(BridgeSetupError) as caught:
        open_bus(CanConfig(interface="socketcan", channel="can0", bitrate=500_000))
    message = str(caught.value)
    assert message.startswith("cannot open CAN bus socketcan:can0: ")
    for words in said:
        assert words in message, message
    assert not_said not in message, message


def test_a_serial_autopilot_that_is_not_there_is_named_with_what_to_check() -> None:
    from firmware_bridge.mavlink_transport import open_transport

    with pytest.raises(BridgeSetupError) as caught:
        open_transport("serial:/dev/no-such-rover-autopilot:921600")
    message = str(caught.value)
    assert message.startswith("MAVLink serial device /dev/no-such-rover-autopilot (921600 baud): cannot open")
    # A missing device is not a permissions problem: the hint names the device list, not dialout.
    assert "is the autopilot plugged in" in message and "dialout" not in message, message


def test_a_mavlink_port_already_taken_names_the_likely_holder_and_the_fix() -> None:
    import socket

    from firmware_bridge.mavlink_transport import open_transport

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind(("127.0.0.1", 0))
        port = holder.getsockname()[1]
        with pytest.raises(BridgeSetupError) as caught:
            open_transport(f"udpin:127.0.0.1:{port}")
    message = str(caught.value)
    assert message.startswith(f"MAVLink udpin:127.0.0.1:{port}: cannot bind: "), message
    assert "another program holds that port" in message and "[mavlink] connection" in message, message
