"""Two Zenoh sessions on loopback for system tests: the rover listens, a ground station connects."""

from __future__ import annotations

import socket

import zenoh

from logs.settings import parse_toml
from logs.telemetry import ZenohSettings, open_session


def free_loopback_port() -> int:
    # Ask the OS for a free port; the tiny window before zenoh binds it is acceptable in a test.
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def settings(text: str) -> ZenohSettings:
    return ZenohSettings.from_table(parse_toml(text, "<test>").table("zenoh"))


def open_pair() -> tuple[zenoh.Session, zenoh.Session]:
    """(listening session, connecting session), both multicast scouting off, loopback only."""
    endpoint = f"tcp/127.0.0.1:{free_loopback_port()}"
    listener = open_session(settings(f'[zenoh]\nenabled = true\nlisten = ["{endpoint}"]\n'))
    connector = open_session(settings(f'[zenoh]\nenabled = true\nlisten = []\nconnect = ["{endpoint}"]\n'))
    return listener, connector
