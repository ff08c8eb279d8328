"""The start-up checks are on ``safety/events``: which are pending from the first tick, and when they pass."""

from __future__ import annotations

from tests.runtime.rig import Rig, rig_config


def test_pending_start_up_checks_are_reported_then_their_passing() -> None:
    rig = Rig(rig_config())
    try:
        rig.control_tick()
        first = rig.events("startup_checks")
        # The supervisor starts in IDLE, so no mode change says why the rover waits: this event does.
        assert len(first) == 1 and first[0][1]["detail"].startswith("pending: ")
        assert "estimate" in first[0][1]["detail"]
        passed_ns = rig.run_until(
            lambda: rig.events("startup_checks")[-1][1]["detail"].startswith("passed"), 10.0, "checks passed"
        )
        driving_ns = rig.drive()
        rig.run_for(1.0)
        events = rig.events("startup_checks")
        details = [m["detail"] for _, m in events]
        # On change only (not every tick), the settling wait named, and one "passed", before driving.
        assert len(details) < 10 and len(set(details)) == len(details)
        assert any("estimate healthy for < 2 s" in d for d in details)
        assert [d for d in details if d.startswith("passed")] == [details[-1]]
        assert events[-1][0] == passed_ns <= driving_ns
        assert all(m["severity"] == "info" for _, m in events)
    finally:
        rig.close()
