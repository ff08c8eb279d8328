"""MCAP recorder: the ``MessageSink`` that writes every published message to one MCAP file.

Each topic gets its JSON schema (``jsonschema`` encoding, from the registry in ``logs.topics``) and a
channel (``json`` message encoding) the first time it is published. ``log_time`` and ``publish_time``
both come from the caller's clock; sequence numbers count per channel from 1.

The writer is the Foxglove SDK's (``foxglove-sdk``: Rust, the mcap crate): ~1.2 us a message, zstd
included, where the pure-Python ``mcap.writer.Writer`` took ~4.6 us (the default trial's messages, writer
alone), and the lockstep trial records ~1300 messages per simulated second. It writes the same standard
MCAP (zstd chunks, message and chunk indexes, statistics, summary); the reading side (``logs.reader``,
``rover logs recover``) stays on the ``mcap`` package. Two things the SDK decides that the old writer let
us choose: the header's library string is the SDK's (``foxglove-sdk-python/... mcap-rust/...``), and
sequence numbers start at 1, not 0.

``publish`` sits on the simulator's hot path (thousands of calls per simulated second), so it does one
dict lookup, one ``encode_message`` and one call into the writer; the slow path (NaN repair,
registration) runs only when needed. ``publish_encoded`` takes bytes already encoded (a ``FanoutSink``
encodes each message once for the recorder and the live stream), and ``publish_bytes`` the bytes alone
(``logs.encoding.BytesSink``: the CAN link's frame records come formatted, with no dict built for them),
``publish_bytes_many`` several of those of one topic and log time at once (a poll's frames).
``encode_message`` lives in ``logs.encoding``.
"""

from __future__ import annotations

import json
import logging
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import BinaryIO, NoReturn

from foxglove import Channel, Context, Schema, open_mcap
from foxglove.mcap import MCAPCompression, MCAPWriteOptions

from logs.closing import ClosesOnExit
from logs.encoding import encode_message
from logs.errors import RecordingError
from logs.sink import Message
from logs.topics import spec

logger = logging.getLogger(__name__)

SCHEMA_ENCODING = "jsonschema"
MESSAGE_ENCODING = "json"

_COMPRESSIONS: dict[str, MCAPCompression | None] = {"zstd": MCAPCompression.Zstd, "none": None}
# Crash budget: a chunk is closed and pushed to the OS once it spans this much log time, so SIGKILL or a
# power cut loses at most about one second.
DEFAULT_CHUNK_DURATION_NS = 1_000_000_000
# The size limit, above the ~430 kB of uncompressed messages a lockstep trial records per simulated second,
# so that the time limit closes the chunks: at 256 KiB the size limit closed a chunk every ~0.6 s and the
# time limit another soon after (84 chunks for the default trial's 41 s instead of 41), and each closed
# chunk costs the writer its zstd start and the reader a decompression call (writer alone on the trial's
# messages: ~62 -> ~56 ms). A chunk still holds at most this much in memory.
DEFAULT_CHUNK_SIZE = 1024 * 1024
# The SDK's writer raises on flush and close only, and then without the operating system's reason
# ("a write method failed"); writes that fail while a message closes a chunk it logs, not raises.
_SDK_FAILURES = (OSError, RuntimeError)
# McapRecorder._checked_ns before the first message: no log time is this object.
_NOTHING_CHECKED = object()
# McapRecorder._chunk_due_ns while no chunk is open: below every log time, so the next message opens one.
_NO_OPEN_CHUNK = -1


class _Output:
    """The recording's stream as the SDK writes to it, keeping the first ``OSError`` it raised.

    The SDK reports a failed write as "a write method failed"; this keeps the reason (a full disk, a
    closed pipe) so the ``RecordingError`` can name it, and lets ``publish`` see a failure on the very
    message whose chunk could not be written. Only whole chunks and records pass through here, never
    single messages, so the extra Python call costs nothing that matters.
    """

    def __init__(self, stream: BinaryIO) -> None:
        self._stream = stream
        self.failure: OSError | None = None

    def write(self, data: bytes | bytearray) -> int:
        try:
            return self._stream.write(data)
        except OSError as err:
            self.failure = self.failure or err
            raise

    def seek(self, offset: int, whence: int = 0) -> int:
        return self._stream.seek(offset, whence)

    def flush(self) -> None:
        try:
            self._stream.flush()
        except OSError as err:
            self.failure = self.failure or err
            raise


class McapRecorder(ClosesOnExit):
    """Writes published messages to an MCAP file (a path or a binary stream).

    A path's parent folders are created; the recorder owns and closes that file. ``exclusive``: a path that
    exists already is a ``RecordingError``, not emptied (``rover run``, the HIL peer and the ground station
    never write over a recording). A stream given by the caller is flushed on ``close()`` but left open.
    ``close()`` is safe to call twice; the recorder is also a context manager.

    A chunk closes when it holds ``chunk_size`` uncompressed bytes or spans ``chunk_duration_ns`` of log
    time (``None``: size only), whichever comes first; each time-closed chunk is flushed to the OS. A file
    cut by a crash therefore keeps everything up to about ``chunk_duration_ns`` before the cut
    (``rover logs recover``).
    """

    def __init__(
        self,
        output: str | Path | BinaryIO,
        *,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        compression: str = "zstd",
        profile: str = "",
        chunk_duration_ns: int | None = DEFAULT_CHUNK_DURATION_NS,
        exclusive: bool = False,
    ) -> None:
        if chunk_size <= 0:
            raise RecordingError(f"chunk_size must be > 0 bytes, got {chunk_size}")
        if chunk_duration_ns is not None and chunk_duration_ns <= 0:
            raise RecordingError(f"chunk_duration_ns must be > 0 ns or None, got {chunk_duration_ns}")
        if compression not in _COMPRESSIONS:
            raise RecordingError(
                f"unknown MCAP compression {compression!r}; use one of {', '.join(sorted(_COMPRESSIONS))}"
            )
        self.message_count = 0
        self._chunk_duration_ns = chunk_duration_ns
        # Log time from which a message goes to _chunk_by_time: the open chunk's first message's log time
        # plus chunk_duration_ns; _NO_OPEN_CHUNK (every message) before a chunk opens; infinite without a
        # time limit.
        self._chunk_due_ns: float = self._no_open_chunk_due()
        self._closed = False
        # The log time checked last (publish_bytes): a non-negative int, or before the first message an
        # object of our own that no caller can pass (not None, not a small int: those are shared objects).
        self._checked_ns: object = _NOTHING_CHECKED
        self._owned_file: BinaryIO | None = None
        if isinstance(output, str | Path):
            path = Path(output)
            self.name = str(path)
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                # Exclusive: created here or not at all, never an earlier recording emptied (even one
                # another process made after the caller looked).
                self._owned_file = path.open("xb" if exclusive else "wb")
            except FileExistsError as err:
                raise RecordingError(
                    f"recording {path} already exists (an earlier run's, left as it is): give another "
                    "file or folder, or move it away"
                ) from err
            except OSError as err:
                raise RecordingError(f"cannot create recording {path}: {err}; check the folder") from err
            stream: BinaryIO = self._owned_file
        else:
            self.name = str(getattr(output, "name", "<stream>"))
            stream = output
        self._stream = stream
        self._output = _Output(stream)
        options = MCAPWriteOptions(
            compression=_COMPRESSIONS[compression],
            profile=profile,
            chunk_size=chunk_size,
            # No compression threads: the same messages give the same bytes, and the recording stays on
            # the one core a lockstep trial or a pinned benchmark runs on.
            compression_threads=0,
            # zstd level 1, not the default 3: on the default trial's messages it is both faster
            # (~1.15 us against ~1.3 us a message, writer alone) and smaller (3.71 MB against 3.89 MB).
            compression_level=1,
            # Each chunk goes to the stream whole when it closes (as the mcap package's writer does), not
            # streamed with its length patched in afterwards: a file cut by a crash ends in complete
            # chunks, which ``rover logs recover`` keeps, and at most a cut record after them.
            disable_seeking=True,
        )
        # A context of our own: channels and the writer belong to this recording alone, not to the SDK's
        # process-wide default context that any other recorder (or a Foxglove server) would share.
        self._context = Context()
        # topic -> the channel's log(data, log_time); the SDK counts sequence numbers per channel.
        self._channels: dict[str, Callable[[bytes, int], None]] = {}
        try:
            self._writer = open_mcap(self._output, context=self._context, writer_options=options)
        except _SDK_FAILURES as err:
            self._abandon()
            raise RecordingError(f"cannot write MCAP header to {self.name}: {self._reason(err)}") from err

    # --- MessageSink ---------------------------------------------------------------------------
    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        try:
            data = encode_message(message)
        except (TypeError, ValueError) as err:
            raise RecordingError(f"{topic} at {log_time_ns} ns: message cannot be encoded: {err}") from err
        self.publish_bytes(topic, log_time_ns, data)

    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None:
        """Record ``data``, which is ``encode_message(message)`` (a ``FanoutSink`` encodes once for all)."""
        self.publish_bytes(topic, log_time_ns, data)

    # --- BytesSink: the record is the bytes; the message itself is never looked at ------------------
    records_bytes_only = True

    def publish_bytes(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """Record ``data``: a message's JSON bytes (``encode_message`` of it, or the same text formatted
        directly, as the CAN link formats its frame records)."""
        # A closed recorder has no channels (_abandon), so a topic's channel found is an open recorder's:
        # the message that finds none goes to _register, which refuses on a closed recorder.
        log = self._channels.get(topic)
        if log is None:
            log = self._register(topic)
        # The messages of one tick share their log time, the very int object (the clock's): the one
        # checked last passes with an identity comparison, every other one is checked in full.
        if log_time_ns is not self._checked_ns:
            self._check_log_time(topic, log_time_ns)
        log(data, log_time_ns)  # publish_time = log_time, as the SDK writes it
        if self._output.failure is not None:  # this message closed a chunk that could not be written
            self._write_failed()
        self.message_count += 1
        # One comparison per message (hot path): only a message that opens a chunk or is due to close one
        # by its age goes further.
        if log_time_ns >= self._chunk_due_ns:
            self._chunk_by_time(log_time_ns)

    def publish_bytes_many(self, topic: str, log_time_ns: int, datas: Sequence[bytes]) -> None:
        """Record each of ``datas`` in turn at ``log_time_ns``: ``publish_bytes`` for each, in one call.

        Hot path (the CAN link's frames of one poll or command round: half the trial's messages): the
        channel, the recorder's state and the log time are checked once for them all; each message is
        still counted, checked for a failed chunk write and for the chunk's age as ``publish_bytes`` does,
        so the file holds the same records and chunks."""
        log = self._channels.get(topic)
        if log is None:
            if not datas and not self._closed:
                return  # nothing to record: no channel either, as before the first message
            log = self._register(topic)
        if log_time_ns is not self._checked_ns:
            self._check_log_time(topic, log_time_ns)
        output = self._output
        for data in datas:
            log(data, log_time_ns)
            if output.failure is not None:
                self._write_failed()
            self.message_count += 1
            if log_time_ns >= self._chunk_due_ns:
                self._chunk_by_time(log_time_ns)

    def _check_log_time(self, topic: str, log_time_ns: int) -> None:
        """Refuse a log time that is not a non-negative int; remember one that is (``_checked_ns``)."""
        if not isinstance(log_time_ns, int) or log_time_ns < 0:
            raise RecordingError(f"{topic}: log_time_ns must be a non-negative int, got {log_time_ns!r}")
        self._checked_ns = log_time_ns

    def _chunk_by_time(self, log_time_ns: int) -> None:
        """``log_time_ns`` opens a chunk (its age counts from here) or is ``chunk_duration_ns`` past the
        open chunk's first message (the chunk is closed)."""
        if self._chunk_due_ns == _NO_OPEN_CHUNK:
            assert self._chunk_duration_ns is not None  # without one, _chunk_due_ns is infinite
            self._chunk_due_ns = log_time_ns + self._chunk_duration_ns
        else:
            self.flush()  # also pushes Python's file buffer to the OS, where SIGKILL cannot lose it

    def _no_open_chunk_due(self) -> float:
        return _NO_OPEN_CHUNK if self._chunk_duration_ns is not None else math.inf

    def _register(self, topic: str) -> Callable[[bytes, int], None]:
        self._check_open(f"record {topic!r}")
        try:
            topic_spec = spec(topic)
        except KeyError as err:
            raise RecordingError(f"cannot record unknown topic: {err.args[0]}") from err
        schema_data = json.dumps(topic_spec.schema, separators=(",", ":"), sort_keys=True).encode()
        schema = Schema(name=topic_spec.schema_name, encoding=SCHEMA_ENCODING, data=schema_data)
        # The SDK writes the schema (once per distinct schema) and the channel record when the channel is
        # made in our context, and fails the write quietly: look at the output afterwards.
        # (The SDK's ``foxglove.channel`` module keeps every Channel it made for the life of the process:
        # our ~13 kB of schemas per recording, which a campaign of many trials in one process carries.)
        channel = Channel(topic, schema=schema, message_encoding=MESSAGE_ENCODING, context=self._context)
        if self._output.failure is not None:
            self._write_failed()
        # The channel's own log(bytes, log_time), not Channel.log: that one first checks whether a dict
        # or a str was passed (~0.4 us of ~0.9 us a message); ours are always the encoded bytes.
        log = channel.base.log
        self._channels[topic] = log
        return log

    # --- trial records -------------------------------------------------------------------------
    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """A named key/value record (scenario, config, seed, version); all keys and values are strings."""
        self._check_open(f"add metadata {name!r}")
        bad = [key for key, value in data.items() if not isinstance(key, str) or not isinstance(value, str)]
        if bad:
            raise RecordingError(f"metadata {name!r}: keys and values must be strings; bad entries: {bad}")
        try:
            self._writer.write_metadata(name, dict(data))  # an empty ``data`` writes no record
        except _SDK_FAILURES as err:
            raise RecordingError(f"cannot write to {self.name}: {self._reason(err)}") from err

    def add_attachment(self, name: str, media_type: str, data: bytes, log_time_ns: int) -> None:
        """A file stored whole in the recording (e.g. the scenario TOML)."""
        self._check_open(f"add attachment {name!r}")
        if log_time_ns < 0:
            raise RecordingError(f"attachment {name!r}: log_time_ns must be >= 0, got {log_time_ns}")
        try:
            # create_time = log_time: nothing here may read the wall clock.
            self._writer.attach(
                log_time=log_time_ns, create_time=log_time_ns, name=name, media_type=media_type, data=data
            )
        except _SDK_FAILURES as err:
            raise RecordingError(f"cannot write to {self.name}: {self._reason(err)}") from err

    def flush(self) -> None:
        """Close the chunk in progress and push it to the output, so a crash loses less."""
        self._check_open("flush")
        self._chunk_due_ns = self._no_open_chunk_due()
        try:
            self._writer.flush()  # writes the chunk and flushes our stream
        except _SDK_FAILURES as err:
            raise RecordingError(f"cannot write to {self.name}: {self._reason(err)}") from err

    # --- lifetime ------------------------------------------------------------------------------
    @property
    def closed(self) -> bool:
        return self._closed

    def close(self) -> None:
        """Write the summary and footer; close the file if the recorder opened it. Safe to repeat."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.close()  # the summary and footer; the stream stays open
            self._stream.flush()
        except _SDK_FAILURES as err:
            raise RecordingError(f"cannot finish recording {self.name}: {self._reason(err)}") from err
        finally:
            self._abandon()
        logger.debug("closed recording %s with %d messages", self.name, self.message_count)

    def _abandon(self) -> None:
        self._closed = True
        self._channels.clear()  # publish_bytes finds no channel, so _register refuses every message
        if self._owned_file is not None:
            self._owned_file.close()
            self._owned_file = None

    def _write_failed(self) -> NoReturn:
        failure = self._output.failure
        raise RecordingError(f"cannot write to {self.name}: {failure}") from failure

    def _reason(self, err: Exception) -> str:
        """What went wrong: the operating system's reason when a write to our stream failed."""
        return str(self._output.failure or err)

    def _check_open(self, action: str) -> None:
        if self._closed:
            raise RecordingError(f"recorder {self.name} is closed; cannot {action}")
