"""Faults over time, in PX4's failure vocabulary: what breaks, how, from when, for how long.

A scenario lists ``[[faults]]``; each names a ``target`` (what breaks) and a ``kind`` (how it breaks, PX4's
``failure`` command words: off, stuck, garbage, wrong, slow, delayed, intermittent), a start time and
optionally a duration. Which kinds a target supports, and what each means here:

========  =============  =====================================================================
target    kind           effect
========  =============  =====================================================================
gps       off            no GPS_RAW_INT at all (loss)
gps       wrong          fixes offset by ``offset_m`` (a glitch / multipath jump)
gps       delayed        fixes report the position of ``delay_s`` ago (latency)
gps       slow           fixes at the rate divided by ``factor``
gps       intermittent   each fix dropped with ``probability``
gps       garbage        every fix: type 0 (no fix), 0 satellites, position nonsense
imu       wrong          gyro / accel biased by ``gyro_bias_rps`` / ``accel_bias_mps2`` (3-vectors)
imu       stuck          the same reading repeated (frozen sensor)
imu       off            no SCALED_IMU
can       off            bus-off: no frame passes either way; the rover's controller is off (hil.bus_off)
can       intermittent   each frame dropped with ``probability``
can       delayed        frames arrive ``delay_s`` late
can       garbage        each frame's payload corrupted with ``probability``
vesc      off            controller ``controller`` (wheel index 0-5) reboots: silent, then fresh state
vesc      stuck          seized wheel ``controller``: no turn, stall current when commanded
mavlink   off            link loss: no byte passes either way
mavlink   garbage        each outgoing chunk corrupted with ``probability`` (seen on ``mavlink/stats``)
battery   wrong          pack sags: ``sag_v`` volts lower and ``extra_resistance_ohm`` more resistance
========  =============  =====================================================================

docs/hil.md lists every parameter with its unit, default and range, and an example of each kind.

Faults are applied by the components they break (``hil.fault_links`` for the wires, the sensor models, the
controllers, the battery); each activation and end is recorded on the ``log`` topic under the name
``hil.faults`` so a recording says what was injected and when.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from firmware_bridge.wheel_names import wheel_label
from logs import topics
from logs.clock import to_ns
from logs.settings import Table
from logs.sink import MessageSink

FAULT_KINDS = ("off", "stuck", "garbage", "wrong", "slow", "delayed", "intermittent")

# target -> the kinds it supports
SUPPORTED: dict[str, tuple[str, ...]] = {
    "gps": ("off", "wrong", "delayed", "slow", "intermittent", "garbage"),
    "imu": ("wrong", "stuck", "off"),
    "can": ("off", "intermittent", "delayed", "garbage"),
    "vesc": ("off", "stuck"),
    "mavlink": ("off", "garbage"),
    "battery": ("wrong",),
}


@dataclass(frozen=True)
class Fault:
    """One fault: ``target`` broken in manner ``kind`` from ``start_ns`` until ``end_ns`` (exclusive)."""

    target: str
    kind: str
    start_ns: int
    end_ns: int  # the trial's end when no duration was given
    offset_m: tuple[float, float] = (0.0, 0.0)
    delay_s: float = 0.0
    factor: float = 1.0
    probability: float = 1.0
    gyro_bias_rps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_bias_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    controller: int = 0
    sag_v: float = 0.0
    extra_resistance_ohm: float = 0.0

    @property
    def name(self) -> str:
        suffix = f"[{self.controller}]" if self.target == "vesc" else ""
        return f"{self.target}{suffix}/{self.kind}"

    def active_at(self, t_ns: int) -> bool:
        return self.start_ns <= t_ns < self.end_ns


@dataclass
class FaultSchedule:
    """The scenario's faults; asked by each component "is my fault active now?".

    Callers ask with their clock's time; fault times count from ``epoch_ns`` on that clock (the world's
    start: 0 in lockstep, the moment the real-time peer started on its monotonic clock).
    """

    faults: tuple[Fault, ...] = ()
    epoch_ns: int = 0
    # The wheels' CAN ids in wheel order (``[vesc] controller_ids``): a vesc fault's log names its wheel as
    # the rover's own messages do (``firmware_bridge.wheel_names``).
    controller_ids: tuple[int, ...] = ()
    _announced: set[int] = field(default_factory=set)
    _ended: set[int] = field(default_factory=set)

    def active(self, target: str, t_ns: int, kind: str | None = None) -> Fault | None:
        """The first fault on ``target`` (of ``kind``, if given) active at ``t_ns``, else None."""
        t_ns -= self.epoch_ns
        for fault in self.faults:
            if fault.target == target and fault.active_at(t_ns) and (kind is None or fault.kind == kind):
                return fault
        return None

    def scheduled(self, target: str, kind: str | None = None) -> bool:
        """Whether any fault on ``target`` (of ``kind``, if given) is scheduled at all."""
        return any(f.target == target and (kind is None or f.kind == kind) for f in self.faults)

    def active_all(self, target: str, t_ns: int) -> list[Fault]:
        t_ns -= self.epoch_ns
        return [f for f in self.faults if f.target == target and f.active_at(t_ns)]

    def next_change_ns(self, t_ns: int) -> float:
        """The first moment after ``t_ns`` (clock time) at which a fault starts or ends, when which faults
        are active and what ``announce`` records next can change; ``math.inf`` when none is left."""
        t_ns -= self.epoch_ns
        moments = [m for f in self.faults for m in (f.start_ns, f.end_ns) if m > t_ns]
        return self.epoch_ns + min(moments) if moments else math.inf

    def announce(self, sink: MessageSink, t_ns: int) -> None:
        """Record each fault's start and end on the ``log`` topic once (call every tick)."""
        log_ns, t_ns = t_ns, t_ns - self.epoch_ns
        for index, fault in enumerate(self.faults):
            if index not in self._announced and t_ns >= fault.start_ns:
                self._announced.add(index)
                _log(
                    sink,
                    log_ns,
                    topics.LOG_WARNING,
                    f"fault injected: {fault.name} ({self._describe(fault)})",
                )
            if index not in self._ended and t_ns >= fault.end_ns:
                self._ended.add(index)
                _log(sink, log_ns, topics.LOG_INFO, f"fault cleared: {fault.name}{self._on_wheel(fault)}")

    def _wheel(self, fault: Fault) -> str | None:
        """The wheel a ``vesc`` fault breaks, named as the rover names it; None for other targets."""
        return wheel_label(fault.controller, self.controller_ids) if fault.target == "vesc" else None

    def _on_wheel(self, fault: Fault) -> str:
        wheel = self._wheel(fault)
        return "" if wheel is None else f" on {wheel}"

    def _describe(self, fault: Fault) -> str:
        wheel = self._wheel(fault)
        return _describe(fault) + ("" if wheel is None else f", on {wheel}")


def _describe(fault: Fault) -> str:
    parts = [f"from {fault.start_ns / 1e9:g} s to {fault.end_ns / 1e9:g} s"]
    if fault.kind == "wrong" and fault.target == "gps":
        parts.append(f"offset {fault.offset_m} m")
    if fault.kind == "delayed":
        parts.append(f"delay {fault.delay_s:g} s")
    if fault.kind == "slow":
        parts.append(f"rate / {fault.factor:g}")
    if _takes_probability(fault.target, fault.kind):
        parts.append(f"probability {fault.probability:g}")
    if fault.target == "imu" and fault.kind == "wrong":
        parts.append(f"gyro bias {fault.gyro_bias_rps} rad/s, accel bias {fault.accel_bias_mps2} m/s2")
    if fault.target == "battery":
        parts.append(f"sag {fault.sag_v:g} V, +{fault.extra_resistance_ohm:g} ohm")
    return ", ".join(parts)


def _log(sink: MessageSink, t_ns: int, level: int, message: str) -> None:
    sink.publish(topics.LOG, t_ns, topics.log_message(t_ns, level, "hil.faults", message))


def faults_from_tables(tables: Sequence[Table], duration_s: float) -> tuple[Fault, ...]:
    """Parse ``[[faults]]`` tables; ``ConfigError`` naming the key on anything wrong."""
    faults = []
    for table in tables:
        target = table.text("target", choices=tuple(SUPPORTED))
        kind = table.text("kind", choices=FAULT_KINDS)
        if kind not in SUPPORTED[target]:
            raise table.error("kind", f"{target} faults can be {', '.join(SUPPORTED[target])}; got {kind!r}")
        start_s = table.number("start_s", 0.0, lo=0.0, hi=duration_s)
        # A fault the trial cannot run (in full) is a mistake in the scenario: say so now, not after the run.
        if start_s >= duration_s:
            raise table.error(
                "start_s", f"{start_s:g} s is not before the scenario's duration_s {duration_s:g} s"
            )
        # Without a duration the fault lasts past the trial's end (it never clears).
        if table.has("duration_s"):
            fault_s = table.number("duration_s", lo=0.0, hi=24 * 3600.0)
            if fault_s == 0.0:  # active from start_s until start_s: it would never happen
                raise table.error(
                    "duration_s",
                    "a fault of 0 s never happens; give it a duration, or leave duration_s out for one that "
                    "lasts until the trial ends",
                )
            end_s = start_s + fault_s
            if end_s > duration_s:
                raise table.error(
                    "duration_s",
                    f"the fault would end at {end_s:g} s, after the scenario's duration_s {duration_s:g} s; "
                    "shorten it, or leave duration_s out for a fault that lasts until the trial ends",
                )
        else:
            end_s = duration_s + 1.0
        fault = Fault(
            target=target,
            kind=kind,
            start_ns=to_ns(start_s),
            end_ns=to_ns(end_s),
            offset_m=_pair(table, "offset_m", target == "gps" and kind == "wrong"),
            delay_s=table.number("delay_s", 0.5, lo=0.0, hi=60.0) if kind == "delayed" else 0.0,
            factor=table.number("factor", 5.0, lo=1.0, hi=1000.0) if kind == "slow" else 1.0,
            probability=(
                table.number("probability", 0.5, lo=0.0, hi=1.0) if _takes_probability(target, kind) else 1.0
            ),
            gyro_bias_rps=_triple(table, "gyro_bias_rps", target == "imu" and kind == "wrong"),
            accel_bias_mps2=_triple(table, "accel_bias_mps2", target == "imu" and kind == "wrong"),
            controller=table.integer("controller", 0, lo=0, hi=5) if target == "vesc" else 0,
            sag_v=table.number("sag_v", 0.0, lo=0.0, hi=100.0) if target == "battery" else 0.0,
            extra_resistance_ohm=(
                table.number("extra_resistance_ohm", 0.0, lo=0.0, hi=100.0) if target == "battery" else 0.0
            ),
        )
        table.finish()
        faults.append(fault)
    return tuple(faults)


def _takes_probability(target: str, kind: str) -> bool:
    """Faults that hit each frame or fix by chance; a GPS gone to garbage reports nonsense on every fix."""
    return kind == "intermittent" or (kind == "garbage" and target != "gps")


def _pair(table: Table, key: str, allowed: bool) -> tuple[float, float]:
    if not allowed:
        return (0.0, 0.0)
    x, y = table.point(key)
    return (x, y)


def _triple(table: Table, key: str, allowed: bool) -> tuple[float, float, float]:
    if not allowed:
        return (0.0, 0.0, 0.0)
    values = table.numbers(key, [0.0, 0.0, 0.0], length=3)
    return (values[0], values[1], values[2])
