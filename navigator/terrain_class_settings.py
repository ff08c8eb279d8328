"""``[terrain_classes.<name>]`` tables: a team's own figures for a terrain class, over the built-in table.

``navigator.terrain_classes.TERRAIN_CLASSES`` is the default. A scenario's tables replace what the true
world is made of (the simulator's wheel-ground laws: every field but ``cost_factor``); a rover config's
replace what the planner and guidance believe (every field, ``cost_factor`` included). A field not written
keeps the table's value, so ``[terrain_classes.sandy] friction_mu = 0.3`` changes one number. Ids and
names are fixed: maps refer to classes by id, so a table can only retune a class, never add one.

The overrides are kept as written (class name -> field -> value): that is what a recording keeps, so a
report shows where a trial's world or beliefs left the built-in table (``overrides_flat``).
"""

from __future__ import annotations

import json
from collections.abc import Mapping

from logs.settings import Table, did_you_mean
from navigator.errors import TerrainError
from navigator.terrain_classes import TERRAIN_CLASSES, TerrainClass

TABLE_KEY = "terrain_classes"
# The simulator's wheel-ground parameters, in the order docs/physics.md's table lists them.
PHYSICS_FIELDS = (
    "friction_mu",
    "rolling_resistance",
    "slip_constant",
    "sinkage_resistance",
    "sinkage_exponent",
    "lateral_resistance",
)
PLANNER_FIELDS = ("cost_factor",)
# The planner's unit is firm ground (cost 1 per metre): a class is never cheaper than that (docs/physics.md).
MIN_COST_FACTOR = 1.0

# Class name -> field -> value, as a file wrote them.
ClassOverrides = Mapping[str, Mapping[str, float]]
# A scenario's refused keys and why: the cost per metre is a belief of the planner's, not part of the world.
SCENARIO_REFUSALS = {
    "cost_factor": "the planner's cost per metre is its belief, not part of the world: set it in the rover "
    "config's [terrain_classes.<name>] (in a campaign, a variant's overrides.terrain_classes.<name>)"
}


def overrides_from_table(root: Table, fields: tuple[str, ...], refused: Mapping[str, str]) -> ClassOverrides:
    """The ``[terrain_classes.<name>]`` tables of ``root`` ({} when it has none), each checked by building
    its class: ``fields`` are the keys a class table takes; a key in ``refused`` is refused with its reason
    (a scenario's ``cost_factor``: the planner's, not the world's). ``ConfigError`` naming the key path on an
    unknown class, a refused or unknown key, a value that is no finite number, or one the class refuses."""
    if not root.has(TABLE_KEY):
        return {}
    classes = root.table(TABLE_KEY)
    known = {c.name: c for c in TERRAIN_CLASSES.values()}
    overrides: dict[str, dict[str, float]] = {}
    for name in list(classes.keys()):
        if name not in known:
            raise classes.error(
                name,
                f"unknown terrain class ({did_you_mean(name, list(known))}known classes: "
                f"{', '.join(known)}); a class's id and name are fixed, only its figures can be set",
            )
        table = classes.table(name)
        written = set(table.keys())  # not table.has(): a refused key must not count as a known one
        for key, reason in refused.items():
            if key in written:
                raise table.error(key, reason)
        values = {key: table.number(key) for key in fields if table.has(key)}
        table.finish()
        _check_class(table, known[name], values)
        overrides[name] = values
    classes.finish()
    return overrides


def _check_class(table: Table, base: TerrainClass, values: dict[str, float]) -> None:
    """``ConfigError`` when the class check (``TerrainClass.__post_init__``) refuses the class, under the
    key to blame: the written key whose built-in value passes the check, else the first written key the
    check's message names, else the class table itself."""
    if "cost_factor" in values and values["cost_factor"] < MIN_COST_FACTOR:
        raise table.error(
            "cost_factor",
            f"must be >= {MIN_COST_FACTOR} (firm ground's: the planner's cost per metre is relative to it), "
            f"got {values['cost_factor']}",
        )
    problem = _refusal(base, values)
    if problem is None:
        return
    blamed = [key for key in values if _refusal(base, {k: v for k, v in values.items() if k != key}) is None]
    named = sorted((problem.find(key), key) for key in values if key in problem)
    kept = [
        f"{key} = {getattr(base, key)!r}" for key in PHYSICS_FIELDS if key in problem and key not in values
    ]
    if kept:
        problem += f" (the built-in table's {', '.join(kept)})"
    raise table.error(blamed[0] if blamed else named[0][1] if named else "", problem)


def _refusal(base: TerrainClass, values: Mapping[str, float]) -> str | None:
    """Why the class check refuses ``base`` with ``values`` set, or None when it takes it."""
    try:
        retuned(base, values)
    except TerrainError as err:
        return str(err)
    return None


def override_refusal(class_name: str, field: str, value: float) -> str | None:
    """Why a rover config's ``[terrain_classes.<class_name>] <field> = <value>`` would be refused (an unknown
    class or field, a value the class check refuses), or None when the config takes it: for tables written
    by a tool (``rover logs learned``) from recordings another build may have made."""
    known = {c.name: c for c in TERRAIN_CLASSES.values()}
    if class_name not in known:
        return f"no terrain class {class_name!r} (known: {', '.join(known)})"
    fields = PHYSICS_FIELDS + PLANNER_FIELDS
    if field not in fields:
        return f"{field!r} is no field of a terrain class table (fields: {', '.join(fields)})"
    return _refusal(known[class_name], {field: value})


def with_overrides(
    overrides: ClassOverrides, base: Mapping[int, TerrainClass] = TERRAIN_CLASSES
) -> dict[int, TerrainClass]:
    """``base`` with ``overrides`` applied (checked ones: ``overrides_from_table``'s), as a new dict."""
    if not overrides:
        return dict(base)
    by_name = {c.name: c for c in base.values()}
    changed = {by_name[name].id: retuned(by_name[name], values) for name, values in overrides.items()}
    return {class_id: changed.get(class_id, c) for class_id, c in base.items()}


def retuned(base: TerrainClass, values: Mapping[str, float]) -> TerrainClass:
    """``base`` with the fields ``values`` names set (``TerrainError`` if the class check refuses them); its
    source says which figures are no longer the cited ones."""
    if not values:
        return base
    return TerrainClass(
        base.id,
        base.name,
        friction_mu=values.get("friction_mu", base.friction_mu),
        rolling_resistance=values.get("rolling_resistance", base.rolling_resistance),
        cost_factor=values.get("cost_factor", base.cost_factor),
        source=f"{', '.join(values)} set in [{TABLE_KEY}.{base.name}]; the rest: {base.source}",
        slip_constant=values.get("slip_constant", base.slip_constant),
        sinkage_resistance=values.get("sinkage_resistance", base.sinkage_resistance),
        sinkage_exponent=values.get("sinkage_exponent", base.sinkage_exponent),
        lateral_resistance=values.get("lateral_resistance", base.lateral_resistance),
    )


def overrides_flat(overrides: ClassOverrides) -> dict[str, str]:
    """``terrain_classes.sandy.friction_mu`` -> ``"0.3"``: the overrides as metadata keys, spelled as the
    rover config's ``config`` record spells its values (JSON), so the two records read alike."""
    return {
        f"{TABLE_KEY}.{name}.{key}": json.dumps(value)
        for name, values in overrides.items()
        for key, value in values.items()
    }
