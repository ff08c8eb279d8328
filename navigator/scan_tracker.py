"""Obstacles from a range sensor's scans: discs per scan, tracked across scans, with an id and a velocity.

The navigator needs what the simulator's object perception gives it: the same obstacle under the same id
from scan to scan, and a velocity for the moving ones (a cart predicted on the path stops the rover; a
static obstacle goes into the map). A lidar gives neither. Each scan's discs (``navigator.scan_clusters``)
are matched to the tracks (``navigator.scan_track``) nearest them, nearest pairs first, within ``gate_m``
of where each track is predicted. A track is reported from its ``confirm_scans``-th scan on and forgotten
``forget_s`` after it was last seen; a sensor slower than that keeps its tracks for two and a half of its
scan periods, and fits over three (a 1 Hz lidar would otherwise start a new track every scan). A static
track forgotten (out of view, behind another) leaves a landmark: the next disc there takes its id again, so
guidance does not put the same rock in its map twice under two names.

Rangefinders' beams (``add_beams``) become discs of their own (``navigator.beam_detections``), matched
to the same tracks. The beams of one read of the link come as one partial scan: a sensor is heard on its
own period, and only the discs it saw touch any track. A scan, or a batch of beams, that does not see a
track leaves it alone: tracks age out by time since they were last seen, never because one sensor looked
the other way, so a forward rangefinder cannot make a lidar's track behind the rover look lost, nor
moving. The sensors' periods are kept apart (a lidar's at 1 Hz and rangefinders' at 10 Hz together are no
10 Hz sensor): the slowest sets how long tracks are remembered.

``ScanTracker`` is an ``ObstacleSource``: the onboard stack hands it each scan with its pose (in a frame of
its choosing, ``navigator.odometry_frame``) and polls the observations like those of any other perception.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Sequence

from firmware_bridge.distance_sensor import RangeBeam
from firmware_bridge.obstacle_scan import ObstacleScan
from navigator.beam_detections import BeamPlacer
from navigator.perception import ObstacleObservation
from navigator.scan_clusters import Detection, detections
from navigator.scan_track import ScanTrack
from navigator.scan_tracker_config import ScanTrackerConfig

MAX_LANDMARKS = 10_000  # forgotten static tracks kept for their ids; the oldest go first
# A pair is fitted only when the disc's own centre lies this much beyond the gate at most (a cheap test
# first: the fit is a few Gauss-Newton steps, and a cluttered scan has many far pairs).
_PAIR_SLACK_M = 1.0


class ScanTracker:
    """Tracks obstacles through the scans given to ``add``; ``poll`` returns the tracks updated since the
    last poll that are reportable (an ``ObstacleSource``)."""

    def __init__(self, config: ScanTrackerConfig | None = None) -> None:
        self.config = config or ScanTrackerConfig()
        self._clusters = self.config.clusters
        self._mount = self.config.mount
        self._tracks: list[ScanTrack] = []
        self._updated: dict[str, ScanTrack] = {}
        # Forgotten static tracks: where they were reported, and their radius.
        self._landmarks: OrderedDict[str, tuple[float, float, float]] = OrderedDict()
        self._next_id = 1
        self._offset = (0.0, 0.0)  # map minus the tracking frame, as of the last scan (add)
        self._beams = BeamPlacer(self.config.rangefinders)
        # Per kind of sensor ("scan", "beams"): the last one's time, and the gap between the last two.
        self._last_ns: dict[str, int] = {}
        self._periods_ns: dict[str, int] = {}
        self.scans = 0
        self.beam_batches = 0
        # Scans (beam batches) that came before the rover knew where it was (and which way it faced).
        self.scans_without_pose = 0
        self.beams_without_pose = 0

    @property
    def track_count(self) -> int:
        return len(self._tracks)

    @property
    def landmark_count(self) -> int:
        return len(self._landmarks)

    def add(
        self,
        scan: ObstacleScan,
        pose: tuple[float, float, float] | None,
        offset: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """Take in ``scan`` seen from ``pose`` (x, y ENU m, yaw rad from east, of the rover's reference point;
        the sensor sits where ``[perception]`` says; None: not known yet).

        ``pose`` may be in a frame of its own, parallel to the map (the onboard stack's dead-reckoned one,
        ``navigator.odometry_frame``): tracks are kept in it, and ``offset`` (map minus frame, as of this
        scan) places them on the map when they are reported."""
        if pose is None:
            self.scans_without_pose += 1
            return
        self.scans += 1
        found = detections(scan, pose[0], pose[1], pose[2], self._clusters, self._mount)
        self._take(found, scan.t_ns, "scan", offset)

    def add_beams(
        self,
        beams: Sequence[RangeBeam],
        pose: tuple[float, float, float] | None,
        offset: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """Take in ``beams``, the rangefinder readings of one read of the link (one receive time), seen
        from ``pose``, as ``add`` takes a scan; each sensor sits where ``[perception] rangefinders`` says."""
        if not beams:
            return
        if pose is None:
            self.beams_without_pose += 1
            return
        self.beam_batches += 1
        found = self._beams.detections(beams, pose[0], pose[1], pose[2], self._clusters.min_radius_m)
        self._take(found, beams[-1].t_ns, "beams", offset)

    @property
    def unmounted_rangefinders(self) -> set[int]:
        """Rangefinder ids heard that ``[perception] rangefinders`` does not place."""
        return self._beams.unmounted

    def _take(self, found: list[Detection], t_ns: int, kind: str, offset: tuple[float, float]) -> None:
        """The discs one sensor saw at ``t_ns`` into the tracks (``kind``: which sensor, for its period)."""
        self._offset = offset
        config = self.config
        # The slowest sensor's period as its readings before this one showed it: a gap before this one (the
        # sensor paused) is a reason to forget, not to remember longer.
        period_ns = max(self._periods_ns.values(), default=0)
        window_ns = max(round(config.window_s * 1e9), 3 * period_ns)
        forget_ns = max(round(config.forget_s * 1e9), 5 * period_ns // 2)
        last_ns = self._last_ns.get(kind)
        if last_ns is not None:
            self._periods_ns[kind] = max(0, t_ns - last_ns)
        self._last_ns[kind] = t_ns
        self._forget(t_ns, forget_ns)
        from_scan = kind == "scan"
        for detection, track in self._associate(found, t_ns, from_scan):
            if track is None:
                track = ScanTrack(self._new_id(detection, from_scan), detection, from_scan)
                self._tracks.append(track)
            elif from_scan or track.scanned or not track.reportable(config.confirm_scans):
                track.add(detection, window_ns, config.confirm_scans, config.moving_speed_mps, from_scan)
            else:
                track.hold(detection)  # mapped where it was reported: more of it is another track
            if track.reportable(config.confirm_scans):
                self._updated[track.track_id] = track

    def poll(self) -> list[ObstacleObservation]:
        updated, self._updated = self._updated, {}
        dx, dy = self._offset
        return [track.observation(dx, dy) for track in updated.values()]

    def _forget(self, t_ns: int, forget_ns: int) -> None:
        kept = []
        for track in self._tracks:
            if t_ns - track.last_ns <= forget_ns:
                kept.append(track)
            elif not track.moving and track.reportable(self.config.confirm_scans):
                self._landmarks[track.track_id] = (*track.mean_xy, track.radius_m)
                self._landmarks.move_to_end(track.track_id)
                if len(self._landmarks) > MAX_LANDMARKS:
                    self._landmarks.popitem(last=False)
        self._tracks = kept

    def _new_id(self, detection: Detection, from_scan: bool = True) -> str:
        """A landmark's id when ``detection`` lies within the gate of one (the nearest), else a new one. A
        beam's disc (not ``from_scan``) takes a landmark's id only where the two overlap, as it continues a
        track (``_associate``): a piece of a wall further along is not the piece mapped before, and under
        its id guidance, which has that one mapped, would not map it."""
        cx, cy = detection.centre(detection.radius_m)
        gate = self.config.gate_m
        nearest, nearest_gap = None, gate
        for landmark_id, (lx, ly, radius) in self._landmarks.items():
            gap = math.hypot(cx - lx, cy - ly)
            if gap <= nearest_gap and (from_scan or gap <= radius + detection.radius_m):
                nearest, nearest_gap = landmark_id, gap
        if nearest is not None:
            del self._landmarks[nearest]
            return nearest
        track_id = f"scan-{self._next_id}"
        self._next_id += 1
        return track_id

    def _associate(
        self, found: list[Detection], t_ns: int, from_scan: bool = True
    ) -> list[tuple[Detection, ScanTrack | None]]:
        """Each detection with the track it continues (None: a new one): nearest pairs first, one detection
        per track, within the gate around each track's predicted position. A beam's disc (not
        ``from_scan``) continues a track only where it overlaps the track's disc: beams sweeping a long
        boulder's side otherwise dragged one track along it (``ScanTrack.hold``)."""
        gate = self.config.gate_m
        predicted = [track.predicted(t_ns) for track in self._tracks]
        pairs = []
        for i, detection in enumerate(found):
            own_x, own_y = detection.centre(detection.radius_m)
            for j, track in enumerate(self._tracks):
                px, py = predicted[j]
                reach = gate + abs(track.radius_m - detection.radius_m) + _PAIR_SLACK_M
                if abs(own_x - px) > reach or abs(own_y - py) > reach:
                    continue
                if from_scan:
                    cx, cy = detection.centre(track.radius_m)
                    gap = math.hypot(cx - px, cy - py)
                    if gap <= gate:
                        pairs.append((gap, i, j))
                    continue
                # Where it is reported (a beam-only track's fitted velocity is no motion: not judged).
                tx, ty = (px, py) if track.scanned else track.mean_xy
                gap = math.hypot(own_x - tx, own_y - ty)
                if gap <= min(gate, track.radius_m + detection.radius_m):
                    pairs.append((gap, i, j))
        pairs.sort()
        taken_detections: dict[int, ScanTrack] = {}
        taken_tracks: set[int] = set()
        for _, i, j in pairs:
            if i in taken_detections or j in taken_tracks:
                continue
            taken_detections[i] = self._tracks[j]
            taken_tracks.add(j)
        return [(detection, taken_detections.get(i)) for i, detection in enumerate(found)]
