"""Continuations along the road: follow the lane a road user is on, where the map has one.

The lanes come from the scenario's OpenDRIVE map (:func:`vei.maps.roads.load_roads`, every
lane type: riders use driving lanes, bike lanes and pavements alike). A road user's end
lies on a lane when it is inside the lane's polygon and its course is within the
tolerance of the lane's direction, either way (a rider may ride against a lane's
direction; a car's lane is chosen by its course). From the end point the continuation
follows that lane's centre line at the road user's own lateral offset, and on into the
lane whose centre line continues it (start within 1 m and direction within the
tolerance: lane sections, junctions); where none does, straight on along the last
tangent. The free continuation is blended into it over ``road_blend_m`` with a smooth
step (3u^2 - 2u^3), so that position and course join the recording exactly. The caller
(:mod:`vei.continuation.tracks`) checks the blended path against the curvature bounds and
keeps the free one where it does not hold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.continuation.path import EndState, path_arc, wrap

FloatArray = npt.NDArray[np.float64]

#: A lane's centre line continues another when it starts this close to its end [m].
_LINK_M = 1.0
#: Resampling step of the lane path [m].
_STEP_M = 0.25


@dataclass(frozen=True)
class LaneSet:
    """The lanes of a map as centre lines with their polygons.

    Attributes:
        centres: per lane [N, 2] centre line x, y [m] along the lane's s.
        polygons: per lane a shapely polygon (None where degenerate).
        types: per lane its OpenDRIVE type.
        source: the map file.
    """

    centres: tuple[FloatArray, ...]
    polygons: tuple[Any, ...]
    types: tuple[str, ...]
    source: str = ""

    @property
    def tree(self) -> Any:
        """STRtree of the polygons (built once)."""
        cached = self.__dict__.get("_tree")
        if cached is None:
            from shapely.strtree import STRtree

            cached = STRtree([p for p in self.polygons if p is not None])
            object.__setattr__(self, "_tree", cached)
            object.__setattr__(
                self, "_tree_idx", [i for i, p in enumerate(self.polygons) if p is not None]
            )
        return cached


@lru_cache(maxsize=8)
def _load(path: str, mtime_ns: int) -> LaneSet:
    from shapely.geometry import Polygon

    from vei.maps.roads import load_roads

    roads = load_roads(path)
    centres, polys, types = [], [], []
    for lane in roads.lanes:
        c = 0.5 * (lane.inner + lane.outer)
        if c.shape[0] < 2:
            continue
        poly = Polygon(lane.outline)
        if not poly.is_valid:
            poly = poly.buffer(0)
        centres.append(np.ascontiguousarray(c, dtype=np.float64))
        polys.append(poly if not poly.is_empty else None)
        types.append(lane.lane_type)
    return LaneSet(tuple(centres), tuple(polys), tuple(types), path)


def load_lanes(xodr_path: str | Path) -> LaneSet:
    """The lanes of an OpenDRIVE file (cached per file and modification time)."""
    p = Path(xodr_path)
    return _load(str(p), p.stat().st_mtime_ns)


def _project(line: FloatArray, x: float, y: float) -> tuple[int, float, float, float]:
    """(segment index, fraction, signed lateral offset (left > 0) [m], segment course
    [rad]) of the point's projection onto the polyline."""
    a = line[:-1]
    d = line[1:] - a
    ll = np.maximum((d * d).sum(axis=1), 1e-12)
    u = np.clip(((x - a[:, 0]) * d[:, 0] + (y - a[:, 1]) * d[:, 1]) / ll, 0.0, 1.0)
    px, py = a[:, 0] + u * d[:, 0], a[:, 1] + u * d[:, 1]
    dist = np.hypot(x - px, y - py)
    i = int(np.argmin(dist))
    course = math.atan2(d[i, 1], d[i, 0])
    side = d[i, 0] * (y - py[i]) - d[i, 1] * (x - px[i])
    return i, float(u[i]), math.copysign(float(dist[i]), side) if dist[i] > 0 else 0.0, course


def _forward(line: FloatArray, i: int, u: float, reverse: bool) -> FloatArray:
    """The polyline from the projection (segment i, fraction u) onwards (or backwards)."""
    p = line[i] + u * (line[i + 1] - line[i])
    if reverse:
        return np.vstack([p, line[i::-1]])
    return np.vstack([p, line[i + 1 :]])


def _successor(
    lanes: LaneSet, end: FloatArray, course: float, tol: float, used: set[int]
) -> tuple[int, bool] | None:
    """The lane whose centre line continues a line ending at ``end`` with ``course``."""
    best, best_d = None, _LINK_M
    for j, c in enumerate(lanes.centres):
        if j in used:
            continue
        for rev in (False, True):
            start = c[-1] if rev else c[0]
            nxt = c[-2] if rev else c[1]
            d = math.hypot(start[0] - end[0], start[1] - end[1])
            if d > best_d:
                continue
            ang = math.atan2(nxt[1] - start[1], nxt[0] - start[0])
            if abs(float(wrap(ang - course))) <= tol:
                best, best_d = (j, rev), d
    return best


def _offset(line: FloatArray, d: float) -> FloatArray:
    """The polyline moved by d [m] to its left (vertex normals)."""
    tang = np.gradient(line, axis=0)
    n = np.hypot(tang[:, 0], tang[:, 1])
    n = np.where(n > 1e-12, n, 1.0)
    nx, ny = -tang[:, 1] / n, tang[:, 0] / n
    return line + d * np.column_stack([nx, ny])


def lane_path(lanes: LaneSet, end: EndState, length_m: float, tol_rad: float) -> FloatArray | None:
    """[M, 2] the path along the lane the end lies on, from the end point, at least
    ``length_m`` long (straight on past the last lane), resampled every 0.25 m; None when
    the end lies on no lane whose direction matches its course within ``tol_rad``."""
    from shapely.geometry import Point

    if not lanes.centres:
        return None
    tree = lanes.tree
    idx = lanes.__dict__["_tree_idx"]
    pt = Point(end.x_m, end.y_m)
    best = None
    for k in tree.query(pt, predicate="intersects"):
        j = idx[int(k)]
        i, u, off, course = _project(lanes.centres[j], end.x_m, end.y_m)
        for rev in (False, True):
            ang = abs(float(wrap(course + (math.pi if rev else 0.0) - end.course_rad)))
            if ang <= tol_rad and (best is None or ang < best[0]):
                best = (ang, j, i, u, -off if rev else off, rev)
    if best is None:
        return None
    _, j, i, u, off, rev = best
    parts = [_forward(lanes.centres[j], i, u, rev)]
    used = {j}
    total = float(path_arc(parts[0])[-1])
    while total < length_m:
        last = parts[-1]
        if last.shape[0] < 2:
            break
        course = math.atan2(last[-1, 1] - last[-2, 1], last[-1, 0] - last[-2, 0])
        nxt = _successor(lanes, last[-1], course, tol_rad, used)
        if nxt is None:
            break
        jn, rn = nxt
        used.add(jn)
        c = lanes.centres[jn][::-1] if rn else lanes.centres[jn]
        parts.append(c[1:])
        total += float(path_arc(np.vstack([last[-1:], c[1:]]))[-1])
    line = _dedupe(np.vstack(parts))
    if line.shape[0] < 2:
        return None
    line = _offset(line, off)
    line[0] = (end.x_m, end.y_m)
    arc = path_arc(line)
    if arc[-1] < length_m:  # straight on along the last tangent
        d = line[-1] - line[-2]
        d = d / max(float(np.hypot(*d)), 1e-12)
        line = np.vstack([line, line[-1] + (length_m - arc[-1] + 1.0) * d])
        arc = path_arc(line)
    s = np.arange(0.0, arc[-1], _STEP_M)
    return np.column_stack([np.interp(s, arc, line[:, 0]), np.interp(s, arc, line[:, 1])])


def _dedupe(line: FloatArray) -> FloatArray:
    keep = np.concatenate([[True], np.hypot(*np.diff(line, axis=0).T) > 1e-6])
    return line[keep]


def blend(free: FloatArray, lane: FloatArray, blend_m: float) -> FloatArray:
    """[M, 3] the free path (x, y, course every 0.02 m) blended into the lane path
    (x, y) with weight 3u^2 - 2u^3, u = s / blend_m (clipped); course from the result."""
    s_f = path_arc(free)
    s_l = path_arc(np.column_stack([lane, np.zeros(lane.shape[0])]))
    s = s_f[s_f <= s_l[-1]]
    fx, fy = free[: s.size, 0], free[: s.size, 1]
    lx, ly = np.interp(s, s_l, lane[:, 0]), np.interp(s, s_l, lane[:, 1])
    u = np.clip(s / blend_m, 0.0, 1.0)
    w = u * u * (3.0 - 2.0 * u)
    x = (1.0 - w) * fx + w * lx
    y = (1.0 - w) * fy + w * ly
    th = np.empty(s.size)
    th[:-1] = np.arctan2(np.diff(y), np.diff(x))
    th[-1] = th[-2] if s.size > 1 else free[0, 2]
    th[0] = free[0, 2]
    return np.column_stack([x, y, np.unwrap(th)])


def max_curvature(path: FloatArray, window_m: float = 1.0) -> float:
    """Largest |curvature| of a path [1/m]: course change over ``window_m`` of arc."""
    arc = path_arc(path)
    if arc[-1] <= window_m:
        return 0.0
    th = np.unwrap(path[:, 2])
    s = np.arange(0.0, arc[-1] - window_m, 0.1)
    c0 = np.interp(s, arc, th)
    c1 = np.interp(s + window_m, arc, th)
    return float(np.abs(c1 - c0).max() / window_m) if s.size else 0.0
