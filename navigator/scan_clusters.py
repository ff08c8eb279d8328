"""From one range scan to obstacle discs on the map: neighbouring returns at similar ranges are one object.

The planner and the moving-obstacle checks think in discs (``ObstacleObservation``), a lidar gives ranges
per sector. Returns one sector apart whose ranges differ by less than ``gap_m`` plus ``gap_ratio`` of the
nearer range form a cluster; a free or unmeasured sector ends it. A cluster whose ends lie more than
``max_piece_m`` apart (a wall, a hedge) is cut into pieces no wider than that, one disc each, so a long
object is a row of discs and not one disc as wide as the row.

A disc of radius R whose near edge is r away spans a half-angle a with sin a = R / (r + R), so
R = r sin a / (1 - sin a); a is half the angle the cluster's sectors cover. Its centre lies r + R out along
the cluster's middle ray. Seen from one side only, the disc is a guess at the object's size, never smaller
than ``min_radius_m`` and never wider than the piece's ends allow, plus a sector's arc.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from firmware_bridge.obstacle_scan import ObstacleScan
from navigator.sensor_mount import AT_CENTRE, SensorMount

_FIT_STEPS = 4


@dataclass(frozen=True)
class ClusterSettings:
    gap_m: float = 0.3
    gap_ratio: float = 0.1
    max_piece_m: float = 1.5
    min_radius_m: float = 0.1


@dataclass(frozen=True)
class Detection:
    """One disc from one scan, in local ENU metres: the point of its edge nearest the sensor (``edge_x``,
    ``edge_y``), the unit vector from there to its centre (``ux``, ``uy``), its radius, and the scan's
    receive time. The centre is ``radius_m`` along the vector; a tracker that knows the object's size
    better (``navigator.scan_tracker``) places it with that instead."""

    t_ns: int
    edge_x: float
    edge_y: float
    ux: float
    uy: float
    radius_m: float
    points: tuple[tuple[float, float], ...]  # the returns themselves, ENU m

    def centre(self, radius_m: float) -> tuple[float, float]:
        """The centre of a disc of ``radius_m`` whose edge passes nearest the returns (least squares, a few
        Gauss-Newton steps from the edge point pushed back along the bearing). The bearing alone moves in
        steps of a sector as the rover drives past (5 degrees: 0.5 m at 6 m), and a static rock seemed to
        move with it; the returns move smoothly."""
        cx, cy = self.edge_x + radius_m * self.ux, self.edge_y + radius_m * self.uy
        points = self.points
        if len(points) < 2:
            return cx, cy
        for _ in range(_FIT_STEPS):
            # Normal equations of the residuals |p - c| - R in c (2 x 2, solved by hand).
            sxx = sxy = syy = bx = by = 0.0
            for px, py in points:
                dx, dy = cx - px, cy - py
                distance = math.hypot(dx, dy) or 1e-9
                jx, jy = dx / distance, dy / distance
                residual = distance - radius_m
                sxx += jx * jx
                sxy += jx * jy
                syy += jy * jy
                bx += jx * residual
                by += jy * residual
            determinant = sxx * syy - sxy * sxy
            if determinant < 1e-9:  # the returns in a line with the sensor: no lateral fix to make
                break
            cx -= (syy * bx - sxy * by) / determinant
            cy -= (sxx * by - sxy * bx) / determinant
        return cx, cy


def _clusters(scan: ObstacleScan, settings: ClusterSettings) -> list[list[tuple[float, float]]]:
    """Runs of neighbouring returns at similar ranges, each as ``(angle_rad, range_m)`` in ray order; on a
    full circle a run across the last and first sector is one."""
    rays = scan.rays
    step = scan.increment_rad
    runs: list[list[tuple[float, float]]] = []
    current: list[tuple[float, float]] = []
    previous_angle: float | None = None
    for angle, distance in rays:
        neighbour = (
            previous_angle is not None and abs(abs(_wrapped(angle - previous_angle)) - step) < step / 2
        )
        previous_angle = angle
        if distance is None:
            if current:
                runs.append(current)
            current = []
            continue
        if current and neighbour and _same_object(current[-1][1], distance, settings):
            current.append((angle, distance))
            continue
        if current:
            runs.append(current)
        current = [(angle, distance)]
    if current:
        runs.append(current)
    if scan.full_circle and len(runs) > 1 and rays[0][1] is not None and rays[-1][1] is not None:
        # The first ray opens the first run and the last closes the last: one object if they touch.
        touching = abs(abs(_wrapped(rays[0][0] - rays[-1][0])) - step) < step / 2
        if touching and _same_object(runs[-1][-1][1], runs[0][0][1], settings):
            runs[0] = runs.pop() + runs[0]
    return runs


def _same_object(range_a: float, range_b: float, settings: ClusterSettings) -> bool:
    return abs(range_a - range_b) <= settings.gap_m + settings.gap_ratio * min(range_a, range_b)


def _wrapped(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _point(angle: float, distance: float) -> tuple[float, float]:
    return distance * math.cos(angle), distance * math.sin(angle)


def _pieces(run: list[tuple[float, float]], max_piece_m: float) -> list[list[tuple[float, float]]]:
    """``run`` cut into consecutive pieces whose end points lie at most ``max_piece_m`` apart (a single
    return is always a piece)."""
    pieces: list[list[tuple[float, float]]] = []
    piece: list[tuple[float, float]] = []
    for ray in run:
        if piece and math.dist(_point(*piece[0]), _point(*ray)) > max_piece_m:
            pieces.append(piece)
            piece = []
        piece.append(ray)
    if piece:
        pieces.append(piece)
    return pieces


def _disc(
    piece: list[tuple[float, float]], step_rad: float, settings: ClusterSettings
) -> tuple[float, float, float]:
    """(bearing, centre distance, radius) of the disc behind ``piece``, in the scan's angles."""
    nearest = min(distance for _, distance in piece)
    first_angle = piece[0][0]
    # Unwrapped: the piece may run across +-pi.
    span = abs(_wrapped(piece[-1][0] - first_angle))
    middle = _wrapped(first_angle + math.copysign(span / 2.0, _wrapped(piece[-1][0] - first_angle)))
    half_angle = min((span + step_rad) / 2.0, math.radians(80.0))
    sine = math.sin(half_angle)
    radius = nearest * sine / (1.0 - sine)
    ends_apart = math.dist(_point(*piece[0]), _point(*piece[-1]))
    radius = min(radius, ends_apart / 2.0 + nearest * step_rad)
    radius = max(radius, settings.min_radius_m)
    return middle, nearest + radius, radius


def detections(
    scan: ObstacleScan,
    x: float,
    y: float,
    yaw: float,
    settings: ClusterSettings,
    mount: SensorMount = AT_CENTRE,
) -> list[Detection]:
    """The discs ``scan`` saw, placed on the map from the rover's pose (``x``, ``y`` ENU m, ``yaw`` rad from
    east) and where the sensor sits on it (``mount``).

    The discs are found in the scan's own polar coordinates, about the sensor (a disc's half-angle is as
    the sensor saw it); only the rays' origin and direction move onto the map. The origin is the sensor's
    position in either frame. A body-frame scan counts from the sensor's forward direction, so it turns
    by the rover's yaw and the mount's; a north-aligned one is on the map's axes already and turns by
    neither (the rover's heading still places the sensor, when it sits off the reference point)."""
    x, y = mount.origin(x, y, yaw)
    turn = mount.facing(yaw) if scan.body_frame else 0.0
    found: list[Detection] = []
    for run in _clusters(scan, settings):
        for piece in _pieces(run, settings.max_piece_m):
            bearing, distance, radius = _disc(piece, scan.increment_rad, settings)
            ux, uy = math.cos(bearing + turn), math.sin(bearing + turn)
            edge = distance - radius
            points = tuple(
                (x + r * math.cos(angle + turn), y + r * math.sin(angle + turn)) for angle, r in piece
            )
            found.append(Detection(scan.t_ns, x + edge * ux, y + edge * uy, ux, uy, radius, points))
    return found
