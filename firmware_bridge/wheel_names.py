"""One name for a wheel in every message: its index on the CAN link, its position and its controller's id.

The same wheel used to be "motor controller 3" (its CAN id) in the link's health events, "#2" (its index)
in the supervisor's ``wheel_silent`` and "wheel 2 (left rear)" in ``wheel_stalled``; an operator had to
know the mapping to see they were one wheel. Everything that names a wheel calls ``wheel_label``:
``wheel 2 (left rear, CAN id 3)``. The index is the wheel order of ``[vesc] controller_ids`` (the order
``firmware_bridge.vesc`` commands and the mixer produces), the id is the controller's own.
"""

from __future__ import annotations

from collections.abc import Sequence

# Wheel order on the CAN link (``[vesc] controller_ids``, ``navigator.mixing``): left side front to rear,
# then right side front to rear.
WHEEL_POSITIONS = ("left front", "left middle", "left rear", "right front", "right middle", "right rear")


def wheel_label(index: int, controller_ids: Sequence[int] = ()) -> str:
    """``wheel 2 (left rear, CAN id 3)``; without ``controller_ids`` (not known here) the id is left out."""
    where = WHEEL_POSITIONS[index] if 0 <= index < len(WHEEL_POSITIONS) else "position unknown"
    if 0 <= index < len(controller_ids):
        return f"wheel {index} ({where}, CAN id {controller_ids[index]})"
    return f"wheel {index} ({where})"


def wheel_labels(indices: Sequence[int], controller_ids: Sequence[int] = ()) -> str:
    """Several wheels, comma-separated, each as ``wheel_label`` names it."""
    return ", ".join(wheel_label(index, controller_ids) for index in indices)
