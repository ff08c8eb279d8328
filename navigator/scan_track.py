"""One obstacle followed across a range sensor's scans: where it is, how fast it moves, whether it moves.

Each detection's centre is placed with the track's radius, not its own (``Detection.centre``): the radius
one scan gives jumps with the number of sectors the object fills, and its centre would jump with it (a
boulder seen from a driving rover seemed to move at 1 m/s). The track's radius is the median of its
window's, in steps of ``RADIUS_STEP_M``, so the centres (a small fit each) are worked out again only when
that changes. Position and velocity are a straight-line fit through the window's centres.

A track is moving once its fitted speed stayed above the threshold for ``confirm_scans`` scans in a row
over at least half a window, and static again after as many below half that. A track whose speed is above
the threshold but not yet for long enough is undecided, and not reported: reported as static, a cart went
into the map for a scan or two before it was taken off again as moving.
"""

from __future__ import annotations

import math
from collections import deque

from navigator.perception import ObstacleObservation
from navigator.scan_clusters import Detection

RADIUS_STEP_M = 0.05


class ScanTrack:
    """The detections of one obstacle within the window, and what they say about it."""

    def __init__(self, track_id: str, first: Detection, from_scan: bool = True) -> None:
        self.track_id = track_id
        self.seen: deque[Detection] = deque([first])
        # Seen in a lidar's scan at least once; else by rangefinders' beams alone (add, hold).
        self.scanned = from_scan
        self.last_ns = first.t_ns  # when last seen (``hold`` sees it without adding to the window)
        self._centres: deque[tuple[float, float]] = deque()
        self.hits = 1
        self.moving = False
        self.fast = False  # the last fit's speed is above the moving threshold
        self._streak = 0  # scans in a row whose speed argues for the other state
        self.radius_m = _stepped(first.radius_m)
        self._centres.append(first.centre(self.radius_m))
        self.x, self.y = self._centres[0]
        self.vx = self.vy = 0.0
        self.mean_xy = (self.x, self.y)

    def predicted(self, t_ns: int) -> tuple[float, float]:
        age_s = (t_ns - self.seen[-1].t_ns) * 1e-9
        return self.x + self.vx * age_s, self.y + self.vy * age_s

    def add(
        self,
        detection: Detection,
        window_ns: int,
        confirm_scans: int,
        moving_speed_mps: float,
        from_scan: bool = True,
    ) -> None:
        """Add ``detection`` to the window and fit again. Only a lidar's scan (``from_scan``) lets the fit's
        speed move the track towards moving or static; a rangefinder's beam does not: it places its disc
        on the beam's axis wherever in the cone the echo came from, and a rock swept by a turning rover's
        cone seemed to move with the cone (docs/planning.md "Perception from rangefinders")."""
        self.last_ns = detection.t_ns
        self.scanned = self.scanned or from_scan
        seen, centres = self.seen, self._centres
        seen.append(detection)
        self.hits += 1
        oldest_ns = detection.t_ns - window_ns
        while len(seen) > 2 and seen[0].t_ns < oldest_ns:
            seen.popleft()
            centres.popleft()
        radius = _stepped(sorted(d.radius_m for d in seen)[len(seen) // 2])
        if radius != self.radius_m:
            self.radius_m = radius
            centres.clear()
            centres.extend(d.centre(radius) for d in seen)
        else:
            centres.append(detection.centre(radius))
        span_s = (seen[-1].t_ns - seen[0].t_ns) * 1e-9
        self._fit()
        if not from_scan:
            return
        speed = math.hypot(self.vx, self.vy)
        self.fast = speed > moving_speed_mps
        # To start moving, over half a window at least: two or three scans' fit says little about a speed.
        half_window = span_s >= window_ns * 0.5e-9
        arguing = speed < moving_speed_mps / 2.0 if self.moving else self.fast and half_window
        self._streak = self._streak + 1 if arguing else 0
        if self._streak >= confirm_scans:
            self.moving = not self.moving
            self._streak = 0

    def hold(self, detection: Detection) -> None:
        """Seen again where it stands (a rangefinder's beam on a track it alone has mapped): alive and
        counted, but not moved. Guidance maps a static obstacle where it was first reported and keeps it
        there; a track that slid on with the beams sweeping a long boulder's side left the boulder's
        front unmapped, and the rover drove into it (``scenarios/hidden-boulders.toml`` seed 5)."""
        self.last_ns = detection.t_ns
        self.hits += 1

    def reportable(self, confirm_scans: int) -> bool:
        """Seen often enough, and not a static track that seems to be starting to move."""
        return self.hits >= confirm_scans and (self.moving or not self.fast)

    def _fit(self) -> None:
        """Least-squares line through the window's centres: position at the newest, and velocity."""
        seen, centres = self.seen, self._centres
        t0 = seen[-1].t_ns
        ts = [(d.t_ns - t0) * 1e-9 for d in seen]
        n = len(ts)
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


def _stepped(radius_m: float) -> float:
    return max(RADIUS_STEP_M, round(radius_m / RADIUS_STEP_M) * RADIUS_STEP_M)
