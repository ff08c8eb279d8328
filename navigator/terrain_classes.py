"""Terrain classes: integer ids shared by maps, costs, the simulator and the reports.

Values are typical figures for a small rover on rubber tyres, rounded, not measurements of ours. The planner
reads ``friction_mu``, ``rolling_resistance`` and ``cost_factor``; the simulator (``hil.traction``) reads
all of them. docs/physics.md has the table with the sources. This table is the default: a scenario's and a
rover config's ``[terrain_classes.<name>]`` tables retune a class for the simulated world and for the
planner's beliefs respectively (``navigator.terrain_class_settings``).

* ``friction_mu``: peak traction coefficient (drawbar pull / weight at full slip). Firm soil and dry
  rock ~0.7-0.8, loose sand ~0.4, wet mud ~0.3 (Wong, *Theory of Ground Vehicles*, 4th ed., ch. 1-2;
  Bekker, *Introduction to Terramechanics*).
* ``rolling_resistance``: coefficient of rolling resistance crr (force / normal load) of a wheel carrying
  ``REFERENCE_WHEEL_LOAD_N``. Hard ground 0.01-0.03, gravel ~0.05, grass ~0.07, loose sand 0.1-0.3, mud
  0.1-0.4 (Wong, table 1.2 for tyres; scaled up for small wheels which sink deeper relative to their radius).
* ``cost_factor``: planner multiplier per metre relative to firm ground: how much the planner prefers to
  avoid a class (energy, slip and risk), a tuning value, >= 1.
* ``slip_constant``: the traction curve's slip scale s_k: the drawbar-pull coefficient rises with slip s as
  ``1 - exp(-s / s_k)`` (normalised to reach ``friction_mu`` at s = 1). This is the Janosi-Hanamoto
  shear-displacement law (Wong ch. 2) with the shear displacement j = s x (contact length), so s_k is the
  shear-deformation modulus K over the contact length. Tyres on firm ground reach their peak at 15-20 %
  slip (Wong ch. 1): s_k ~0.05; sand and clay with K of 1-3 cm under a ~10 cm contact patch: 0.1-0.2.
* ``sinkage_resistance``: the part of ``rolling_resistance`` that is compaction of the ground under the
  wheel (0 on rock). By Bekker's rigid-wheel sinkage law it grows with the wheel load W as
  ``W^(1/(2n+1))`` relative to the load (Wong ch. 2 / Bekker), so a heavier wheel sinks deeper and meets
  more resistance per newton.
* ``sinkage_exponent``: Bekker's pressure-sinkage exponent n (dry sand ~1.1, sandy loam ~0.7, clayey soil
  ~0.5; Wong ch. 2, table of measured terrain values).
* ``lateral_resistance``: coefficient of lateral resistance mu_t of a wheel scrubbing sideways in a
  skid-steer turn at its tightest (a turn on the spot). Wong ch. 7 (steering of tracked vehicles, the
  resisting moment ``mu_t W l / 4`` and its fall with turning radius); Yu et al., IEEE Trans. Robotics
  26(2), 2010, for skid-steered wheeled robots. Below ``friction_mu``: a turn on the spot must stay
  possible on every class.
"""

from __future__ import annotations

from dataclasses import dataclass

from navigator.errors import TerrainError

# ``rolling_resistance`` holds for this wheel load: the default 45 kg rover at rest on the level, per wheel.
REFERENCE_WHEEL_LOAD_N = 45.0 * 9.81 / 6.0


@dataclass(frozen=True)
class TerrainClass:
    id: int
    name: str
    friction_mu: float
    rolling_resistance: float
    cost_factor: float
    source: str
    # Wheel-ground laws of the simulator; the defaults are firm ground (a stiff tyre, no sinkage).
    slip_constant: float = 0.05
    sinkage_resistance: float = 0.0
    sinkage_exponent: float = 1.0
    lateral_resistance: float = 0.4

    def __post_init__(self) -> None:
        if not (self.friction_mu > 0.0 and self.rolling_resistance >= 0.0):
            raise TerrainError(
                f"terrain class {self.name!r}: need friction_mu > 0 and rolling_resistance >= 0"
            )
        if not 0.0 < self.slip_constant <= 1.0:
            raise TerrainError(f"terrain class {self.name!r}: slip_constant must be in (0, 1]")
        if not 0.0 <= self.sinkage_resistance <= self.rolling_resistance:
            raise TerrainError(
                f"terrain class {self.name!r}: sinkage_resistance must be in [0, rolling_resistance]"
            )
        if not (self.sinkage_exponent > 0.0 and self.lateral_resistance >= 0.0):
            raise TerrainError(
                f"terrain class {self.name!r}: need sinkage_exponent > 0 and lateral_resistance >= 0"
            )


_WONG = "Wong, Theory of Ground Vehicles (4th ed.), ch. 1-2 and 7; typical values"
_BEKKER = (
    "Bekker, Introduction to Terramechanics; Wong, Theory of Ground Vehicles, ch. 2 and 7; typical values"
)

FIRM = 0
ROCKY = 1
SANDY = 2
MUDDY = 3
GRAVEL = 4
GRASS = 5

TERRAIN_CLASSES: dict[int, TerrainClass] = {
    c.id: c
    for c in (
        # id, name, friction_mu, rolling_resistance, cost_factor, source,
        # slip_constant, sinkage_resistance, sinkage_exponent, lateral_resistance
        TerrainClass(FIRM, "firm", 0.8, 0.02, 1.0, _WONG, 0.05, 0.0, 1.0, 0.40),
        TerrainClass(ROCKY, "rocky", 0.7, 0.04, 1.6, _WONG, 0.06, 0.0, 1.0, 0.35),
        TerrainClass(SANDY, "sandy", 0.4, 0.12, 2.0, _BEKKER, 0.15, 0.10, 1.1, 0.35),
        TerrainClass(MUDDY, "muddy", 0.3, 0.15, 2.6, _BEKKER, 0.20, 0.13, 0.5, 0.20),
        TerrainClass(GRAVEL, "gravel", 0.6, 0.05, 1.3, _WONG, 0.08, 0.03, 0.8, 0.35),
        TerrainClass(GRASS, "grass", 0.5, 0.07, 1.2, _WONG, 0.10, 0.05, 0.7, 0.30),
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
