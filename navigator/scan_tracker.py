"""Obstacles from a range sensor's scans: discs per scan, tracked across scans, with an id and a velocity.

The navigator needs what the simulator's object perception gives it: the same obstacle under the same id
from scan to scan, and a velocity for the moving ones (a cart predicted on the path stops the rover; a
static obstacle goes into the map). A lidar gives neither. Each scan's discs (``navigator.scan_clusters``)
are matched to the tracks nearest them, nearest pairs first, within ``gate_m`` of where each track is
predicted. A track's position and velocity are a straight-line fit through its detections of the last
``window_s``; it is reported once it has been seen ``confirm_scans`` times, and forgotten ``forget_s`` after
it was last seen. It counts as moving after its fitted speed stayed above ``moving_speed_mps`` for
``confirm_scans`` scans in a row, and as static again after the same number below half that: a static
post whose disc wobbles with the rover's heading error must not flicker in and out of the map.

``ScanTracker`` is an ``ObstacleSource``: the onboard stack hands it each scan with its pose estimate and
polls the observations like those of any other perception.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from firmware_bridge.obstacle_scan import ObstacleScan
from logs.settings import Table
from navigator.perception import ObstacleObservation
from navigator.scan_clusters import ClusterSettings, Detection, detections


@dataclass(frozen=True)
class ScanTrackerConfig:
    """``[perception]`` in the rover config: how scans become tracked obstacles (docs/navigator.md). The
    first four say how returns become discs (``navigator.scan_clusters.ClusterSettings``)."""

    cluster_gap_m: float = 0.3
    cluster_gap_ratio: float = 0.1
    max_piece_m: float = 1.5
    min_radius_m: float = 0.1
    gate_m: float = 1.0
    window_s: float = 1.0
    confirm_scans: int = 3
    forget_s: float = 1.0
    moving_speed_mps: float = 0.3

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
        )
        table.finish()
        return config


class _Track:
    """One obstacle followed across scans: its recent detections and whether it counts as moving.

    Each detection's centre is placed with the window's median radius, not its own: the radius a scan
    gives jumps with the number of sectors the object fills, and its centre would jump with it (a boulder
    seen from a driving rover seemed to move at 1 m/s)."""

    def __init__(self, track_id: str, first: Detection) -> None:
        self.track_id = track_id
        self.seen: deque[Detection] = deque([first])
        self.hits = 1
        self.moving = False
        self._streak = 0  # scans in a row whose speed argues for the other state
        self.radius_m = first.radius_m
        self.x, self.y = first.centre(first.radius_m)
        self.vx = self.vy = 0.0
        self.mean_xy = (self.x, self.y)

    def predicted(self, t_ns: int) -> tuple[float, float]:
        age_s = (t_ns - self.seen[-1].t_ns) * 1e-9
        return self.x + self.vx * age_s, self.y + self.vy * age_s

    def add(self, detection: Detection, config: ScanTrackerConfig) -> None:
        seen = self.seen
        seen.append(detection)
        self.hits += 1
        oldest_ns = detection.t_ns - round(config.window_s * 1e9)
        while len(seen) > 2 and seen[0].t_ns < oldest_ns:
            seen.popleft()
        self.radius_m = sorted(d.radius_m for d in seen)[len(seen) // 2]
        span_s = (seen[-1].t_ns - seen[0].t_ns) * 1e-9
        self._fit()
        speed = math.hypot(self.vx, self.vy)
        if self.moving:
            arguing = speed < config.moving_speed_mps / 2.0
        else:
            # Most of a window at least: a short fit takes a lateral jump of the disc (5 degree sectors are
            # 0.7 m apart at 8 m) for a speed.
            arguing = speed > config.moving_speed_mps and span_s >= config.window_s / 2.0
        self._streak = self._streak + 1 if arguing else 0
        if self._streak >= config.confirm_scans:
            self.moving = not self.moving
            self._streak = 0

    def _fit(self) -> None:
        """Least-squares line through the window's centres: position at the newest, and velocity."""
        seen = self.seen
        t0 = seen[-1].t_ns
        ts = [(d.t_ns - t0) * 1e-9 for d in seen]
        centres = [d.centre(self.radius_m) for d in seen]
        n = len(seen)
        mean_t = sum(ts) / n
        mean_x = sum(c[0] for c in centres) / n
        mean_y = sum(c[1] for c in centres) / n
        self.mean_xy = (mean_x, mean_y)
        spread = sum((t - mean_t) ** 2 for t in ts)
        if spread < 1e-6:  # all at one time: no velocity to fit
            self.x, self.y = centres[-1]
            self.vx = self.vy = 0.0
            return
        self.vx = sum((t - mean_t) * (c[0] - mean_x) for t, c in zip(ts, centres, strict=True)) / spread
        self.vy = sum((t - mean_t) * (c[1] - mean_y) for t, c in zip(ts, centres, strict=True)) / spread
        self.x = mean_x - self.vx * mean_t  # the fit's value at the newest detection (t = 0)
        self.y = mean_y - self.vy * mean_t

    def observation(self, dx: float, dy: float) -> ObstacleObservation:
        """As an observation on the map: the tracking frame's position moved by (``dx``, ``dy``)."""
        t_ns = self.seen[-1].t_ns
        if self.moving:
            x, y = self.x + dx, self.y + dy
            return ObstacleObservation(t_ns, self.track_id, x, y, self.radius_m, self.vx, self.vy)
        # Static: where the window's centres cluster, without a velocity the noise made up.
        mean_x, mean_y = self.mean_xy
        return ObstacleObservation(t_ns, self.track_id, mean_x + dx, mean_y + dy, self.radius_m)


class ScanTracker:
    """Tracks obstacles through the scans given to ``add``; ``poll`` returns the confirmed tracks updated
    since the last poll (an ``ObstacleSource``)."""

    def __init__(self, config: ScanTrackerConfig | None = None) -> None:
        self.config = config or ScanTrackerConfig()
        self._clusters = self.config.clusters
        self._tracks: list[_Track] = []
        self._updated: dict[str, _Track] = {}
        self._next_id = 1
        self._offset = (0.0, 0.0)  # map minus the tracking frame, as of the last scan (add)
        self.scans = 0
        self.scans_without_pose = (
            0  # scans that came before the rover knew where it was and which way it faced
        )

    @property
    def track_count(self) -> int:
        return len(self._tracks)

    def add(
        self,
        scan: ObstacleScan,
        pose: tuple[float, float, float] | None,
        offset: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """Take in ``scan`` seen from ``pose`` (x, y ENU m, yaw rad from east; None: not known yet).

        ``pose`` may be in a frame of its own, parallel to the map (the onboard stack's dead-reckoned one,
        ``navigator.odometry_frame``): tracks are kept in it, and ``offset`` (map minus frame, as of this
        scan) places them on the map when they are reported."""
        if pose is None:
            self.scans_without_pose += 1
            return
        self._offset = offset
        self.scans += 1
        config = self.config
        found = detections(scan, pose[0], pose[1], pose[2], self._clusters)
        forget_ns = round(config.forget_s * 1e9)
        self._tracks = [t for t in self._tracks if scan.t_ns - t.seen[-1].t_ns <= forget_ns]
        for detection, track in self._associate(found, scan.t_ns):
            if track is None:
                track = _Track(f"scan-{self._next_id}", detection)
                self._next_id += 1
                self._tracks.append(track)
            else:
                track.add(detection, config)
            if track.hits >= config.confirm_scans:
                self._updated[track.track_id] = track

    def _associate(self, found: list[Detection], t_ns: int) -> list[tuple[Detection, _Track | None]]:
        """Each detection with the track it continues (None: a new one): nearest pairs first, one detection
        per track, within the gate around each track's predicted position."""
        gate = self.config.gate_m
        pairs = []
        for i, detection in enumerate(found):
            for j, track in enumerate(self._tracks):
                px, py = track.predicted(t_ns)
                cx, cy = detection.centre(track.radius_m)
                gap = math.hypot(cx - px, cy - py)
                if gap <= gate:
                    pairs.append((gap, i, j))
        pairs.sort()
        taken_detections: dict[int, _Track] = {}
        taken_tracks: set[int] = set()
        for _, i, j in pairs:
            if i in taken_detections or j in taken_tracks:
                continue
            taken_detections[i] = self._tracks[j]
            taken_tracks.add(j)
        return [(detection, taken_detections.get(i)) for i, detection in enumerate(found)]

    def poll(self) -> list[ObstacleObservation]:
        updated, self._updated = self._updated, {}
        dx, dy = self._offset
        return [track.observation(dx, dy) for track in updated.values()]
