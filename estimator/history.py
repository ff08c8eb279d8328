"""Buffer-and-re-fuse for late GPS fixes: the filter states and samples of the last fraction of a second.

A fix that reached us ``latency`` after it was taken belongs at its own time. We keep, for every IMU and
wheel sample and every absolute heading (AHRS / compass) fused recently, the filter state just before it and
the update it made. A late fix rewinds to the last state before its time, is fused there, and the samples
after it are fused again on top. Only the filter arithmetic is replayed: counters, innovations messages and
the heading bootstrap saw those samples once already.
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


@dataclass(frozen=True)
class HeadingSample:
    """An absolute heading update (``Estimator.on_attitude``), at the filter time it was fused at.

    Without it a late fix's rewind undid every heading update since the fix was taken (a fifth of a second
    of AHRS corrections at 0.2 s latency), and only the next AHRS sample put the heading back.
    """

    t_ns: int
    yaw_rad: float
    std_rad: float
    acceleration: float = 0.0
    learn_scale: bool = True


Sample = GyroSample | OdometrySample | HeadingSample


def apply(ekf: RoverEkf, sample: Sample) -> None:
    """Predict to the sample's time and fuse it (the filter arithmetic only)."""
    ekf.acceleration = sample.acceleration
    ekf.learn_scale(sample.learn_scale)
    if isinstance(sample, GyroSample):
        ekf.update_gyro(sample.gyro_z_rps, t_ns=sample.t_ns)
    elif isinstance(sample, HeadingSample):
        ekf.predict(sample.t_ns)
        # Gated again on the replayed prior, as a first pass at this state would have been.
        ekf.update_heading(sample.yaw_rad, sample.std_rad)
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
        self._cut_ns: int | None = None

    @property
    def horizon_ns(self) -> int:
        return self._horizon_ns

    def cut(self, t_ns: int) -> None:
        """The filter was changed at ``t_ns`` by something not kept here (a heading given or learnt, with the
        fixes fused on arrival before it): no state before it may be restored, so everything is dropped."""
        self._entries.clear()
        self._cut_ns = t_ns

    def cut_after(self, t_ns: int) -> bool:
        """Whether the history was cut after ``t_ns`` (so a fix taken then cannot be put at its time)."""
        return self._cut_ns is not None and t_ns < self._cut_ns

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
