"""What the onboard stack learns of its ground's traction, and how it tells it: one count for both ways.

Two things show the stack a class's ``friction_mu`` was believed too high: a climb it dug in on
(``navigator.climb_learning``, judged in ``OnboardStack._learn_from_digging_in`` when ``no_progress`` holds
it) and a side slope it slides down while driving (``navigator.slide_learning``, watched every tick here).
Either lowers the belief and plans the goal again. They share one count, ``MAX_LEARNINGS_PER_GOAL`` per goal
or resume: each is a belief of the ground under this goal's route lowered, and a route that keeps showing a
wrong belief after two lowerings is the operator's to judge, whichever way it showed. ``[planner]
learn_traction = false`` turns both off; neither learns in ``cost_mode = "classical"`` (it reads no class
figures: believing others would plan the same route).
"""

from __future__ import annotations

import math

from estimator.ekf import YAW
from estimator.pose import PoseEstimate
from firmware_bridge.mavlink_link import AttitudeSample
from logs import topics
from logs.clock import Clock
from logs.sink import MessageSink
from navigator.climb_learning import LEARN_BELOW_RAD, MAX_LEARNINGS_PER_GOAL, learned_class, with_learned
from navigator.config import RoverConfig
from navigator.route_guidance import Mode, RouteGuidance
from navigator.safety import TIP_OVER, EventSink, SafetySupervisor
from navigator.slide_learning import SlideSample, SlideWatch, routed_across, slide_evidence
from navigator.terrain import TerrainMap
from navigator.terrain_classes import TerrainClass


class TractionLearning:
    """The count of learnings for the goal in force, the slide watch, and what a learning does: believe
    the lower figure (a new planner on it), plan the goal again, tell it (``learned.terrain``) and record
    it (``navigator/learned``)."""

    def __init__(
        self,
        config: RoverConfig,
        clock: Clock,
        terrain: TerrainMap,
        guidance: RouteGuidance,
        safety: SafetySupervisor,
        sink: MessageSink,
        event: EventSink,
    ) -> None:
        self._on = config.planner.learn_traction and config.planner.cost_mode == "terrain"
        self._half_base_m = 0.5 * config.vehicle.wheelbase_m
        self._clock = clock
        self._terrain = terrain
        self._guidance = guidance
        self._safety = safety
        self._sink = sink
        self._event = event
        self._learned_at_goal = 0  # SafetySupervisor.goals_given when the count below began
        self._learnings = 0
        self.slides = SlideWatch()
        # The newest GPS fix's ground velocity: (receive time, speed over ground m/s, ENU course rad).
        self._gps_velocity: tuple[int, float, float] | None = None

    def may_learn(self) -> bool:
        """Learning is on, in terrain mode, and the count for this goal or resume is not spent."""
        if not self._on:
            return False
        goals_given = self._safety.goals_given
        if goals_given != self._learned_at_goal:
            self._learned_at_goal, self._learnings = goals_given, 0
        return self._learnings < MAX_LEARNINGS_PER_GOAL

    def gps_velocity(self, t_ns: int, speed_mps: float, course_rad: float) -> None:
        """A 3D fix's speed and course over ground (``GpsFix``); unknown ones (NaN) end what stood."""
        known = math.isfinite(speed_mps) and math.isfinite(course_rad)
        self._gps_velocity = (t_ns, speed_mps, course_rad) if known else None

    def watch_slide(
        self,
        now: int,
        pose: PoseEstimate | None,
        attitude: AttitudeSample | None,
        faults: tuple[str, ...],
        wheels_free: bool,
    ) -> None:
        """One tick of the slide watch (``navigator.slide_learning``); a whole window of sliding downhill
        on one class is learned from at once. ``wheels_free``: the supervisor let guidance's command through
        this tick (a held rover is not driving its route)."""
        sample = self._slide_sample(now, pose, attitude, faults, wheels_free) if self._on else None
        slide = self.slides.feed(now, sample)
        if slide is None or pose is None or not self.may_learn():
            return
        route = self._guidance
        believed, margin = route.classes.get(slide.class_id), route.planner.climb_margin_rad
        if believed is None or not routed_across(slide, believed, margin):
            return
        learned = learned_class(believed, slide.roll_rad, margin)
        if learned is None:
            return
        self.learn(
            pose, slide.class_id, believed, learned, slide.roll_rad, "slid sideways across", drive_on=True
        )

    def _slide_sample(
        self,
        now: int,
        pose: PoseEstimate | None,
        attitude: AttitudeSample | None,
        faults: tuple[str, ...],
        wheels_free: bool,
    ) -> SlideSample | None:
        gps = self._gps_velocity
        if attitude is None or abs(attitude.roll_rad) <= LEARN_BELOW_RAD:
            return None  # nearly every tick on level ground: no map look-up
        if pose is None or gps is None or not (wheels_free and pose.healthy and pose.heading_known):
            return None
        if self._guidance.mode is not Mode.DRIVING:
            return None
        gps_ns, ground_speed, course = gps
        axles = self._terrain.ground_under_axles(pose.x, pose.y, pose.yaw, self._half_base_m)
        if axles is None:
            return None  # off the map
        rear, centre, front = axles
        return slide_evidence(
            pose.speed,
            pose.yaw_rate,
            math.sqrt(max(float(pose.covariance[YAW, YAW]), 0.0)),
            TIP_OVER in faults,
            now - gps_ns,
            (ground_speed, course),
            pose.yaw,
            attitude.roll_rad,
            (rear.roll_rad, centre.roll_rad, front.roll_rad),
            (rear.terrain_class, centre.terrain_class, front.terrain_class),
        )

    def learn(
        self,
        pose: PoseEstimate,
        class_id: int,
        believed: TerrainClass,
        learned: TerrainClass,
        slope_rad: float,
        what: str,
        *,
        drive_on: bool,
    ) -> None:
        """Believe ``learned`` for ``class_id`` from now on and plan the goal again (``drive_on``: following
        the old path meanwhile, ``RouteGuidance.retune``); told as ``learned.terrain`` (``what`` the rover
        did on ``slope_rad``) and recorded on ``navigator/learned``. Counts one learning for the goal."""
        self._learnings += 1
        route = self._guidance
        margin = route.planner.climb_margin_rad
        route.retune(with_learned(route.classes, class_id, learned), drive_on=drive_on)
        plans_to = math.atan(learned.friction_mu - learned.rolling_resistance) - margin
        detail = (
            f"{what} {math.degrees(abs(slope_rad)):.1f} deg on {believed.name}: friction_mu "
            f"{learned.friction_mu:.2f} (believed {believed.friction_mu:.2f}), so it plans up to "
            f"{math.degrees(plans_to):.1f} deg there; planning again"
        )
        self._event("learned.terrain", "warning", detail)
        now = self._clock.now_ns()
        self._sink.publish(
            topics.NAVIGATOR_LEARNED,
            now,
            {
                "timestamp": topics.stamp(now),
                "class_name": believed.name,
                "class_id": class_id,
                "field": "friction_mu",
                "value": learned.friction_mu,
                "believed": believed.friction_mu,
                "slope_rad": abs(slope_rad),
                "plans_up_to_rad": plans_to,
                "x": pose.x,
                "y": pose.y,
            },
        )
