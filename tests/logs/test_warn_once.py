"""``each_message_once``: a warning given again while the work runs is dropped; other texts, other loggers
and the time after it are untouched."""

from __future__ import annotations

import logging

import pytest

from logs.warn_once import each_message_once


def test_a_message_is_given_once_while_open_and_every_time_after(caplog: pytest.LogCaptureFixture) -> None:
    reader, other = logging.getLogger("logs.reader"), logging.getLogger("logs.other")
    caplog.set_level(logging.WARNING)
    with each_message_once("logs.reader"):
        for _ in range(3):
            reader.warning("f.mcap is cut short")
            other.warning("f.mcap is cut short")
        reader.warning("g.mcap is cut short")
    reader.warning("f.mcap is cut short")
    said = [(r.name, r.getMessage()) for r in caplog.records]
    assert said.count(("logs.reader", "f.mcap is cut short")) == 2  # once inside, once after
    assert said.count(("logs.other", "f.mcap is cut short")) == 3
    assert ("logs.reader", "g.mcap is cut short") in said
