"""Two short lockstep trials for the replay tests, run once a session, and the helpers the tests share."""

from __future__ import annotations

import collections
import hashlib
from pathlib import Path

import pytest
from mcap.reader import make_reader

from hil.scenario import load_scenario
from hil.trial import run_trial
from logs.settings import parse_toml
from navigator.config import RoverConfig, rover_config_from_table

DATA = Path(__file__).resolve().parents[1] / "data"


def config_of(text: str = "") -> RoverConfig:
    return rover_config_from_table(parse_toml(text, "<test config>"))


def digests(path: Path) -> dict[str, tuple[int, str]]:
    """Per topic: message count and a hash of every message's log time and bytes, in file order."""
    hashes: dict[str, hashlib._Hash] = collections.defaultdict(hashlib.sha256)
    counts: collections.Counter[str] = collections.Counter()
    with path.open("rb") as stream:
        for _schema, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            hashes[channel.topic].update(message.log_time.to_bytes(8, "little") + message.data)
            counts[channel.topic] += 1
    return {topic: (counts[topic], digest.hexdigest()) for topic, digest in hashes.items()}


@pytest.fixture(scope="session")
def trials(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A trial perceiving obstacles as objects (small_rocky), one through a lidar's scans (hidden_rock), and
    one with faults, a moving cart and the simulator's log lines (sandy_cart_glitch)."""
    out = tmp_path_factory.mktemp("replay-trials")
    return {
        name: run_trial(load_scenario(DATA / f"{name}.toml"), config_of(), out / name).mcap_path
        for name in ("small_rocky", "hidden_rock", "sandy_cart_glitch")
    }
