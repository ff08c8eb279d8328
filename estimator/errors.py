"""The estimator's error family: one base, then setup / operation / timeout.

Rejected measurements are *not* raised in the normal path: the front end counts and logs them, because a bad
GPS fix must never stop the loop. ``MeasurementRejected`` exists for callers that want to turn a rejection
into an exception (tests, one-shot tools).
"""

from __future__ import annotations


class EstimatorError(Exception):
    """Base of every error the estimator raises."""


class EstimatorSetupError(EstimatorError, ValueError):
    """A configuration or datum value the estimator cannot work with.

    ``field`` names the offending setting so a config loader can point at the right key.
    """

    def __init__(self, field: str, problem: str) -> None:
        self.field = field
        self.problem = problem
        super().__init__(f"estimator setting {field!r}: {problem}")


class EstimatorOperationError(EstimatorError):
    """The filter was used wrongly at run time (e.g. updated before it was initialised)."""


class MeasurementRejected(EstimatorOperationError):
    """A measurement was refused (bad value or outside the gate); ``reason`` is the counter key."""

    def __init__(self, reason: str, detail: str) -> None:
        self.reason = reason
        self.detail = detail
        super().__init__(f"measurement rejected ({reason}): {detail}")


class EstimatorTimeoutError(EstimatorError, TimeoutError):
    """Waiting for the estimator (e.g. to become healthy) took longer than allowed, in clock time."""
