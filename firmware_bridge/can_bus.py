"""CAN bus configuration and opening: python-can's ``Bus`` with everything passed explicitly."""

from __future__ import annotations

import errno
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import can

from firmware_bridge.errors import BridgeSetupError
from firmware_bridge.private_network import require_loopback_only
from logs.settings import Table

logger = logging.getLogger(__name__)

# socketcan: the rover (can0) and HIL on hosts with vcan; virtual: lockstep in one process;
# udp_multicast: HIL across processes where vcan is missing (only inside a loopback-only namespace).
CAN_INTERFACES: tuple[str, ...] = ("socketcan", "virtual", "udp_multicast")
_CHANNEL_EXAMPLES = "e.g. 'can0', 'vcan0', 'rover0'"


@dataclass(frozen=True)
class CanConfig:
    interface: str = "virtual"
    channel: str = "rover0"
    bitrate: int = 1_000_000
    command_rate_hz: float = 50.0
    # A command older than this is not resent: a stalled control loop must not keep the motors running.
    command_max_age_s: float = 0.2
    # The rate the controllers send STATUS at; silent for ``liveness_periods`` of it means a fault.
    status_rate_hz: float = 50.0
    liveness_periods: int = 3

    def __post_init__(self) -> None:
        if self.interface not in CAN_INTERFACES:
            raise BridgeSetupError(
                f"CAN interface must be one of {', '.join(CAN_INTERFACES)}, got {self.interface!r}"
            )
        if not self.channel:
            raise BridgeSetupError(f"CAN channel must not be empty ({_CHANNEL_EXAMPLES})")
        if self.bitrate <= 0:
            raise BridgeSetupError(f"CAN bitrate must be positive, got {self.bitrate}")
        if not self.command_rate_hz > 0:
            raise BridgeSetupError(f"CAN command_rate_hz must be positive, got {self.command_rate_hz}")
        if not self.command_max_age_s > 0:
            raise BridgeSetupError(f"CAN command_max_age_s must be positive, got {self.command_max_age_s}")
        if not self.status_rate_hz > 0:
            raise BridgeSetupError(f"CAN status_rate_hz must be positive, got {self.status_rate_hz}")
        if self.liveness_periods < 1:
            raise BridgeSetupError(f"CAN liveness_periods must be >= 1, got {self.liveness_periods}")

    @classmethod
    def from_table(cls, table: Table) -> CanConfig:
        """Keys: interface, channel, bitrate, command_rate_hz, command_max_age_s, status_rate_hz,
        liveness_periods (all optional); unknown keys are errors."""
        defaults = cls()
        interface = table.text("interface", defaults.interface, choices=CAN_INTERFACES)
        channel = table.text("channel", defaults.channel)
        if not channel:  # checked before the dataclass's own check, which knows neither file nor key
            raise table.error("channel", f"must not be empty ({_CHANNEL_EXAMPLES})")
        config = cls(
            interface=interface,
            channel=channel,
            bitrate=table.integer("bitrate", defaults.bitrate, lo=10_000, hi=8_000_000),
            command_rate_hz=table.number("command_rate_hz", defaults.command_rate_hz, lo=1.0, hi=1000.0),
            command_max_age_s=table.number("command_max_age_s", defaults.command_max_age_s, lo=0.001, hi=5.0),
            status_rate_hz=table.number("status_rate_hz", defaults.status_rate_hz, lo=0.1, hi=1000.0),
            liveness_periods=table.integer("liveness_periods", defaults.liveness_periods, lo=1, hi=1000),
        )
        table.finish()
        return config


@runtime_checkable
class BatchBus(Protocol):
    """A bus that also moves frames a batch at a time (``hil.lockstep_bus.LockstepBus``): the CAN link and
    the simulated controllers use these where the bus has them, ``send`` and ``recv`` elsewhere.

    ``send_all(msgs)``: the same as ``send`` of each in turn when all go; when the bus refuses (raises
    ``can.CanError``), it has sent none of them, so the caller can send them one by one to learn which
    fail. ``recv_all()``: what calling ``recv(timeout=0)`` until it gives None would give, in order.
    A wrapper that changes frames (faults) is not one unless it implements both itself."""

    def send_all(self, msgs: Sequence[can.Message]) -> None: ...

    def recv_all(self) -> Sequence[can.Message]: ...


def open_bus(config: CanConfig, receive_own_messages: bool = False) -> can.BusABC:
    """Open the configured bus. Never reads python-can config files or environment variables.

    None of our three backends takes a bitrate: socketcan's is set with ``ip link`` outside the process,
    and virtual / udp_multicast have none. ``config.bitrate`` is still what bus-load figures use.
    """
    if config.interface == "udp_multicast":
        require_loopback_only(f"CAN over udp_multicast ({config.channel})")
    kwargs: dict[str, Any] = {"receive_own_messages": receive_own_messages}
    try:
        bus = can.Bus(
            channel=config.channel,
            interface=config.interface,
            ignore_config=True,
            **kwargs,
        )
    except (can.CanError, ImportError, OSError, ValueError) as err:
        raise BridgeSetupError(
            f"cannot open CAN bus {config.interface}:{config.channel}: {err}; {_open_hint(config, err)}"
        ) from err
    logger.info("opened CAN bus %s:%s", config.interface, config.channel)
    return bus


def _open_hint(config: CanConfig, err: BaseException) -> str:
    """What to do about a bus that did not open, from what the OS said (a first day on a new computer
    meets the first two: a kernel without SocketCAN, an adapter not plugged in or not named so)."""
    code = getattr(err, "errno", None)
    if config.interface == "socketcan" and code == errno.EAFNOSUPPORT:
        # No such interface could exist: "check the interface exists" would send a person to ip link.
        return (
            "this kernel has no SocketCAN (load it: modprobe can_raw; a kernel built without CAN cannot "
            "reach the motor controllers)"
        )
    if config.interface == "socketcan" and code == errno.ENODEV:
        return (
            f"there is no interface {config.channel} (ip link show: is the CAN adapter plugged in and its "
            f"driver loaded, and is it named {config.channel}?), then: ip link set {config.channel} up type "
            f"can bitrate {config.bitrate}"
        )
    return "check the interface exists (ip link show) and the [can] settings"
