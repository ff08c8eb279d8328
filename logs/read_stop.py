"""Where a read of a recording stopped before the recording's end, and the one sentence tools say about it.

A read stops early at a *cut* (the file's bytes end inside a record: a crash, a power loss, a full disk)
or, for tools that keep what they have read (``logs.reader.read_entries(..., stop_at_damage=True)``), at
*damage* (a complete record that does not parse: a flipped bit, a chunk failing its CRC). ``rover can
export``, ``rover logs csv`` and ``rover logs doctor`` describe either with ``ReadStop.describe`` and
``partial_notice``, so the same file reads the same way in every tool.
"""

from __future__ import annotations

from dataclasses import dataclass

CUT = "cut"
DAMAGED = "damaged"


@dataclass(frozen=True)
class ReadStop:
    """``kind``: ``CUT`` or ``DAMAGED``; ``offset``: the byte of the file where the record that stopped the
    read begins (everything before it was read); ``detail``: what was found there."""

    kind: str
    offset: int
    detail: str

    def describe(self) -> str:
        """``cut short at byte N (detail)`` or ``damaged at byte N (detail)``."""
        state = "cut short" if self.kind == CUT else "damaged"
        return f"{state} at byte {self.offset} ({self.detail})"


def partial_notice(source: object, stop: ReadStop, kept: str) -> str:
    """The sentence for an output made from the part of ``source`` before ``stop``; ``kept`` says what that
    output holds (``wrote the 1386 frames before it to run.log``)."""
    if stop.kind == DAMAGED:
        advice = "`rover logs recover FILE OUT` also keeps the complete chunks after the damage"
    else:
        advice = "`rover logs doctor FILE` says more"
    return f"{source} is {stop.describe()}: {kept}; {advice}"
