"""First heading from motion, for a rover that starts with no idea which way it faces.

An EKF linearised around a heading that may be off by up to pi can settle on a wrong heading with a
falsely small covariance. So, while the heading is unknown, we also dead-reckon in the frame of an *anchor*
GPS fix: the filter's speed and yaw rate (measured well by odometry and gyro even while the absolute heading
is unknown) integrate to a displacement ``s`` expressed in the anchor's body frame. GPS gives the same
displacement ``d`` in ENU. The two differ by a rotation through the anchor heading, so
``yaw_anchor = arg(d) - arg(s)`` and the heading now is ``yaw_anchor + turned``. This holds for any path
shape, including reversing (negative speed) and turns.

Without odometry the path is unknown; we then assume forward driving along a circular arc, whose chord
points along the anchor heading plus half the angle turned.
"""

from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

from estimator.angles import wrap_angle

# Dead-reckoned and GPS displacement must agree in length within this ratio, else the rover was not
# driving the way its wheels say (pushed, sliding, GPS wandering) and the pair says nothing about heading.
_MAX_LENGTH_RATIO = 2.0
# Circling in a small loop may never reach the distance: after this many times the distance driven, take a
# guess from any displacement of at least _SHORT_CHORD_SHARE of it.
_LONG_PATH_FACTOR = 3.0
_SHORT_CHORD_SHARE = 0.4
# Dead reckoning drifts; beyond this many times the distance driven, start over from a fresh anchor.
_RESTART_PATH_FACTOR = 6.0
# Heading error of dead reckoning per metre driven per metre of displacement (rad): odometry yaw-rate error.
_DEAD_RECKONING_ERROR = 0.03
# Model error of the circular-arc assumption without odometry, as a share of the angle turned (rad/rad).
_ARC_ERROR_SHARE = 0.1


@dataclass(frozen=True)
class HeadingGuess:
    yaw_rad: float
    std_rad: float


class HeadingBootstrap:
    """Dead-reckons from an anchor fix and turns the match with GPS into a heading.

    Parameters
    ----------
    min_distance_m : float
        GPS displacement (m) wanted before a heading is guessed; larger means a better first guess.
    """

    def __init__(self, min_distance_m: float) -> None:
        if not math.isfinite(min_distance_m) or min_distance_m <= 0.0:
            raise ValueError(f"min_distance_m must be > 0, got {min_distance_m}")
        self._min_distance_m = min_distance_m
        self._anchor: tuple[float, float, float] | None = None  # x, y, std
        self._turned_rad = 0.0
        self._displacement = 0j  # dead-reckoned, in the anchor's body frame (x forward, y left), metres
        self._path_length_m = 0.0

    def add_motion(self, turned_rad: float, path_m: float) -> None:
        """Accumulate a step: yaw change (rad) and signed distance driven (m, < 0 reversing)."""
        mid_heading = self._turned_rad + 0.5 * turned_rad
        self._displacement += path_m * cmath.exp(1j * mid_heading)
        self._turned_rad += turned_rad
        self._path_length_m += abs(path_m)

    def on_fix(self, x_m: float, y_m: float, std_m: float, *, path_known: bool) -> HeadingGuess | None:
        """Offer a GPS fix (ENU m, per-axis std m); returns a heading once the rover has moved far enough.

        ``path_known`` says whether ``add_motion`` was given distances from odometry.
        """
        if self._anchor is None:
            self._set_anchor(x_m, y_m, std_m)
            return None
        ax, ay, anchor_std = self._anchor
        gps = complex(x_m - ax, y_m - ay)
        distance = abs(gps)
        wanted = self._min_distance_m
        if path_known and self._path_length_m > _RESTART_PATH_FACTOR * wanted:
            self._set_anchor(x_m, y_m, std_m)
            return None
        long_path = path_known and self._path_length_m > _LONG_PATH_FACTOR * wanted
        if distance < wanted and not (long_path and distance >= _SHORT_CHORD_SHARE * wanted):
            return None
        gps_error = math.hypot(anchor_std, std_m) / distance
        if not path_known:
            yaw = math.atan2(gps.imag, gps.real) + 0.5 * self._turned_rad
            return HeadingGuess(wrap_angle(yaw), gps_error + _ARC_ERROR_SHARE * abs(self._turned_rad))
        reckoned = abs(self._displacement)
        if not 1.0 / _MAX_LENGTH_RATIO <= reckoned / distance <= _MAX_LENGTH_RATIO:
            self._set_anchor(x_m, y_m, std_m)
            return None
        anchor_yaw = cmath.phase(gps) - cmath.phase(self._displacement)
        std = gps_error + _DEAD_RECKONING_ERROR * self._path_length_m / distance
        return HeadingGuess(wrap_angle(anchor_yaw + self._turned_rad), std)

    def _set_anchor(self, x_m: float, y_m: float, std_m: float) -> None:
        self._anchor = (x_m, y_m, std_m)
        self._turned_rad = 0.0
        self._displacement = 0j
        self._path_length_m = 0.0
