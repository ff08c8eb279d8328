"""When the real-time peer's scenario starts: with the peer, or on the rover's first wheel command.

``rover run`` is another process, and it may first tick 5-45 s after ``rover hil peer`` came up (process
start, imports, a cold numba cache compiling; 76 s was seen on an empty cache on a loaded host). A
scenario that starts with the peer runs its faults and moving obstacles on a clock the rover has not
joined yet: a fault at 10 s can be over before the rover exists. With ``rover hil peer
--start-on-command`` the peer holds the scenario (``SimWorld.hold``: sensors and wheel status stream as
usual, the rover stands at its start, no fault or moving obstacle counts) until the rover's wheel commands
reach its simulated controllers, and starts the scenario's time at the first of them
(``SimWorld.start_at``; ``RealtimePeer._start_on_command``: a round of commands counts only when another
follows within the controllers' command timeout, so the zeros a link sends as it closes do not start it).
It says when in ``truth.mcap`` (the ``world`` record's ``epoch_ns``, its ``start``, a ``hil.peer`` log
line) and in its status file (``status()``). A rover that never commands is given up on ``timeout_ns``
after the peer is ready (``peer_start_ns``, after its own warm-up): the peer stops and says so, rather
than wait on silently.
"""

from __future__ import annotations

from dataclasses import dataclass

from logs.clock import NS_PER_S

ON_PEER_START = "peer start"
ON_FIRST_COMMAND = "first wheel command"
DEFAULT_TIMEOUT_S = 120.0  # covers a first `rover run` on a cold numba cache (76 s seen at load 7)


@dataclass
class ScenarioStart:
    """How the peer's scenario starts (``on``: ``ON_PEER_START`` or ``ON_FIRST_COMMAND``) and when.

    ``peer_start_ns``: when the peer started stepping, on its clock; ``timeout_ns`` (on the first
    command only; None: no limit): how long it waits for one from then. ``started_ns``: the scenario's
    time zero on that clock, None while it is held; ``timed_out``: the wait ran out.
    """

    on: str
    peer_start_ns: int
    timeout_ns: int | None = None
    started_ns: int | None = None
    timed_out: bool = False

    def __post_init__(self) -> None:
        if self.on not in (ON_PEER_START, ON_FIRST_COMMAND):
            choices = f"{ON_PEER_START!r} or {ON_FIRST_COMMAND!r}"
            raise ValueError(f"a scenario starts on {choices}, not {self.on!r}")
        if self.timeout_ns is not None and self.timeout_ns <= 0:
            raise ValueError(f"the wait for the first wheel command must be > 0 ns, got {self.timeout_ns}")
        if self.on == ON_PEER_START:
            self.started_ns = self.peer_start_ns

    @property
    def held(self) -> bool:
        return self.started_ns is None and not self.timed_out

    def start(self, now_ns: int) -> str:
        """The scenario started at ``now_ns``; returns the words the peer records for it."""
        self.started_ns = now_ns
        return (
            f"scenario started on the rover's first wheel command, {self.held_s(now_ns):.2f} s after the "
            "peer started: its faults and moving obstacles count from here"
        )

    def expired(self, now_ns: int) -> str | None:
        """If the wait for the first command has run out at ``now_ns``: marks it and returns the words
        the peer records and stops on; else None."""
        if self.timeout_ns is None or now_ns - self.peer_start_ns < self.timeout_ns:
            return None
        self.timed_out = True
        return self.describe()

    def held_s(self, now_ns: int) -> float:
        """How long the scenario was (or is, at ``now_ns``) held after the peer's start."""
        end = now_ns if self.started_ns is None else self.started_ns
        return (end - self.peer_start_ns) / NS_PER_S

    def status(self, now_ns: int) -> dict[str, object]:
        """The status file's entries: how the scenario starts, when it did (None: not yet), how long it
        was held, whether the wait ran out."""
        return {
            "scenario_start": self.on,
            "scenario_started_ns": self.started_ns,
            "scenario_held_s": self.held_s(now_ns),
            "scenario_start_timed_out": self.timed_out,
        }

    def record(self) -> dict[str, str]:
        """The ``world`` record's entries beside ``epoch_ns``: what started the scenario, and when the
        peer did (both on the clock that stamps the recording)."""
        return {"start": self.on, "peer_start_ns": str(self.peer_start_ns)}

    def describe(self) -> str:
        """One line for the operator at the end of the run."""
        if self.started_ns is not None:
            if self.on == ON_PEER_START:
                return "scenario started with the peer"
            held_s = self.held_s(self.started_ns)
            return f"scenario started on the rover's first wheel command, {held_s:.2f} s after the peer"
        if self.timed_out:
            assert self.timeout_ns is not None
            return (
                f"no wheel command from the rover within {self.timeout_ns / NS_PER_S:g} s of the peer's "
                "start: the scenario never started (is `rover run` running, with the rover-hil.toml the "
                "peer wrote, on the same CAN bus?)"
            )
        return "the peer stopped before the rover's first wheel command: the scenario never started"
