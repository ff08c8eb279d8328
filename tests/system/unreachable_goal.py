"""A goal the planner cannot reach, for short trials that end in ``no_path``: a goal inside an obstacle is
refused when the scenario loads, so the goal sits on free ground inside a closed ring of rocks."""

from __future__ import annotations

import math


def ring_of_rocks(x: float, y: float) -> str:
    """Eight 0.6 m rocks 1.2 m round (x, y): each overlaps the next, so no way in; the centre is free."""
    rocks = []
    for index in range(8):
        angle = index * math.pi / 4.0
        cx, cy = x + 1.2 * math.cos(angle), y + 1.2 * math.sin(angle)
        rocks.append(f'[[obstacles]]\nid = "ring{index}"\nxy = [{cx:.3f}, {cy:.3f}]\nradius_m = 0.6\n')
    return "\n".join(rocks)
