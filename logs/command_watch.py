"""What on a rover's own streams shows that a command from the ground took effect.

The ground station cannot see inside the rover; it can read what the rover publishes after acting on a
command (``navigator.onboard``):

- ``estop``: the safety supervisor latches the e-stop and publishes ``failsafe.estop`` on
  ``safety/events`` (then a ``mode`` event ``... -> ESTOP``); every ``navigator/state`` after it gives the
  speed-limit reason ``safety estop``. A rover already e-stopped publishes no new event, but its state
  still says so, which is the effect the operator asked for.
- ``resume``: ``cleared.estop`` on ``safety/events`` when an e-stop was latched; ``navigator/state``'s
  reason then stops being ``safety estop`` (it may name another hold: the outcome says which).
- ``goal X Y``: the rover first accepts the goal (a ``goal`` event ``new goal (X, Y)``; a goal outside the
  geofence is refused with a ``goal_rejected`` event naming it instead), then plans. Acceptance alone does
  not confirm: a goal off the map or inside a rock is accepted and then proved unreachable. What decides
  is the plan's outcome on ``navigator/state`` with goal (X, Y): ``DRIVING`` (or ``ARRIVED``, ``BLOCKED``,
  ``YIELDING``, ``RECOVERING``: it has a path) confirms, ``NO_PATH`` refuses, with the rover's reason from its
  ``guidance.no_path`` event. Before the acceptance is seen, a state that already shows goal (X, Y) in
  ``DRIVING`` may be the answer to an earlier, identical goal, so it decides nothing.

Each sample is judged by what it shows: a state published before the rover read the command confirms
it only if it already shows the effect (a rover e-stopped before), so a stale "driving" never confirms an
e-stop.
"""

from __future__ import annotations

import enum
import math
import threading
from dataclasses import dataclass
from typing import Any

from logs import topics
from logs.commands import CommandKind
from logs.telemetry import TelemetrySample

# The navigator's speed-limit reason while the supervisor is in ESTOP (``navigator.onboard._limit_reason``:
# ``f"safety {mode.value.lower()}"``); tests/logs/test_telemetry_send_contract.py holds the two together.
ESTOP_SPEED_LIMIT_REASON = "safety estop"
ESTOP_FAILSAFE = "failsafe.estop"
ESTOP_CLEARED = "cleared.estop"
MODE_EVENT = "mode"
GOAL_REJECTED = "goal_rejected"
GOAL_ACCEPTED = "goal"  # navigator.onboard.OnboardStack.set_goal: "new goal (X, Y)"
NO_PATH_EVENT = "guidance.no_path"  # navigator.route_guidance.RouteGuidance.tick: the planner's reason
# Guidance's modes (navigator.route_guidance.Mode) as navigator/state names them.
GOAL_PENDING_MODES = frozenset({"WAITING_ESTIMATE", "PLANNING"})  # accepted, no plan outcome yet
# A path to the goal exists (RECOVERING: it had one, and plans again once backed out).
GOAL_PLANNED_MODES = frozenset({"DRIVING", "ARRIVED", "BLOCKED", "YIELDING", "RECOVERING"})
NO_PATH_MODE = "NO_PATH"
# JSON carries a float exactly; the tolerance only forgives a rover that rounds its goal to a micrometre.
GOAL_TOLERANCE_M = 1e-6
WATCHED_TOPICS = (topics.SAFETY_EVENTS, topics.NAVIGATOR_STATE)


class Verdict(enum.StrEnum):
    CONFIRMED = "confirmed"
    REJECTED = "rejected"  # the rover heard the command and refused it
    NO_LISTENER = "no listener"  # nothing subscribed to the command key: not sent
    UNCONFIRMED = "unconfirmed"  # sent, but the rover's streams did not show its effect in time


@dataclass(frozen=True)
class SendOutcome:
    verdict: Verdict
    detail: str
    # NO_LISTENER only: Zenoh peers and routers the station was connected to (0: it reached nobody).
    connections: int | None = None

    @property
    def confirmed(self) -> bool:
        return self.verdict is Verdict.CONFIRMED


def expected_effect(kind: CommandKind, x: float | None = None, y: float | None = None) -> str:
    """What the operator should see for ``kind``, in words for an error message."""
    if kind == "estop":
        return (
            f"the ESTOP transition ({ESTOP_FAILSAFE} on {topics.SAFETY_EVENTS}, "
            f"or {topics.NAVIGATOR_STATE} in '{ESTOP_SPEED_LIMIT_REASON}')"
        )
    if kind == "resume":
        return (
            f"the mode leaving ESTOP ({ESTOP_CLEARED} on {topics.SAFETY_EVENTS}, "
            f"or {topics.NAVIGATOR_STATE} no longer in '{ESTOP_SPEED_LIMIT_REASON}')"
        )
    return (
        f"{topics.NAVIGATOR_STATE}'s goal becoming ({x:.2f}, {y:.2f}) and its plan's outcome "
        f"(mode DRIVING, or NO_PATH with the reason)"
    )


class CommandWatch:
    """Judges the rover's samples for one command; the first verdict wins. Thread-safe: zenoh delivers
    on its own threads. ``decided`` is set once ``outcome`` holds a verdict."""

    def __init__(self, kind: CommandKind, x: float | None = None, y: float | None = None) -> None:
        if kind == "goal" and (x is None or y is None):
            raise ValueError("a goal needs x and y (ENU metres)")
        self._kind = kind
        self._x = x
        self._y = y
        self._lock = threading.Lock()
        self.decided = threading.Event()
        # Set once nothing more is expected: the verdict, and for a NO_PATH state the planner's reason
        # (its event travels on another topic and may arrive after the state).
        self.complete = threading.Event()
        self._no_path_without_reason = False
        self.outcome: SendOutcome | None = None
        self.seen: dict[str, int] = dict.fromkeys(WATCHED_TOPICS, 0)
        self._last_state: dict[str, Any] | None = None
        # Goal only: the rover has taken this goal (its event, or a state that can only follow it).
        self._accepted = False
        self._other_goal_seen = False  # a state with another goal: a later one with ours is fresh

    @property
    def accepted(self) -> bool:
        """Goal only: the rover took the goal; the plan's outcome may still be pending."""
        with self._lock:
            return self._accepted

    def observe(self, sample: TelemetrySample) -> None:
        if sample.topic not in self.seen:
            return
        with self._lock:
            self.seen[sample.topic] += 1
            if sample.topic == topics.NAVIGATOR_STATE:
                self._last_state = sample.message
            if self.outcome is not None:
                self._add_reason(sample)
                return
            outcome = self._judge(sample.topic, sample.message)
            if outcome is not None:
                self.outcome = outcome
                self.decided.set()
                if not self._awaiting_reason:
                    self.complete.set()

    @property
    def _awaiting_reason(self) -> bool:
        return self._no_path_without_reason and self.outcome is not None

    def _add_reason(self, sample: TelemetrySample) -> None:
        """A NO_PATH state that came before the planner's reason: the reason, when it comes, is added."""
        if not self._awaiting_reason or sample.topic != topics.SAFETY_EVENTS:
            return
        if sample.message.get("kind") != NO_PATH_EVENT:
            return
        reason = f"{topics.SAFETY_EVENTS} {NO_PATH_EVENT}: {sample.message.get('detail', '')}"
        self.outcome = SendOutcome(
            Verdict.REJECTED, f"the rover accepted the goal but cannot reach it: {reason}"
        )
        self._no_path_without_reason = False
        self.complete.set()

    def _judge(self, topic: str, message: dict[str, Any]) -> SendOutcome | None:
        if topic == topics.SAFETY_EVENTS:
            return self._judge_event(str(message.get("kind")), str(message.get("detail", "")))
        return self._judge_state(message)

    def _judge_event(self, kind: str, detail: str) -> SendOutcome | None:
        seen = f"{topics.SAFETY_EVENTS} {kind}: {detail}"
        if self._kind == "estop" and (
            kind == ESTOP_FAILSAFE or (kind == MODE_EVENT and "-> ESTOP" in detail)
        ):
            return SendOutcome(Verdict.CONFIRMED, seen)
        if self._kind == "resume" and (
            kind == ESTOP_CLEARED or (kind == MODE_EVENT and detail.startswith("ESTOP ->"))
        ):
            return SendOutcome(Verdict.CONFIRMED, seen)
        # The rover names a refused goal to two decimals (navigator.onboard.OnboardStack.set_goal).
        if self._kind != "goal":
            return None
        ours = f"({self._x:.2f}, {self._y:.2f})" in detail
        if kind == GOAL_REJECTED and ours:
            return SendOutcome(Verdict.REJECTED, f"the rover refused the goal: {seen}")
        if kind == GOAL_ACCEPTED and ours:
            self._accepted = True
        elif kind == NO_PATH_EVENT and self._accepted:
            return SendOutcome(Verdict.REJECTED, f"the rover accepted the goal but cannot reach it: {seen}")
        return None

    def _judge_state(self, state: dict[str, Any]) -> SendOutcome | None:
        reason = state.get("speed_limit_reason")
        seen = f"{topics.NAVIGATOR_STATE}: {describe_state(state)}"
        if self._kind == "estop" and reason == ESTOP_SPEED_LIMIT_REASON:
            return SendOutcome(Verdict.CONFIRMED, seen)
        if self._kind == "resume" and isinstance(reason, str) and reason != ESTOP_SPEED_LIMIT_REASON:
            return SendOutcome(Verdict.CONFIRMED, seen)
        if self._kind == "goal":
            return self._judge_goal_state(state, seen)
        return None

    def _judge_goal_state(self, state: dict[str, Any], seen: str) -> SendOutcome | None:
        if not _goal_is(state, self._x, self._y):
            self._other_goal_seen = True
            return None
        mode = state.get("mode")
        if mode in GOAL_PENDING_MODES or self._other_goal_seen:
            self._accepted = True
        if not self._accepted or mode in GOAL_PENDING_MODES:
            return None
        if mode in GOAL_PLANNED_MODES:
            return SendOutcome(Verdict.CONFIRMED, seen)
        if mode == NO_PATH_MODE:
            # The reason comes on guidance.no_path: another topic, which may arrive after this state (it
            # is added then, see _add_reason) or not at all (a lost or thinned event).
            self._no_path_without_reason = True
            why = f"the rover accepted the goal but found no path to it: {seen}"
            return SendOutcome(Verdict.REJECTED, why)
        return None

    def what_was_seen(self) -> str:
        """The samples heard so far, for a message that says why nothing confirmed the command."""
        with self._lock:
            counts = ", ".join(f"{n} on {topic}" for topic, n in self.seen.items())
            last = self._last_state
        if not any(self.seen.values()):
            return f"heard nothing on {' or '.join(WATCHED_TOPICS)}: is the rover's onboard loop running?"
        if last is None:
            return f"heard {counts}"
        return f"heard {counts}; the last {topics.NAVIGATOR_STATE}: {describe_state(last)}"


def describe_state(state: dict[str, Any]) -> str:
    goal = _goal_of(state)
    where = "none" if goal is None else f"({goal[0]:.2f}, {goal[1]:.2f})"
    safety = state.get("safety_mode")
    supervisor = "" if safety is None else f", safety {safety}"
    return (
        f"mode {state.get('mode')}{supervisor}, goal {where}, "
        f"speed limit reason {state.get('speed_limit_reason')!r}"
    )


def _goal_is(state: dict[str, Any], x: float | None, y: float | None) -> bool:
    goal = _goal_of(state)
    if goal is None or x is None or y is None:
        return False
    return math.isclose(goal[0], x, abs_tol=GOAL_TOLERANCE_M) and math.isclose(
        goal[1], y, abs_tol=GOAL_TOLERANCE_M
    )


def _goal_of(state: dict[str, Any]) -> tuple[float, float] | None:
    """The state's goal; None when it has none (the rover sends NaN, i.e. null, then)."""
    goal = state.get("goal")
    if not isinstance(goal, dict):
        return None
    gx, gy = _finite(goal.get("x")), _finite(goal.get("y"))
    return None if gx is None or gy is None else (gx, gy)


def _finite(value: object) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)
