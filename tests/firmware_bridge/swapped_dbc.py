"""A VESC DBC profile laid out unlike the shipped one, as another team's firmware might send it.

For tests of ``[vesc] dbc``: other controller ids, STATUS ``current`` in centiamps instead of deciamps (the
struct packer follows the new scale) and STATUS_5 little-endian (no packer: encode and decode go through
cantools). Made by editing ``generate_dbc`` text, so each change is one line a reader can check.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from firmware_bridge.vesc_dbc import generate_dbc

SWAPPED_IDS = (11, 12, 13, 14, 15, 16)
CURRENT_SCALE = 0.01  # A per raw count in the swapped STATUS (the shipped one: 0.1)

_EDITS = (
    (
        re.escape(' SG_ current : 39|16@0- (0.1,0) [-3276.8|3276.7] "A" COMPANION'),
        ' SG_ current : 39|16@0- (0.01,0) [-327.68|327.67] "A" COMPANION',
    ),
    # Little-endian (@1) signals are located by their least significant bit: byte 0 -> 0, byte 4 -> 32.
    (re.escape(" SG_ tacho : 7|32@0-"), " SG_ tacho : 0|32@1-"),
    (re.escape(" SG_ voltage_in : 39|16@0-"), " SG_ voltage_in : 32|16@1-"),
)


def swapped_dbc_text(controller_ids: Sequence[int] = SWAPPED_IDS) -> str:
    text = generate_dbc(controller_ids)
    for pattern, replacement in _EDITS:
        text, count = re.subn(pattern, replacement, text)
        assert count == len(controller_ids), f"{pattern}: {count} lines edited"
    return text


def without_message(text: str, name: str) -> str:
    """``text`` with the message ``name`` (its BO_ line and signals) removed."""
    edited, count = re.subn(rf"BO_ \d+ {name}:[^\n]*\n(?: SG_[^\n]*\n)*", "", text)
    assert count == 1, name
    return edited
