"""Geometry along a planned path (a list of map-frame points): the projection of a point
on a segment, its distance to it, and the point a given distance along the path."""

from __future__ import annotations

import math
from collections.abc import Sequence

from cloudnav_core.se2 import Point


def distance_to_segment(p: Point, a: Point, b: Point) -> float:
    return math.dist(p, projection_on(p, a, b))


def projection_on(p: Point, a: Point, b: Point) -> Point:
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    along = 0.0 if length2 == 0 else ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2
    t = max(0.0, min(1.0, along))
    return a[0] + t * dx, a[1] + t * dy


def point_along(path: Sequence[Point], index: int, position: Point, lookahead: float) -> Point:
    """The point ``lookahead`` metres along ``path`` from the projection of ``position``
    on segment ``index``; the path's end if it is nearer."""
    if len(path) == 1:
        return path[0]
    point, left = projection_on(position, path[index], path[index + 1]), lookahead
    for nxt in path[index + 1 :]:
        step = math.dist(point, nxt)
        if step >= left:
            f = left / step
            return point[0] + f * (nxt[0] - point[0]), point[1] + f * (nxt[1] - point[1])
        point, left = nxt, left - step
    return path[-1]
