"""From rangefinder beams to obstacle discs on the map: one disc per beam that saw something.

A single-beam rangefinder says only that the nearest echo within its cone lies ``r`` away: the obstacle's
near side touches the arc of radius ``r`` across the cone's horizontal field of view, somewhere. The disc
that stands for it holds that whole arc, as small as it can: with half-angle ``a`` the arc's ends lie
``r sin a`` either side of the axis, so its radius is ``R = max(r sin a, min_radius_m)`` and its centre
lies on the axis at ``r cos a + sqrt(R^2 - (r sin a)^2)``. A narrow beam (a 1-D lidar, ``a`` near 0)
gives a ``min_radius_m`` disc just behind the echo, as a single lidar return does
(``navigator.scan_clusters``); a wide sonar cone a disc as wide as its arc, whose near edge comes closer
than ``r`` (the echo could be at either end of the arc). A cone wider than 90 degrees is taken as 90: the
disc holding a wider arc would reach back over the sensor. Neighbouring beams are not merged: 45 degrees
apart, two echoes at one range are as likely two objects as one.

Each sensor id sits where the rover config's ``[perception] rangefinders`` says (``RangefinderMount``); it
faces the way its message's orientation says. A beam from an id the config does not name is placed at the
pose's reference point, with a warning the first time (as a lidar whose mount is not given is).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from firmware_bridge.distance_sensor import RangeBeam
from navigator.scan_clusters import Detection
from navigator.sensor_mount import SensorMount

logger = logging.getLogger(__name__)

MAX_HALF_ANGLE_RAD = math.pi / 4.0
MAX_FOV_DEG = 90.0


@dataclass(frozen=True)
class RangefinderMount:
    """Where rangefinder ``sensor_id`` sits: ``forward_m``, ``left_m`` from the pose's reference point in the
    rover's body frame; ``fov_deg``, its horizontal field of view when its messages say 0 (unknown, as
    ArduPilot's always do), 0-90 degrees; 0 is a narrow beam."""

    sensor_id: int
    forward_m: float = 0.0
    left_m: float = 0.0
    fov_deg: float = 0.0


def beam_detection(
    beam: RangeBeam, x: float, y: float, yaw: float, mount: RangefinderMount, min_radius_m: float
) -> Detection | None:
    """The disc ``beam`` saw (None: it saw nothing within range), with the rover's reference point at
    ``x``, ``y`` (ENU m) facing ``yaw`` (rad from east)."""
    distance = beam.range_m
    if distance is None:
        return None
    fov = beam.fov_rad if beam.fov_rad is not None else math.radians(mount.fov_deg)
    half = min(fov / 2.0, MAX_HALF_ANGLE_RAD)
    arc_half_width = distance * math.sin(half)
    radius = max(arc_half_width, min_radius_m)
    centre = distance * math.cos(half) + math.sqrt(radius * radius - arc_half_width * arc_half_width)
    sensor = SensorMount(mount.forward_m, mount.left_m, beam.bearing_rad)
    sx, sy = sensor.origin(x, y, yaw)
    heading = sensor.facing(yaw)
    ux, uy = math.cos(heading), math.sin(heading)
    edge = centre - radius
    echo = (sx + distance * ux, sy + distance * uy)
    return Detection(beam.t_ns, sx + edge * ux, sy + edge * uy, ux, uy, radius, (echo,))


class BeamPlacer:
    """Places beams by their sensor's mount (``mounts``, by id)."""

    def __init__(self, mounts: Iterable[RangefinderMount]) -> None:
        self._mounts: Mapping[int, RangefinderMount] = {m.sensor_id: m for m in mounts}
        self.unmounted: set[int] = set()  # ids seen that the config does not place

    def detections(
        self, beams: Iterable[RangeBeam], x: float, y: float, yaw: float, min_radius_m: float
    ) -> list[Detection]:
        found = []
        for beam in beams:
            mount = self._mounts.get(beam.sensor_id)
            if mount is None:
                mount = RangefinderMount(beam.sensor_id)
                if beam.sensor_id not in self.unmounted:
                    self.unmounted.add(beam.sensor_id)
                    logger.warning(
                        "rangefinder %d is not in [perception] rangefinders: its readings are placed at the "
                        "pose's reference point",
                        beam.sensor_id,
                    )
            detection = beam_detection(beam, x, y, yaw, mount, min_radius_m)
            if detection is not None:
                found.append(detection)
        return found
