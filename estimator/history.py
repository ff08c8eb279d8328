"""Buffer-and-re-fuse for late GPS fixes: the filter states and samples of the last fraction of a second.

A fix that reached us ``latency`` after it was taken belongs at its own time. We keep, for every IMU and
wheel sample fused recently, the filter state just before it and the update it made. A late fix rewinds to
the last state before its time, is fused there, and the samples after it are fused again on top. Only the
filter arithmetic is replayed: counters, innovations messages and the heading bootstrap saw those samples
once already.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from estimator.ekf import RoverEkf, Snapshot


@dataclass(frozen=True)
class GyroSample:
    t_ns: int
    gyro_z_rps: float
    acceleration: float = 0.0  # the EKF's acceleration input its predict ran with (RoverEkf.acceleration)
    learn_scale: bool = True  # whether the update could change the odometry scale (RoverEkf.learn_scale)


@dataclass(frozen=True)
class OdometrySample:
    """An odometry update exactly as it was made (its noise was judged at the time, so is kept)."""

    t_ns: int
    speed_mps: float
    yaw_rate_rps: float
    speed_std_mps: float
    yaw_rate_std_rps: float
    use_speed: bool
    acceleration: float = 0.0
    speed_reset: tuple[float, float] | None = None  # (speed m/s, std m/s) put in before it (reset_speed)
    learn_scale: bool = True


Sample = GyroSample | OdometrySample


def apply(ekf: RoverEkf, sample: Sample) -> None:
    """Predict to the sample's time and fuse it (the filter arithmetic only)."""
    ekf.acceleration = sample.acceleration
    ekf.learn_scale(sample.learn_scale)
    if isinstance(sample, GyroSample):
        ekf.update_gyro(sample.gyro_z_rps, t_ns=sample.t_ns)
    else:
        if sample.speed_reset is not None:
            ekf.reset_speed(*sample.speed_reset)
        ekf.update_odometry(
            sample.speed_mps,
            sample.yaw_rate_rps,
            sample.speed_std_mps,
            sample.yaw_rate_std_rps,
            use_speed=sample.use_speed,
            t_ns=sample.t_ns,
        )


class FusionHistory:
    """The recent (state before, sample) pairs, oldest first, kept for ``horizon_ns``."""

    def __init__(self, horizon_ns: int) -> None:
        self._horizon_ns = horizon_ns
        self._entries: deque[tuple[Snapshot, Sample]] = deque()

    def __len__(self) -> int:
        return len(self._entries)

    def record(self, before: Snapshot, sample: Sample) -> None:
        self._entries.append((before, sample))
        oldest = sample.t_ns - self._horizon_ns
        while self._entries and self._entries[0][1].t_ns < oldest:
            self._entries.popleft()

    def covers(self, t_ns: int) -> bool:
        """Whether the buffer reaches back to ``t_ns`` (a fix older than that cannot be placed)."""
        return bool(self._entries) and self._entries[0][0].t_ns <= t_ns

    def rewind(self, ekf: RoverEkf, t_ns: int) -> list[Sample]:
        """Put ``ekf`` back to its state just before the first sample after ``t_ns``; returns the samples
        to re-fuse (removed from the buffer: ``replay`` records them again)."""
        entries = self._entries
        later: list[Sample] = []
        earliest: Snapshot | None = None
        while entries and entries[-1][1].t_ns > t_ns:
            earliest, sample = entries.pop()
            later.append(sample)
        if earliest is not None:
            ekf.restore(earliest)
        later.reverse()
        return later

    def replay(self, ekf: RoverEkf, samples: list[Sample]) -> None:
        for sample in samples:
            before = ekf.snapshot()
            apply(ekf, sample)
            self.record(before, sample)
