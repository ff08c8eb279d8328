"""TruthRecorder.on_moving_contacts: each moving obstacle's contact is reported once, when it begins."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from hil.scenario import load_scenario
from hil.truth import TruthRecorder
from logs.sink import MemorySink
from logs.topics import TRUTH_CONTACTS

SCENARIO = load_scenario(Path(__file__).parents[2] / "scenarios" / "default.toml")


def test_a_contact_is_reported_when_it_begins_and_again_only_after_it_ended() -> None:
    sink = MemorySink()
    truth = TruthRecorder(sink, SCENARIO)
    body = SimpleNamespace(x=4.0, y=5.0)
    ticks: list[list[str]] = [[], ["cart"], ["cart", "van"], ["van"], [], ["cart"]]
    for now, touching in enumerate(ticks):
        truth.on_moving_contacts(now, touching, body)  # type: ignore[arg-type]
    reported = [(ns, c["obstacle_id"], c["kind"], c["x"], c["y"]) for _t, ns, c in sink.records]
    assert [topic for topic, _ns, _c in sink.records] == [TRUTH_CONTACTS] * 3
    # cart begins at 1, van at 2 (cart still touching: not again), cart ends at 3 and begins anew at 5.
    assert reported == [
        (1, "cart", "collision", 4.0, 5.0),
        (2, "van", "collision", 4.0, 5.0),
        (5, "cart", "collision", 4.0, 5.0),
    ]
