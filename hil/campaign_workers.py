"""How many worker processes a campaign runs: one rule for the campaign file's ``workers`` and the
command line's ``--workers`` (0 in either means one per core). Kept apart from ``hil.campaign`` so the
CLI can check the option without importing the simulator."""

from __future__ import annotations

import os

MAX_WORKERS = 256


def resolved_workers(requested: int) -> int:
    """``requested`` worker processes, or one per core for 0."""
    return requested if requested > 0 else max(1, os.cpu_count() or 1)
