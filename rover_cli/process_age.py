"""How long this process has been running: what "wall time in all" means to someone timing the command.

A command's own clock starts after Python has started and imported what it needs (2-3 s for `rover hil
trial` on the build VM, a third of the whole run), so a figure from it under-reports what `time` shows. The
kernel knows when the process started: ``/proc/self/stat``'s start time, in clock ticks since boot, against
the boot-time clock. Linux only (the rover's companion computer and the HIL hosts); None elsewhere.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

# /proc/self/stat's fields after the command name's closing parenthesis: the state is field 3 of the
# whole line, the start time field 22 (proc(5)), so the start time is the 20th after the name.
_START_TIME_AFTER_NAME = 19


def process_age_s(stat_path: Path = Path("/proc/self/stat")) -> float | None:
    """Seconds since this process started (to the kernel's clock tick, 10 ms), or None where the kernel
    does not say (no /proc, no boot-time clock)."""
    try:
        text = stat_path.read_text(encoding="ascii", errors="replace")
        # The name may hold spaces and parentheses: the fields start after its last ")".
        fields = text.rsplit(")", 1)[1].split()
        started_s = int(fields[_START_TIME_AFTER_NAME]) / os.sysconf("SC_CLK_TCK")
        since_boot_s = time.clock_gettime(time.CLOCK_BOOTTIME)
    except (OSError, ValueError, IndexError, AttributeError):
        return None
    age = since_boot_s - started_s
    return age if age >= 0.0 else None
