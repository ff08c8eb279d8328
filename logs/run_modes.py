"""What kind of run made a recording: the ``trial`` metadata record's ``mode``, one name per writer."""

from __future__ import annotations

# A lockstep trial (hil.trial): a simulated clock counted from 0, the simulator in the same process.
LOCKSTEP_MODE = "sim-lockstep"
# The real-time HIL peer's truth file (hil.peer): the simulated world, no onboard stack.
PEER_MODE = "sim-realtime-peer"
# `rover run` (navigator.rover_process): the onboard stack on the rover's clock (on the rover, or beside
# the peer).
ROVER_RUN_MODE = "rover-run"
