"""What rovers learned of their ground, from their recordings, as rover-config tables for the next run.

A rover that digs in learns that a terrain class climbs less than it believed (``navigator.climb_learning``),
one that slides down a side slope that the class holds less (``navigator.slide_learning``), and records it
on ``navigator/learned`` (the slope: the pitch it dug in on, or the roll it slid on); the learning ends with
the run. ``learned_tables`` reads one or more recordings and writes what they learned as
``[terrain_classes.<name>]`` tables, the rover config's own overrides (``navigator.terrain_class_settings``),
so the next run, in HIL or on the rover, plans on it from the start instead of learning it again.

Several recordings may have learned the same field of a class: the most cautious value is kept (for
``friction_mu``, the lowest: the learning only ever lowers it), and a comment above it names every learning.
A message that cannot be taken (a field missing, a value that is no finite number, a name that is not a
plain key, or one the caller's ``check`` refuses: a class or field this build does not know, a value its
class check refuses) is refused with what was wrong, and the rest are taken. Times are seconds from the
recording's first message, as a report gives them (a ``rover run`` recording's log time is the computer's
monotonic clock).
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from logs.errors import LogsError
from logs.read_stop import ReadStop
from logs.reader import ReadStats, RecordedMessage, read_entries, read_outline
from logs.topics import NAVIGATOR_LEARNED

_log = logging.getLogger(__name__)

# Fields whose cautious value is known: the one the planner is most careful with. Any other field keeps
# the last learned value (read in the order the recordings were given).
_CAUTIOUS: dict[str, Callable[[float, float], float]] = {"friction_mu": min}
_PLAIN_KEY = re.compile(r"^[A-Za-z0-9_-]+$")  # a TOML bare key: written without quotes

# Why a rover config would refuse [terrain_classes.<class>] <field> = <value>, or None: the config's own check
# (navigator.terrain_class_settings.override_refusal), given by the caller; logs/ knows no terrain classes.
LearningCheck = Callable[[str, str, float], str | None]


@dataclass(frozen=True)
class Learning:
    """One ``navigator/learned`` message: ``class_name``'s ``field`` believed ``value`` from ``t_s`` on."""

    source: Path
    t_s: float  # from the recording's first message
    class_name: str
    field: str
    value: float
    believed: float
    slope_rad: float
    plans_up_to_rad: float
    x: float
    y: float


@dataclass
class LearnedRead:
    """The learnings of the recordings read, in order; the messages refused and why; where reads stopped."""

    sources: list[Path]
    learnings: list[Learning] = field(default_factory=list)
    refused: list[str] = field(default_factory=list)
    stops: dict[Path, ReadStop] = field(default_factory=dict)


def read_learned(sources: Sequence[Path], check: LearningCheck | None = None) -> LearnedRead:
    """Every ``navigator/learned`` message of ``sources`` that ``check`` (if given) takes. A cut or damaged
    recording gives what was read before the cut or damage (``stops``); ``LogReadError`` for a file that is
    no recording."""
    result = LearnedRead(list(sources))
    for source in sources:
        start_ns = _first_message_ns(source)
        stats = ReadStats()
        for entry in read_entries(
            source, topics=[NAVIGATOR_LEARNED], stats=stats, stop_at_damage=True, refuse_empty=True
        ):
            if not isinstance(entry, RecordedMessage):
                continue
            t_s = (entry.log_time_ns - (start_ns or 0)) / 1e9
            learning = _learning(source, t_s, entry.message, check)
            if isinstance(learning, str):
                why = f"{_shown(source)} at {t_s:.3f} s: {learning}"
                _log.debug("navigator/learned message refused: %s", why)  # the caller says it
                result.refused.append(why)
            else:
                result.learnings.append(learning)
        if stats.skipped:
            result.refused.append(f"{_shown(source)}: {stats.skipped} message(s) that could not be decoded")
        if stats.stop is not None:
            result.stops[source] = stats.stop
    return result


def _first_message_ns(source: Path) -> int | None:
    """The log time of the recording's first message (from its chunk headers), or None when that cannot be
    read (damage that read_entries's ``stop_at_damage`` reads up to): times are then the log times."""
    try:
        span = read_outline(source, warn_cut=False).span_ns
    except LogsError:
        return None
    return None if span is None else span[0]


def _shown(path: Path) -> str:
    """``path`` as a TOML comment can hold it: one line."""
    text = str(path)
    return text if text.isprintable() else repr(text)


def _learning(
    source: Path, t_s: float, message: dict[str, Any], check: LearningCheck | None
) -> Learning | str:
    """The message as a ``Learning``, or what is wrong with it."""
    texts = {}
    for key in ("class_name", "field"):
        text = message.get(key)
        if not isinstance(text, str) or not _PLAIN_KEY.match(text):
            return f"{key} {text!r} is not a plain name"
        texts[key] = text
    numbers = {}
    for key in ("value", "believed", "slope_rad", "plans_up_to_rad", "x", "y"):
        number = message.get(key)
        if isinstance(number, bool) or not isinstance(number, int | float) or not math.isfinite(number):
            return f"{key} {number!r} is not a finite number"
        numbers[key] = float(number)
    refusal = None if check is None else check(texts["class_name"], texts["field"], numbers["value"])
    if refusal is not None:
        return f"a rover config would refuse it: {refusal}"
    return Learning(source, t_s, texts["class_name"], texts["field"], **numbers)


def learned_tables(read: LearnedRead) -> str:
    """The learnings as ``[terrain_classes.<name>]`` TOML tables (a class's fields in the order first
    learned), each value with a comment per learning behind it; only comments when nothing was learned."""
    names = ", ".join(_shown(source) for source in read.sources)
    if not read.learnings:
        return f"# Nothing learned of the ground in {names} (no navigator/learned messages).\n"
    lines = [
        f"# What the rover learned of its ground, from {names} (`rover logs learned`).",
        "# Add these tables to the rover config; where it has a class's table already, set the field there.",
    ]
    by_class: dict[str, dict[str, list[Learning]]] = {}
    for learning in read.learnings:
        by_class.setdefault(learning.class_name, {}).setdefault(learning.field, []).append(learning)
    for class_name, fields in by_class.items():
        lines.append("")
        lines.append(f"[terrain_classes.{class_name}]")
        for field_name, learnings in fields.items():
            for learning in learnings:
                lines.append(
                    f"# {_shown(learning.source)} at {learning.t_s:.2f} s, "
                    f"at ({learning.x:.1f}, {learning.y:.1f}): "
                    f"learned on a {math.degrees(learning.slope_rad):.1f} deg slope; {field_name} "
                    f"{learning.believed:.4g} -> {learning.value:.4g}, plans up to "
                    f"{math.degrees(learning.plans_up_to_rad):.1f} deg"
                )
            lines.append(f"{field_name} = {_kept(field_name, learnings)!r}")
    return "\n".join(lines) + "\n"


def _kept(field_name: str, learnings: list[Learning]) -> float:
    cautious = _CAUTIOUS.get(field_name)
    if cautious is None:
        return learnings[-1].value
    kept = learnings[0].value
    for learning in learnings[1:]:
        kept = cautious(kept, learning.value)
    return kept
