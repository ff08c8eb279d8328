"""A GPS that does not know its accuracy says so the MAVLink way (GPS_RAW_INT eph = UINT16_MAX), and its
fixes are still fixes: the onboard stack drives on them, taking the estimator's configured GPS noise."""

from __future__ import annotations

from typing import Any

from tests.runtime.rig import Rig, rig_config

UINT16_UNKNOWN = 65535
_EPH, _EPV = 5, 6  # gps_raw_int_encode(time_usec, fix_type, lat, lon, alt, eph, epv, vel, cog, satellites)


def test_fixes_of_unknown_accuracy_are_fused_and_the_rover_drives() -> None:
    rig = Rig(rig_config())
    try:
        encode = rig.autopilot._mav.gps_raw_int_encode

        def unknown_accuracy(*fields: Any) -> Any:
            sent = list(fields)
            sent[_EPH] = sent[_EPV] = UINT16_UNKNOWN
            return encode(*sent)

        rig.autopilot._mav.gps_raw_int_encode = unknown_accuracy
        rig.drive()  # the start-up checks pass: the estimate is healthy on these fixes alone
        assert "gps_bad_eph" not in rig.stack.estimator.counters
        assert rig.stack.estimator.counters.get("gps_initialised") == 1
    finally:
        rig.close()
