import pytest

from navigator.errors import TerrainError
from navigator.terrain_classes import TERRAIN_CLASSES, class_by_name


def test_ids_names_and_values():
    names = {class_id: c.name for class_id, c in TERRAIN_CLASSES.items()}
    assert names == {0: "firm", 1: "rocky", 2: "sandy", 3: "muddy", 4: "gravel", 5: "grass"}
    for terrain_class in TERRAIN_CLASSES.values():
        assert 0.0 < terrain_class.rolling_resistance < terrain_class.friction_mu <= 1.0
        assert terrain_class.cost_factor >= 1.0
        assert terrain_class.source


def test_class_by_name():
    assert class_by_name("Sandy").id == 2
    with pytest.raises(TerrainError, match="firm, rocky, sandy, muddy, gravel, grass"):
        class_by_name("lava")
