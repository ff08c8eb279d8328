import random
import time

import can
import pytest

from firmware_bridge.can_bus import CanConfig
from firmware_bridge.can_health import (
    CAN_ERR_CRTL_ACTIVE,
    CAN_ERR_CRTL_RX_PASSIVE,
    CAN_ERR_CRTL_TX_PASSIVE,
    BusSignal,
    ControllerLiveness,
    classify_bus_state,
    classify_error_frame,
)
from firmware_bridge.can_link import CanLink, CanLinkState
from hil.vesc_sim import SimVescBank
from logs.clock import MonotonicClock, SimClock, to_ns
from logs.reader import read_messages
from logs.recorder import McapRecorder
from logs.sink import MemorySink
from logs.topics import CAN_FRAMES, SAFETY_EVENTS
from tests.firmware_bridge.faulty_bus import CAN_ERR_CRTL, FaultyBus, error_frame
from tests.firmware_bridge.virtual_can import TEST_PROFILE, make_codec, virtual_bus_pair

TICK_NS = to_ns(0.01)
DRIVE = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0]


@pytest.fixture
def buses(request):
    with virtual_bus_pair(request.node.name) as pair:
        yield pair


@pytest.mark.parametrize(
    ("msg", "signal"),
    [
        (error_frame(0x40), BusSignal.BUS_OFF),
        (error_frame(0x100), BusSignal.BACK),
        (error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_PASSIVE), BusSignal.ERROR_PASSIVE),
        (error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_PASSIVE), BusSignal.ERROR_PASSIVE),
        (error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_ACTIVE), BusSignal.BACK),
        (error_frame(0x08), BusSignal.NONE),  # protocol violation: counted, no state change
        (error_frame(CAN_ERR_CRTL, 0x04), BusSignal.NONE),  # only the RX warning level
    ],
)
def test_error_frames_are_classified_as_linux_lays_them_out(msg, signal):
    assert classify_error_frame(msg) is signal


def test_interface_bus_state_is_classified():
    assert classify_bus_state(can.BusState.ERROR) is BusSignal.BUS_OFF
    assert classify_bus_state(can.BusState.PASSIVE) is BusSignal.ERROR_PASSIVE
    assert classify_bus_state(can.BusState.ACTIVE) is BusSignal.NONE


class Rig:
    """Lockstep: the onboard link on a bus that can fail, six simulated VESCs on the other end."""

    def __init__(self, buses, clock, sink):
        ours, theirs = buses
        self.clock = clock
        self.bus = FaultyBus(ours)
        self.link = CanLink(self.bus, make_codec(), clock, sink)
        self.sim = SimVescBank(theirs, make_codec(), clock)

    def run(self, seconds, speeds=DRIVE):
        """100 Hz physics, 50 Hz control: poll then command, as the onboard loop does."""
        for tick in range(round(seconds / 0.01)):
            self.sim.poll()
            self.clock.advance(TICK_NS)
            self.sim.step(0.01)
            if tick % 2 == 1:
                self.link.poll()
                self.link.send_wheel_speeds(speeds)


def tx_erpm_after(sink, t_ns):
    return [
        int.from_bytes(bytes.fromhex(m["data"]), "big", signed=True)
        for topic, t, m in sink.records
        if topic == CAN_FRAMES and m["direction"] == "tx" and t > t_ns
    ]


def test_bus_off_while_driving_stops_commands_and_resumes_only_after_every_controller(buses, tmp_path):
    clock = SimClock()
    path = tmp_path / "bus_off.mcap"
    with McapRecorder(path) as recorder:
        sink = MemorySink()

        class Both:
            def publish(self, topic, t, message):
                sink.publish(topic, t, message)
                recorder.publish(topic, t, message)

        rig = Rig(buses, clock, Both())
        rig.run(0.5)
        assert rig.link.state is CanLinkState.OK
        assert rig.sim.wheel_speeds_mps() == pytest.approx(DRIVE, abs=0.02)

        rig.bus.go_bus_off()
        rig.link.poll()
        off_ns = clock.now_ns()
        assert rig.link.state is CanLinkState.BUS_OFF
        assert rig.link.send_wheel_speeds(DRIVE) == [0.0] * 6  # at once: nothing goes out
        rig.run(0.3)
        assert tx_erpm_after(sink, off_ns) == []
        assert rig.link.state is CanLinkState.BUS_OFF
        assert not any(rig.link.controllers_alive().values())

        rig.bus.restart()
        restart_ns = clock.now_ns()
        rig.link.poll()
        assert rig.link.state is CanLinkState.RECOVERING
        rig.link.send_wheel_speeds(DRIVE)
        assert tx_erpm_after(sink, restart_ns - 1) == [0] * 6  # zeros until every controller reports
        # Five controllers report; the sixth stays silent: still recovering, still zero.
        for cid in (1, 2, 3, 4, 5):
            rig.bus.inject(make_codec().encode("STATUS", cid, erpm=0, current=0, duty=0))
        rig.link.poll()
        assert rig.link.state is CanLinkState.RECOVERING
        assert rig.link.send_wheel_speeds(DRIVE) == [0.0] * 6
        rig.run(0.1)  # the simulated bank's STATUS round brings the sixth back
        assert rig.link.state is CanLinkState.OK
        assert rig.link.last_sent_erpm == [round(TEST_PROFILE.erpm_from_speed(1.0))] * 6
        rig.run(0.5)
        assert rig.sim.wheel_speeds_mps() == pytest.approx(DRIVE, abs=0.02)
        assert rig.link.counters.withheld >= 15

    kinds = [m["kind"] for m in sink.on(SAFETY_EVENTS)]
    link_kinds = [k for k in kinds if not k.startswith("can_controller")]
    assert link_kinds == ["can_bus_off", "can_recovering", "can_recovered"]
    assert kinds.count("can_controller_silent") == 6 and kinds.count("can_controller_alive") == 6
    recorded = [m.message["kind"] for m in read_messages(path, topics=[SAFETY_EVENTS])]
    assert recorded == kinds


def test_error_passive_sends_zero_and_error_active_starts_recovery(buses):
    clock, sink = SimClock(), MemorySink()
    rig = Rig(buses, clock, sink)
    rig.run(0.2)
    rig.bus.inject(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_PASSIVE))
    rig.link.poll()
    assert rig.link.state is CanLinkState.ERROR_PASSIVE
    assert rig.link.send_wheel_speeds(DRIVE) == [0.0] * 6
    assert rig.link.last_sent_erpm == [0] * 6  # the bus still carries frames: an explicit stop
    rig.bus.inject(error_frame(CAN_ERR_CRTL, CAN_ERR_CRTL_ACTIVE))
    rig.run(0.1)
    assert rig.link.state is CanLinkState.OK
    assert [m["kind"] for m in sink.on(SAFETY_EVENTS)] == [
        "can_error_passive",
        "can_recovering",
        "can_recovered",
    ]
    assert rig.link.counters.bus_errors == 2


def test_interface_reported_bus_off_is_honoured(buses):
    clock, sink = SimClock(), MemorySink()
    rig = Rig(buses, clock, sink)
    rig.run(0.1)
    rig.bus.state = can.BusState.ERROR
    rig.bus.off = True
    rig.link.poll()
    assert rig.link.state is CanLinkState.BUS_OFF
    assert "interface reports it" in sink.on(SAFETY_EVENTS)[0]["detail"]


def test_a_round_of_failed_sends_means_bus_off(buses):
    clock, sink = SimClock(), MemorySink()
    rig = Rig(buses, clock, sink)
    rig.bus.off = True  # e.g. the interface went down: every send fails, no error frame arrives
    rig.link.send_wheel_speeds(DRIVE)
    assert rig.link.state is CanLinkState.BUS_OFF
    assert rig.link.counters.bus_errors == 6
    assert sink.on(SAFETY_EVENTS)[0]["kind"] == "can_bus_off"


def test_silent_controller_is_a_fault_until_heard_again(buses):
    clock, sink = SimClock(), MemorySink()
    ours, theirs = buses
    link = CanLink(ours, make_codec(), clock, sink, config=CanConfig(status_rate_hz=50.0, liveness_periods=3))
    codec = make_codec()

    def statuses(ids):
        for cid in ids:
            theirs.send(codec.encode("STATUS", cid, erpm=0, current=0, duty=0))

    for _ in range(3):
        clock.advance(to_ns(0.02))
        statuses(range(1, 7))
        link.poll()
    assert all(link.controllers_alive().values())
    for _ in range(3):
        clock.advance(to_ns(0.02))
        statuses((1, 2, 4, 5, 6))
        link.poll()
    assert link.controllers_alive()[3]  # 60 ms silent: at the limit, not past it
    clock.advance(to_ns(0.02))
    statuses((1, 2, 4, 5, 6))
    link.poll()
    assert link.controllers_alive() == {1: True, 2: True, 3: False, 4: True, 5: True, 6: True}
    (event,) = sink.on(SAFETY_EVENTS)
    assert event["kind"] == "can_controller_silent"
    assert (
        event["detail"] == "motor controller of wheel 2 (left rear, CAN id 3) silent for 80 ms (limit 60 ms)"
    )
    statuses((3,))
    link.poll()
    assert link.controllers_alive()[3]
    assert sink.on(SAFETY_EVENTS)[-1]["kind"] == "can_controller_alive"
    assert link.state is CanLinkState.OK  # liveness reports; the safety supervisor decides


def test_keep_alive_repeats_fresh_commands_at_the_command_rate_then_zero(buses):
    clock, sink = SimClock(), MemorySink()
    ours, theirs = buses
    link = CanLink(ours, make_codec(), clock, sink, config=CanConfig(command_max_age_s=0.2))
    wanted = round(TEST_PROFILE.erpm_from_speed(1.0))
    link.keep_alive()  # nothing commanded yet: nothing to repeat
    assert link.counters.tx == 0
    link.send_wheel_speeds(DRIVE)
    link.keep_alive()  # the round just sent is not repeated
    clock.advance(to_ns(0.01))
    link.keep_alive()  # half a period
    assert link.counters.resent == 0
    erpm_seen = []
    for _ in range(21):  # 10 ms steps, 20 ms .. 220 ms
        clock.advance(to_ns(0.01))
        link.keep_alive()
        erpm_seen.append(link.last_sent_erpm[0])
    assert link.counters.resent == 11  # every other step: the 50 Hz rate, not the 100 Hz calls
    assert link.counters.stale_zeroed == 1
    assert erpm_seen[0] == wanted and erpm_seen[-1] == 0
    # once stale, zero keeps going out at the rate and the old command never comes back
    for _ in range(10):
        clock.advance(to_ns(0.02) + 1)
        link.keep_alive()
    assert tx_erpm_after(sink, to_ns(0.221))[-6:] == [0] * 6
    assert set(tx_erpm_after(sink, to_ns(0.22))) == {0}
    frames = []
    while (msg := theirs.recv(timeout=0)) is not None:
        frames.append(msg)
    assert len(frames) == link.counters.tx


def wait_for(condition, timeout_s=5.0):
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise TimeoutError("condition not met in time")
        time.sleep(0.005)


@pytest.mark.realtime
def test_threaded_link_repeats_by_itself_and_stops_a_stalled_loop(buses):
    ours, theirs = buses
    sink = MemorySink()
    config = CanConfig(command_rate_hz=50.0, command_max_age_s=0.2)
    link = CanLink(ours, make_codec(), MonotonicClock(), sink, config=config, threaded=True)
    try:
        link.send_wheel_speeds(DRIVE)
        # The loop now stalls: the repeater keeps the command alive, then zeros it.
        wait_for(lambda: link.counters.stale_zeroed == 1)
        wait_for(lambda: link.counters.resent >= 12)
        theirs.send(make_codec().encode("STATUS", 2, erpm=1234, current=1.0, duty=0.1))
        wait_for(lambda: link.poll() > 0 and link.readings()[1].erpm == 1234.0)
    finally:
        link.close()
    erpm = [
        int.from_bytes(m.data, "big", signed=True)
        for m in iter(lambda: theirs.recv(timeout=0), None)
        if m.arbitration_id >> 8 == 3
    ]
    wanted = round(TEST_PROFILE.erpm_from_speed(1.0))
    assert erpm[:12] == [wanted] * 12  # first round plus at least one repeat
    first_zero = erpm.index(0)
    assert set(erpm[first_zero:]) == {0}  # never the old command after it went stale
    assert 0.1 <= (first_zero // 6) * 0.02 <= 0.3
    # background records reached the sink from the loop's thread at poll()/close()
    assert len([m for m in sink.on(CAN_FRAMES) if m["direction"] == "tx"]) == link.counters.tx


@pytest.mark.parametrize("seed", range(4))
def test_liveness_skips_checks_only_while_no_controller_can_be_silent(seed):
    """check() returns early until the earliest living controller's limit (hot path: every poll); its
    changes are those of looking at every controller each time, through hearings, silences, revivals and
    start()."""
    rng = random.Random(seed)
    ids, limit = (1, 2, 3), 60
    liveness = ControllerLiveness(ids, limit, 0)
    last, alive = dict.fromkeys(ids, 0), dict.fromkeys(ids, True)
    now = 0
    for _ in range(2000):
        now += rng.choice([0, 1, 7, 20, 45])
        action = rng.random()
        if action < 0.5:
            cid = rng.choice(ids)
            change = liveness.heard(cid, now)
            assert (change is not None) == (not alive[cid])
            last[cid], alive[cid] = now, True
        elif action < 0.53:
            liveness.start(now)
            last = {cid: max(t, now) for cid, t in last.items()}
        else:
            silent = [cid for cid in ids if alive[cid] and now - last[cid] > limit]
            changes = liveness.check(now)
            assert [c.kind for c in changes] == ["can_controller_silent"] * len(silent)
            for cid in silent:
                alive[cid] = False
        assert liveness.alive() == alive


def test_a_bus_that_keeps_python_cans_fixed_state_is_not_asked_for_it(buses):
    """BusABC.state is ACTIVE for ever: a poll asks only a bus whose class gives its own state."""

    class Tracking(can.BusABC):
        asked = 0

        def __init__(self, inner: can.BusABC) -> None:
            super().__init__(channel="tracking")
            self._inner = inner

        @property  # type: ignore[misc]  # read-only: this bus only reports its state
        def state(self) -> can.BusState:
            Tracking.asked += 1
            return can.BusState.ACTIVE

        def send(self, msg: can.Message, timeout: float | None = None) -> None:
            self._inner.send(msg)

        def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
            return self._inner.recv(timeout=0), False

    clock = SimClock()
    plain = CanLink(buses[0], make_codec(), clock, MemorySink())
    tracking = CanLink(Tracking(buses[0]), make_codec(), clock, MemorySink())
    assert not plain._bus_tracks_state and tracking._bus_tracks_state
    tracking.poll()
    assert Tracking.asked == 1
