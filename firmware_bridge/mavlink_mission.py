"""The MAVLink mission protocol with the companion as mission server: a ground station uploads, downloads
and clears a mission and sets its current item (https://mavlink.io/en/services/mission.html).

The server speaks the protocol and keeps the mission in force as uploaded (what a download returns); it
does not drive. What a transfer changes comes back from ``take`` as a ``MissionChange`` for the onboard
stack (``navigator.onboard_mission``), which drives the mission (``navigator.mission``: the waypoints and
loiters in order, each speed change applied as it comes, a return to launch driven home, each jump taken
as its count allows, each delay waited out) and reports progress back (``tick``: MISSION_CURRENT, naming
the item driven to or waited at, never a speed change or a jump; ``item_reached``: MISSION_ITEM_REACHED,
per waypoint, loiter, return or delay done and per speed change applied). It also judges and answers
MAV_CMD_MISSION_START (COMMAND_LONG or COMMAND_INT, which the link hands over as mission messages), as
``firmware_bridge.mavlink_commands.judge_mission_start`` rules, with COMMAND_ACK. The home commands the link
hands over the same way (``firmware_bridge.mavlink_home``) are the onboard stack's
(``navigator.onboard_home``), not the server's.

What is accepted, and the answer to everything else (each refusal a MISSION_ACK with the protocol's
result, or a STATUSTEXT where the protocol has no ACK, counted in the link's ``mission_refused`` and
logged naming what was wrong):

* Only ``MAV_MISSION_TYPE_MISSION`` (fence and rally: ``MAV_MISSION_UNSUPPORTED``); a clear of
  ``MAV_MISSION_TYPE_ALL`` clears the mission.
* Items ``MAV_CMD_NAV_WAYPOINT``, ``MAV_CMD_NAV_LOITER_TIME``, ``MAV_CMD_NAV_LOITER_UNLIM``,
  ``MAV_CMD_NAV_RETURN_TO_LAUNCH``, ``MAV_CMD_DO_CHANGE_SPEED``, ``MAV_CMD_DO_JUMP`` and
  ``MAV_CMD_NAV_DELAY`` (``ITEM_COMMANDS``); any other command: ``MAV_MISSION_UNSUPPORTED``. A waypoint
  (and a loiter) is in a global frame the goal commands take (``GLOBAL_FRAMES``; else
  ``MAV_MISSION_UNSUPPORTED_FRAME``), latitude and longitude degrees x 1e7 in range
  (``MAV_MISSION_INVALID_PARAM5_X`` / ``_PARAM6_Y``), placed by the rover (``place``: ENU through the
  estimator's datum, inside the geofence; else ``MAV_MISSION_DENIED`` naming why), with its hold time
  (param1, seconds the rover waits there: ``firmware_bridge.mission_hold``; ``MAV_MISSION_INVALID_PARAM1``
  past it). Its altitude, acceptance radius, yaw and ``autocontinue`` are kept for a download and not used.
  A loiter is a waypoint with a hold (``firmware_bridge.mission_hold``): LOITER_TIME's param1 is its time
  (judged as a hold time, but NaN refused: ``MAV_MISSION_INVALID_PARAM1``), LOITER_UNLIM holds until the
  operator moves the mission on; the other params (radius; LOITER_TIME's heading required and Xtrack,
  LOITER_UNLIM's yaw) are kept, not used. A return to launch has no position
  and no parameters (any frame is taken, everything kept for a download): the rover drives to home as it
  is when the mission comes to it (``firmware_bridge.mavlink_home.ReturnToLaunch``); reached, the mission
  goes on to its next item (complete when it was the last), as ArduPilot Rover's Auto mode does.
  A speed change has no position (any frame is taken) and is judged by ``firmware_bridge.mission_speed``:
  its speed type (``MAV_MISSION_INVALID_PARAM1``) and speed (``MAV_MISSION_INVALID_PARAM2``).
  A jump (any frame, no position) is judged by ``firmware_bridge.mission_jump``: its target (param1), an
  item of the mission (``MAV_MISSION_INVALID_PARAM1``), and its repeat count (param2), a whole number or -1
  for ever (``MAV_MISSION_INVALID_PARAM2``); at the upload's last item, a jump whose loop has no item that
  moves the rover is refused (``MAV_MISSION_INVALID_PARAM1``): the mission must never go round without a
  waypoint, loiter or return to launch in between. A delay (any frame, no position) is judged by
  ``firmware_bridge.mission_delay``: param1 seconds, 0 to 3600; -1 (until a time of day) refused
  (``MAV_MISSION_INVALID_PARAM1``). A mission needs at least one waypoint, loiter or return to launch: an
  upload of speed changes, jumps and delays alone is refused at its last item (``MAV_MISSION_ERROR``). The
  legacy float MISSION_ITEM is refused (``MAV_MISSION_UNSUPPORTED``): we ask with MISSION_REQUEST_INT.
* Items are numbered as uploaded, speed changes and jumps included (a jump's target counts the same way):
  item 0 is the first item, as the spec numbers them (as PX4 does). ArduPilot's convention of home as item
  0 is not taken: nothing in an upload says which one it follows, and taking item 0 as home would drop
  every other ground station's first waypoint; an ArduPilot-style upload drives to home first (and its
  jump targets, counted with home as item 0, still name the same items).
* At most ``MAX_MISSION_ITEMS`` items (``MAV_MISSION_NO_SPACE``). A count of 0 clears.
* One transfer at a time. A new operation (MISSION_COUNT, MISSION_REQUEST_LIST, MISSION_CLEAR_ALL) from
  the partner of the transfer under way replaces it (a ground station that started over); from anyone else
  it is refused (``MAV_MISSION_DENIED``, the transfer goes on).
* A duplicate item (one already received: the late answer to a request sent again) is dropped silently, as
  PX4 and mavros do. An item after a gap (one lost) is dropped and the expected one asked for again (the
  spec's recovery); each such request, like each request resent after a timeout (250 ms for an item,
  1.5 s otherwise, the spec's values), uses one of 5 retries, which a good item renews. An item beyond the
  announced count, or with no upload of its sender under way: ``MAV_MISSION_INVALID_SEQUENCE``; except
  that for one operation timeout after an upload completed, its partner's last item again (our ACK was
  lost) is answered ACCEPTED again, and not applied again.
* A transfer whose retries run out is abandoned (``MAV_MISSION_OPERATION_CANCELLED`` to the partner,
  counted in ``mission_timeouts``). An upload replaces the mission in force only when its last item is
  accepted: a partial, refused, cancelled or timed-out upload leaves it as it was.

Mission messages count only when addressed to our system (or broadcast) and to our component by its id:
a component-broadcast mission (0) on the autopilot's link is the autopilot's, and two servers answering
one ground station would break its transfer.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple, Protocol

from pymavlink.dialects.v20 import common as mavlink2

from firmware_bridge.errors import BridgeOperationError
from firmware_bridge.mavlink_commands import (
    GLOBAL_FRAMES,
    StartRequest,
    Verdict,
    is_mission_start,
    judge_mission_start,
)
from firmware_bridge.mavlink_health import MavlinkCounters
from firmware_bridge.mavlink_home import ReturnToLaunch
from firmware_bridge.mission_delay import Delay, delay, delay_refusal
from firmware_bridge.mission_hold import HOLD_UNLIMITED, PlacedWaypoint, hold_refusal, hold_seconds
from firmware_bridge.mission_jump import (
    Jump,
    idle_loop,
    idle_loop_reason,
    jump,
    jump_refusal,
    moves_the_rover,
)
from firmware_bridge.mission_speed import SpeedChange, speed_change, speed_change_refusal
from firmware_bridge.mission_state import MissionState
from logs.clock import NS_PER_S, Clock

logger = logging.getLogger(__name__)

MISSION_MESSAGES = frozenset(
    {
        "MISSION_COUNT",
        "MISSION_ITEM_INT",
        "MISSION_ITEM",
        "MISSION_REQUEST_LIST",
        "MISSION_REQUEST_INT",
        "MISSION_REQUEST",
        "MISSION_ACK",
        "MISSION_CLEAR_ALL",
        "MISSION_SET_CURRENT",
    }
)
# Taken only signed when signing is on, like commands: an upload, clear or current item drives the rover
# as a goal does, and an unsigned download request would hold the one transfer slot from a signed upload.
MISSION_MESSAGE_IDS = frozenset(
    msgid for msgid, message in mavlink2.mavlink_map.items() if message.msgname in MISSION_MESSAGES
)
# A bound on what a partner can make us hold and on an upload's length (one round trip per item): well
# above a rover's survey pattern; a larger mission is refused with MAV_MISSION_NO_SPACE.
MAX_MISSION_ITEMS = 256
# The spec's recommended timeouts and retries (mission.html, "Timeouts and Retries").
ITEM_TIMEOUT_NS = 250_000_000  # waiting for a MISSION_ITEM_INT we asked for
OPERATION_TIMEOUT_NS = 1_500_000_000  # waiting for a download's next request or its ACK
MAX_RETRIES = 5
CURRENT_PERIOD_NS = NS_PER_S  # MISSION_CURRENT while a ground station follows the mission (and on change)
_NO_MISSION_TOTAL = 65535  # MISSION_CURRENT.total: UINT16_MAX, "no mission on the vehicle"
_DEGREES_E7 = 1e-7
_MISSION = mavlink2.MAV_MISSION_TYPE_MISSION
# The items taken; the ones with a position (placed by the rover, in a global frame) first.
_PLACED_COMMANDS = frozenset(
    {mavlink2.MAV_CMD_NAV_WAYPOINT, mavlink2.MAV_CMD_NAV_LOITER_TIME, mavlink2.MAV_CMD_NAV_LOITER_UNLIM}
)
ITEM_COMMANDS = _PLACED_COMMANDS | {
    mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH,
    mavlink2.MAV_CMD_DO_CHANGE_SPEED,
    mavlink2.MAV_CMD_DO_JUMP,
    mavlink2.MAV_CMD_NAV_DELAY,
}
_TAKEN = (
    "MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_LOITER_TIME, MAV_CMD_NAV_LOITER_UNLIM, "
    "MAV_CMD_NAV_RETURN_TO_LAUNCH, MAV_CMD_DO_CHANGE_SPEED, MAV_CMD_DO_JUMP and MAV_CMD_NAV_DELAY"
)
# MissionState -> (MISSION_STATE, MISSION_CURRENT.mission_mode: 1 in mission mode, 2 suspended (not in
# mission mode), 0 unknown).
_STATES = {
    MissionState.NONE: (mavlink2.MISSION_STATE_NO_MISSION, 0),
    MissionState.NOT_STARTED: (mavlink2.MISSION_STATE_NOT_STARTED, 2),
    MissionState.ACTIVE: (mavlink2.MISSION_STATE_ACTIVE, 1),
    MissionState.PAUSED: (mavlink2.MISSION_STATE_PAUSED, 2),
    MissionState.COMPLETE: (mavlink2.MISSION_STATE_COMPLETE, 1),
}


class MissionItemRefused(BridgeOperationError):
    """The rover cannot take a waypoint (no datum yet, outside the geofence): raised by a ``Placer``, the
    upload is refused with MAV_MISSION_DENIED and this message."""


# (latitude, longitude) in degrees -> local ENU (x, y) metres, or MissionItemRefused naming why not.
Placer = Callable[[float, float], tuple[float, float]]


class MissionLink(Protocol):
    """What the server needs of a MAVLink link (``firmware_bridge.mavlink_link.MavlinkLink``)."""

    name: str
    counters: MavlinkCounters

    def send(self, msg: Any) -> None: ...

    def send_status_text(self, text: str, severity: int = ...) -> None: ...


class MissionMessage(NamedTuple):
    """A mission protocol message addressed to us, as the link read it (for ``MissionServer.take``)."""

    msg: Any
    t_ns: int


def refuse_command(link: MissionLink, msg: Any, result: int, reason: str) -> None:
    """A COMMAND_LONG / COMMAND_INT handed to the onboard stack (a mission start, a home command) refused
    as the link refuses the other commands: COMMAND_ACK with ``result`` to its sender, counted in
    ``commands_rejected``, logged at WARNING with ``reason``, and a STATUSTEXT ``refused: <reason>``."""
    sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
    link.send(mavlink2.MAVLink_command_ack_message(msg.command, result, 0, 0, sysid, compid))
    link.counters.commands_rejected += 1
    logger.warning("refused %s %d from %d/%d: %s", msg.get_type(), msg.command, sysid, compid, reason)
    link.send_status_text(f"refused: {reason}", mavlink2.MAV_SEVERITY_WARNING)


def mission_addressed(msg: Any, system_id: int, component_id: int) -> bool:
    """Our system (or broadcast) and our component by its id (see the module's note)."""
    return msg.target_system in (0, system_id) and msg.target_component == component_id


@dataclass(frozen=True)
class MissionItem:
    """One item as uploaded (a waypoint or a speed change): what a download gives back, field for field."""

    seq: int
    frame: int
    command: int  # one of ITEM_COMMANDS
    x: int  # latitude, degrees x 1e7
    y: int  # longitude, degrees x 1e7
    z: float
    params: tuple[float, float, float, float]
    autocontinue: int

    @property
    def lat_deg(self) -> float:
        return self.x * _DEGREES_E7

    @property
    def lon_deg(self) -> float:
        return self.y * _DEGREES_E7


# One item as the rover drives it: a waypoint placed in ENU metres (with its hold time; a plain (x, y) from a
# trial's goals holds for none; a loiter item is one too), a speed change, a return to launch, a jump or a
# delay.
MissionStep = PlacedWaypoint | tuple[float, float] | SpeedChange | ReturnToLaunch | Jump | Delay


@dataclass(frozen=True)
class MissionAccepted:
    """An upload completed: its items, and each as the rover drives it (``steps``, item for item); from
    whom."""

    items: tuple[MissionItem, ...]
    steps: tuple[MissionStep, ...]
    sysid: int
    compid: int


@dataclass(frozen=True)
class MissionCleared:
    sysid: int
    compid: int


@dataclass(frozen=True)
class CurrentRequested:
    """MISSION_SET_CURRENT for an item the mission has."""

    seq: int
    sysid: int
    compid: int


# A StartRequest here is MAV_CMD_MISSION_START accepted (and acknowledged): drive the mission from its item
# ``first``.
MissionChange = MissionAccepted | MissionCleared | CurrentRequested | StartRequest


class MissionProgress(NamedTuple):
    """What the rover does with the mission: the current item and its state."""

    current: int
    state: MissionState


@dataclass
class _Partner:
    """A ground station: its system and component, on one link."""

    link: MissionLink
    sysid: int
    compid: int

    def is_with(self, link: MissionLink, sysid: int, compid: int) -> bool:
        return self.link is link and self.sysid == sysid and self.compid == compid


@dataclass
class _Transfer(_Partner):
    """An upload or a download under way with one partner."""

    upload: bool
    count: int
    resend: Any  # our last message waiting for an answer: sent again at a timeout
    deadline_ns: int
    retries: int = 0
    next_seq: int = 0  # upload: the item asked for
    items: list[MissionItem] = field(default_factory=list)  # upload: received; download: the snapshot
    steps: list[MissionStep] = field(default_factory=list)  # upload: the items as the rover drives them

    @property
    def what(self) -> str:
        kind = "upload from" if self.upload else "download to"
        return f"mission {kind} {self.sysid}/{self.compid} on the {self.link.name} link"


@dataclass
class _Finished(_Partner):
    """An upload completed at ``t_ns``: its partner may resend its last item if our ACK was lost."""

    count: int
    t_ns: int


class MissionServer:
    """The mission protocol for every MAVLink link of the rover: one mission in force, one transfer at a
    time (see the module's notes for what is accepted and refused).

    ``place`` turns a waypoint's latitude and longitude into local ENU metres, or raises
    ``MissionItemRefused``. Times are the ``clock``'s; the caller calls ``tick`` every control tick.
    """

    def __init__(
        self,
        clock: Clock,
        place: Placer,
        *,
        max_items: int = MAX_MISSION_ITEMS,
        item_timeout_ns: int = ITEM_TIMEOUT_NS,
        operation_timeout_ns: int = OPERATION_TIMEOUT_NS,
        max_retries: int = MAX_RETRIES,
        slowest_speed_mps: float = 0.0,
    ) -> None:
        self._clock = clock
        self._place = place
        self._slowest_speed_mps = slowest_speed_mps  # DO_CHANGE_SPEED below it is refused
        self.max_items = max_items
        self._item_timeout_ns = item_timeout_ns
        self._operation_timeout_ns = operation_timeout_ns
        self._max_retries = max_retries
        self.items: tuple[MissionItem, ...] = ()  # the mission in force, as uploaded
        self._transfer: _Transfer | None = None
        self._finished: _Finished | None = None  # the last upload completed (``_repeat_of_finished``)
        # The links a mission partner has talked to us on: MISSION_CURRENT and MISSION_ITEM_REACHED go
        # there (none until then: a rover no ground station asked about a mission sends neither).
        self._links: list[MissionLink] = []
        self._reported: tuple[int, int, int] | None = None
        self._next_current_ns = 0
        self._progress = MissionProgress(0, MissionState.NONE)
        self._handlers: dict[str, Callable[[MissionLink, Any, int, int], MissionChange | None]] = {
            "MISSION_COUNT": self._on_count,
            "MISSION_ITEM_INT": self._on_item_int,
            "MISSION_ITEM": self._on_float_item,
            "MISSION_REQUEST_LIST": self._on_request_list,
            "MISSION_REQUEST_INT": self._on_request,
            # Deprecated: answered with MISSION_ITEM_INT, as the spec says.
            "MISSION_REQUEST": self._on_request,
            "MISSION_ACK": self._on_ack,
            "MISSION_CLEAR_ALL": self._on_clear_all,
            "MISSION_SET_CURRENT": self._on_set_current,
            "COMMAND_LONG": self._on_mission_start,  # MAV_CMD_MISSION_START only (the link's routing)
            "COMMAND_INT": self._on_mission_start,
        }

    @property
    def transfer_under_way(self) -> bool:
        return self._transfer is not None

    @property
    def followers(self) -> tuple[MissionLink, ...]:
        """The links a mission partner has talked to us on (MISSION_CURRENT goes there), in that order."""
        return tuple(self._links)

    # --- from the rover -----------------------------------------------------------------------------
    def replace(self, positions: Sequence[tuple[float, float]]) -> None:
        """The rover started a mission of its own (a scenario's goals): ``positions`` (latitude, longitude
        in degrees) become the mission in force, as waypoints in MAV_FRAME_GLOBAL_INT, so a ground station
        downloads what is driven."""
        self.items = tuple(
            MissionItem(
                seq,
                mavlink2.MAV_FRAME_GLOBAL_INT,
                mavlink2.MAV_CMD_NAV_WAYPOINT,
                round(lat / _DEGREES_E7),
                round(lon / _DEGREES_E7),
                0.0,
                (0.0, 0.0, 0.0, 0.0),
                1,
            )
            for seq, (lat, lon) in enumerate(positions)
        )

    def tick(self, current: int, state: MissionState) -> None:
        """Every control tick, with the rover's progress (the current item and the mission's state):
        timeouts of the transfer under way, and MISSION_CURRENT to the links a ground station follows the
        mission on (at once when the progress changes, else once a second)."""
        progress = self._progress
        if progress.current != current or progress.state != state:
            self._progress = progress = MissionProgress(current, state)
        if self._transfer is None and not self._links:
            return
        now = self._clock.now_ns()
        transfer = self._transfer
        if transfer is not None and now >= transfer.deadline_ns:
            self._ask_again(transfer, now)
        if self._links:
            self._report_current(now, progress)

    def item_reached(self, seq: int) -> None:
        """MISSION_ITEM_REACHED to the links a ground station follows the mission on."""
        for link in self._links:
            link.send(mavlink2.MAVLink_mission_item_reached_message(seq))

    # --- from a ground station ------------------------------------------------------------------------
    def take(self, link: MissionLink, msg: Any) -> MissionChange | None:
        """One mission message addressed to us (``mission_addressed``), read on ``link``: answered there;
        returns what it changed for the rover to act on, if anything."""
        link.counters.mission_messages += 1
        if not any(known is link for known in self._links):
            self._links.append(link)
        handler = self._handlers[msg.get_type()]
        return handler(link, msg, msg.get_srcSystem(), msg.get_srcComponent())

    def _on_count(self, link: MissionLink, msg: Any, sysid: int, compid: int) -> MissionChange | None:
        if not self._may_start(link, msg, sysid, compid, "MISSION_COUNT"):
            return None
        if msg.mission_type != _MISSION:
            self._refuse_type(link, msg, sysid, compid, "upload")
            return None
        count = msg.count
        if count > self.max_items:
            self._refuse(
                link,
                sysid,
                compid,
                mavlink2.MAV_MISSION_NO_SPACE,
                f"a mission of {count} items: at most {self.max_items} are taken",
            )
            return None
        if count == 0:  # the spec: an empty upload clears
            return self._clear(link, sysid, compid, _MISSION)
        now = self._clock.now_ns()
        request = self._request(sysid, compid, 0)
        deadline_ns = now + self._item_timeout_ns
        self._transfer = _Transfer(
            link, sysid, compid, upload=True, count=count, resend=request, deadline_ns=deadline_ns
        )
        logger.info("mission upload of %d items from %d/%d on the %s link", count, sysid, compid, link.name)
        link.send(request)
        return None

    def _on_item_int(self, link: MissionLink, msg: Any, sysid: int, compid: int) -> MissionChange | None:
        transfer = self._transfer
        seq = msg.seq
        if transfer is None or not transfer.upload or not transfer.is_with(link, sysid, compid):
            if self._repeat_of_finished(link, msg, sysid, compid):
                return None
            # A transfer of someone else's goes on; an upload of ours that timed out is told so here.
            self._refuse_outside_transfer(link, msg, sysid, compid, "upload")
            return None
        if self._ends_transfer(transfer, link, msg, sysid, compid, f"item {seq} of"):
            return None
        if seq < transfer.next_seq:
            # A duplicate: the late answer to a request we sent again after a timeout (or the partner's
            # own resend). Dropped silently, as PX4 and mavros do: asking again for the expected item here
            # would have the partner answer that request as well as the one already out, and from then on
            # every item would be asked for and sent twice.
            link.counters.mission_out_of_sequence += 1
            logger.debug("%s: item %d again (a duplicate), dropped", transfer.what, seq)
            return None
        if seq > transfer.next_seq:
            # An item skipped (lost on the way): the spec's recovery is to drop this one and ask again for
            # the expected one (a retry: a partner that keeps skipping cannot hold the transfer open).
            link.counters.mission_out_of_sequence += 1
            logger.info("%s: item %d out of sequence, %d asked again", transfer.what, seq, transfer.next_seq)
            self._ask_again(transfer, self._clock.now_ns())
            return None
        step = self._step(msg, transfer.count)
        if not isinstance(step, _Refusal) and seq + 1 == transfer.count:
            step = _judge_mission(transfer.steps, step, transfer.count)
        if isinstance(step, _Refusal):
            self._transfer = None
            self._refuse(link, sysid, compid, *step)
            return None
        transfer.items.append(
            MissionItem(
                seq,
                msg.frame,
                msg.command,
                msg.x,
                msg.y,
                msg.z,
                (msg.param1, msg.param2, msg.param3, msg.param4),
                msg.autocontinue,
            )
        )
        transfer.steps.append(step)
        transfer.retries = 0
        if seq + 1 < transfer.count:
            transfer.next_seq = seq + 1
            transfer.resend = self._request(sysid, compid, seq + 1)
            transfer.deadline_ns = self._clock.now_ns() + self._item_timeout_ns
            link.send(transfer.resend)
            return None
        # The last item: only now does the upload replace the mission in force.
        self._transfer = None
        self._finished = _Finished(link, sysid, compid, count=transfer.count, t_ns=self._clock.now_ns())
        self.items = tuple(transfer.items)
        link.counters.missions_accepted += 1
        logger.info("%s: %d items accepted", transfer.what, transfer.count)
        link.send(_ack(sysid, compid, mavlink2.MAV_MISSION_ACCEPTED, _MISSION))
        return MissionAccepted(self.items, tuple(transfer.steps), sysid, compid)

    def _on_float_item(self, link: MissionLink, msg: Any, sysid: int, compid: int) -> MissionChange | None:
        transfer = self._transfer
        if transfer is not None and transfer.is_with(link, sysid, compid):
            self._transfer = None
        self._refuse(
            link,
            sysid,
            compid,
            mavlink2.MAV_MISSION_UNSUPPORTED,
            f"MISSION_ITEM {msg.seq}: the float MISSION_ITEM is not taken, send MISSION_ITEM_INT",
        )
        return None

    def _on_request_list(self, link: MissionLink, msg: Any, sysid: int, compid: int) -> MissionChange | None:
        if not self._may_start(link, msg, sysid, compid, "MISSION_REQUEST_LIST"):
            return None
        if msg.mission_type != _MISSION:
            self._refuse_type(link, msg, sysid, compid, "download")
            return None
        count = mavlink2.MAVLink_mission_count_message(sysid, compid, len(self.items), _MISSION)
        if self.items:
            self._transfer = _Transfer(
                link,
                sysid,
                compid,
                upload=False,
                count=len(self.items),
                resend=count,
                deadline_ns=self._clock.now_ns() + self._operation_timeout_ns,
                items=list(self.items),
            )
        else:
            link.counters.mission_downloads += 1  # nothing to ask for: done with the count
        link.send(count)
        return None

    def _on_request(self, link: MissionLink, msg: Any, sysid: int, compid: int) -> MissionChange | None:
        transfer = self._transfer
        seq = msg.seq
        if transfer is None or transfer.upload or not transfer.is_with(link, sysid, compid):
            self._refuse_outside_transfer(link, msg, sysid, compid, "download")
            return None
        if self._ends_transfer(transfer, link, msg, sysid, compid, f"item {seq} asked of"):
            return None
        transfer.resend = self._item_message(sysid, compid, transfer.items[seq])
        transfer.retries = 0
        transfer.deadline_ns = self._clock.now_ns() + self._operation_timeout_ns
        link.send(transfer.resend)
        return None

    def _on_ack(self, link: MissionLink, msg: Any, sysid: int, compid: int) -> MissionChange | None:
        # Never answered (an ACK for an ACK could loop between two servers); it only ends a transfer.
        transfer = self._transfer
        if transfer is None or not transfer.is_with(link, sysid, compid):
            return None
        self._transfer = None
        if not transfer.upload and msg.type == mavlink2.MAV_MISSION_ACCEPTED:
            link.counters.mission_downloads += 1
            logger.info("%s: complete", transfer.what)
        else:
            logger.warning(
                "%s ended by the partner's MISSION_ACK %s; the mission in force is unchanged",
                transfer.what,
                _result_name(msg.type),
            )
        return None

    def _on_clear_all(self, link: MissionLink, msg: Any, sysid: int, compid: int) -> MissionChange | None:
        if not self._may_start(link, msg, sysid, compid, "MISSION_CLEAR_ALL"):
            return None
        if msg.mission_type not in (_MISSION, mavlink2.MAV_MISSION_TYPE_ALL):
            self._refuse_type(link, msg, sysid, compid, "clear")
            return None
        return self._clear(link, sysid, compid, msg.mission_type)

    def _on_set_current(self, link: MissionLink, msg: Any, sysid: int, compid: int) -> MissionChange | None:
        seq = msg.seq
        if seq < len(self.items):
            # The rover makes it current; the next tick's MISSION_CURRENT says so (the spec's answer).
            return CurrentRequested(seq, sysid, compid)
        reason = (
            "there is no mission" if not self.items else f"the mission has items 0..{len(self.items) - 1}"
        )
        # The spec's answer to a refused MISSION_SET_CURRENT is a STATUSTEXT, not an ACK.
        link.counters.mission_refused += 1
        logger.warning(
            "MISSION_SET_CURRENT %d from %d/%d on the %s link refused: %s",
            seq,
            sysid,
            compid,
            link.name,
            reason,
        )
        link.send_status_text(f"mission item {seq} not set: {reason}", mavlink2.MAV_SEVERITY_WARNING)
        return None

    def _on_mission_start(self, link: MissionLink, msg: Any, sysid: int, compid: int) -> MissionChange | None:
        """MAV_CMD_MISSION_START, judged against the mission in force and answered with COMMAND_ACK as the
        link answers the other commands (a refusal also with a STATUSTEXT, counted in
        ``commands_rejected``). Any other command handed here (a home command is the onboard stack's, not
        the server's: ``navigator.onboard_mission``) is refused UNSUPPORTED, never read as a start."""
        if is_mission_start(msg):
            verdict = judge_mission_start(msg, self._clock.now_ns(), len(self.items))
        else:
            name = _enum_name("MAV_CMD", msg.command)
            verdict = Verdict(
                None, mavlink2.MAV_RESULT_UNSUPPORTED, f"{name} is not the mission server's to answer"
            )
        if verdict.start is None:
            refuse_command(link, msg, verdict.result, verdict.reason)
            return None
        link.send(mavlink2.MAVLink_command_ack_message(msg.command, verdict.result, 0, 0, sysid, compid))
        return verdict.start

    # --- internals --------------------------------------------------------------------------------
    def _step(self, msg: Any, count: int) -> MissionStep | _Refusal:
        """A MISSION_ITEM_INT of a mission of ``count`` items as the rover drives it (a waypoint or loiter
        placed in ENU, a speed change, a return to launch, a jump, a delay), or why it cannot be taken."""
        refusal = _judge_item(msg, self._slowest_speed_mps, count)
        if refusal is not None:
            return refusal
        command = msg.command
        if command == mavlink2.MAV_CMD_DO_CHANGE_SPEED:
            return speed_change(msg.param2)
        if command == mavlink2.MAV_CMD_DO_JUMP:
            return jump(msg.param1, msg.param2)
        if command == mavlink2.MAV_CMD_NAV_DELAY:
            return delay(msg.param1)
        if command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return ReturnToLaunch()  # to home as it is when the mission comes to it
        try:
            x, y = self._place(msg.x * _DEGREES_E7, msg.y * _DEGREES_E7)
        except MissionItemRefused as err:
            return _Refusal(mavlink2.MAV_MISSION_DENIED, f"item {msg.seq}: {err}")
        if command == mavlink2.MAV_CMD_NAV_LOITER_UNLIM:
            return PlacedWaypoint(x, y, HOLD_UNLIMITED)
        return PlacedWaypoint(x, y, hold_seconds(msg.param1))  # a waypoint's hold, a loiter's time

    def _repeat_of_finished(self, link: MissionLink, msg: Any, sysid: int, compid: int) -> bool:
        """Whether ``msg`` (a MISSION_ITEM_INT with no upload of its sender under way) belongs to the
        upload that partner finished within the last operation timeout, and is answered as such: its last
        item again means our MISSION_ACK ACCEPTED was lost (the partner resends until it hears one), so
        the ACK is sent again, neither counted as a refusal nor applied again."""
        finished = self._finished
        if finished is None or not finished.is_with(link, sysid, compid) or msg.seq != finished.count - 1:
            return False
        if self._clock.now_ns() - finished.t_ns > self._operation_timeout_ns:
            self._finished = None
            return False
        logger.info(
            "mission upload from %d/%d on the %s link: last item again (our ACK lost), accepted again",
            sysid,
            compid,
            link.name,
        )
        link.send(_ack(sysid, compid, mavlink2.MAV_MISSION_ACCEPTED, _MISSION))
        return True

    def _may_start(self, link: MissionLink, msg: Any, sysid: int, compid: int, name: str) -> bool:
        """Whether ``sysid/compid`` may start an operation now: refused while another partner's transfer
        is under way; its own transfer under way is given up (it started over)."""
        transfer = self._transfer
        if transfer is None:
            return True
        if not transfer.is_with(link, sysid, compid):
            self._refuse(
                link,
                sysid,
                compid,
                mavlink2.MAV_MISSION_DENIED,
                f"{name} from {sysid}/{compid} while a {transfer.what} is under way",
                msg.mission_type,
            )
            return False
        logger.info("%s given up: the partner sent %s", transfer.what, name)
        self._transfer = None
        return True

    def _clear(self, link: MissionLink, sysid: int, compid: int, mission_type: int) -> MissionCleared:
        self.items = ()
        self._finished = None  # its last item again must not look accepted now
        link.counters.missions_cleared += 1
        logger.info("mission cleared by %d/%d on the %s link", sysid, compid, link.name)
        link.send(_ack(sysid, compid, mavlink2.MAV_MISSION_ACCEPTED, mission_type))
        return MissionCleared(sysid, compid)

    def _ask_again(self, transfer: _Transfer, now: int) -> None:
        """Send the request (or, in a download, the count or item) waiting for an answer again, while
        retries last; then abandon the transfer."""
        if transfer.retries >= self._max_retries:
            self._abandon(transfer)
            return
        transfer.retries += 1
        transfer.link.counters.mission_resends += 1
        timeout = self._item_timeout_ns if transfer.upload else self._operation_timeout_ns
        transfer.deadline_ns = now + timeout
        transfer.link.send(transfer.resend)

    def _abandon(self, transfer: _Transfer) -> None:
        self._transfer = None
        link = transfer.link
        link.counters.mission_timeouts += 1
        if transfer.upload:
            logger.warning(
                "%s abandoned: item %d of %d not received after %d requests; the mission in force is "
                "unchanged",
                transfer.what,
                transfer.next_seq,
                transfer.count,
                self._max_retries + 1,
            )
        else:
            logger.warning(
                "%s abandoned: no request or ACK after %d tries", transfer.what, self._max_retries + 1
            )
        link.send(_ack(transfer.sysid, transfer.compid, mavlink2.MAV_MISSION_OPERATION_CANCELLED, _MISSION))

    def _ends_transfer(
        self, transfer: _Transfer, link: MissionLink, msg: Any, sysid: int, compid: int, item: str
    ) -> bool:
        """A message of the transfer under way in the wrong mission type, or for an item beyond its count,
        ends the transfer with the protocol's refusal: True then. ``item`` names the item in the refusal."""
        if msg.mission_type != _MISSION:
            self._transfer = None
            self._refuse_type(link, msg, sysid, compid, "upload" if transfer.upload else "download")
            return True
        if msg.seq >= transfer.count:
            self._transfer = None
            self._refuse(
                link,
                sysid,
                compid,
                mavlink2.MAV_MISSION_INVALID_SEQUENCE,
                f"{item} a mission of {transfer.count} items (0..{transfer.count - 1})",
            )
            return True
        return False

    def _refuse_type(self, link: MissionLink, msg: Any, sysid: int, compid: int, operation: str) -> None:
        mission_type = msg.mission_type
        self._refuse(
            link,
            sysid,
            compid,
            mavlink2.MAV_MISSION_UNSUPPORTED,
            f"{operation} of mission type {mission_type} ({_type_name(mission_type)}): only "
            "MAV_MISSION_TYPE_MISSION is supported",
            mission_type,
        )

    def _refuse_outside_transfer(
        self, link: MissionLink, msg: Any, sysid: int, compid: int, kind: str
    ) -> None:
        """An item (upload) or a request for one (download) from a partner with no ``kind`` under way."""
        self._refuse(
            link,
            sysid,
            compid,
            mavlink2.MAV_MISSION_INVALID_SEQUENCE,
            f"{msg.get_type()} {msg.seq} from {sysid}/{compid}, which has no {kind} under way",
        )

    def _refuse(
        self,
        link: MissionLink,
        sysid: int,
        compid: int,
        result: int,
        reason: str,
        mission_type: int = _MISSION,
    ) -> None:
        """A MISSION_ACK with ``result`` and a STATUSTEXT naming ``reason``; counted and logged."""
        link.counters.mission_refused += 1
        logger.warning(
            "mission refused (%s) to %d/%d on the %s link: %s",
            _result_name(result),
            sysid,
            compid,
            link.name,
            reason,
        )
        link.send(_ack(sysid, compid, result, mission_type))
        link.send_status_text(f"mission refused: {reason}", mavlink2.MAV_SEVERITY_WARNING)

    def _report_current(self, now: int, progress: MissionProgress) -> None:
        total = len(self.items)
        state, mode = _STATES[progress.state]
        # A complete mission reports the item after its last ("on last item, sequence == total").
        seq = total if progress.state is MissionState.COMPLETE else progress.current
        key = (seq, total, state)
        if key == self._reported and now < self._next_current_ns:
            return
        self._reported = key
        self._next_current_ns = now + CURRENT_PERIOD_NS
        message = mavlink2.MAVLink_mission_current_message(
            seq, total if total else _NO_MISSION_TOTAL, state, mode
        )
        for link in self._links:
            link.send(message)

    def _request(self, sysid: int, compid: int, seq: int) -> Any:
        return mavlink2.MAVLink_mission_request_int_message(sysid, compid, seq, _MISSION)

    def _item_message(self, sysid: int, compid: int, item: MissionItem) -> Any:
        progress = self._progress
        current = int(progress.state is MissionState.ACTIVE and progress.current == item.seq)
        return mavlink2.MAVLink_mission_item_int_message(
            sysid,
            compid,
            item.seq,
            item.frame,
            item.command,
            current,
            item.autocontinue,
            *item.params,
            item.x,
            item.y,
            item.z,
            _MISSION,
        )


class _Refusal(NamedTuple):
    """Why an item, or an upload at its last item, is refused: the MISSION_ACK result and the reason."""

    result: int
    reason: str


def _judge_item(msg: Any, slowest_speed_mps: float, count: int) -> _Refusal | None:
    """Why a MISSION_ITEM_INT of a mission of ``count`` items cannot be an item of ours (result and
    reason), or None."""
    seq, command = msg.seq, msg.command
    if command == mavlink2.MAV_CMD_DO_CHANGE_SPEED:
        refusal = speed_change_refusal(seq, msg.param1, msg.param2, slowest_speed_mps)
        return None if refusal is None else _Refusal(*refusal)
    if command == mavlink2.MAV_CMD_DO_JUMP:
        refusal = jump_refusal(seq, msg.param1, msg.param2, count)
        return None if refusal is None else _Refusal(*refusal)
    if command == mavlink2.MAV_CMD_NAV_DELAY:
        refusal = delay_refusal(seq, msg.param1)
        return None if refusal is None else _Refusal(*refusal)
    if command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH:
        return None  # no position, no parameters: any frame, all kept for a download
    if command not in _PLACED_COMMANDS:
        name = _enum_name("MAV_CMD", command)
        return _Refusal(
            mavlink2.MAV_MISSION_UNSUPPORTED,
            f"item {seq}: command {command} ({name}) is not supported: only {_TAKEN}",
        )
    if msg.frame not in GLOBAL_FRAMES:
        name = _enum_name("MAV_FRAME", msg.frame)
        return _Refusal(
            mavlink2.MAV_MISSION_UNSUPPORTED_FRAME,
            f"item {seq}: frame {msg.frame} ({name}) is not global (latitude, longitude)",
        )
    if not -90.0 <= msg.x * _DEGREES_E7 <= 90.0:
        return _Refusal(
            mavlink2.MAV_MISSION_INVALID_PARAM5_X, f"item {seq}: latitude {msg.x} x 1e-7 is out of range"
        )
    if not -180.0 <= msg.y * _DEGREES_E7 <= 180.0:
        return _Refusal(
            mavlink2.MAV_MISSION_INVALID_PARAM6_Y, f"item {seq}: longitude {msg.y} x 1e-7 is out of range"
        )
    if command == mavlink2.MAV_CMD_NAV_LOITER_UNLIM:
        return None  # param1 is empty; it holds for ever
    if command == mavlink2.MAV_CMD_NAV_LOITER_TIME:
        refusal = hold_refusal(seq, msg.param1, "MAV_CMD_NAV_LOITER_TIME loiter time", unset_is_none=False)
    else:
        refusal = hold_refusal(seq, msg.param1)
    return None if refusal is None else _Refusal(*refusal)


def _judge_mission(steps: Sequence[MissionStep], last: MissionStep, count: int) -> MissionStep | _Refusal:
    """The last item of an upload, or the upload's refusal at it: when no item is one to drive to (a
    waypoint, a loiter, a return to launch: a mission of speed changes, jumps and delays alone has nowhere
    to drive), or when a jump loops without one (``firmware_bridge.mission_jump.idle_loop``)."""
    every = [*steps, last]
    if not any(moves_the_rover(step) for step in every):
        return _Refusal(
            mavlink2.MAV_MISSION_ERROR,
            f"a mission of {count} item(s) with no MAV_CMD_NAV_WAYPOINT: it needs at least one waypoint (or "
            "loiter, or return to launch)",
        )
    found = idle_loop(every)
    if found is not None:
        return _Refusal(mavlink2.MAV_MISSION_INVALID_PARAM1, idle_loop_reason(*found))
    return last


def _ack(sysid: int, compid: int, result: int, mission_type: int) -> Any:
    return mavlink2.MAVLink_mission_ack_message(sysid, compid, result, mission_type)


def _enum_name(enum: str, value: int) -> str:
    entry = mavlink2.enums[enum].get(value)
    return "unknown" if entry is None else str(entry.name)


def _type_name(mission_type: int) -> str:
    return _enum_name("MAV_MISSION_TYPE", mission_type)


def _result_name(result: int) -> str:
    return _enum_name("MAV_MISSION_RESULT", result)
