"""argparse types for numbers with a range, so a bad value is refused by argparse itself (usage and exit 2)
before a command opens, creates or writes anything."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

from hil.hardware_priority import MAX_FIFO_PRIORITY
from logs.settings import MAX_SEED


def bounded_int(lo: int, hi: int, meaning: str = "") -> Callable[[str], int]:
    """A type converter for a whole number in ``[lo, hi]``; ``meaning`` is said after the range."""
    note = f" ({meaning})" if meaning else ""

    def convert(text: str) -> int:
        try:
            value = int(text, 10)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected a whole number {lo} to {hi}{note}, got {text!r}"
            ) from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"must be {lo} to {hi}{note}, got {value}")
        return value

    convert.__name__ = "whole number"  # argparse names the type in some messages
    return convert


def bounded_float(lo: float, hi: float, meaning: str = "") -> Callable[[str], float]:
    """A type converter for a finite number in ``[lo, hi]``; ``meaning`` is said after the range."""
    note = f" ({meaning})" if meaning else ""

    def convert(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected a number {lo:g} to {hi:g}{note}, got {text!r}"
            ) from None
        if not (math.isfinite(value) and lo <= value <= hi):
            raise argparse.ArgumentTypeError(f"must be {lo:g} to {hi:g}{note}, got {text}")
        return value

    convert.__name__ = "number"  # argparse names the type in some messages
    return convert


# Every command's --seed: numpy's generators refuse negative seeds, and a seed must fit in a TOML file.
seed = bounded_int(0, MAX_SEED)


def positive_seconds(text: str) -> float:
    """A duration in seconds: a finite number above 0. (``float`` alone takes 'nan' and 'inf', which ended
    ``rover run --duration`` in a traceback, and 0 or -1, which ran no tick and exited 0.)"""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds (a number), got {text!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds above 0, got {text!r}")
    return value


positive_seconds.__name__ = "seconds"


# `--fifo` / `--peer-fifo`: the simulated rover's real-time priority (hil.hardware_priority).
fifo_priority = bounded_int(0, MAX_FIFO_PRIORITY, "a SCHED_FIFO priority; 0: normal scheduling")
