"""``ground/commands``: the record of a command the stack took, and the command read back from it."""

from __future__ import annotations

import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from logs.commands import RoverCommand, command_from_record, command_record
from logs.encoding import encode_message
from logs.topics import GROUND_COMMANDS, spec


@pytest.mark.parametrize(
    "command",
    [
        RoverCommand("goal", 1_500_000_001, 12.25, -3.5),
        RoverCommand("goal", 3, 1.0, 2.0, origin="command line"),
        RoverCommand("estop", 7),
        RoverCommand("resume", 0),
    ],
)
def test_a_command_survives_its_record(command: RoverCommand) -> None:
    record = json.loads(encode_message(command_record(2_000_000_000, command)))
    assert record["timestamp"] == {"sec": 2, "nsec": 0}
    assert command_from_record(record) == command


def test_the_record_follows_its_schema() -> None:
    schema = spec(GROUND_COMMANDS).schema
    record = command_record(5, RoverCommand("estop", 3))
    assert set(record) == set(schema["properties"]) == set(schema["required"])


@pytest.mark.parametrize(
    ("record", "match"),
    [
        ({"kind": "launch", "received": {"sec": 0, "nsec": 0}}, "unknown command"),
        ({"kind": "estop"}, "received time"),
        ({"kind": "estop", "received": {"sec": "x", "nsec": 0}}, "received time"),
        ({"kind": "estop", "received": {"sec": -1, "nsec": 0}}, "negative"),
        ({"kind": "estop", "received": {"sec": float("inf"), "nsec": 0}}, "received time"),
        ({"kind": "goal", "x": None, "y": 1.0, "received": {"sec": 0, "nsec": 0}}, "'x'"),
        ({"kind": "goal", "x": 1.0, "y": float("nan"), "received": {"sec": 0, "nsec": 0}}, "finite"),
        ({"kind": "estop", "received": {"sec": 0, "nsec": 0}, "origin": "radio"}, "origin 'radio'"),
    ],
)
def test_a_record_without_a_command_is_a_value_error_naming_it(record: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        command_from_record(record)


@given(
    st.dictionaries(
        st.sampled_from(["kind", "x", "y", "received", "timestamp", "origin"]),
        st.one_of(
            st.none(),
            st.booleans(),
            st.integers(),
            st.floats(),
            st.sampled_from(["goal", "estop", "resume", "x", "zenoh", "command line"]),
            st.dictionaries(
                st.sampled_from(["sec", "nsec"]),
                st.one_of(st.integers(), st.floats(), st.text(max_size=2)),
            ),
        ),
    )
)
def test_any_record_gives_a_command_or_a_value_error(record: dict[str, object]) -> None:
    try:
        command = command_from_record(record)
    except ValueError:
        return
    assert command.kind in ("goal", "estop", "resume") and command.received_ns >= 0
    assert command.origin in ("zenoh", "command line")


def test_a_record_from_before_origins_is_a_zenoh_command() -> None:
    record = {"kind": "estop", "received": {"sec": 1, "nsec": 0}, "x": None, "y": None}
    assert command_from_record(record) == RoverCommand("estop", 1_000_000_000)
