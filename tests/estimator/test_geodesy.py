import math

import numpy as np
import pymap3d
import pytest

from estimator.errors import EstimatorSetupError
from estimator.geodesy import Datum, to_enu, to_geodetic

WGS84 = pymap3d.Ellipsoid.from_name("wgs84")


def test_round_trip_is_below_a_millimetre():
    rng = np.random.default_rng(7)
    datum = Datum(47.3769, 8.5417, 408.0)
    for e, n, u in rng.uniform(-2000.0, 2000.0, size=(50, 3)):
        lat, lon, alt = to_geodetic(datum, e, n, u)
        back = to_enu(datum, lat, lon, alt)
        assert math.dist(back, (e, n, u)) < 1e-3


def test_to_enu_gives_pymap3ds_own_floats():
    """``to_enu`` keeps the datum's ECEF position and rotation terms between calls: the result must still
    be, to the bit, what pymap3d.geodetic2enu computes from scratch."""
    rng = np.random.default_rng(3)
    datums = (
        Datum(47.3769, 8.5417, 408.0),
        Datum(-33.0, 151.0, 0.0),
        Datum(47.3769, 8.5417, 1.0),
        Datum(0.01, -179.97, -20.0),  # every sign of the sines and cosines, near the equator and date line
        Datum(-89.5, -95.0, 2800.0),
    )
    for datum in datums:
        for lat, lon, alt in zip(
            datum.lat_deg + rng.uniform(-0.02, 0.02, 200),
            datum.lon_deg + rng.uniform(-0.02, 0.02, 200),
            datum.alt_m + rng.uniform(-50.0, 50.0, 200),
            strict=True,
        ):
            expected = pymap3d.geodetic2enu(
                lat, lon, alt, datum.lat_deg, datum.lon_deg, datum.alt_m, ell=WGS84, deg=True
            )
            assert to_enu(datum, lat, lon, alt) == tuple(float(v) for v in expected)


def test_north_and_east_point_the_right_way():
    datum = Datum(-33.0, 151.0, 0.0)
    east, north, _ = to_enu(datum, -33.0 + 1e-4, 151.0 + 1e-4, 0.0)
    assert north == pytest.approx(11.09, abs=0.05)  # 1e-4 deg of latitude is about 11.1 m
    assert east == pytest.approx(11.09 * math.cos(math.radians(33.0)), abs=0.05)


def test_datum_origin_is_zero():
    datum = Datum(10.0, 20.0, 5.0)
    assert to_enu(datum, 10.0, 20.0, 5.0) == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)


@pytest.mark.parametrize(
    ("lat", "lon", "alt", "field"),
    [
        (95.0, 0.0, 0.0, "datum_lat_deg"),
        (math.nan, 0.0, 0.0, "datum_lat_deg"),
        (0.0, 181.0, 0.0, "datum_lon_deg"),
        (0.0, 0.0, math.inf, "datum_alt_m"),
    ],
)
def test_bad_datum_is_refused_naming_the_field(lat, lon, alt, field):
    with pytest.raises(EstimatorSetupError) as info:
        Datum(lat, lon, alt)
    assert info.value.field == field
