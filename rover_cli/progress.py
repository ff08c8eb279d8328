"""The progress bar of the commands that run many jobs (a campaign's trials, a sweep's replays)."""

from __future__ import annotations

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn


def job_progress(console: Console, *, transient: bool = False) -> Progress:
    """Description, bar, done of total, time elapsed; ``transient``: gone from the console when done."""
    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        transient=transient,
    )
