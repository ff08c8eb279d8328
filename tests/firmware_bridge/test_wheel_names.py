"""Every message names a wheel by its index, its place and its controller's CAN id, the same way."""

from __future__ import annotations

from firmware_bridge.can_health import ControllerLiveness
from firmware_bridge.wheel_names import wheel_label, wheel_labels
from navigator.safety import SafetySupervisor
from navigator.safety_config import SafetyConfig
from navigator.vehicle import VehicleParams


def test_a_wheel_is_named_by_index_place_and_the_configured_can_id() -> None:
    ids = (11, 12, 13, 14, 15, 16)  # not 1..6: the index and the id must not be confused
    assert wheel_label(2, ids) == "wheel 2 (left rear, CAN id 13)"
    assert wheel_label(4) == "wheel 4 (right middle)"  # no ids known: no id guessed
    assert wheel_labels([0, 5], ids) == "wheel 0 (left front, CAN id 11), wheel 5 (right rear, CAN id 16)"
    assert wheel_label(7, ids) == "wheel 7 (position unknown)"


def test_the_link_names_a_silent_controller_by_its_wheel() -> None:
    liveness = ControllerLiveness((11, 12, 13, 14, 15, 16), silent_after_ns=60_000_000, start_ns=0)
    for cid in (11, 12, 14, 15, 16):
        liveness.heard(cid, 70_000_000)
    (change,) = liveness.check(80_000_000)
    assert (
        change.detail == "motor controller of wheel 2 (left rear, CAN id 13) silent for 80 ms (limit 60 ms)"
    )


def test_the_supervisor_names_silent_wheels_with_the_configured_ids() -> None:
    from tests.runtime.test_supervisor import inputs

    events: list[tuple[str, str, str]] = []
    supervisor = SafetySupervisor(
        SafetyConfig(),
        VehicleParams(),
        0,
        lambda *e: events.append(e),
        controller_ids=(11, 12, 13, 14, 15, 16),
    )
    now = 2_000_000_000
    heard = (now, now, 0, now, 0, now)  # wheels 2 and 4 last heard at 0
    supervisor.update(inputs(now, (1.0, 1.0))._replace(wheel_last_status_ns=heard), True)
    (detail,) = [d for kind, _, d in events if kind == "failsafe.wheel_silent"]
    assert detail == (
        "motor controller of wheel 2 (left rear, CAN id 13), wheel 4 (right middle, CAN id 15) silent for "
        "more than 250 ms"
    )
