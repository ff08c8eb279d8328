"""Terrain classes: integer ids shared by maps, costs, the simulator and the reports.

Values are typical figures for a small rover on rubber tyres, rounded, not measurements of ours:

* ``friction_mu``: peak traction coefficient (drawbar pull / weight at high slip). Firm soil and dry
  rock ~0.7-0.8, loose sand ~0.4, wet mud ~0.3 (Wong, *Theory of Ground Vehicles*, 4th ed., ch. 1-2;
  Bekker, *Introduction to Terramechanics*).
* ``rolling_resistance``: coefficient of rolling resistance crr (force / normal load). Hard ground 0.01-0.03,
  gravel ~0.05, grass ~0.07, loose sand 0.1-0.3, mud 0.1-0.4 (Wong, table 1.2 for tyres; scaled up for
  small wheels which sink deeper relative to their radius).
* ``cost_factor``: planner multiplier per metre relative to firm ground: how much the planner prefers to
  avoid a class (energy, slip and risk), a tuning value, >= 1.
"""

from __future__ import annotations

from dataclasses import dataclass

from navigator.errors import TerrainError


@dataclass(frozen=True)
class TerrainClass:
    id: int
    name: str
    friction_mu: float
    rolling_resistance: float
    cost_factor: float
    source: str


_WONG = "Wong, Theory of Ground Vehicles (4th ed.), ch. 1-2; typical values"
_BEKKER = "Bekker, Introduction to Terramechanics; Wong, Theory of Ground Vehicles; typical values"

FIRM = 0
ROCKY = 1
SANDY = 2
MUDDY = 3
GRAVEL = 4
GRASS = 5

TERRAIN_CLASSES: dict[int, TerrainClass] = {
    c.id: c
    for c in (
        # id, name, friction_mu, rolling_resistance, cost_factor, source
        TerrainClass(FIRM, "firm", 0.8, 0.02, 1.0, _WONG),
        TerrainClass(ROCKY, "rocky", 0.7, 0.04, 1.6, _WONG),
        TerrainClass(SANDY, "sandy", 0.4, 0.12, 2.0, _BEKKER),
        TerrainClass(MUDDY, "muddy", 0.3, 0.15, 2.6, _BEKKER),
        TerrainClass(GRAVEL, "gravel", 0.6, 0.05, 1.3, _WONG),
        TerrainClass(GRASS, "grass", 0.5, 0.07, 1.2, _WONG),
    )
}


def class_by_name(name: str, classes: dict[int, TerrainClass] = TERRAIN_CLASSES) -> TerrainClass:
    """The class called ``name`` (case-insensitive); TerrainError naming the known names otherwise."""
    wanted = name.strip().lower()
    for terrain_class in classes.values():
        if terrain_class.name == wanted:
            return terrain_class
    known = ", ".join(c.name for c in classes.values())
    raise TerrainError(f"unknown terrain class {name!r}; known classes: {known}")
