"""Send a command to a rover and wait until its own streams show the effect (the ground station's side).

Order matters: subscribe to the rover's ``safety/events`` and ``navigator/state`` first, so a fast rover's
answer cannot slip past; declare a publisher on the command key and wait for zenoh's *matching status*
(some subscriber's key expression covers ours) before putting, so "nobody is listening" is told apart from
"the rover heard it and did nothing"; then put once and wait for ``logs.command_watch`` to see the effect.
Everything shares one deadline, so the call returns within ``timeout_s``.

Matching says only that *something* subscribes to the key (a rover, or a recorder on ``rover/<id>/**``);
the effect on the rover's streams is what confirms a command.
"""

from __future__ import annotations

import contextlib
import logging
import threading

import zenoh

from logs.clock import Clock, to_ns
from logs.command_watch import CommandWatch, SendOutcome, Verdict, expected_effect
from logs.commands import CommandKind, command_key, command_payload
from logs.errors import TelemetryError
from logs.telemetry import subscribe

logger = logging.getLogger(__name__)

# The rover publishes the reason (safety/events) in the same tick as the NO_PATH state; on loopback or a
# LAN it follows within milliseconds, so half a second covers it without keeping the operator waiting.
REASON_GRACE_NS = 500_000_000


def send_confirmed(
    session: zenoh.Session,
    rover_id: str,
    kind: CommandKind,
    x: float | None = None,
    y: float | None = None,
    *,
    timeout_s: float,
    clock: Clock,
) -> SendOutcome:
    """Send ``kind`` and judge the rover's answer within ``timeout_s`` (measured on ``clock``).

    Returns the verdict; ``TelemetryError`` for a bad timeout or goal, or when zenoh itself fails.
    """
    if not timeout_s > 0:
        raise TelemetryError(f"the confirmation timeout must be > 0 s, got {timeout_s!r}")
    payload = command_payload(kind, x, y)
    key = command_key(rover_id, kind)
    deadline_ns = clock.now_ns() + to_ns(timeout_s)
    watch = CommandWatch(kind, x, y)
    expected = expected_effect(kind, x, y)
    heard = threading.Event()

    def on_matching(status: zenoh.MatchingStatus) -> None:
        if status.matching:
            heard.set()

    with contextlib.ExitStack() as undo:
        try:
            for topic in watch.seen:
                undo.callback(subscribe(session, rover_id, watch.observe, topic).close)
            publisher = session.declare_publisher(key, encoding=zenoh.Encoding.APPLICATION_JSON)
            undo.callback(publisher.undeclare)
            undo.callback(publisher.declare_matching_listener(on_matching).undeclare)
            if not _wait(heard, clock, deadline_ns):
                # Zenoh drops a put nobody subscribes to at the sender: not putting changes nothing.
                info = session.info
                peers, routers = len(info.peers_zid()), len(info.routers_zid())
                reached = (
                    "no Zenoh peer or router"
                    if peers + routers == 0
                    else f"{peers} Zenoh peer(s) and {routers} router(s), none subscribed to the command"
                )
                return SendOutcome(
                    Verdict.NO_LISTENER,
                    f"no rover is listening: nothing subscribed to {key} within {timeout_s:g} s, so the "
                    f"command was not sent; this station is connected to {reached}",
                    connections=peers + routers,
                )
            publisher.put(payload)
        except zenoh.ZError as err:
            raise TelemetryError(f"cannot send {kind} to rover {rover_id!r}: {err}") from err
        logger.info("%s sent; waiting for %s", key, expected)
        _wait(watch.decided, clock, deadline_ns)
        if watch.decided.is_set():
            # A NO_PATH state may come before the event with the planner's reason: wait a little for it.
            _wait(watch.complete, clock, min(deadline_ns, clock.now_ns() + REASON_GRACE_NS))
        if watch.outcome is None and kind == "goal" and watch.accepted:
            return SendOutcome(
                Verdict.UNCONFIRMED,
                f"the rover accepted the goal ({x:.2f}, {y:.2f}) but showed no plan outcome (DRIVING or "
                f"NO_PATH) within {timeout_s:g} s; {watch.what_was_seen()}",
            )
        if watch.outcome is None:
            return SendOutcome(
                Verdict.UNCONFIRMED,
                f"{key} reached a subscriber, but within {timeout_s:g} s the rover did not show "
                f"{expected}; {watch.what_was_seen()}",
            )
        return watch.outcome


def _wait(event: threading.Event, clock: Clock, deadline_ns: int) -> bool:
    remaining_s = (deadline_ns - clock.now_ns()) / 1e9
    return event.is_set() if remaining_s <= 0 else event.wait(remaining_s)
