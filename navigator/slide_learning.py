"""Learning from sliding sideways: a side slope the rover slides down tells it its ground's grip.

Driving along the contour of a slope, a rover whose wheels cannot hold it sideways slides downhill. The
planner keeps every class below ``atan(mu - crr)`` less its climb margin in any direction
(``navigator.costs``), and that is below the slope a driving rover slides on (docs/physics.md): a rover
routed across a slope it slides on was routed by a belief of its class's ``friction_mu`` that was too high.
It learns the class as ``navigator.climb_learning`` does from a climb it dug in on, the roll in place of
the pitch (``learned_class``: the planner then stops ``LEARN_BELOW_RAD`` below that roll, only ever lower).

What a real rover has to see it: the GPS's velocity over the ground (GPS_RAW_INT ``vel`` and ``cog``)
against the estimated heading. Its part across the heading is the slide; averaged over ``WINDOW_NS`` it must
be at least ``SLIDE_MPS``, downhill (the side the map's roll falls to), while the rover drives at
``MIN_SPEED_MPS`` or more (the course of a slow or standing rover says little), with the AHRS roll within
``ROLL_AGREEMENT_RAD`` of the map's rolls under its axles (so the slope is the ground's, one the map
shows), one class under all three axles and no tip-over margin breached. Any tick that fails one of these
starts the window again (``SlideWatch``): a slide is learned from only when every tick of a whole window
shows it.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from logs.clock import NS_PER_S
from navigator.climb_learning import LEARN_BELOW_RAD
from navigator.terrain_classes import TerrainClass
from navigator.vehicle import max_climbable_slope_rad

# Long enough that the across-heading velocity's errors (heading estimate, GPS latency in turns, cm/s and
# centidegree quantisation) average out; short enough to learn before a slide has carried the rover far.
WINDOW_NS = 2 * NS_PER_S
# The window's mean downhill velocity across the heading that counts as a slide. Without sliding, the
# simulated rover driving at speed shows per tick up to 0.15 m/s (rms 0.014-0.05) and over 2 s means up to
# 0.08 m/s (the maze's tight turns, the fix's latency against the heading now; 0.055 elsewhere; 0.5 m GPS
# noise, docs/planning.md "Learning from sliding sideways" has the runs): 0.15 is about twice the worst.
SLIDE_MPS = 0.15
# The estimated speed below which the course over ground is not trusted (and the rover is not "driving").
MIN_SPEED_MPS = 0.3
# The AHRS's roll and the map's must agree this well: else the roll is not the ground's.
ROLL_AGREEMENT_RAD = math.radians(2.0)
# The newest GPS fix's velocity stands for this long (5 Hz fixes: a tick without a fresh one ends the window).
GPS_FRESH_NS = NS_PER_S // 2
# A tick turning faster than this is no evidence: the fix's course lags the heading by its latency (a GPS
# delayed 0.5 s in a 0.4 rad/s turn at 1 m/s shows 0.2 m/s across the heading, past SLIDE_MPS).
MAX_YAW_RATE_RPS = 0.15
# Ticks further apart than this are not one unbroken window (a tick the watch was not fed, a stalled loop):
# the window starts again rather than read one late tick as 2 s of evidence.
MAX_GAP_NS = NS_PER_S // 10


def across_heading_mps(ground_speed_mps: float, course_rad: float, heading_rad: float) -> float:
    """The ground velocity's part across the heading, positive to the left (m/s). ``course_rad``: the
    course over ground in the ENU convention (counter-clockwise from east, as ``GpsFix.course_rad``)."""
    return ground_speed_mps * math.sin(course_rad - heading_rad)


def downhill_mps(across_left_mps: float, roll_rad: float) -> float:
    """``across_left_mps`` toward the side the roll falls to: positive downhill. A positive roll (the
    ground rising to the left, ``TerrainMap.tilt_at``) has its downhill to the right; level ground none."""
    if roll_rad == 0.0:
        return 0.0
    return -across_left_mps if roll_rad > 0.0 else across_left_mps


def trustworthy_roll(ahrs_roll_rad: float, map_rolls_rad: tuple[float, ...]) -> bool:
    """Whether the AHRS's roll is the map's slope under the rover: within ``ROLL_AGREEMENT_RAD`` of the
    span of the map's rolls under its axles (rear, centre, front), and steep enough to learn from (a roll
    within ``LEARN_BELOW_RAD`` of level leaves ``learned_class`` nothing to learn)."""
    low, high = min(map_rolls_rad), max(map_rolls_rad)
    agrees = low - ROLL_AGREEMENT_RAD <= ahrs_roll_rad <= high + ROLL_AGREEMENT_RAD
    return agrees and abs(ahrs_roll_rad) > LEARN_BELOW_RAD


def slide_evidence(
    speed_mps: float,
    yaw_rate_rps: float,
    heading_std_rad: float,
    tipping: bool,
    gps_age_ns: int,
    ground_velocity: tuple[float, float],
    heading_rad: float,
    ahrs_roll_rad: float,
    map_rolls_rad: tuple[float, ...],
    classes: tuple[int, ...],
) -> SlideSample | None:
    """One driving tick's evidence of a slide, or None where the tick cannot show one it could trust.

    ``speed_mps``: the estimated speed along the heading; ``yaw_rate_rps``: the estimated yaw rate (a tick
    turning faster than ``MAX_YAW_RATE_RPS`` is none); ``heading_std_rad``: the heading's standard
    deviation: a tick whose speed times the sine of twice it reaches half of ``SLIDE_MPS`` is none (a heading
    error of ``d`` reads as ``v sin d`` across it); ``tipping``: a tip-over margin is breached;
    ``gps_age_ns``: how old the newest fix is; ``ground_velocity``: its speed (m/s) and ENU course (rad)
    over ground; ``heading_rad``: the estimated heading; ``map_rolls_rad`` and ``classes``: the map's
    roll and class under the rover's axles (rear, centre, front). The sample's ``downhill_mps`` is signed
    (negative: uphill), so a window of drift uphill averages below any threshold."""
    if tipping or abs(speed_mps) < MIN_SPEED_MPS or gps_age_ns > GPS_FRESH_NS:
        return None
    if abs(yaw_rate_rps) > MAX_YAW_RATE_RPS:
        return None
    if abs(speed_mps) * math.sin(min(2.0 * heading_std_rad, 0.5 * math.pi)) >= 0.5 * SLIDE_MPS:
        return None
    if len(set(classes)) != 1 or not trustworthy_roll(ahrs_roll_rad, map_rolls_rad):
        return None
    across = across_heading_mps(ground_velocity[0], ground_velocity[1], heading_rad)
    return SlideSample(downhill_mps(across, ahrs_roll_rad), ahrs_roll_rad, classes[0])


@dataclass(frozen=True)
class SlideSample:
    """One tick's evidence: the downhill velocity across the heading (m/s), the AHRS roll (rad) and the
    class under the rover."""

    downhill_mps: float
    roll_rad: float
    class_id: int


@dataclass(frozen=True)
class Slide:
    """A whole window of sliding: its mean downhill speed across the heading (m/s), its mean roll (rad,
    signed as the AHRS's) and the class it slid on."""

    downhill_mps: float
    roll_rad: float
    class_id: int


def routed_across(slide: Slide, believed: TerrainClass, climb_margin_rad: float) -> bool:
    """Whether the slope slid on is one the planner, believing ``believed``, routes across: its roll within
    the class's limit (``atan(mu - crr)`` less the margin). On a steeper one the belief already keeps routes
    off it (a rover leaving the slope after a learning, pushed onto it): its slide says nothing new."""
    limit = max_climbable_slope_rad(believed.friction_mu, believed.rolling_resistance, climb_margin_rad)
    return abs(slide.roll_rad) <= limit


class SlideWatch:
    """Fed every control tick with that tick's ``SlideSample`` (None: this tick shows no trustworthy
    slide evidence: not driving at speed, no fresh GPS, the roll not the map's, two classes, tipping), it
    reports a ``Slide`` once ``window_ns`` of unbroken evidence on one class averages at least
    ``threshold_mps`` downhill; then it starts again. Driven by the tick's time only (lockstep: the same
    ticks give the same answer)."""

    def __init__(self, window_ns: int = WINDOW_NS, threshold_mps: float = SLIDE_MPS) -> None:
        if window_ns <= 0 or not (math.isfinite(threshold_mps) and threshold_mps > 0.0):
            raise ValueError(
                f"SlideWatch needs a window > 0 ns and a finite threshold > 0 m/s, got {window_ns} ns, "
                f"{threshold_mps} m/s"
            )
        self._window_ns = window_ns
        self._threshold = threshold_mps
        self._since_ns: int | None = None  # the first tick of the unbroken evidence
        self._samples: deque[tuple[int, SlideSample]] = deque()

    def reset(self) -> None:
        self._since_ns = None
        self._samples.clear()

    def feed(self, now_ns: int, sample: SlideSample | None) -> Slide | None:
        samples = self._samples
        if samples and now_ns - samples[-1][0] > MAX_GAP_NS:
            self.reset()  # not fed for a while: what came before is not this window's
        if sample is None or (samples and samples[-1][1].class_id != sample.class_id):
            self.reset()
            if sample is None:
                return None
        if self._since_ns is None:
            self._since_ns = now_ns
        samples.append((now_ns, sample))
        oldest = now_ns - self._window_ns
        while samples[0][0] < oldest:
            samples.popleft()
        if now_ns - self._since_ns < self._window_ns:
            return None
        count = len(samples)
        mean_downhill = math.fsum(s.downhill_mps for _t, s in samples) / count
        if mean_downhill < self._threshold:
            return None
        slide = Slide(mean_downhill, math.fsum(s.roll_rad for _t, s in samples) / count, sample.class_id)
        self.reset()
        return slide
