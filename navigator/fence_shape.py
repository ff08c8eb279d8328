"""The geofence polygon's geometry: inside or not, and whether a fence from a config is one at all.

A fence is judged with the even-odd rule, which gives an answer for any list of points; so a fence whose
points are all on one line (nothing is inside), whose edges cross (inside flips at every crossing, which
no one meant), or that lies off the map (every goal on the map refused) is caught when the config loads.
"""

from __future__ import annotations

Point = tuple[float, float]
Polygon = tuple[Point, ...]


def inside_polygon(x: float, y: float, polygon: Polygon) -> bool:
    """Even-odd rule: a ray to +x crosses the polygon's edges an odd number of times iff inside."""
    inside = False
    n = len(polygon)
    for i in range(n):
        x1, y1 = polygon[i]
        x2, y2 = polygon[(i + 1) % n]
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


def polygon_area(polygon: Polygon) -> float:
    """Enclosed area (m^2, shoelace formula; sign dropped: either winding is a fence)."""
    n = len(polygon)
    twice = sum(
        polygon[i][0] * polygon[(i + 1) % n][1] - polygon[(i + 1) % n][0] * polygon[i][1] for i in range(n)
    )
    return abs(twice) / 2.0


def first_crossing(polygon: Polygon) -> tuple[int, int] | None:
    """Indices ``(i, j)`` of the first two non-neighbouring edges that meet (edge ``i`` runs from point
    ``i`` to point ``i + 1``), or None for a simple polygon."""
    n = len(polygon)
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # the last edge ends where the first begins
            if _segments_meet(polygon[i], polygon[(i + 1) % n], polygon[j], polygon[(j + 1) % n]):
                return i, j
    return None


def overlaps_box(polygon: Polygon, low: Point, high: Point) -> bool:
    """Whether the polygon and the axis-aligned box ``low``-``high`` share any area (or an edge)."""
    (x0, y0), (x1, y1) = low, high
    if any(x0 <= x <= x1 and y0 <= y <= y1 for x, y in polygon):
        return True
    corners = ((x0, y0), (x1, y0), (x1, y1), (x0, y1))
    if any(inside_polygon(x, y, polygon) for x, y in corners):
        return True
    n = len(polygon)
    return any(
        _segments_meet(polygon[i], polygon[(i + 1) % n], corners[k], corners[(k + 1) % 4])
        for i in range(n)
        for k in range(4)
    )


def _orientation(a: Point, b: Point, c: Point) -> float:
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _on_segment(a: Point, b: Point, p: Point) -> bool:
    return min(a[0], b[0]) <= p[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])


def _segments_meet(a: Point, b: Point, c: Point, d: Point) -> bool:
    """Whether segments a-b and c-d share a point (crossing, touching or overlapping)."""
    d1, d2 = _orientation(c, d, a), _orientation(c, d, b)
    d3, d4 = _orientation(a, b, c), _orientation(a, b, d)
    if ((d1 > 0) != (d2 > 0) and d1 != 0 and d2 != 0) and ((d3 > 0) != (d4 > 0) and d3 != 0 and d4 != 0):
        return True
    return (
        (d1 == 0 and _on_segment(c, d, a))
        or (d2 == 0 and _on_segment(c, d, b))
        or (d3 == 0 and _on_segment(a, b, c))
        or (d4 == 0 and _on_segment(a, b, d))
    )
