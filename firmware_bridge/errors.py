"""The firmware_bridge error family: one base, then setup / operation / timeout, as python-can does."""

from __future__ import annotations


class BridgeError(Exception):
    """Anything that went wrong talking to the motor controllers or the autopilot."""


class BridgeSetupError(BridgeError):
    """A link could not be opened or configured (bad DBC, unknown interface, refused address...)."""


class DbcProfileError(BridgeSetupError):
    """A DBC file given in place of the shipped one (``[vesc] dbc``) is unreadable, not a DBC, or lacks a
    message, id format or signal the VESC codec needs; the message names the file and what is wrong."""


class BridgeOperationError(BridgeError):
    """A link was open but an operation on it failed."""


class FrameError(BridgeOperationError):
    """A frame we cannot decode: unknown id, wrong DLC, bad payload.

    ``reason`` is a short machine-readable cause (``unknown_id``, ``not_extended``, ``wrong_dlc``,
    ``decode``) so callers can count rejections without parsing the message text.
    """

    def __init__(self, message: str, *, reason: str = "decode", frame_id: int | None = None) -> None:
        super().__init__(message)
        self.reason = reason
        self.frame_id = frame_id


class BridgeTimeoutError(BridgeError, TimeoutError):
    """A peer did not answer in time."""
