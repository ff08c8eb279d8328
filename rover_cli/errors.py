"""Printing an error on the console: the message as written, never read as rich markup.

Messages quote what was wrong, and that often holds brackets (``expected [x, y] ...``, ``covers x [0, 2.4)``,
a TOML key path with an index); printed through rich's markup they would silently vanish.
"""

from __future__ import annotations

from rich.console import Console
from rich.markup import escape


def print_error(console: Console, err: object, context: str = "") -> None:
    """``error: [context: ]err`` in red, with ``err`` printed literally."""
    where = f"{escape(context)}: " if context else ""
    # soft_wrap: one line however long, so a path or key in it is never broken across lines.
    # emoji=False: rich reads ":x:" in "virtual:x: ..." as an emoji code, and printed "virtual❌".
    console.print(f"[red]error:[/red] {where}{escape(str(err))}", soft_wrap=True, emoji=False)
