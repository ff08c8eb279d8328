"""WGS84 geodetic <-> local ENU around a datum, via pymap3d.

The datum is the ENU origin: x east, y north, z up, in metres. All angles here are degrees, as GPS gives them.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pymap3d

from estimator.errors import EstimatorSetupError

# Named explicitly so a change of pymap3d's default can never move our origin.
_WGS84 = pymap3d.Ellipsoid.from_name("wgs84")

# Beyond these the "local tangent plane" stops being local; a datum there is a unit or sign mistake.
_MIN_ALT_M = -1_000.0
_MAX_ALT_M = 10_000.0


@dataclass(frozen=True)
class Datum:
    """Origin of the local ENU frame.

    Parameters
    ----------
    lat_deg : float
        Geodetic latitude, degrees, in [-90, 90].
    lon_deg : float
        Longitude, degrees, in [-180, 180].
    alt_m : float
        Height above the WGS84 ellipsoid, metres.
    """

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0

    def __post_init__(self) -> None:
        check_latitude("datum_lat_deg", self.lat_deg)
        check_longitude("datum_lon_deg", self.lon_deg)
        if not math.isfinite(self.alt_m) or not _MIN_ALT_M <= self.alt_m <= _MAX_ALT_M:
            raise EstimatorSetupError(
                "datum_alt_m", f"must be a finite height in [{_MIN_ALT_M}, {_MAX_ALT_M}] m, got {self.alt_m}"
            )


def check_latitude(field: str, lat_deg: float) -> None:
    if not math.isfinite(lat_deg) or not -90.0 <= lat_deg <= 90.0:
        raise EstimatorSetupError(field, f"latitude must be finite and in [-90, 90] degrees, got {lat_deg}")


def check_longitude(field: str, lon_deg: float) -> None:
    if not math.isfinite(lon_deg) or not -180.0 <= lon_deg <= 180.0:
        raise EstimatorSetupError(field, f"longitude must be finite, in [-180, 180] degrees, got {lon_deg}")


def to_enu(datum: Datum, lat_deg: float, lon_deg: float, alt_m: float) -> tuple[float, float, float]:
    """Geodetic point to (east, north, up) metres relative to ``datum``.

    ``pymap3d.geodetic2enu`` in its own steps (both points to ECEF, then the difference turned into the
    datum's ENU axes), with what depends on the datum alone (its ECEF position, the sines and cosines of
    its latitude and longitude) worked out once per datum rather than on every GPS fix: the same numbers
    through the same operations, so the same floats (tests/estimator/test_geodesy.py).
    """
    x, y, z = pymap3d.geodetic2ecef(lat_deg, lon_deg, alt_m, _WGS84, deg=True)
    frame = _frame_of(datum)
    u, v, w = float(x) - frame.x0, float(y) - frame.y0, float(z) - frame.z0
    # The ECEF offset rotated onto the datum's east / north / up axes, each product and sum in the order
    # pymap3d.uvw2enu takes them (Python floats and numpy float64 scalars round alike).
    t = frame.cos_lon * u + frame.sin_lon * v
    east = -frame.sin_lon * u + frame.cos_lon * v
    up = frame.cos_lat * t + frame.sin_lat * w
    north = -frame.sin_lat * t + frame.cos_lat * w
    return east, north, up


class _DatumFrame(NamedTuple):
    """A datum's ECEF position (m) and the sines and cosines of its latitude and longitude."""

    x0: float
    y0: float
    z0: float
    sin_lat: float
    cos_lat: float
    sin_lon: float
    cos_lon: float


@functools.lru_cache(maxsize=16)
def _frame_of(datum: Datum) -> _DatumFrame:
    """The datum's ECEF position and ENU rotation terms, once per datum (a rover has one; a test suite a few).

    numpy's ufuncs, as pymap3d applies them: pymap3d's own sines and cosines to the bit."""
    x0, y0, z0 = pymap3d.geodetic2ecef(datum.lat_deg, datum.lon_deg, datum.alt_m, _WGS84, deg=True)
    lat, lon = np.radians(datum.lat_deg), np.radians(datum.lon_deg)
    return _DatumFrame(
        float(x0), float(y0), float(z0),
        float(np.sin(lat)), float(np.cos(lat)), float(np.sin(lon)), float(np.cos(lon)),
    )  # fmt: skip


def to_geodetic(datum: Datum, east_m: float, north_m: float, up_m: float) -> tuple[float, float, float]:
    """(east, north, up) metres relative to ``datum`` to (lat_deg, lon_deg, alt_m)."""
    lat, lon, alt = pymap3d.enu2geodetic(
        east_m, north_m, up_m, datum.lat_deg, datum.lon_deg, datum.alt_m, ell=_WGS84, deg=True
    )
    return float(lat), float(lon), float(alt)
