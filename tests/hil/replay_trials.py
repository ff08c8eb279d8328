"""What the replay tests share: the test data, a config from TOML text, and per-topic digests of a recording.

The trials they replay are the ``trials`` fixture (tests/hil/conftest.py), run once a session."""

from __future__ import annotations

import collections
import hashlib
from pathlib import Path

from mcap.reader import make_reader

from hil.scenario import load_scenario
from logs.settings import parse_toml
from navigator.config import RoverConfig, rover_config_from_table

DATA = Path(__file__).resolve().parents[1] / "data"


def config_of(text: str = "") -> RoverConfig:
    return rover_config_from_table(parse_toml(text, "<test config>"))


def rover_run_config() -> RoverConfig:
    """small_rocky's terrain as the config's [map] and its datum as the estimator's, as `rover run` needs
    (small_rocky_bus_off has the same terrain and datum)."""
    lat, lon, alt = load_scenario(DATA / "small_rocky.toml").datum
    map_table = (DATA / "small_rocky.toml").read_text().split("[terrain]")[1].split("[start]")[0]
    return config_of(
        f"[estimator]\ndatum_lat_deg = {lat!r}\ndatum_lon_deg = {lon!r}\ndatum_alt_m = {alt!r}\n"
        f"[map]{map_table}"
    )


def digests(path: Path) -> dict[str, tuple[int, str]]:
    """Per topic: message count and a hash of every message's log time and bytes, in file order."""
    hashes: dict[str, hashlib._Hash] = collections.defaultdict(hashlib.sha256)
    counts: collections.Counter[str] = collections.Counter()
    with path.open("rb") as stream:
        for _schema, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            hashes[channel.topic].update(message.log_time.to_bytes(8, "little") + message.data)
            counts[channel.topic] += 1
    return {topic: (counts[topic], digest.hexdigest()) for topic, digest in hashes.items()}
