"""Each warning of a logger once while a piece of work runs, however many times the work meets its cause.

A replay reads its recording several times (its header, its inputs, the estimates to compare, the
analysis), and a reader warns of a cut or damaged file on every pass: the same line four times for one
fact. ``each_message_once`` drops a record whose text the logger already gave while it is open.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager


class _Once(logging.Filter):
    def __init__(self) -> None:
        super().__init__()
        self.seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        text = record.getMessage()
        if text in self.seen:
            return False
        self.seen.add(text)
        return True


@contextmanager
def each_message_once(logger_name: str) -> Iterator[None]:
    """While open, a message ``logger_name`` gave once is not given again (other loggers untouched)."""
    logger = logging.getLogger(logger_name)
    once = _Once()
    logger.addFilter(once)
    try:
        yield
    finally:
        logger.removeFilter(once)
