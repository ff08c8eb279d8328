"""Estimator health: named flags with the thresholds they were judged against, for the safety supervisor."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class EstimatorHealth:
    """What the estimator can vouch for right now.

    ``healthy`` is what the navigator drives on: initialised, heading known, and both position and heading
    std inside their limits. ``gps_fresh`` and ``odometry_trusted`` are reported separately: dead
    reckoning through a GPS dropout or over spinning wheels is fine until the covariance says otherwise,
    but a supervisor may want to slow down meanwhile.

    Attributes
    ----------
    initialised, heading_known : bool
        A first fix was fused; the heading was given or learnt (until then yaw is a placeholder).
    position_std_m, position_std_limit_m : float
        Worst-direction position std (m) and the limit it must stay below (m); inf before initialisation.
    heading_std_deg, heading_std_limit_deg : float
        Heading std (degrees) and its limit.
    gps_age_s, gps_timeout_s : float
        Seconds since the last accepted GPS fix (inf if none) and the age beyond which GPS counts as lost.
    odometry_trusted : bool
        False while the wheels are judged to spin in place (their speed is then not fused).
    """

    initialised: bool
    heading_known: bool
    position_std_m: float
    position_std_limit_m: float
    heading_std_deg: float
    heading_std_limit_deg: float
    gps_age_s: float
    gps_timeout_s: float
    odometry_trusted: bool

    @property
    def position_ok(self) -> bool:
        return self.initialised and self.position_std_m < self.position_std_limit_m

    @property
    def heading_ok(self) -> bool:
        return self.initialised and self.heading_known and self.heading_std_deg < self.heading_std_limit_deg

    @property
    def gps_fresh(self) -> bool:
        return self.gps_age_s <= self.gps_timeout_s

    @property
    def healthy(self) -> bool:
        return self.position_ok and self.heading_ok
