"""The motors' current limit on wheel speed: a wheel its torque cannot drive turns as the ground lets it.

Each wheel is speed-commanded (its VESC's speed loop), and its pull is capped at what its motor's current
limit gives, ``F_cap = I_max k_t gear / r`` (VESC ``l_current_max``; ``hil.traction.drive_forces``). When
that cap, not the ground's ``mu N``, is what stops the pull (the speed loop asks for more torque than the
limit lets it have), a real controller cannot hold the commanded speed: the motor slows until the traction
the wheel's slip gives is the force its limited torque makes, ``traction_ratio(s) N = F_cap``. So the wheel
turns at the surface speed ``u`` whose slip against the ground speed ``v`` under it is the curve's slip for
``F_cap / N`` (``hil.traction.slip_for_ratio``), with the model's slip definition
``(u - v) / max(|u|, |v|)``:

* pulling (force and ground speed the same way, or the rover at rest): ``u = v / (1 - s)``;
* against the ground's motion (a motor braking at its limit, or driving forward while the rover rolls
  back): ``u = v (1 - s)``.

A stalled climb: the rover stops and its wheels stop with it (at a slope whose climb the motors' torque
cannot hold they are turned backwards with it, still pulling uphill at the limit). The wheel turns at
``u`` only where the speed it was given is further in the force's direction (the speed loop asks for more
than the torque gives); a wheel given less turns at the speed given, as before. A seized wheel is held by
its lock, not its motor: never here.

The force is the step's (``drive_forces``), the ground speed the step's end: the held speed is what the
wheel turns at after the step. The speed its controller drives it to is left as it is: the simulated
VESC's speed loop still asks for its command (so the next step's force is again the cap, for as long as
the loop asks for more than the torque gives), while the VESC measures and reports the held speed
(``hil.vesc_sim``). The next step's rolling resistance opposes the turning the wheel was held to
(``rolling_speeds``), not the speed asked for: a rover stalled on a climb does not roll, and so meets
at most ``crr N`` either way, which holds it where its motors' pull falls short of the slope's by less.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np
from numpy.typing import NDArray

from hil import traction
from hil.traction import MU, SLIP_K, slip_for_ratio
from navigator.kernel_cache import sources_fingerprint

Array = NDArray[np.float64]


def _compile_hold(fingerprint: str) -> Callable[..., None]:
    """``hold_at_current_limit``, with ``fingerprint`` (of ``hil.traction``, whose ``slip_for_ratio`` it
    compiles in) in numba's cache key: see ``navigator.kernel_cache``."""

    @numba.njit(cache=True)
    def hold_at_current_limit(
        wheels: Array,
        forces: Array,
        normals: Array,
        locked: Array,
        speed: float,
        yaw_rate: float,
        effective_track: float,
        ground: Array,
        cap: float,
        out_floors: Array,
        out_ceilings: Array,
    ) -> None:
        """Set each wheel (``wheels``, surface speeds m/s, in place) whose ``forces`` (N, signed) its
        motor's current limit ``cap`` (N) holds, below the ground's ``mu N`` (``normals``, N), to the speed
        at which the class's traction curve (``ground``: ``hil.traction.drive_forces``'s class vector) gives
        that force over the ground under it (``speed``, ``yaw_rate`` and ``effective_track``: the body's
        motion after the step), where the speed given is further in the force's direction. ``locked``:
        nonzero for a seized wheel, left as it is.

        Writes the slowest and fastest each wheel's current limit lets it turn at (m/s, signed) into
        ``out_floors`` and ``out_ceilings``: the held speed on the side the force pushes to (a pulling
        wheel's ceiling, a braking one's floor), -inf / +inf elsewhere and for wheels not held.
        """
        _ = fingerprint  # in the closure, so in numba's cache key (see _compile_hold)
        mu, slip_constant = ground[MU], ground[SLIP_K]
        for i in range(6):
            out_floors[i] = -math.inf
            out_ceilings[i] = math.inf
            force = forces[i]
            limit = mu * normals[i]
            # At its motor's cap (hil.traction._share_side writes a capped wheel's +-cap; the last wheel of a
            # side to reach it may get the side's force less the others' caps, an ulp or so off) and below
            # the ground's limit, as hil.traction.wheel_outputs tells a wheel on the curve.
            at_cap = abs(force) >= cap * (1.0 - 1e-9)
            if locked[i] != 0.0 or not at_cap or not cap < limit * (1.0 - 1e-9):
                continue
            slip = abs(slip_for_ratio(cap / normals[i], mu, slip_constant))  # < 1: below mu N
            side = 1.0 if i >= 3 else -1.0
            ground_speed = speed + side * 0.5 * yaw_rate * effective_track
            if force > 0.0:
                held = ground_speed / (1.0 - slip) if ground_speed >= 0.0 else ground_speed * (1.0 - slip)
                out_ceilings[i] = held
                if wheels[i] > held:
                    wheels[i] = held
            else:
                held = ground_speed / (1.0 - slip) if ground_speed <= 0.0 else ground_speed * (1.0 - slip)
                out_floors[i] = held
                if wheels[i] < held:
                    wheels[i] = held

    return hold_at_current_limit


hold_at_current_limit = _compile_hold(sources_fingerprint(traction))


@numba.njit(cache=True)
def rolling_speeds(wheels: Array, floors: Array, ceilings: Array, out: Array) -> None:
    """The speed each wheel turns at (m/s, into ``out``): the one its controller drives it to
    (``wheels``), within the slowest and fastest its motor's current limit held it to at the last step
    (``floors``, ``ceilings``: ``hold_at_current_limit``'s; +-inf where the limit did not hold it)."""
    for i in range(6):
        out[i] = min(max(wheels[i], floors[i]), ceilings[i])
