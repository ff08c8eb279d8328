"""The effective rover config as a recording keeps it: flattened for comparison, secrets redacted."""

from __future__ import annotations

import dataclasses
import json

from hil.campaign import campaign_config
from navigator.config_record import REDACTED, effective_config, flattened

KEY = "ab" * 32  # a well-formed 32-byte MAVLink signing key


def test_two_variants_differ_exactly_in_their_overridden_key():
    terrain = flattened(effective_config(campaign_config(None, {"planner": {"cost_mode": "terrain"}}, "a")))
    classical = flattened(
        effective_config(campaign_config(None, {"planner": {"cost_mode": "classical"}}, "b"))
    )
    assert terrain.keys() == classical.keys()
    differing = {key for key in terrain if terrain[key] != classical[key]}
    assert differing == {"planner.cost_mode"}
    assert (terrain["planner.cost_mode"], classical["planner.cost_mode"]) == ("terrain", "classical")


def test_values_are_plain_json_and_lists_stay_lists():
    record = flattened(effective_config(campaign_config(None, {}, "t")))
    assert json.loads(record["vesc.controller_ids"]) == [1, 2, 3, 4, 5, 6]
    assert record["zenoh.enabled"] == "false"
    assert "source" not in record and "terrain" not in record


def test_the_signing_key_is_redacted_but_its_presence_is_kept():
    config = campaign_config(None, {"mavlink": {"signing_key": KEY}}, "t")
    effective = effective_config(config)
    assert effective["mavlink"]["signing_key"] == REDACTED
    assert KEY not in json.dumps(effective)
    unsigned = dataclasses.replace(config, mavlink=dataclasses.replace(config.mavlink, signing_key=""))
    assert effective_config(unsigned)["mavlink"]["signing_key"] == ""


def test_the_hil_peer_run_id_is_no_parameter_two_runs_differ_in():
    # Each real-time HIL run has its own id: in the config record a report listed it as a differing parameter.
    base = campaign_config(None, {}, "t")
    run_a, run_b = (dataclasses.replace(base, hil_peer_run=run) for run in ("run-a", "run-b"))
    assert (
        flattened(effective_config(run_a))
        == flattened(effective_config(run_b))
        == flattened(effective_config(base))
    )
