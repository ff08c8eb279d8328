import pytest

from estimator.config import EstimatorConfig
from estimator.errors import EstimatorSetupError
from estimator.geodesy import Datum
from logs.settings import ConfigError, Table, parse_toml


def _table(text: str) -> Table:
    return parse_toml(text, "rover.toml").table("estimator", optional=True)


def test_empty_table_gives_defaults():
    assert EstimatorConfig.from_table(_table("")) == EstimatorConfig()


def test_values_and_datum_are_read():
    config = EstimatorConfig.from_table(
        _table("[estimator]\ngps_noise_m = 1.5\ndatum_lat_deg = 47.0\ndatum_lon_deg = 8\n")
    )
    assert config.gps_noise_m == 1.5
    assert config.datum == Datum(47.0, 8.0, 0.0)


def test_unknown_key_is_an_error_naming_it():
    with pytest.raises(ConfigError, match=r"estimator\.gps_nosie_m"):
        EstimatorConfig.from_table(_table("[estimator]\ngps_nosie_m = 1.0\n"))


@pytest.mark.parametrize(
    ("line", "key"),
    [
        ("gyro_noise_rps = 0.0", "estimator.gyro_noise_rps"),
        ("gate_probability = 1.0", "estimator.gate_probability"),
        ("track_m = 'wide'", "estimator.track_m"),
        ("datum_lat_deg = 47.0", "estimator.datum_lat_deg"),
        ("gps_reset_after_s = 0.0", "estimator.gps_reset_after_s"),
        ("gps_latency_s = -0.1", "estimator.gps_latency_s"),
    ],
)
def test_bad_values_name_file_and_key(line, key):
    with pytest.raises(ConfigError) as info:
        EstimatorConfig.from_table(_table(f"[estimator]\n{line}\n"))
    assert info.value.source == "rover.toml"
    assert info.value.key == key


def test_direct_construction_is_validated_too():
    with pytest.raises(EstimatorSetupError, match="skid_factor"):
        EstimatorConfig(skid_factor=-1.0)
