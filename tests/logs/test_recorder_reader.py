"""MCAP recording and reading: round trips, metadata, attachments, cut files, damaged and foreign files."""

from __future__ import annotations

import dataclasses
import errno
import io
import json
import math
import os
import zlib
from pathlib import Path

import numpy as np
import pytest
from fastcrc import crc32
from mcap.reader import make_reader
from mcap.writer import Writer

from logs.errors import LogReadError, RecordingError
from logs.reader import (
    ReadStats,
    RecordedMessage,
    RecordedRaw,
    read_attachments,
    read_entries,
    read_messages,
    read_metadata,
    topic_counts,
)
from logs.recorder import McapRecorder, encode_message
from logs.topics import LOG, NAVIGATOR_STATE, SAFETY_EVENTS, TRUTH_POSE, planar_pose, stamp


def _log(i: int) -> dict:
    return {"timestamp": stamp(i), "level": 2, "message": f"line {i}", "name": "t", "file": "f.py", "line": i}


def _pose(i: int) -> dict:
    return {"timestamp": stamp(i), "frame_id": "enu", "pose": planar_pose(0.1 * i, -0.2 * i, 0.01 * i)}


def _expected(n: int = 400) -> list[tuple[str, int, dict]]:
    """Interleaved topics, log times strictly increasing."""
    out: list[tuple[str, int, dict]] = []
    for i in range(n):
        t = 1_000_000 * i + 7
        out.append((TRUTH_POSE, t, _pose(t)))
        if i % 3 == 0:
            out.append((LOG, t, _log(t)))
        if i % 50 == 0:
            out.append(
                (SAFETY_EVENTS, t, {"timestamp": stamp(t), "kind": "k", "severity": "info", "detail": "é"})
            )
    return out


def _record(output: object, expected: list[tuple[str, int, dict]], chunk_size: int = 4096) -> None:
    with McapRecorder(output, chunk_size=chunk_size) as recorder:  # type: ignore[arg-type]
        for topic, t, message in expected:
            recorder.publish(topic, t, message)
        recorder.add_metadata("scenario", {"name": "flat", "path_tolerance_m": "0.5"})
        recorder.add_metadata("seed", {"seed": "42"})
        recorder.add_attachment("scenario.toml", "application/toml", b"[world]\nsize = 10\n", 5)
        assert recorder.message_count == len(expected)


def _as_tuples(messages: list[RecordedMessage]) -> list[tuple[str, int, dict]]:
    return [(m.topic, m.log_time_ns, m.message) for m in messages]


@pytest.fixture(scope="module")
def recording() -> tuple[bytes, list[tuple[str, int, dict]]]:
    expected = _expected()
    buffer = io.BytesIO()
    _record(buffer, expected)
    return buffer.getvalue(), expected


def test_round_trip_through_bytesio(recording: tuple[bytes, list]) -> None:
    data, expected = recording
    stats = ReadStats()
    assert _as_tuples(list(read_messages(io.BytesIO(data), stats=stats))) == expected
    assert stats.complete and not stats.truncated and stats.skipped == 0
    assert stats.messages == len(expected)


def test_round_trip_through_file_with_new_parent_folders(tmp_path: Path) -> None:
    expected = _expected(120)
    path = tmp_path / "trials" / "deep" / "run.mcap"
    _record(path, expected, chunk_size=256 * 1024)
    assert _as_tuples(list(read_messages(path))) == expected
    assert _as_tuples(list(read_messages(str(path)))) == expected
    assert read_metadata(path)["seed"] == {"seed": "42"}


def test_entries_are_the_frozen_classes_own_objects(recording: tuple[bytes, list]) -> None:
    # The reader sets the slots of each entry directly (a frozen dataclass's __init__ is ~3x slower):
    # what it hands over equals, hashes and refuses changes like an object the class itself built.
    data, expected = recording
    entries = [e for e in read_entries(io.BytesIO(data), raw_topics=[LOG]) if hasattr(e, "topic")]
    kinds = [RecordedRaw if topic == LOG else RecordedMessage for topic, _, _ in expected]
    assert [type(e) for e in entries] == kinds
    for entry, (topic, t, message) in zip(entries, expected, strict=True):
        if isinstance(entry, RecordedRaw):
            assert entry == RecordedRaw(topic, t, encode_message(message))
            assert hash(entry) == hash(RecordedRaw(topic, t, encode_message(message)))
            assert repr(entry) == repr(RecordedRaw(topic, t, encode_message(message)))
        else:
            assert entry == RecordedMessage(topic, t, message)
            assert repr(entry) == repr(RecordedMessage(topic, t, message))
    with pytest.raises(dataclasses.FrozenInstanceError):
        entries[0].topic = "other"  # type: ignore[misc]


def test_topic_filter_and_counts(recording: tuple[bytes, list]) -> None:
    data, expected = recording
    only_logs = list(read_messages(io.BytesIO(data), topics=[LOG]))
    assert _as_tuples(only_logs) == [e for e in expected if e[0] == LOG]
    counts = topic_counts(io.BytesIO(data))
    assert counts == {LOG: 134, SAFETY_EVENTS: 8, TRUTH_POSE: 400}


def test_metadata_and_attachments_round_trip(recording: tuple[bytes, list]) -> None:
    data, _ = recording
    assert read_metadata(io.BytesIO(data)) == {
        "scenario": {"name": "flat", "path_tolerance_m": "0.5"},
        "seed": {"seed": "42"},
    }
    assert read_attachments(io.BytesIO(data)) == {"scenario.toml": b"[world]\nsize = 10\n"}


def test_file_is_standard_mcap_with_schemas_and_per_channel_sequences(recording: tuple[bytes, list]) -> None:
    data, _ = recording
    reader = make_reader(io.BytesIO(data))
    summary = reader.get_summary()
    assert summary is not None
    topics = {channel.topic: channel for channel in summary.channels.values()}
    assert topics[TRUTH_POSE].message_encoding == "json"
    schema = summary.schemas[topics[TRUTH_POSE].schema_id]
    assert schema.encoding == "jsonschema" and schema.name == "foxglove.PoseInFrame"
    assert json.loads(schema.data)["properties"]["pose"]["type"] == "object"
    sequences: dict[str, list[int]] = {}
    for _, channel, message in reader.iter_messages():
        sequences.setdefault(channel.topic, []).append(message.sequence)
        assert message.publish_time == message.log_time
    # Per channel, from 1 (the Foxglove SDK's writer counts them).
    assert sequences[SAFETY_EVENTS] == list(range(1, 9))
    assert sequences[LOG] == list(range(1, 135))


@pytest.mark.parametrize("fraction", [0.0, 0.001, 0.004, 0.1, 0.37, 0.5, 0.81, 0.99])
def test_cut_file_reads_the_complete_prefix_without_raising(
    recording: tuple[bytes, list], fraction: float
) -> None:
    data, expected = recording
    cut = int(len(data) * fraction)
    stats = ReadStats()
    got = _as_tuples(list(read_messages(io.BytesIO(data[:cut]), stats=stats)))
    assert got == expected[: len(got)]  # a prefix, in order, payloads intact
    # A cut inside the summary section (after DataEnd) loses nothing: every message is there.
    assert stats.truncated != stats.complete
    assert stats.truncated or got == expected
    if fraction >= 0.5:
        assert len(got) > 0.3 * len(expected)  # small chunks: only the tail is lost


def test_cut_file_keeps_metadata_written_before_the_cut(tmp_path: Path) -> None:
    buffer = io.BytesIO()
    recorder = McapRecorder(buffer, chunk_size=1024)
    recorder.add_metadata("scenario", {"name": "early"})
    for topic, t, message in _expected(50):
        recorder.publish(topic, t, message)
    recorder.flush()
    data = buffer.getvalue()  # never closed: no summary, no footer, like a crash
    assert read_metadata(io.BytesIO(data)) == {"scenario": {"name": "early"}}
    assert len(list(read_messages(io.BytesIO(data)))) == recorder.message_count


def test_non_mcap_file_raises_naming_the_file(tmp_path: Path) -> None:
    path = tmp_path / "notes.mcap"
    path.write_text("this is not an mcap file\n")
    with pytest.raises(LogReadError, match=r"notes\.mcap"):
        list(read_messages(path))
    with pytest.raises(LogReadError, match="not an MCAP file"):
        read_metadata(path)


def test_missing_file_raises_log_read_error(tmp_path: Path) -> None:
    with pytest.raises(LogReadError, match=r"nowhere\.mcap"):
        topic_counts(tmp_path / "nowhere.mcap")


def test_damaged_chunk_raises_log_read_error(recording: tuple[bytes, list]) -> None:
    data, _ = recording
    damaged = bytearray(data)
    middle = len(damaged) // 3
    for i in range(middle, middle + 16):
        damaged[i] ^= 0xFF
    with pytest.raises(LogReadError, match="damaged"):
        list(read_messages(io.BytesIO(bytes(damaged))))


def test_a_chunk_that_fails_to_decompress_leaves_the_next_read_whole(recording: tuple[bytes, list]) -> None:
    # The reader keeps one zstd decompressor per thread: a failure inside it must not spoil the next chunk.
    data, expected = recording
    chunk = data.index(b"\x28\xb5\x2f\xfd")  # the first zstd frame's magic
    damaged = bytearray(data)
    damaged[chunk + 20 : chunk + 60] = bytes(40)
    with pytest.raises(LogReadError, match="damaged"):
        list(read_messages(io.BytesIO(bytes(damaged))))
    assert len(list(read_messages(io.BytesIO(data)))) == len(expected)


class _Trickle(io.RawIOBase):
    """A stream that returns at most 7 bytes a read, as a pipe may return less than asked."""

    def __init__(self, data: bytes) -> None:
        self._data = io.BytesIO(data)

    def readable(self) -> bool:
        return True

    def read(self, size: int = -1) -> bytes:
        return self._data.read(min(size, 7) if size >= 0 else 7)


def test_a_stream_that_returns_less_than_asked_reads_the_same(recording: tuple[bytes, list]) -> None:
    data, _ = recording
    whole = list(read_messages(io.BytesIO(data)))
    assert list(read_messages(_Trickle(data))) == whole  # type: ignore[arg-type]
    assert len(whole) > 100


def test_a_chunk_whose_bytes_fail_its_crc_is_damage() -> None:
    # Uncompressed, one payload letter changed: the framing and the JSON still read, only the CRC can tell.
    buffer = io.BytesIO()
    with McapRecorder(buffer, compression="none") as recorder:
        for t in range(20):
            recorder.publish(LOG, t, _log(t))
    data = buffer.getvalue()
    assert len(list(read_messages(io.BytesIO(data)))) == 20
    damaged = data.replace(b'"line 7"', b'"Line 7"')
    assert damaged != data
    with pytest.raises(LogReadError, match="fails its CRC check"):
        list(read_messages(io.BytesIO(damaged)))


def test_the_chunk_crc_is_zlibs_crc32() -> None:
    rng = np.random.default_rng(3)
    for size in (0, 1, 7, 64, 4099, 1 << 16):
        data = rng.integers(0, 256, size, dtype=np.uint8).tobytes()
        assert crc32.iso_hdlc(data) == zlib.crc32(data)


def _raw_payloads_on_one_channel(payloads: list[bytes]) -> bytes:
    """An MCAP file (the library's writer) whose JSON channel holds ``payloads`` as they are, at 1, 2, ..."""
    buffer = io.BytesIO()
    writer = Writer(buffer)
    writer.start()
    schema = writer.register_schema("rover.X", "jsonschema", b"{}")
    channel = writer.register_channel(LOG, "json", schema)
    for t, payload in enumerate(payloads, start=1):
        writer.add_message(channel, t, payload, t)
    writer.finish()
    return buffer.getvalue()


def test_malformed_json_payload_is_skipped_and_counted() -> None:
    data = _raw_payloads_on_one_channel([b'{"a": 1}', b"{not json", b"[1, 2]", b'{"b": 2}'])
    stats = ReadStats()
    got = list(read_messages(io.BytesIO(data), stats=stats))
    assert [(m.log_time_ns, m.message) for m in got] == [(1, {"a": 1}), (4, {"b": 2})]
    assert stats.malformed == 2 and stats.messages == 2


def test_foreign_json_only_the_standard_library_reads_is_still_read() -> None:
    # Another writer's NaN / Infinity literals: Python's json reads them, orjson does not.
    data = _raw_payloads_on_one_channel([b'{"a": NaN}', b'{"b": [Infinity, 2]}'])
    stats = ReadStats()
    got = list(read_messages(io.BytesIO(data), stats=stats))
    assert math.isnan(got[0].message["a"]) and got[1].message == {"b": [math.inf, 2]}
    assert stats.malformed == 0 and stats.messages == 2


def test_topic_filter_keeps_exactly_the_asked_topics_across_chunks() -> None:
    buffer = io.BytesIO()
    with McapRecorder(buffer, chunk_size=200) as recorder:  # many small chunks
        for i in range(50):
            recorder.publish(LOG, i, {"timestamp": {"sec": 0, "nsec": i}, "i": i})
            recorder.publish(NAVIGATOR_STATE, i, {"mode": "DRIVING", "i": i})
    data = buffer.getvalue()
    stats = ReadStats()
    got = list(read_messages(io.BytesIO(data), topics=[NAVIGATOR_STATE], stats=stats))
    assert [(m.topic, m.message["i"]) for m in got] == [(NAVIGATOR_STATE, i) for i in range(50)]
    assert stats.messages == 50 and stats.skipped == 0
    assert len(list(read_messages(io.BytesIO(data)))) == 100


def test_nan_and_numpy_values_are_encoded_deterministically() -> None:
    message = {"a": float("nan"), "b": [1.0, float("inf")], "c": np.float32(2.5), "d": np.array([1, 2])}
    assert encode_message(message) == b'{"a":null,"b":[1.0,null],"c":2.5,"d":[1,2]}'
    assert encode_message({"e": np.array([np.nan])}) == b'{"e":[null]}'
    buffer = io.BytesIO()
    with McapRecorder(buffer) as recorder:
        recorder.publish(NAVIGATOR_STATE, 10, {"cross_track_error_m": math.nan, "mode": "DRIVING"})
    (got,) = read_messages(io.BytesIO(buffer.getvalue()))
    assert got.message == {"cross_track_error_m": None, "mode": "DRIVING"}


def test_recorder_rejects_unknown_topics_bad_values_and_use_after_close() -> None:
    recorder = McapRecorder(io.BytesIO())
    with pytest.raises(RecordingError, match="unknown topic"):
        recorder.publish("no/such/topic", 0, {})
    with pytest.raises(RecordingError, match="cannot be encoded"):
        recorder.publish(LOG, 0, {"x": object()})
    with pytest.raises(RecordingError, match="log_time_ns"):
        recorder.publish(LOG, -1, _log(0))
    with pytest.raises(RecordingError, match="strings"):
        recorder.add_metadata("bad", {"k": 1})  # type: ignore[dict-item]
    recorder.close()
    recorder.close()  # idempotent
    with pytest.raises(RecordingError, match="closed"):
        recorder.publish(LOG, 0, _log(0))
    with pytest.raises(RecordingError, match="compression"):
        McapRecorder(io.BytesIO(), compression="lz77")


def test_each_log_time_is_checked_though_the_last_good_one_is_remembered() -> None:
    # publish_bytes checks a log time in full only when it is not the very object checked last: a value
    # equal to a good one but of another type, or a bad one after good ones, is still refused.
    for first in (None, -1, 0.0):  # nothing checked yet: the first message's log time is checked too
        with pytest.raises(RecordingError, match="log_time_ns must be a non-negative int"):
            McapRecorder(io.BytesIO()).publish_bytes(LOG, first, b"{}")  # type: ignore[arg-type]
        with pytest.raises(RecordingError, match="log_time_ns must be a non-negative int"):
            McapRecorder(io.BytesIO()).publish_bytes_many(LOG, first, [b"{}"])  # type: ignore[arg-type]
    recorder = McapRecorder(io.BytesIO())
    good = 2**40 + 7  # an int object of its own, as the clock hands out
    recorder.publish_bytes(LOG, good, encode_message(_log(0)))
    recorder.publish_bytes(LOG, good, encode_message(_log(1)))
    for bad in (float(good), str(good), -good, None):
        with pytest.raises(RecordingError, match="log_time_ns must be a non-negative int"):
            recorder.publish_bytes(LOG, bad, b"{}")  # type: ignore[arg-type]
        with pytest.raises(RecordingError, match="log_time_ns must be a non-negative int"):
            recorder.publish_bytes_many(LOG, bad, [b"{}"])  # type: ignore[arg-type]
    assert recorder.message_count == 2
    recorder.close()
    # A closed recorder keeps no channels: every topic, recorded before or not, is refused as closed.
    for topic in (LOG, TRUTH_POSE):
        with pytest.raises(RecordingError, match="closed; cannot record"):
            recorder.publish_bytes(topic, good, b"{}")
        with pytest.raises(RecordingError, match="closed; cannot record"):
            recorder.publish_bytes_many(topic, good, [b"{}"])
        with pytest.raises(RecordingError, match="closed; cannot record"):
            recorder.publish_bytes_many(topic, good, [])


class _DiskFills(io.BytesIO):
    """A stream that takes the header, then refuses every write as a full disk does."""

    def __init__(self) -> None:
        super().__init__()
        self.full = False

    def write(self, data: object) -> int:
        if self.full:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return super().write(data)  # type: ignore[arg-type]


@pytest.mark.parametrize("chunk_size", [200, 256 * 1024])
def test_a_failed_write_is_a_recording_error_naming_the_reason(chunk_size: int) -> None:
    stream = _DiskFills()
    recorder = McapRecorder(stream, chunk_size=chunk_size, chunk_duration_ns=None)
    recorder.publish(LOG, 0, _log(0))  # registers the channel while the disk has room
    stream.full = True
    with pytest.raises(RecordingError, match="No space left on device"):
        # Small chunks: a message closes one and the publish that did it raises. Large ones: the flush.
        for t in range(1, 50):
            recorder.publish(LOG, t, _log(t))
        recorder.flush()
    with pytest.raises(RecordingError, match="No space left on device"):
        recorder.close()
    assert recorder.closed


def test_same_inputs_give_identical_bytes() -> None:
    first, second = io.BytesIO(), io.BytesIO()
    _record(first, _expected(60))
    _record(second, _expected(60))
    assert first.getvalue() == second.getvalue()


@pytest.mark.parametrize("cut", [1, 3, 8, 12, 17, 40])
def test_cut_in_the_first_bytes_reads_nothing_and_warns(
    recording: tuple[bytes, list], cut: int, caplog: pytest.LogCaptureFixture
) -> None:
    data, _ = recording
    stats = ReadStats()
    assert list(read_messages(io.BytesIO(data[:cut]), stats=stats)) == []
    assert stats.truncated
    assert "cut short" in caplog.text


@pytest.mark.parametrize("duration_ns", [1_000_000_000, None])
def test_a_chunk_closes_once_it_spans_the_chunk_duration(duration_ns: int | None) -> None:
    """The message whose log time is ``chunk_duration_ns`` past the open chunk's first closes that chunk
    (it is the chunk's last); the next message opens a new one. Without a duration only the size counts."""

    stream = io.BytesIO()
    with McapRecorder(stream, chunk_duration_ns=duration_ns) as recorder:
        for tick in range(36):  # every 0.1 s from 0 to 3.5 s
            recorder.publish(LOG, tick * 100_000_000, {"tick": tick})
    stream.seek(0)
    summary = make_reader(stream).get_summary()
    assert summary is not None
    spans = sorted((c.message_start_time, c.message_end_time) for c in summary.chunk_indexes)
    if duration_ns is None:
        assert spans == [(0, 3_500_000_000)]
    else:
        tenth = 100_000_000
        assert spans == [
            (0, 10 * tenth),
            (11 * tenth, 21 * tenth),
            (22 * tenth, 32 * tenth),
            (33 * tenth, 35 * tenth),
        ]


def _sockets_open() -> set[str]:
    fds = Path("/proc/self/fd")
    targets = set()
    for fd in fds.iterdir():
        try:
            targets.add(os.readlink(fd))
        except OSError:
            continue  # closed since listed (the listing's own fd)
    return {target for target in targets if target.startswith("socket:")}


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs Linux /proc")
def test_recording_opens_no_socket(tmp_path: Path) -> None:
    # The writer is the Foxglove SDK's, which can also serve and upload; recording must do neither.
    before = _sockets_open()
    _record(tmp_path / "r.mcap", _expected(200))
    assert _sockets_open() - before == set()


def test_an_exclusive_recorder_never_empties_an_earlier_recording(tmp_path: Path) -> None:
    earlier = tmp_path / "rover.mcap"
    earlier.write_bytes(b"an earlier run's recording")
    with pytest.raises(RecordingError, match="already exists"):
        McapRecorder(earlier, exclusive=True)
    assert earlier.read_bytes() == b"an earlier run's recording"
    with McapRecorder(tmp_path / "new.mcap", exclusive=True) as recorder:  # a new file: made as usual
        recorder.publish("log", 1, {"message": "x"})
    assert (tmp_path / "new.mcap").stat().st_size > 0
