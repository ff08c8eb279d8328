"""``[perception]`` in the rover config: how a range sensor's scans (and rangefinders' beams) become tracked
obstacles."""

from __future__ import annotations

import math
from dataclasses import dataclass

from logs.settings import Table
from navigator.beam_detections import MAX_FOV_DEG, RangefinderMount
from navigator.scan_clusters import ClusterSettings
from navigator.sensor_mount import SensorMount

# How far from the reference point a sensor may sit (m), either way: a mast on the rover, not a typo.
MAX_MOUNT_OFFSET_M = 5.0


@dataclass(frozen=True)
class ScanTrackerConfig:
    """``[perception]`` in the rover config: how scans become tracked obstacles (docs/planning.md
    "Perception from scans"). The first four say how returns become discs (``ClusterSettings``); the
    ``mount_*`` keys where the sensor sits (``SensorMount``: forward and left of the estimator's reference
    point, and its forward direction from the rover's, degrees counter-clockwise); ``rangefinders`` where
    each single-beam rangefinder sits, by its DISTANCE_SENSOR id (docs/planning.md "Perception from
    rangefinders")."""

    cluster_gap_m: float = 0.3
    cluster_gap_ratio: float = 0.1
    max_piece_m: float = 1.5
    min_radius_m: float = 0.1
    gate_m: float = 1.0
    window_s: float = 1.0
    confirm_scans: int = 3
    forget_s: float = 1.0
    moving_speed_mps: float = 0.3
    mount_forward_m: float = 0.0
    mount_left_m: float = 0.0
    mount_yaw_deg: float = 0.0
    rangefinders: tuple[RangefinderMount, ...] = ()

    @property
    def mount(self) -> SensorMount:
        return SensorMount(self.mount_forward_m, self.mount_left_m, math.radians(self.mount_yaw_deg))

    @property
    def clusters(self) -> ClusterSettings:
        return ClusterSettings(
            self.cluster_gap_m, self.cluster_gap_ratio, self.max_piece_m, self.min_radius_m
        )

    @classmethod
    def from_table(cls, table: Table) -> ScanTrackerConfig:
        d = cls()
        config = cls(
            cluster_gap_m=table.number("cluster_gap_m", d.cluster_gap_m, lo=0.01, hi=10.0),
            cluster_gap_ratio=table.number("cluster_gap_ratio", d.cluster_gap_ratio, lo=0.0, hi=1.0),
            max_piece_m=table.number("max_piece_m", d.max_piece_m, lo=0.1, hi=20.0),
            min_radius_m=table.number("min_radius_m", d.min_radius_m, lo=0.01, hi=5.0),
            gate_m=table.number("gate_m", d.gate_m, lo=0.05, hi=20.0),
            window_s=table.number("window_s", d.window_s, lo=0.1, hi=10.0),
            confirm_scans=table.integer("confirm_scans", d.confirm_scans, lo=1, hi=100),
            forget_s=table.number("forget_s", d.forget_s, lo=0.05, hi=60.0),
            moving_speed_mps=table.number("moving_speed_mps", d.moving_speed_mps, lo=0.01, hi=50.0),
            mount_forward_m=table.number(
                "mount_forward_m", d.mount_forward_m, lo=-MAX_MOUNT_OFFSET_M, hi=MAX_MOUNT_OFFSET_M
            ),
            mount_left_m=table.number(
                "mount_left_m", d.mount_left_m, lo=-MAX_MOUNT_OFFSET_M, hi=MAX_MOUNT_OFFSET_M
            ),
            mount_yaw_deg=table.number("mount_yaw_deg", d.mount_yaw_deg, lo=-180.0, hi=180.0),
            rangefinders=_rangefinders(table),
        )
        table.finish()
        return config


def _rangefinders(table: Table) -> tuple[RangefinderMount, ...]:
    """``rangefinders = [{id = 0, forward_m = 0.3, left_m = 0.1, fov_deg = 20.0}, ...]``: ids 0-255, each
    once; the offsets within ``MAX_MOUNT_OFFSET_M``; ``fov_deg`` 0-90 (default 0, a narrow beam)."""
    mounts: list[RangefinderMount] = []
    seen: set[int] = set()
    for entry in table.tables("rangefinders"):
        sensor_id = entry.integer("id", lo=0, hi=255)
        if sensor_id in seen:
            raise entry.error("id", f"rangefinder {sensor_id} is placed twice")
        seen.add(sensor_id)
        mounts.append(
            RangefinderMount(
                sensor_id,
                entry.number("forward_m", 0.0, lo=-MAX_MOUNT_OFFSET_M, hi=MAX_MOUNT_OFFSET_M),
                entry.number("left_m", 0.0, lo=-MAX_MOUNT_OFFSET_M, hi=MAX_MOUNT_OFFSET_M),
                entry.number("fov_deg", 0.0, lo=0.0, hi=MAX_FOV_DEG),
            )
        )
        entry.finish()
    return tuple(mounts)
