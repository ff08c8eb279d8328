"""The map sizes ``rover bench plan`` times by default, apart from ``navigator.plan_bench``.

The CLI prints them in its ``--help``; importing the benchmark itself for that would pull in its peers
(scipy.sparse.csgraph, pyastar2d, tcod) on every ``rover bench`` start-up.
"""

from __future__ import annotations

DEFAULT_SIZES = (256, 1024, 2048)  # cells a side: 64 m to 512 m squares at 0.25 m
