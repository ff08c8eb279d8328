"""Recorded topics as CSV, one file per topic: what an analyst loads into pandas, MATLAB or a spreadsheet.

Each row is one message: ``log_time_ns`` and ``log_time_s`` first, then the message's fields flattened
with dots (``pose.position.x``); a short list is spread over indexed columns (``wheels.0.erpm``), a long
one (a planned path) stays one cell holding its JSON, so a topic's column count stays bounded. The columns
of a topic are every field any of its messages had, in order of first appearance; a message without one
leaves the cell empty. Two passes over the file: the first learns the columns, the second writes.

A recording cut short or damaged partway is exported up to that point (``CsvExport.stop`` says where:
``logs.read_stop``); a file with no recording in it (empty, not MCAP) is an error and writes nothing.
"""

from __future__ import annotations

import csv
import json
import math
import re
from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TextIO

from logs.errors import LogsError
from logs.read_stop import ReadStop
from logs.reader import ReadStats, RecordedMessage, read_entries, topic_counts

TIME_COLUMNS = ("log_time_ns", "log_time_s")
# Lists up to this long are spread over indexed columns (six wheels, a 3x3 covariance); longer ones stay
# one JSON cell.
MAX_SPREAD_LIST = 16
_UNSAFE_FILE_CHARS = re.compile(r"[^A-Za-z0-9_.-]+")

Cell = str | int | float | bool | None


class CsvExportError(LogsError):
    """The export cannot be made: an unknown topic asked for, or an output folder that cannot be written."""


@dataclass
class CsvExport:
    source: Path
    files: dict[str, Path] = field(default_factory=dict)  # topic -> CSV file
    rows: dict[str, int] = field(default_factory=dict)  # topic -> rows written
    truncated: bool = False  # the recording was cut short: the rows are its readable part
    stop: ReadStop | None = None  # where a cut or damage ended the export early (None: read to the end)
    skipped_messages: int = 0  # messages that could not be decoded (counted by the reader)
    # topic -> its messages that could not be decoded (not JSON, not an object), of those exported
    undecodable: dict[str, int] = field(default_factory=dict)


def flatten(message: dict[str, Any]) -> dict[str, Cell]:
    """One message as ``column -> cell`` (see the module's docstring)."""
    cells: dict[str, Cell] = {}
    _flatten_into(cells, "", message)
    return cells


def _flatten_into(cells: dict[str, Cell], prefix: str, value: Any) -> None:
    if isinstance(value, dict):
        for key, item in value.items():
            _flatten_into(cells, f"{prefix}.{key}" if prefix else str(key), item)
    elif isinstance(value, list) and len(value) <= MAX_SPREAD_LIST:
        for index, item in enumerate(value):
            _flatten_into(cells, f"{prefix}.{index}" if prefix else str(index), item)
    elif isinstance(value, list):
        cells[prefix] = json.dumps(value, separators=(",", ":"))
    elif isinstance(value, float) and not math.isfinite(value):
        cells[prefix] = repr(value)  # nan, inf, -inf: what pandas and numpy read back
    else:
        cells[prefix] = value


def file_name_for(topic: str, taken: Collection[str]) -> str:
    """``truth/pose`` -> ``truth.pose.csv``; any other character becomes ``_``; a clash gets a number."""
    stem = _UNSAFE_FILE_CHARS.sub("_", topic.replace("/", ".")).strip(".") or "topic"
    name = f"{stem}.csv"
    number = 2
    while name in taken:
        name = f"{stem}-{number}.csv"
        number += 1
    return name


def export_csv(source: Path, out_dir: Path, topics: Collection[str] | None = None) -> CsvExport:
    """Write one CSV per topic of ``source`` (all topics, or ``topics``) into ``out_dir``.

    ``LogReadError`` for a file that is not a readable MCAP (``NotARecording``: empty, or not MCAP);
    ``CsvExportError`` for a topic that is not in the recording or an ``out_dir`` that cannot be written.
    A recording cut short or damaged exports its readable part (``stop``; ``truncated`` for a cut).
    """
    counted = ReadStats()
    present = topic_counts(source, stats=counted, stop_at_damage=True, refuse_empty=True)
    if topics is not None:
        missing = sorted(set(topics) - set(present))
        if missing:
            readable = "" if counted.stop is None else f" before it is {counted.stop.describe()}"
            raise CsvExportError(
                f"{source}: no topic {', '.join(missing)} in this recording{readable}; "
                f"it has {', '.join(present) or 'no messages'}"
            )
    wanted = sorted(present) if topics is None else sorted(set(topics))
    columns = _columns(source, wanted)
    result = CsvExport(source)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise CsvExportError(f"cannot create the output folder {out_dir}: {err.strerror or err}") from err
    taken: set[str] = set()
    handles: dict[str, TextIO] = {}
    try:
        writers: dict[str, csv.DictWriter[str]] = {}
        for topic in wanted:
            if topic not in columns:
                continue  # no message of it could be decoded
            name = file_name_for(topic, taken)
            taken.add(name)
            path = out_dir / name
            handles[topic] = path.open("w", newline="", encoding="utf-8")
            writer = csv.DictWriter(handles[topic], fieldnames=[*TIME_COLUMNS, *columns[topic]])
            writer.writeheader()
            writers[topic] = writer
            result.files[topic] = path
            result.rows[topic] = 0
        stats = ReadStats()
        for message in _messages(source, wanted, stats):
            writer = writers[message.topic]
            row = flatten(message.message)
            row["log_time_ns"] = message.log_time_ns  # the recording's, whatever the message holds
            row["log_time_s"] = message.log_time_ns / 1e9
            writer.writerow(row)
            result.rows[message.topic] += 1
        result.truncated = stats.truncated
        result.stop = stats.stop
        result.skipped_messages = stats.skipped
        # Per topic, so the summary can name what got fewer rows (or no CSV at all) than it has messages.
        for topic in wanted:
            if present[topic] > result.rows.get(topic, 0):
                result.undecodable[topic] = present[topic] - result.rows.get(topic, 0)
    except OSError as err:
        raise CsvExportError(f"cannot write the CSV files in {out_dir}: {err.strerror or err}") from err
    finally:
        for handle in handles.values():
            handle.close()
    return result


def _columns(source: Path, topics: Collection[str]) -> dict[str, list[str]]:
    """Each topic's columns (after the time columns), in order of first appearance."""
    seen: dict[str, dict[str, None]] = {}
    for message in _messages(source, topics, ReadStats()):
        order = seen.setdefault(message.topic, {})
        for column in flatten(message.message):
            order.setdefault(column, None)
    return {topic: [c for c in order if c not in TIME_COLUMNS] for topic, order in seen.items()}


def _messages(source: Path, topics: Collection[str], stats: ReadStats) -> Iterator[RecordedMessage]:
    # Up to damage, as up to a cut: what was recorded before it is exported, and ``stats.stop`` says so.
    for entry in read_entries(source, topics=topics, stats=stats, stop_at_damage=True, refuse_empty=True):
        if isinstance(entry, RecordedMessage):
            yield entry
