"""One JSON reader for recordings, telemetry and commands: what it cannot read is a ValueError."""

from __future__ import annotations

import math
from io import BytesIO

import pytest

from logs.json_text import loads_json
from logs.reader import ReadStats, read_messages
from logs.recorder import McapRecorder

DEEP = b"[" * 100_000 + b"]" * 100_000  # past orjson's 1024 levels and Python's recursion limit


def test_deep_nesting_bad_text_and_other_writers_literals() -> None:
    with pytest.raises(ValueError, match="nested too deep"):
        loads_json(DEEP)
    with pytest.raises(ValueError):
        loads_json(b"\xff\xfe not text")
    assert math.isnan(loads_json(b'{"x": NaN}')["x"])  # the standard library's literal, from another writer


def test_a_recorded_message_nested_too_deep_is_counted_not_raised() -> None:
    stream = BytesIO()
    with McapRecorder(stream) as recorder:
        recorder.publish("log", 1, {"message": "before"})
        recorder.publish_bytes("log", 2, DEEP)
        recorder.publish("log", 3, {"message": "after"})
    stats = ReadStats()
    read = [m.message["message"] for m in read_messages(BytesIO(stream.getvalue()), ["log"], stats=stats)]
    assert read == ["before", "after"] and stats.malformed == 1
