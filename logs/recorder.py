"""MCAP recorder: the ``MessageSink`` that writes every published message to one MCAP file.

Each topic gets its JSON schema (``jsonschema`` encoding, from the registry in ``logs.topics``) and a
channel (``json`` message encoding) the first time it is published. ``log_time`` and ``publish_time``
both come from the caller's clock; sequence numbers count per channel from 0.

``publish`` sits on the simulator's hot path (thousands of calls per simulated second), so it does one
dict lookup, one ``encode_message`` and one ``add_message``; the slow path (NaN repair, registration) runs
only when needed. ``publish_encoded`` takes bytes already encoded (a ``FanoutSink`` encodes each message
once for the recorder and the live stream). ``encode_message`` lives in ``logs.encoding``.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping
from pathlib import Path
from typing import BinaryIO

from mcap.writer import CompressionType, Writer

from logs.closing import ClosesOnExit
from logs.encoding import encode_message
from logs.errors import RecordingError
from logs.sink import Message
from logs.topics import spec

logger = logging.getLogger(__name__)

SCHEMA_ENCODING = "jsonschema"
MESSAGE_ENCODING = "json"
LIBRARY = "rover-stack logs"

_COMPRESSIONS = {"zstd": CompressionType.ZSTD, "none": CompressionType.NONE}
# Crash budget: a chunk is closed and pushed to the OS once it spans this much log time, so SIGKILL or a
# power cut loses at most about one second. At the lockstep trial's ~80 kB per simulated second the size
# limit below alone would hold ~3 s, so the time limit is what bounds the loss.
DEFAULT_CHUNK_DURATION_NS = 1_000_000_000
DEFAULT_CHUNK_SIZE = 256 * 1024
_SEQUENCE_MODULO = 2**32  # MCAP sequence numbers are uint32


class McapRecorder(ClosesOnExit):
    """Writes published messages to an MCAP file (a path or a binary stream).

    A path's parent folders are created; the recorder owns and closes that file. A stream given by the
    caller is flushed on ``close()`` but left open. ``close()`` is safe to call twice; the recorder is also
    a context manager.

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
        self._chunk_started_ns: int | None = None  # log time of the first message in the open chunk
        self._closed = False
        self._owned_file: BinaryIO | None = None
        if isinstance(output, str | Path):
            path = Path(output)
            self.name = str(path)
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                self._owned_file = path.open("wb")
            except OSError as err:
                raise RecordingError(f"cannot create recording {path}: {err}; check the folder") from err
            stream: BinaryIO = self._owned_file
        else:
            self.name = str(getattr(output, "name", "<stream>"))
            stream = output
        self._stream = stream
        self._writer = Writer(stream, chunk_size=chunk_size, compression=_COMPRESSIONS[compression])
        # topic -> [channel id, next sequence number]; a list so publish() updates it in place.
        self._channels: dict[str, list[int]] = {}
        self._schema_ids: dict[tuple[str, bytes], int] = {}
        try:
            self._writer.start(profile=profile, library=LIBRARY)
        except OSError as err:
            self._abandon()
            raise RecordingError(f"cannot write MCAP header to {self.name}: {err}") from err

    # --- MessageSink ---------------------------------------------------------------------------
    def publish(self, topic: str, log_time_ns: int, message: Message) -> None:
        try:
            data = encode_message(message)
        except (TypeError, ValueError) as err:
            raise RecordingError(f"{topic} at {log_time_ns} ns: message cannot be encoded: {err}") from err
        self.publish_encoded(topic, log_time_ns, message, data)

    def publish_encoded(self, topic: str, log_time_ns: int, message: Message, data: bytes) -> None:
        """Record ``data``, which is ``encode_message(message)`` (a ``FanoutSink`` encodes once for all)."""
        entry = self._channels.get(topic)
        if entry is None:
            entry = self._register(topic)
        elif self._closed:
            raise RecordingError(f"recorder {self.name} is closed; cannot record {topic!r}")
        if not isinstance(log_time_ns, int) or log_time_ns < 0:
            raise RecordingError(f"{topic}: log_time_ns must be a non-negative int, got {log_time_ns!r}")
        sequence = entry[1]
        entry[1] = (sequence + 1) % _SEQUENCE_MODULO
        try:
            self._writer.add_message(
                channel_id=entry[0],
                log_time=log_time_ns,
                data=data,
                publish_time=log_time_ns,
                sequence=sequence,
            )
        except OSError as err:
            raise RecordingError(f"cannot write to {self.name}: {err}") from err
        self.message_count += 1
        if self._chunk_duration_ns is not None:
            started = self._chunk_started_ns
            if started is None:
                self._chunk_started_ns = log_time_ns
            elif log_time_ns - started >= self._chunk_duration_ns:
                self.flush()  # also pushes Python's file buffer to the OS, where SIGKILL cannot lose it

    def _register(self, topic: str) -> list[int]:
        self._check_open(f"record {topic!r}")
        try:
            topic_spec = spec(topic)
        except KeyError as err:
            raise RecordingError(f"cannot record unknown topic: {err.args[0]}") from err
        schema_data = json.dumps(topic_spec.schema, separators=(",", ":"), sort_keys=True).encode()
        key = (topic_spec.schema_name, schema_data)
        try:
            schema_id = self._schema_ids.get(key)
            if schema_id is None:
                schema_id = self._writer.register_schema(
                    name=topic_spec.schema_name, encoding=SCHEMA_ENCODING, data=schema_data
                )
                self._schema_ids[key] = schema_id
            channel_id = self._writer.register_channel(
                topic=topic, message_encoding=MESSAGE_ENCODING, schema_id=schema_id
            )
        except OSError as err:
            raise RecordingError(f"cannot write to {self.name}: {err}") from err
        entry = [channel_id, 0]
        self._channels[topic] = entry
        return entry

    # --- trial records -------------------------------------------------------------------------
    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """A named key/value record (scenario, config, seed, version); all keys and values are strings."""
        self._check_open(f"add metadata {name!r}")
        bad = [key for key, value in data.items() if not isinstance(key, str) or not isinstance(value, str)]
        if bad:
            raise RecordingError(f"metadata {name!r}: keys and values must be strings; bad entries: {bad}")
        try:
            self._writer.add_metadata(name=name, data=dict(data))
        except OSError as err:
            raise RecordingError(f"cannot write to {self.name}: {err}") from err

    def add_attachment(self, name: str, media_type: str, data: bytes, log_time_ns: int) -> None:
        """A file stored whole in the recording (e.g. the scenario TOML)."""
        self._check_open(f"add attachment {name!r}")
        if log_time_ns < 0:
            raise RecordingError(f"attachment {name!r}: log_time_ns must be >= 0, got {log_time_ns}")
        try:
            # create_time = log_time: nothing here may read the wall clock.
            self._writer.add_attachment(
                create_time=log_time_ns, log_time=log_time_ns, name=name, media_type=media_type, data=data
            )
        except OSError as err:
            raise RecordingError(f"cannot write to {self.name}: {err}") from err

    def flush(self) -> None:
        """Close the chunk in progress and push it to the output, so a crash loses less."""
        self._check_open("flush")
        self._chunk_started_ns = None
        try:
            self._writer.flush()
        except OSError as err:
            raise RecordingError(f"cannot write to {self.name}: {err}") from err

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
            self._writer.finish()
            self._stream.flush()
        except OSError as err:
            raise RecordingError(f"cannot finish recording {self.name}: {err}") from err
        finally:
            self._abandon()
        logger.debug("closed recording %s with %d messages", self.name, self.message_count)

    def _abandon(self) -> None:
        self._closed = True
        if self._owned_file is not None:
            self._owned_file.close()
            self._owned_file = None

    def _check_open(self, action: str) -> None:
        if self._closed:
            raise RecordingError(f"recorder {self.name} is closed; cannot {action}")
