"""A recording written again by the mcap library's own writer, as another tool would write it: a topic
filter (a ``rover run`` recording has no ``truth/*``) and the chunk compression of one's choice."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer


def rewrite(
    source: Path,
    target: Path,
    *,
    keep: Callable[[str], bool] = lambda topic: True,
    compression: CompressionType = CompressionType.ZSTD,
    metadata: Callable[[str, dict[str, str]], dict[str, str]] = lambda name, data: data,
    data: Callable[[str, int, bytes], bytes] = lambda topic, log_time_ns, payload: payload,
    log_time: Callable[[str, int], int] = lambda topic, log_time_ns: log_time_ns,
    drop: Callable[[str, bytes], bool] = lambda topic, payload: False,
) -> Path:
    """Every message of a kept topic (with its times and sequence) but those ``drop`` names by topic and
    payload, every metadata record; no attachment.

    ``metadata``, ``data`` and ``log_time`` may change what is written: a record's key/values by its name, a
    message's payload or log time by its topic and log time (the file order stays as it was)."""
    with source.open("rb") as inp, target.open("wb") as out:
        reader = make_reader(inp)
        writer = Writer(out, compression=compression)
        writer.start()
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if not keep(channel.topic) or drop(channel.topic, message.data):
                continue
            if schema is not None and schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                schema_id = schemas.get(channel.schema_id, 0)
                channels[channel.id] = writer.register_channel(
                    channel.topic, channel.message_encoding, schema_id, dict(channel.metadata)
                )
            writer.add_message(
                channels[channel.id],
                log_time(channel.topic, message.log_time),
                data(channel.topic, message.log_time, message.data),
                message.publish_time,
                message.sequence,
            )
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, metadata(record.name, dict(record.metadata)))
        writer.finish()
    return target
