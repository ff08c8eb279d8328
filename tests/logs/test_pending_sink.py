"""``PendingSink``: records made before the destination exists arrive there in order, bytes untouched."""

from __future__ import annotations

import io

import pytest

from logs.encoding import encode_message
from logs.errors import RecordingError
from logs.pending_sink import PendingSink
from logs.reader import read_messages
from logs.recorder import McapRecorder


def test_held_records_reach_the_recording_in_order_and_later_ones_go_straight_through() -> None:
    pending = PendingSink()
    first = {"timestamp": {"sec": 0, "nsec": 5}, "level": 2, "message": "one", "name": "t"}
    first.update(file="", line=0)
    second = dict(first, message="two")
    third = dict(first, message="three")
    pending.publish("log", 5, first)
    pending.publish_encoded("log", 6, second, encode_message(second))
    assert pending.held == 2
    stream = io.BytesIO()
    with McapRecorder(stream) as recorder:
        pending.connect(recorder)
        assert pending.held == 0
        pending.publish("log", 7, third)
        assert recorder.message_count == 3
    stream.seek(0)
    recorded = [(m.log_time_ns, m.message["message"]) for m in read_messages(stream)]
    assert recorded == [(5, "one"), (6, "two"), (7, "three")]


def test_a_second_connect_is_refused() -> None:
    pending = PendingSink()
    with McapRecorder(io.BytesIO()) as recorder:
        pending.connect(recorder)
        with pytest.raises(RecordingError, match="already connected"):
            pending.connect(recorder)
