"""``hil.replay``: a recording's inputs through the onboard stack again.

Under the config the trial ran with, the replay must give every topic of the trial back byte for byte (the
stack is deterministic and takes its clock and links as arguments, so fed the same bytes at the same clock
readings it must do the same). Under another config it must say which values changed and what that did.
Bad recordings get typed errors or counted rejections, never a crash.
"""

from __future__ import annotations

import collections
import itertools
import json
import logging
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hil.recorded_obstacles import RecordedObstacles
from hil.replay import ReplayError, replay_recording
from hil.replay_figures import replay_figures
from hil.scenario import load_scenario
from hil.trial import TrialResult, run_trial
from logs import topics
from logs.commands import RoverCommand
from logs.errors import LogReadError, RecordingError
from logs.reader import read_messages, read_metadata
from navigator.onboard import OnboardStack
from tests.hil.replay_trials import DATA, config_of, digests, rover_run_config
from tests.mcap_rewrite import rewrite


@pytest.mark.parametrize("name", ["small_rocky", "hidden_rock", "sandy_cart_glitch"])
def test_replayed_under_its_own_config_a_trial_gives_every_topic_back(
    trials: dict[str, Path], name: str, tmp_path: Path
) -> None:
    result = replay_recording(trials[name], config_of(), tmp_path / "replay.mcap")
    original, replayed = digests(trials[name]), digests(tmp_path / "replay.mcap")
    assert replayed == original  # the stack's topics, can/frames and mavlink/raw both ways, the copied truth
    assert result.ticks == original[topics.NAVIGATOR_STATE][0]
    assert result.wheel_commands_compared == result.ticks and result.wheel_commands_differing == 0
    assert result.first_difference_s is None and result.config_changes == ()
    assert result.rejected_inputs == 0 and not result.truncated
    if name == "sandy_cart_glitch":  # the simulator's fault lines, copied, beside the stack's own
        assert result.copied_messages > original[topics.TRUTH_POSE][0] * 3
    if name == "small_rocky":  # objects perception: the recorded observations were the stack's input
        assert result.obstacle_records == original[topics.PERCEPTION_OBSTACLES][0] > 0
    if name == "hidden_rock":  # scans arrive over MAVLink: perception/obstacles is the stack's output
        assert result.obstacle_records == 0 and topics.PERCEPTION_OBSTACLES in original


def test_another_config_is_named_and_changes_the_estimate_not_the_truth(
    trials: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "replay.mcap"
    result = replay_recording(trials["small_rocky"], config_of("[estimator]\ngps_noise_m = 2.0\n"), out)
    assert result.config_changes == (("estimator.gps_noise_m", "0.5", "2.0"),)
    original, replayed = digests(trials["small_rocky"]), digests(out)
    assert replayed[topics.ESTIMATOR_POSE] != original[topics.ESTIMATOR_POSE]
    for topic in (topics.TRUTH_POSE, topics.TRUTH_WHEELS, topics.TRUTH_STABILITY):
        assert replayed[topic] == original[topic]
    assert result.copied_messages == sum(original[t][0] for t in original if t.startswith("truth/"))
    metadata = read_metadata(out)
    assert metadata["replay"]["of"] == str(trials["small_rocky"])
    assert metadata["config"]["estimator.gps_noise_m"] == "2.0"
    assert metadata["scenario"] == read_metadata(trials["small_rocky"])["scenario"]
    figures = replay_figures(trials["small_rocky"], out)
    error_rms = figures.position_error_rms
    assert error_rms.recorded is not None and error_rms.replayed is not None
    assert error_rms.recorded != error_rms.replayed
    assert figures.estimate_shift_rms_m is not None and 0.0 < figures.estimate_shift_rms_m < 1.0


def test_a_rover_run_recording_replays_on_the_configs_map(trials: dict[str, Path], tmp_path: Path) -> None:
    """A `rover run` recording has no scenario: the map is the config's [map], the datum its [estimator]'s,
    and no goal is given but what arrived on the links. The estimator sees the same inputs: the same poses."""
    run = rewrite(
        trials["small_rocky"],
        tmp_path / "run.mcap",
        keep=lambda topic: not topic.startswith("truth/"),
        metadata=lambda name, data: {**data, "mode": "rover-run"} if name == "trial" else data,
    )
    result = replay_recording(run, rover_run_config(), tmp_path / "replay.mcap")
    assert result.source_mode == "rover-run" and result.copied_messages == 0
    original, replayed = digests(run), digests(tmp_path / "replay.mcap")
    assert result.ticks == original[topics.NAVIGATOR_STATE][0]
    assert replayed[topics.ESTIMATOR_POSE] == original[topics.ESTIMATOR_POSE]
    # No goal was given (the trial's came from its scenario): the replayed rover never drives.
    assert result.wheel_commands_differing > 0


def test_a_rover_run_replay_takes_each_plan_in_a_tick_after_asking(tmp_path: Path) -> None:
    """`rover run` plans on a worker thread: a plan asked for in one tick is taken in by the next. A trial
    plans inline, in the same tick. Replayed as a `rover run` recording, a trial's replan for a ground
    station's goal at 3.00 s comes a tick later, at 3.02 s."""
    goal = RoverCommand("goal", 3_000_000_000, 12.0, 3.0)
    trial = run_trial(
        load_scenario(DATA / "small_rocky.toml"),
        config_of(),
        tmp_path / "trial",
        commands=_GroundStation([goal]),
    )
    run = rewrite(
        trial.mcap_path,
        tmp_path / "run.mcap",
        metadata=lambda name, data: {**data, "mode": "rover-run"} if name == "trial" else data,
    )
    replay_recording(run, rover_run_config(), tmp_path / "replay.mcap")
    inline = [t for t, _ in _records(run, topics.NAVIGATOR_PATH) if t >= goal.received_ns]
    a_tick_late = [t for t, _ in _records(tmp_path / "replay.mcap", topics.NAVIGATOR_PATH)]
    assert inline[0] == goal.received_ns and a_tick_late[0] == goal.received_ns + _GroundStation.TICK_NS


def test_numbers_too_large_for_a_float_are_no_crash(trials: dict[str, Path], tmp_path: Path) -> None:
    """A recorded wheel command and an estimated pose holding a 400-digit number (JSON allows it): the
    replay and its figures finish, the comparison calling that tick as far apart as can be."""
    huge = str(10**400).encode()

    def spoil(topic: str, log_time_ns: int, payload: bytes) -> bytes:
        if log_time_ns != 4_000_000_000:
            return payload
        record = json.loads(payload)
        if topic == topics.WHEELS_COMMAND:
            record["speed_mps"][0] = 0.0
            return json.dumps(record).encode().replace(b"[0.0,", b"[" + huge + b",", 1)
        if topic == topics.ESTIMATOR_POSE:
            record["pose"]["position"]["x"] = 0.0
            return json.dumps(record).encode().replace(b'"x": 0.0', b'"x": ' + huge, 1)
        return payload

    spoiled = rewrite(trials["small_rocky"], tmp_path / "spoiled.mcap", data=spoil)
    scenario = load_scenario(DATA / "small_rocky.toml")
    result = replay_recording(spoiled, config_of(), tmp_path / "replay.mcap", scenario=scenario)
    assert result.wheel_commands_differing == 1 and result.wheel_speed_difference_max_mps == float("inf")
    figures = replay_figures(spoiled, tmp_path / "replay.mcap")
    assert figures.position_error_rms.recorded is not None and figures.estimate_shift_rms_m is not None


class _GroundStation:
    """A ``CommandSource`` giving each scripted command at the stack's tick of its time: the stack polls
    once a tick, every 20 ms of a lockstep trial from 20 ms on."""

    TICK_NS = 20_000_000

    def __init__(self, script: list[RoverCommand]) -> None:
        self._script = script
        self._polls = 0
        self.last_contact_ns: int | None = None

    def poll(self) -> list[RoverCommand]:
        self._polls += 1
        now = self._polls * self.TICK_NS
        due = [c for c in self._script if c.received_ns <= now]
        self._script = [c for c in self._script if c.received_ns > now]
        if due:
            self.last_contact_ns = due[-1].received_ns
        return due


def test_ground_station_commands_are_recorded_and_replayed(tmp_path: Path) -> None:
    """A goal, an e-stop and a resume over Zenoh, recorded on ground/commands as the stack takes them: the
    trial they changed replays to itself byte for byte."""
    script = [
        RoverCommand("goal", 3_000_000_000, 12.0, 3.0),
        RoverCommand("estop", 6_000_000_000),
        RoverCommand("resume", 7_000_000_000),
    ]
    trial = run_trial(
        load_scenario(DATA / "small_rocky.toml"),
        config_of(),
        tmp_path / "trial",
        commands=_GroundStation(script),
    )
    original = digests(trial.mcap_path)
    assert original[topics.GROUND_COMMANDS][0] == 3
    result = replay_recording(trial.mcap_path, config_of(), tmp_path / "replay.mcap")
    assert result.ground_commands == 3
    assert digests(tmp_path / "replay.mcap") == original
    assert result.wheel_commands_differing == 0
    # Without them the replayed rover drives to the scenario's goal instead, never stopping.
    without = rewrite(trial.mcap_path, tmp_path / "without.mcap", keep=lambda t: t != topics.GROUND_COMMANDS)
    scenario = load_scenario(DATA / "small_rocky.toml")
    blind = replay_recording(without, config_of(), tmp_path / "blind.mcap", scenario=scenario)
    assert blind.ground_commands == 0 and blind.wheel_commands_differing > 0
    assert blind.first_difference_s == pytest.approx(3.0, abs=0.05)


def test_links_read_between_ticks_are_read_there_again(tmp_path: Path) -> None:
    """As `rover run`'s loop does, the stack reads its links between ticks (``ingest``): here after every
    odd physics tick, 10 ms before each control tick. Those inputs are recorded at their read time, and the
    replay reads them at that time again: the run replays to itself, the CAN link's bus-load windows aside."""

    def ingest(tick: int, stack: OnboardStack) -> None:
        if tick % 2 == 1:
            stack.ingest()

    trial = _trial_acting_between_ticks(ingest, tmp_path)
    ticks_ns = {t for t, _ in _records(trial.mcap_path, topics.NAVIGATOR_STATE)}
    between = [
        t
        for t, m in _records(trial.mcap_path, topics.MAVLINK_RAW)
        if m["direction"] == "rx" and t not in ticks_ns
    ]
    assert between  # the autopilot's frames were read between ticks
    result = replay_recording(trial.mcap_path, config_of(), tmp_path / "replay.mcap")
    assert result.ingests > 0 and result.wheel_commands_differing == 0
    original, replayed = digests(trial.mcap_path), digests(tmp_path / "replay.mcap")
    # can/stats closes its one-second window at the first read a second after the link's first read, and a
    # read that found nothing leaves no record to replay (here the first, at 10 ms): its windows may close
    # a read later. Everything else is the same bytes.
    assert replayed[topics.CAN_STATS][0] == original[topics.CAN_STATS][0]
    del replayed[topics.CAN_STATS], original[topics.CAN_STATS]
    assert replayed == original


def test_a_command_line_goal_is_given_again_at_its_time(tmp_path: Path) -> None:
    """`rover run --goal` hands its goal to the stack at once, outside a tick (``take_command``, origin
    "command line"): recorded on ground/commands at that time, and given again there by the replay."""

    def goal(tick: int, stack: OnboardStack) -> None:
        if tick == 301:  # 3.01 s: between the control ticks at 3.00 and 3.02 s
            stack.take_command(RoverCommand("goal", 3_010_000_000, 12.0, 3.0, origin="command line"))

    trial = _trial_acting_between_ticks(goal, tmp_path)
    (record,) = _records(trial.mcap_path, topics.GROUND_COMMANDS)
    assert record[0] == 3_010_000_000 and record[1]["origin"] == "command line"
    result = replay_recording(trial.mcap_path, config_of(), tmp_path / "replay.mcap")
    assert result.ground_commands == 1 and result.wheel_commands_differing == 0
    assert digests(tmp_path / "replay.mcap") == digests(trial.mcap_path)


def _trial_acting_between_ticks(act: Callable[[int, OnboardStack], None], tmp_path: Path) -> TrialResult:
    """small_rocky in lockstep, with ``act(physics tick number, stack)`` after each physics tick: the odd
    ones fall between control ticks, where `rover run`'s loop also acts."""

    def after_each_physics_tick(components: dict[str, Any]) -> None:
        world, stack = components["world"], components["onboard"]
        world_tick = world.tick
        ticks = itertools.count(1)

        def tick_then_act(dt_s: float) -> None:
            world_tick(dt_s)
            act(next(ticks), stack)

        world.tick = tick_then_act

    return run_trial(
        load_scenario(DATA / "small_rocky.toml"),
        config_of(),
        tmp_path / "trial",
        on_components=after_each_physics_tick,
    )


def _records(path: Path, topic: str) -> list[tuple[int, dict[str, Any]]]:
    return [(m.log_time_ns, m.message) for m in read_messages(path, [topic])]


def test_without_its_attached_scenario_a_trial_needs_one_given(
    trials: dict[str, Path], tmp_path: Path
) -> None:
    bare = rewrite(trials["small_rocky"], tmp_path / "bare.mcap")  # the rewrite keeps no attachment
    with pytest.raises(ReplayError, match=r"no scenario\.toml attached"):
        replay_recording(bare, config_of(), tmp_path / "replay.mcap")
    assert not (tmp_path / "replay.mcap").exists()  # refused before anything was written
    scenario = load_scenario(DATA / "small_rocky.toml")
    result = replay_recording(bare, config_of(), tmp_path / "given.mcap", scenario=scenario)
    assert result.wheel_commands_differing == 0 and result.ticks > 0


@pytest.mark.parametrize(
    ("metadata", "message"),
    [
        ({"mode": "sim-realtime-peer"}, "a HIL peer's truth file"),
        ({"mode": "bench"}, "trial.mode 'bench' is not a recording of the onboard stack"),
        (None, "no trial metadata"),
    ],
)
def test_a_recording_of_no_onboard_stack_is_refused(
    trials: dict[str, Path], tmp_path: Path, metadata: dict[str, str] | None, message: str
) -> None:
    def trial_record(name: str, data: dict[str, str]) -> dict[str, str]:
        if name != "trial":
            return data
        return {"other": "x"} if metadata is None else {**data, **metadata}

    other = rewrite(trials["small_rocky"], tmp_path / "other.mcap", metadata=trial_record)
    with pytest.raises(ReplayError, match=message):
        replay_recording(other, config_of(), tmp_path / "replay.mcap")


def test_a_rover_run_recording_without_a_map_in_the_config_is_refused(
    trials: dict[str, Path], tmp_path: Path
) -> None:
    run = rewrite(
        trials["small_rocky"],
        tmp_path / "run.mcap",
        metadata=lambda name, data: {**data, "mode": "rover-run"} if name == "trial" else data,
    )
    with pytest.raises(ReplayError, match=r"\[map\]"):
        replay_recording(run, config_of(), tmp_path / "replay.mcap")


def test_an_existing_output_is_never_written_over(trials: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "replay.mcap"
    out.write_bytes(b"an earlier replay")
    with pytest.raises(RecordingError, match="already exists"):
        replay_recording(trials["small_rocky"], config_of(), out)
    assert out.read_bytes() == b"an earlier replay"


def test_a_missing_or_foreign_file_is_a_read_error(tmp_path: Path) -> None:
    with pytest.raises(LogReadError):
        replay_recording(tmp_path / "nowhere.mcap", config_of(), tmp_path / "replay.mcap")
    (tmp_path / "text.mcap").write_text("not a recording")
    with pytest.raises(LogReadError):
        replay_recording(tmp_path / "text.mcap", config_of(), tmp_path / "replay2.mcap")


def test_malformed_input_records_are_counted_and_the_rest_replayed(
    trials: dict[str, Path], tmp_path: Path
) -> None:
    """One CAN frame record with a bad id, one MAVLink record whose data is not base64, one obstacle record
    whose radius is text: each is skipped and counted, the replay goes on."""
    spoiled: collections.Counter[str] = collections.Counter()

    def spoil(topic: str, log_time_ns: int, payload: bytes) -> bytes:
        if log_time_ns < 5_000_000_000 or spoiled[topic]:
            return payload
        record = json.loads(payload)
        if record.get("direction", "rx") != "rx":
            return payload
        if topic == topics.CAN_FRAMES:
            record["id"] = -1
        elif topic == topics.MAVLINK_RAW:
            record["data"] = "*not base64*"
        elif topic == topics.PERCEPTION_OBSTACLES and record["obstacles"]:
            record["obstacles"][0]["radius_m"] = "big"
        else:
            return payload
        spoiled[topic] += 1
        return json.dumps(record).encode()

    damaged = rewrite(trials["small_rocky"], tmp_path / "damaged.mcap", data=spoil)
    scenario = load_scenario(DATA / "small_rocky.toml")
    result = replay_recording(damaged, config_of(), tmp_path / "replay.mcap", scenario=scenario)
    assert sum(spoiled.values()) == 3
    assert result.rejected_inputs == 3
    assert result.ticks == digests(damaged)[topics.NAVIGATOR_STATE][0]


def test_unreadable_input_records_and_ticks_back_in_time_are_counted(
    trials: dict[str, Path], tmp_path: Path
) -> None:
    """A mavlink/raw payload that is not JSON (the reader skips it), a CAN record whose direction is a list,
    and a navigator/state a second back in time: each counted, the replay partial, the rest replayed."""
    spoiled: collections.Counter[str] = collections.Counter()

    def spoil(topic: str, log_time_ns: int, payload: bytes) -> bytes:
        if (
            log_time_ns < 3_000_000_000
            or spoiled[topic]
            or topic not in (topics.MAVLINK_RAW, topics.CAN_FRAMES)
        ):
            return payload
        spoiled[topic] += 1
        if topic == topics.MAVLINK_RAW:
            return b"\xff not json"
        return payload.replace(b'"direction":"rx"', b'"direction":["rx"]').replace(
            b'"direction":"tx"', b'"direction":["tx"]'
        )

    def back_in_time(topic: str, log_time_ns: int) -> int:
        return (
            log_time_ns - 1_000_000_000
            if topic == topics.NAVIGATOR_STATE and log_time_ns == 4_000_000_000
            else log_time_ns
        )

    damaged = rewrite(trials["small_rocky"], tmp_path / "damaged.mcap", data=spoil, log_time=back_in_time)
    scenario = load_scenario(DATA / "small_rocky.toml")
    result = replay_recording(damaged, config_of(), tmp_path / "replay.mcap", scenario=scenario)
    assert dict(spoiled) == {topics.MAVLINK_RAW: 1, topics.CAN_FRAMES: 1}
    assert result.rejected_inputs == 2 and result.ticks_skipped == 1 and result.partial
    assert result.ticks == digests(damaged)[topics.NAVIGATOR_STATE][0] - 1


def test_a_recording_with_nothing_to_replay_leaves_no_output(trials: dict[str, Path], tmp_path: Path) -> None:
    no_ticks = rewrite(
        trials["small_rocky"], tmp_path / "no_ticks.mcap", keep=lambda t: t != topics.NAVIGATOR_STATE
    )
    scenario = load_scenario(DATA / "small_rocky.toml")
    with pytest.raises(ReplayError, match="no onboard ticks"):
        replay_recording(no_ticks, config_of(), tmp_path / "replay.mcap", scenario=scenario)
    assert not (tmp_path / "replay.mcap").exists()
    # So the same --out can be given again once the input is right.
    assert replay_recording(trials["small_rocky"], config_of(), tmp_path / "replay.mcap").ticks > 0


def test_a_damaged_recording_replays_up_to_the_damage(trials: dict[str, Path], tmp_path: Path) -> None:
    whole = bytearray(trials["small_rocky"].read_bytes())
    middle = len(whole) // 2
    whole[middle : middle + 64] = bytes(64)  # a chunk's bytes zeroed: its CRC fails or it does not parse
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(whole))
    scenario = load_scenario(DATA / "small_rocky.toml")
    result = replay_recording(damaged, config_of(), tmp_path / "replay.mcap", scenario=scenario)
    assert result.truncated and result.partial
    assert 0 < result.ticks < digests(trials["small_rocky"])[topics.NAVIGATOR_STATE][0]
    assert result.wheel_commands_differing == 0


def test_a_cut_recording_replays_up_to_the_cut(trials: dict[str, Path], tmp_path: Path) -> None:
    whole = trials["small_rocky"].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole[: len(whole) // 2])
    result = replay_recording(
        cut, config_of(), tmp_path / "replay.mcap", scenario=load_scenario(DATA / "small_rocky.toml")
    )
    assert result.truncated
    total = digests(trials["small_rocky"])[topics.NAVIGATOR_STATE][0]
    assert 0 < result.ticks < total
    assert result.wheel_commands_differing == 0  # what was there replays as it ran
    assert read_metadata(tmp_path / "replay.mcap")["replay"]["truncated"] == "true"


@given(
    st.dictionaries(
        st.sampled_from(["obstacles", "timestamp", "x"]),
        st.one_of(
            st.none(),
            st.integers(),
            st.text(max_size=5),
            st.lists(
                st.one_of(
                    st.none(),
                    st.integers(),
                    st.dictionaries(
                        st.sampled_from(["id", "x", "y", "radius_m", "vx", "vy"]),
                        st.one_of(
                            st.none(),
                            st.booleans(),
                            st.floats(),
                            st.integers(),
                            st.integers(min_value=10**300, max_value=10**400),  # beyond a float
                            st.text(max_size=3),
                        ),
                    ),
                ),
                max_size=4,
            ),
        ),
    )
)
def test_recorded_obstacles_take_any_record_without_raising(record: dict[str, object]) -> None:
    source = RecordedObstacles()
    source.add(7, record)
    seen = source.poll()
    entries = record.get("obstacles")
    offered = len(entries) if isinstance(entries, list) else 1
    assert len(seen) + source.rejected == offered
    for observation in seen:
        assert observation.t_ns == 7 and observation.radius_m > 0.0
    assert source.poll() == []


def test_the_stacks_own_marks_are_no_input_and_a_record_of_them_alone_is_not_fed() -> None:
    """Where the rover dug in (navigator.recovery) it marks the spot on perception/obstacles itself: the
    replayed stack marks it again, so the mark is left out and a record of marks alone counts as nothing
    fed (the replay said "2 obstacle records fed" of a map with no obstacles)."""
    mark = {"id": "dug-in-1", "x": 15.4, "y": 3.1, "radius_m": 0.35, "vx": 0.0, "vy": 0.0}
    cart = {"id": "cart", "x": 5.0, "y": 3.0, "radius_m": 0.4, "vx": 1.0, "vy": 0.0}
    source = RecordedObstacles()
    assert source.add(7, {"obstacles": [mark]}) is False and source.poll() == []
    assert source.add(8, {"obstacles": [mark, cart]}) is True
    assert [o.obstacle_id for o in source.poll()] == ["cart"]


def _replay_cli(recording: Path, config: Path, out: Path, *extra: str) -> int:
    from rover_cli.main import main

    return main(["logs", "replay", str(recording), "--config", str(config), "--out", str(out), *extra])


def test_rover_logs_replay_prints_what_changed_and_exits_by_outcome(
    trials: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "noisy.toml"
    config.write_text("[estimator]\ngps_noise_m = 2.0\n")
    assert _replay_cli(trials["small_rocky"], config, tmp_path / "replay.mcap", "--json") == 0
    document = json.loads(capsys.readouterr().out)
    assert document["config_changes"] == [
        {"key": "estimator.gps_noise_m", "recorded": "0.5", "replayed": "2.0"}
    ]
    assert document["ticks"] == document["wheel_commands_compared"] > document["wheel_commands_differing"] > 0
    assert document["figures"]["estimator position error RMS (m, vs truth)"]["replayed"] > 0.0
    # Bad input: nothing replayed, exit 2 naming it.
    assert _replay_cli(tmp_path / "nowhere.mcap", config, tmp_path / "x.mcap") == 2
    assert "nowhere.mcap" in capsys.readouterr().out
    (tmp_path / "broken.toml").write_text("[estimator]\ngps_noise_m = -1\n")
    assert _replay_cli(trials["small_rocky"], tmp_path / "broken.toml", tmp_path / "y.mcap") == 2
    assert "gps_noise_m" in capsys.readouterr().out
    # A cut recording: replayed up to the cut, exit 1 (not all of it).
    whole = trials["small_rocky"].read_bytes()
    (tmp_path / "cut.mcap").write_bytes(whole[: len(whole) // 2])
    assert _replay_cli(tmp_path / "cut.mcap", config, tmp_path / "z.mcap") == 1
    assert "cut short" in capsys.readouterr().out
    # Printed as a table too.
    assert _replay_cli(trials["small_rocky"], config, tmp_path / "table.mcap") == 0
    printed = capsys.readouterr().out
    assert "estimator.gps_noise_m" in printed and "wheel commands differing" in printed


def test_a_cut_recording_replayed_is_said_to_be_cut_once(
    trials: dict[str, Path], tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    whole = trials["small_rocky"].read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(whole[: len(whole) // 2])
    config = tmp_path / "rover.toml"
    config.write_text("")
    caplog.set_level(logging.WARNING, logger="logs.reader")
    scenario = DATA / "small_rocky.toml"
    code = _replay_cli(cut, config, tmp_path / "r.mcap", "--scenario", str(scenario))
    assert code == 1
    notices = [r for r in caplog.records if r.name == "logs.reader" and "cut" in r.getMessage()]
    assert len(notices) == 1, [r.getMessage() for r in notices]
