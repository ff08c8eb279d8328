"""Log lines of a campaign trial carry the trial's label.

A campaign runs trials side by side in worker processes; a warning such as "wheels spinning in place"
means nothing without the trial it came from. A spawned worker has no logging set up (Python would print
the bare message), so it gets a stderr handler of the CLI's format; the label goes into that format.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager

FORMAT = "%(levelname)s {label} %(name)s: %(message)s"


@contextmanager
def trial_log_label(label: str) -> Iterator[None]:
    """Within the block every root handler's lines name ``label``; the handlers are restored after."""
    root = logging.getLogger()
    added: logging.Handler | None = None
    if not root.handlers:
        added = logging.StreamHandler()
        root.addHandler(added)  # the root's level in a fresh process is WARNING, as the CLI's default
    # %-style: a label with a '%' in it must not be read as a field.
    labelled = logging.Formatter(FORMAT.format(label=label.replace("%", "%%")))
    saved = [(handler, handler.formatter) for handler in root.handlers]
    for handler, _ in saved:
        handler.setFormatter(labelled)
    try:
        yield
    finally:
        for handler, formatter in saved:
            handler.setFormatter(formatter)
        if added is not None:
            root.removeHandler(added)
